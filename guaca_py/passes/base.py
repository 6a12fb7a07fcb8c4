"""Render pass interface: declares what it reads and writes by name, then executes."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, ClassVar

import moderngl

from ..pipeline.device import Device
from ..pipeline.settings import Setting
from ..shaders import set_uniform
from ..shaders.slots import Image, Texture

if TYPE_CHECKING:
    from ..pipeline.frame import FrameContext


class Pass:
    """A stage of the frame. `reads`/`writes` name the typed resources it uses (pipeline/resources.py).

    Passes are built once with the device and their settings, then run per frame with the frame
    context as their only input: they never reach the Renderer.
    """

    name: ClassVar[str] = ""
    reads: ClassVar[tuple[str, ...]] = ()
    writes: ClassVar[tuple[str, ...]] = ()
    SETTINGS: ClassVar[dict[str, Setting]] = {}
    # A per-pixel pass maps its one read to its one write pixel by pixel (no neighbours, no other
    # input), so the pass writing that read may apply it to its own output instead (fused when the
    # pipeline is built, see pipeline/assemble.py).
    per_pixel: ClassVar[bool] = False
    # Whether this pass can take a per-pixel pass as an epilogue of its output (see set_epilogue).
    accepts_epilogue: ClassVar[bool] = False

    def __init__(self, device: Device, settings: dict, readers: Mapping[str, tuple[str, ...]] | None = None):
        self.device = device
        self.settings = settings
        # resource -> the passes of this pipeline that read it (a pass may skip work nobody reads)
        self.readers: Mapping[str, tuple[str, ...]] = readers or {}
        self.fused_into: str | None = None  # set when an earlier pass does this pass's work
        self.epilogue: Pass | None = None  # the per-pixel pass this one applies to its output

    def set_epilogue(self, epilogue: Pass) -> None:
        """Apply the per-pixel pass `epilogue` to this pass's output (it then writes the epilogue's resource)."""
        raise NotImplementedError

    def epilogue_vars(self) -> dict:
        """Template variables of a per-pixel pass's GLSL when another pass applies it."""
        raise NotImplementedError

    def set_epilogue_uniforms(self, prog) -> None:
        """Uniforms of a per-pixel pass's GLSL in the program of the pass that applies it."""
        raise NotImplementedError

    @property
    def ctx(self) -> moderngl.Context:
        """The moderngl context."""
        return self.device.ctx

    def execute(self, frame: FrameContext) -> None:
        """Run the pass for one frame."""
        raise NotImplementedError

    def collect(self, frame: FrameContext) -> None:
        """After execute() and outside the pass's timer: read what the pass counted (may set frame.rerender).

        A read can wait for the GPU; inside the timer, the CPU work after that wait would count as
        GPU time (the GPU idles until the pass's end query arrives).
        """

    def release(self) -> None:
        """Free GPU resources held between frames."""


# glMemoryBarrier bits for a full-screen pass's output image: later passes sample it (texture
# fetch) or load it as an image, the next frame's dispatch stores to it again (image access), and it
# is read back (glGetTexImage: texture update), blitted or drawn from (framebuffer), or copied to a
# pixel buffer. Narrower than all bits (the default of ctx.memory_barrier()): nothing reads the
# output as a vertex, index, uniform, storage, command or atomic-counter buffer.
GL_TEXTURE_FETCH_BARRIER_BIT = 0x08
GL_SHADER_IMAGE_ACCESS_BARRIER_BIT = 0x20
GL_PIXEL_BUFFER_BARRIER_BIT = 0x80
GL_TEXTURE_UPDATE_BARRIER_BIT = 0x100
GL_FRAMEBUFFER_BARRIER_BIT = 0x400
IMAGE_OUTPUT_BARRIERS = (
    GL_TEXTURE_FETCH_BARRIER_BIT
    | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT
    | GL_PIXEL_BUFFER_BARRIER_BIT
    | GL_TEXTURE_UPDATE_BARRIER_BIT
    | GL_FRAMEBUFFER_BARRIER_BIT
)

_IMAGE_FORMATS = {"f1": "rgba8", "f2": "rgba16f", "f4": "rgba32f"}


class FullscreenPass(Pass):
    """A pass writing every pixel of an RGBA8/16F/32F target: a compute shader, or a full-screen triangle.

    Its target has the frame's output size: with supersampling the composite reads the rendered
    (larger) frame and writes the output, and the passes after it work at the output size.
    """

    template: ClassVar[str] = ""
    target_dtype: ClassVar[str] = "f1"
    # Compute wherever no rasterizer is needed: fragment shading runs on a small part of
    # data-centre GPUs (H100: the same arithmetic ran 32x slower in a fragment shader).
    compute: ClassVar[bool] = False

    def __init__(self, device: Device, settings: dict, readers: Mapping[str, tuple[str, ...]] | None = None):
        super().__init__(device, settings, readers)
        self._target = None

    def program(self, frame: FrameContext):
        """The compiled program of this pass (templated on its settings)."""
        return self.compile(dict(self.settings))

    def compile(self, variables: dict, template: str | None = None):
        """Compile `template` (default: the pass's) as this pass's kind of program."""
        template = template or self.template
        if self.compute:
            variables = dict(variables, output_format=_IMAGE_FORMATS[self.target_dtype])
            stages = {"compute_shader": (template, variables)}
        else:
            stages = {"vertex_shader": ("composite/fullscreen.vert.j2", {}), "fragment_shader": (template, variables)}
        return self.device.programs.program(stages, label=self.name)

    def target(self, frame: FrameContext):
        """The output framebuffer (the frame's output size), reallocated on resolution change."""
        size = frame.output_size
        if self._target is None or self._target.size != size:
            self.release()
            tex = self.ctx.texture(size, 4, dtype=self.target_dtype)
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
            self._target = self.ctx.framebuffer(color_attachments=[tex])
        return self._target

    def run_fullscreen(
        self, frame: FrameContext, prog, inputs: dict, scale: int = 1, edge: int = 8, strip: int = 0
    ) -> moderngl.Texture:
        """Bind input textures to units, write every pixel of the target, return the output texture.

        A compute pass runs `scale` x `scale` invocations per output pixel in `edge` x `edge` workgroups,
        launched in strips `strip` workgroups wide (0: row by row; post/compute_pass.glsl.j2).
        """
        fbo = self.target(frame)
        for unit, (uname, tex) in enumerate(inputs.items(), start=Texture.PASS_INPUTS):
            tex.use(location=unit)
            set_uniform(prog, uname, unit)
        out = fbo.color_attachments[0]
        if self.compute:
            out.bind_to_image(Image.PASS_OUTPUT, read=False, write=True)
            w, h = frame.output_size
            set_uniform(prog, "gua_size", (w, h))
            set_uniform(prog, "gua_group_strip", strip)
            prog.run(-(-w * scale // edge), -(-h * scale // edge), 1)
            self.ctx.memory_barrier(IMAGE_OUTPUT_BARRIERS)  # later passes sample the result (or read it back)
            return out
        fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        self.device.fullscreen(prog)
        return out

    def release(self) -> None:
        """Free the output target."""
        if self._target is not None:
            for t in self._target.color_attachments:
                t.release()
            self._target.release()
            self._target = None
