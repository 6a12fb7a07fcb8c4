"""Render pass interface: declares what it reads and writes by name, then executes."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from ..pipeline.settings import Setting

if TYPE_CHECKING:
    from ..pipeline.frame import FrameState


class Pass:
    """A stage of the frame. `reads`/`writes` name entries of FrameState.resources."""

    name: ClassVar[str] = ""
    reads: ClassVar[tuple[str, ...]] = ()
    writes: ClassVar[tuple[str, ...]] = ()
    SETTINGS: ClassVar[dict[str, Setting]] = {}

    def __init__(self, renderer, settings: dict):
        self.renderer = renderer
        self.settings = settings

    @property
    def ctx(self):
        """The moderngl context."""
        return self.renderer.ctx

    def execute(self, frame: FrameState) -> None:
        """Run the pass for one frame."""
        raise NotImplementedError

    def release(self) -> None:
        """Free GPU resources held between frames."""


class FullscreenPass(Pass):
    """A post pass drawing one screen-covering triangle into an RGBA8/RGBA16F target."""

    template: ClassVar[str] = ""
    target_dtype: ClassVar[str] = "f1"

    def __init__(self, renderer, settings):
        super().__init__(renderer, settings)
        self._target = None

    def program(self, frame: FrameState):
        """The compiled program of this pass (templated on its settings)."""
        return self.renderer.shaders.program(
            (self.name, tuple(sorted(self.settings.items()))),
            {
                "vertex_shader": ("composite/fullscreen.vert.j2", {}),
                "fragment_shader": (self.template, dict(self.settings)),
            },
            label=self.name,
        )

    def target(self, frame: FrameState):
        """The output framebuffer, reallocated on resolution change."""
        size = (frame.width, frame.height)
        if self._target is None or self._target.size != size:
            self.release()
            tex = self.ctx.texture(size, 4, dtype=self.target_dtype)
            tex.filter = (self.renderer.moderngl.LINEAR, self.renderer.moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
            self._target = self.ctx.framebuffer(color_attachments=[tex])
        return self._target

    def run_fullscreen(self, frame: FrameState, prog, inputs: dict) -> object:
        """Bind input textures to units, draw, return the output texture."""
        fbo = self.target(frame)
        fbo.use()
        self.ctx.disable(self.renderer.moderngl.DEPTH_TEST | self.renderer.moderngl.BLEND)
        for unit, (uname, tex) in enumerate(inputs.items()):
            tex.use(location=unit)
            if uname in prog:
                prog[uname] = unit
        self.renderer.fullscreen(prog)
        return fbo.color_attachments[0]

    def release(self) -> None:
        """Free the output target."""
        if self._target is not None:
            for t in self._target.color_attachments:
                t.release()
            self._target.release()
            self._target = None
