"""The frame context that flows through the passes, and the frame result handed back."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..shaders import mat_bytes, set_uniforms
from .device import Device
from .resources import FrameResources
from .stats import FrameStats

if TYPE_CHECKING:
    from ..scene.graph import Scene
    from .drawlist import Draw


@dataclass
class FrameContext:
    """What one frame hands its passes: the device, the method, the draw list, typed resources, stats.

    Passes, the method and the rasterizers receive it as their argument; it holds no Renderer.
    `raster` draws geometry (hardware or compute, per draw); the views are `view`/`projection`.
    `width` x `height` is the rendered size: with antialiasing.supersample K, K times the output's
    (`output_size`), which the composite writes and the post passes work at.
    """

    device: Device
    # the transparency method (methods.base.TransparencyMethod) and the rasterizer router
    # (raster.router.RasterRouter): typed loosely, as both import this module
    method: Any
    raster: Any
    scene: Scene
    width: int
    height: int
    draws: list[Draw]
    view: np.ndarray
    projection: np.ndarray
    resources: FrameResources = field(default_factory=FrameResources)
    stats: FrameStats = field(default_factory=FrameStats)
    rerender: bool = False
    # Frame loops without read-back: counters are read a frame late instead of waiting for the GPU
    # (the stats then describe the previous frame, and an overflow grows the pool for the next one)
    late_counters: bool = False
    # Which view of a Renderer.render_views() call this frame is, of how many (render(): 0 of 1).
    # Views share the method's storage; what is read a frame late is kept per view, and a pool
    # shrinks only to hold the largest view's need (methods/shared_pool.py)
    view_index: int = 0
    view_count: int = 1
    # GL names of this frame's textures known to hold one colour in every pixel (the composite of a
    # frame with nothing drawn; per-pixel passes of such an image): passes that would not change
    # such an image (FXAA) skip it
    uniform_textures: set = field(default_factory=set)

    @property
    def ctx(self):
        """The moderngl context."""
        return self.device.ctx

    @property
    def caps(self):
        """Device capabilities."""
        return self.device.caps

    @property
    def programs(self):
        """The program builder (templates -> compiled programs, cached by their variables)."""
        return self.device.programs

    @property
    def pixel_count(self) -> int:
        """Pixels in the rendered frame."""
        return self.width * self.height

    @property
    def supersample(self) -> int:
        """Rendered pixels per output pixel along each axis (antialiasing.supersample; 1: off)."""
        return self.device.antialiasing.supersample

    @property
    def output_size(self) -> tuple[int, int]:
        """(width, height) of the frame's image: the rendered size divided by the supersampling factor."""
        k = self.supersample
        return self.width // k, self.height // k

    @property
    def camera_position(self) -> np.ndarray:
        """World-space eye position."""
        return np.linalg.inv(self.view)[:3, 3]

    @cached_property
    def transparent_draws(self) -> list[Draw]:
        """Draws whose material instance can produce alpha < 1."""
        return [d for d in self.draws if d.transparent]

    @cached_property
    def _frame_uniform_bytes(self) -> dict[str, bytes]:
        """The shared camera uniforms as GL bytes, made once per frame (every program of every draw writes them)."""
        return {
            "gua_view_matrix": mat_bytes(self.view),
            "gua_projection_matrix": mat_bytes(self.projection),
            "gua_inverse_view_projection": mat_bytes(np.linalg.inv(self.projection @ self.view)),
            "gua_camera_position": np.asarray(self.camera_position, dtype=np.float32).tobytes(),
            "gua_resolution": np.asarray([self.width, self.height], dtype=np.float32).tobytes(),
        }

    def set_frame_uniforms(self, prog) -> None:
        """Write the shared camera uniforms a program uses (those it holds already cost a lookup each)."""
        set_uniforms(prog, self._frame_uniform_bytes.items())

    def bind_lights(self, prog) -> None:
        """Bind the culled lights (and light grid) for a program that includes shading/lighting."""
        self.resources["light_grid"].bind(prog)

    def shading_vars(self) -> dict:
        """Template variables shading/lighting.glsl.j2 needs (light lookup mode)."""
        return dict(self.resources["light_grid"].template_vars)

    def draw_transparent(
        self, uniforms: dict | None = None, per_program: Callable | None = None, order: list[Draw] | None = None
    ) -> None:
        """Draw every transparent draw (or the draws of `order`, in that order) with the method's program variant.

        Each draw goes through the hardware or the compute rasterizer (transparency.raster).
        """
        draws = self.transparent_draws if order is None else order
        self.raster.draw(self, draws, uniforms or {}, per_program)

    def draw_opaque(self) -> None:
        """Draw every opaque draw into the currently bound G-buffer."""
        self.raster.hardware.draw(self, [d for d in self.draws if not d.transparent], transparent=False)


class FrameResult:
    """A finished frame: display image (row 0 at the top), optional linear color, statistics.

    A frame rendered with `read_back=False` keeps its colour on the GPU (`texture`, valid until
    the renderer's next frame); `image` and `linear` read it back on first access.
    """

    def __init__(
        self,
        image: np.ndarray | None,
        stats: dict,
        linear: np.ndarray | None = None,
        *,
        texture=None,
        reader: Callable | None = None,
    ):
        self._image, self._linear, self.stats, self.texture, self._reader = image, linear, stats, texture, reader

    @property
    def is_read(self) -> bool:
        """Whether the image is on the CPU (a `read_back=False` frame stays on the GPU until asked for)."""
        return self._image is not None

    def read(self) -> FrameResult:
        """Copy the frame to the CPU now (no-op once read)."""
        if self._image is None and self._reader is not None:
            self._image, self._linear = self._reader()
            self._reader = None
        return self

    @property
    def image(self) -> np.ndarray:
        """(H, W, 3) uint8, row 0 at the top; read back from the GPU on first access."""
        self.read()
        return self._image

    @property
    def linear(self) -> np.ndarray | None:
        """(H, W, 3) float32 linear colour when the pipeline ends in a float target, else None."""
        self.read()
        return self._linear

    def save(self, path: str | Path) -> Path:
        """Write the image (format from the suffix, e.g. .png) through a temporary file and a rename."""
        from PIL import Image

        from ..output import IMAGE_SUFFIXES, check_writable, write_atomic

        path = check_writable(path, "--out", IMAGE_SUFFIXES)
        fmt = Image.registered_extensions().get(path.suffix.lower())
        return write_atomic(path, lambda tmp: Image.fromarray(self.image).save(tmp, format=fmt), "--out")

    def _repr_png_(self) -> bytes:
        """The image as PNG bytes: a frame that is a notebook cell's value shows itself (IPython's display hook)."""
        import io

        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(self.image).save(buf, format="PNG")
        return buf.getvalue()

    def save_stats(self, path: str | Path) -> Path:
        """Write the statistics as JSON through a temporary file and a rename."""
        from ..output import check_writable, write_atomic

        text = json.dumps(self.stats, indent=2)
        return write_atomic(check_writable(path, "--stats"), lambda tmp: tmp.write_text(text), "--stats")
