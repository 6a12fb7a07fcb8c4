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


OUTPUT_IMAGE_UNIT = 7  # image units below may be bound by methods (A-buffer saturation depth: 0)
_IMAGE_FORMATS = {"f1": "rgba8", "f2": "rgba16f", "f4": "rgba32f"}


class FullscreenPass(Pass):
    """A pass writing every pixel of an RGBA8/16F/32F target: a compute shader, or a full-screen triangle."""

    template: ClassVar[str] = ""
    target_dtype: ClassVar[str] = "f1"
    # Compute wherever no rasterizer is needed: fragment shading runs on a small part of
    # data-centre GPUs (H100: the same arithmetic ran 32x slower in a fragment shader).
    compute: ClassVar[bool] = False

    def __init__(self, renderer, settings):
        super().__init__(renderer, settings)
        self._target = None

    def program(self, frame: FrameState):
        """The compiled program of this pass (templated on its settings)."""
        return self.compile(dict(self.settings), (self.name, tuple(sorted(self.settings.items()))))

    def compile(self, variables: dict, key, template: str | None = None):
        """Compile `template` (default: the pass's) as this pass's kind of program."""
        template = template or self.template
        if self.compute:
            variables = dict(
                variables, output_image_unit=OUTPUT_IMAGE_UNIT, output_format=_IMAGE_FORMATS[self.target_dtype]
            )
            stages = {"compute_shader": (template, variables)}
        else:
            stages = {"vertex_shader": ("composite/fullscreen.vert.j2", {}), "fragment_shader": (template, variables)}
        return self.renderer.shaders.program(key, stages, label=self.name)

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
        """Bind input textures to units, write every pixel of the target, return the output texture."""
        fbo = self.target(frame)
        for unit, (uname, tex) in enumerate(inputs.items()):
            tex.use(location=unit)
            if uname in prog:
                prog[uname] = unit
        out = fbo.color_attachments[0]
        if self.compute:
            out.bind_to_image(OUTPUT_IMAGE_UNIT, read=False, write=True)
            if "gua_size" in prog:
                prog["gua_size"] = (frame.width, frame.height)
            prog.run(-(-frame.width // 8), -(-frame.height // 8), 1)
            self.ctx.memory_barrier()  # later passes sample the result (or read it back)
            return out
        fbo.use()
        self.ctx.disable(self.renderer.moderngl.DEPTH_TEST | self.renderer.moderngl.BLEND)
        self.renderer.fullscreen(prog)
        return out

    def release(self) -> None:
        """Free the output target."""
        if self._target is not None:
            for t in self._target.color_attachments:
                t.release()
            self._target.release()
            self._target = None
