"""Frame loop output: draw the finished frame into a host framebuffer or texture, on the GPU."""

from __future__ import annotations

import moderngl

from .errors import GuacaError
from .shaders.slots import Texture


class Presenter:
    """Copies the pipeline's final colour into a target with one full-screen triangle."""

    def __init__(self, device):
        self.device = device

    def program(self):
        """The copy program (compiled once by the program builder)."""
        return self.device.programs.program(
            {
                "vertex_shader": ("composite/fullscreen.vert.j2", {}),
                "fragment_shader": ("present/copy.frag.j2", {}),
            },
            label="present",
        )

    def draw(self, color, target, viewport: tuple[int, int, int, int] | None = None) -> None:
        """Draw texture `color` into `target` (a moderngl Framebuffer or Texture) over `viewport`."""
        ctx = self.device.ctx
        own_fbo = None
        if isinstance(target, moderngl.Texture):
            own_fbo = ctx.framebuffer(color_attachments=[target])  # released below: no cache to leak
            fbo = own_fbo
        elif isinstance(target, moderngl.Framebuffer):
            fbo = target
        else:
            raise GuacaError(
                f"render target must be a moderngl Framebuffer or Texture, got {type(target).__name__} "
                "(pass ctx.screen, ctx.fbo, a framebuffer you made, or a texture you own)"
            )
        try:
            vp = tuple(int(v) for v in (viewport or (0, 0, *fbo.size)))
            host_viewport = fbo.viewport  # moderngl keeps it per framebuffer: the host's must survive
            fbo.use()
            ctx.viewport = vp
            ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND | moderngl.CULL_FACE)
            prog = self.program()
            prev_filter = color.filter
            color.filter = (moderngl.LINEAR, moderngl.LINEAR)
            color.use(location=Texture.PRESENT_INPUT)
            prog["gua_input"] = Texture.PRESENT_INPUT
            prog["gua_viewport"] = tuple(float(v) for v in vp)
            self.device.fullscreen(prog)
            color.filter = prev_filter
            fbo.viewport = host_viewport
        finally:
            if own_fbo is not None:
                own_fbo.release()
