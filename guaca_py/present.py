"""Frame loop output: draw the finished frame into a host framebuffer or texture, on the GPU.

Over the host's own frame (`render(..., target=fbo, over_target=True)`) it also moves depth
between the host's framebuffer and guaca's: the host's depth into a texture of the frame's size
before the frame (the host's layer), guaca's opaque depth back into the host's depth attachment
after it, and the frame is blended over the host's colour instead of replacing it.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl

from .errors import GuacaError
from .gl_state import raw_gl
from .pipeline.resources import HostLayer
from .shaders.slots import Texture

GL_DEPTH_BUFFER_BIT = 0x100
GL_NEAREST = 0x2600


@dataclass(frozen=True)
class HostTarget:
    """A host framebuffer a frame is composed over: the framebuffer and the frame's rectangle in it."""

    fbo: moderngl.Framebuffer
    viewport: tuple[int, int, int, int]  # x, y, width, height: the frame's pixels, one for one
    depth_source: str  # "texture" or "renderbuffer"


def host_target(target, width: int, height: int, viewport: tuple[int, int, int, int] | None) -> HostTarget:
    """Check that `target` can hold the opaque layer of a width x height frame; GuacaError says what it lacks."""
    need = "over_target needs a moderngl Framebuffer with a colour attachment and a depth attachment (texture or renderbuffer)"
    if not isinstance(target, moderngl.Framebuffer):
        got = "no target" if target is None else type(target).__name__
        raise GuacaError(f"{need}; got {got}")
    colours = list(target.color_attachments or ())
    depth = target.depth_attachment
    missing = [
        what for what, absent in (("a colour attachment", not colours), ("a depth attachment", depth is None)) if absent
    ]
    if missing:
        raise GuacaError(
            f"{need}; this framebuffer has no {' and no '.join(m.removeprefix('a ') for m in missing)} "
            "(a window's default framebuffer, such as ctx.screen, has no attachments guaca can read: draw the "
            "opaque layer into a framebuffer of your own, then copy it to the window)"
        )
    if any(getattr(a, "samples", 0) > 1 for a in (*colours, depth)):
        raise GuacaError(
            f"{need}, single-sampled: its attachments have several samples per pixel; resolve them into a "
            "single-sample framebuffer first, or use guaca's antialiasing.samples"
        )
    vp = tuple(int(v) for v in viewport) if viewport is not None else (0, 0, *target.size)
    if vp[2:] != (width, height):
        where = f"viewport {vp[2]}x{vp[3]}" if viewport is not None else f"target of {vp[2]}x{vp[3]}"
        raise GuacaError(
            f"over_target composes pixel for pixel: the frame is {width}x{height}, the {where}; render at the "
            "target's size, or give a viewport=(x, y, width, height) of the frame's size"
        )
    if vp[0] < 0 or vp[1] < 0 or vp[0] + vp[2] > target.size[0] or vp[1] + vp[3] > target.size[1]:
        raise GuacaError(f"viewport {vp} reaches outside the {target.size[0]}x{target.size[1]} target")
    source = "renderbuffer" if isinstance(depth, moderngl.Renderbuffer) else "texture"
    return HostTarget(target, vp, source)


class Presenter:
    """Copies the pipeline's final colour into a target with one full-screen triangle; moves the host's depth."""

    def __init__(self, device):
        self.device = device
        self._depth = None  # depth-only framebuffer of the frame's size: the host's layer in and out

    def program(self, over: bool = False):
        """The copy program (over: premultiplied colour and coverage, for blending), compiled once."""
        return self.device.programs.program(
            {
                "vertex_shader": ("composite/fullscreen.vert.j2", {}),
                "fragment_shader": ("present/copy.frag.j2", {"over": over}),
            },
            label="present",
        )

    def draw(self, color, target, viewport: tuple[int, int, int, int] | None = None, over: bool = False) -> None:
        """Draw texture `color` into `target` (a moderngl Framebuffer or Texture) over `viewport`.

        `over`: blend it over what the target holds (premultiplied alpha) instead of replacing it.
        """
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
            if over:
                ctx.enable(moderngl.BLEND)
                ctx.blend_equation = moderngl.FUNC_ADD
                ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
            prog = self.program(over)
            prev_filter = color.filter
            color.filter = (moderngl.LINEAR, moderngl.LINEAR)
            color.use(location=Texture.PRESENT_INPUT)
            prog["gua_input"] = Texture.PRESENT_INPUT
            prog["gua_viewport"] = tuple(float(v) for v in vp)
            self.device.fullscreen(prog)
            color.filter = prev_filter
            if over:
                ctx.disable(moderngl.BLEND)
            fbo.viewport = host_viewport
        finally:
            if own_fbo is not None:
                own_fbo.release()

    # ------------------------------------------------------------------ the host's depth
    def _depth_fbo(self, width: int, height: int) -> moderngl.Framebuffer:
        """The depth-only framebuffer of the frame's size that the host's depth passes through."""
        if self._depth is None or self._depth.size != (width, height):
            self.release()
            tex = self.device.ctx.depth_texture((width, height))
            tex.compare_func = ""  # read as depth values (texelFetch), not compared
            self._depth = self.device.ctx.framebuffer(depth_attachment=tex)
        return self._depth

    def _blit_depth(self, src: moderngl.Framebuffer, src_rect, dst: moderngl.Framebuffer, dst_rect) -> None:
        """Copy depth from `src_rect` of `src` to `dst_rect` of `dst` (rectangles x, y, width, height)."""
        gl = raw_gl()
        if gl is None:
            raise GuacaError("over_target copies depth with glBlitNamedFramebuffer, which no GL library here exposes")
        gl.drain_errors()  # errors pending before the blit are not the blit's
        (sx, sy, sw, sh), (dx, dy, dw, dh) = src_rect, dst_rect
        gl.glBlitNamedFramebuffer(
            src.glo, dst.glo, sx, sy, sx + sw, sy + sh, dx, dy, dx + dw, dy + dh, GL_DEPTH_BUFFER_BIT, GL_NEAREST
        )
        errors = gl.drain_errors()
        if errors:
            raise GuacaError(
                f"copying the target's depth failed (GL error 0x{errors[0]:04X}): over_target needs a depth "
                "attachment of the format moderngl's depth_texture() and depth_renderbuffer() make (24-bit depth)"
            )

    def read_host_layer(self, host: HostTarget) -> HostLayer:
        """The host's depth at the frame's pixels, copied into a texture of guaca's (a renderbuffer cannot be sampled)."""
        x, y, w, h = host.viewport
        fbo = self._depth_fbo(w, h)
        self._blit_depth(host.fbo, host.viewport, fbo, (0, 0, w, h))
        return HostLayer(depth=fbo.depth_attachment, source=host.depth_source)

    def write_host_depth(self, host: HostTarget, gbuffer) -> None:
        """Write the frame's opaque depth (the host's and guaca's nearer opaque surfaces) into the host's depth."""
        ctx = self.device.ctx
        x, y, w, h = host.viewport
        fbo = self._depth_fbo(w, h)  # one value per pixel, then copied as it is
        fbo.use()
        fbo.depth_mask = True
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "1"  # every pixel takes the frame's depth
        prog = self.device.programs.program(
            {
                "vertex_shader": ("composite/fullscreen.vert.j2", {}),
                "fragment_shader": (
                    "present/depth_out.frag.j2",
                    {"samples": gbuffer.samples, "supersample": self.device.antialiasing.supersample},
                ),
            },
            label="host_depth",
        )
        gbuffer.depth.use(location=Texture.HOST_DEPTH)
        self.device.fullscreen(prog)
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST)
        self._blit_depth(fbo, (0, 0, w, h), host.fbo, host.viewport)

    def release(self) -> None:
        """Free the depth framebuffer."""
        if self._depth is not None:
            self._depth.depth_attachment.release()
            self._depth.release()
            self._depth = None
