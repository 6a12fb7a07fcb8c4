"""The typed resources a frame's passes hand each other, and the checked table that holds them.

Every pass declares the names it reads and writes (Pass.reads / Pass.writes); the pipeline checks
the declarations when it is built, and FrameResources checks every access against the running
pass's declaration and every value against its resource's type, so a pass can only use what it
declared (Falcor's reflect/execute split).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import moderngl
import numpy as np

from ..shaders import set_uniform
from ..shaders.slots import Buffer, Texture


def unpack_grid(words: np.ndarray, count: int) -> np.ndarray:
    """Bool (count, th, tw) from light-grid words (layers, th, tw): bit i % 32 of layer i // 32."""
    words = np.asarray(words, dtype=np.uint32)
    i = np.arange(count)
    return ((words[i // 32] >> (i % 32).astype(np.uint32)[:, None, None]) & 1).astype(bool)


@dataclass(frozen=True)
class GBuffer:
    """The opaque layer: albedo, normal+roughness, emissive+metalness, depth (multisampled with antialiasing)."""

    fbo: moderngl.Framebuffer
    depth_only: moderngl.Framebuffer  # the depth attachment alone (transparent passes test against it)
    albedo: moderngl.Texture
    normal: moderngl.Texture
    material: moderngl.Texture
    depth: moderngl.Texture
    # whether its depth holds a surface this frame: an opaque draw, or the host's layer (the composite
    # reads the depth only then, and the colour only where guaca drew: see host_layer)
    has_opaque: bool
    samples: int
    # the host's opaque layer is under the frame (render(..., over_target=True)): its pixels hold the
    # host's depth and the albedo alpha HOST_MARK, which the composite does not shade
    host_layer: bool = False


# Albedo alpha of G-buffer pixels that hold the host's surface (guaca's opaque draws write 0 or 1)
HOST_MARK = -1.0


@dataclass(frozen=True)
class HostLayer:
    """The host's opaque layer under the frame (render(..., target=fbo, over_target=True)).

    Its colour stays in the host's framebuffer (the frame is blended over it); its depth, in the
    standard OpenGL range [0, 1] made with the scene camera's projection and view, is copied here
    (single-sampled, the frame's size) for the geometry pass to start the G-buffer depth from.
    """

    depth: moderngl.Texture  # the host's depth at the frame's pixels (compare mode off: read as values)
    source: str  # "texture" or "renderbuffer": the host's depth attachment it was copied from


@dataclass(frozen=True)
class LightGrid:
    """The visible lights (bit order) and, where built, the per-tile light bit grid."""

    buffer: moderngl.Buffer  # packed lights, read per fragment
    count: int
    grid: moderngl.TextureArray | None  # None: no grid this frame (every light shades every pixel)
    layers: int  # 32-light layers to read (0 without a grid)
    layers_allocated: int
    tile_size: int
    tiles: tuple[int, int]  # (across, down)
    template_vars: Mapping[str, Any]  # how shading/lighting.glsl.j2 looks lights up

    def bind(self, prog) -> None:
        """Bind the light list (and grid, when built) for a shading program."""
        self.buffer.bind_to_storage_buffer(Buffer.LIGHTS)
        set_uniform(prog, "gua_light_count", self.count)
        # its own unit even without a grid (no sampler type may share a unit with another);
        # with 0 layers nothing samples it
        if set_uniform(prog, "gua_light_bits", Texture.LIGHT_GRID):
            if self.grid is not None:
                self.grid.use(location=Texture.LIGHT_GRID)
            set_uniform(prog, "gua_tile_size", self.tile_size)
            set_uniform(prog, "gua_light_layers", self.layers)

    def bits(self) -> np.ndarray:
        """Bool (lights, tiles down, tiles across) read back from the grid (waits for the GPU)."""
        tw, th = self.tiles
        if self.grid is None:
            return np.zeros((0, th, tw), dtype=bool)
        words = np.frombuffer(self.grid.read(), dtype=np.uint32).reshape(self.layers_allocated, th, tw)
        return unpack_grid(words, self.count)


class TransparentStore:
    """What the transparency method stored this frame, as the composite and the debug views may read it.

    A narrow view of the method: the resolve code and its variables, the bindings it reads, the
    threshold the composite stops at. Methods that shade while they draw (peeling) draw here, in
    the composite, once the lights are culled (`draws_in_composite`).
    """

    __slots__ = ("_method", "nodes_by_tile")

    def __init__(self, method):
        self._method = method
        # whether a screen tile's fragments lie together in storage (set by the geometry pass from
        # what the rasterizers did): the composite then reads the frame tile strip by tile strip
        self.nodes_by_tile = False

    @property
    def method_id(self) -> str:
        """The method that stored the fragments."""
        return self._method.id

    @property
    def draws_in_composite(self) -> bool:
        """Whether the method draws its transparent geometry inside the composite pass."""
        return self._method.geometry_in_composite

    def resolve_template(self) -> str:
        """Template defining gua_resolve_transparent() for the composite."""
        return self._method.resolve_template()

    def template_vars(self) -> dict:
        """The method's template variables (its storage layout)."""
        return self._method.template_vars()

    def extensions(self) -> str:
        """Every #extension line the method's code needs."""
        return self._method.extensions()

    def resolve_extensions(self) -> str:
        """The #extension lines the compute resolve can use."""
        return self._method.resolve_extensions()

    def threshold(self) -> float:
        """Accumulated alpha at which the composite stops walking fragments."""
        return self._method.composite_threshold()

    def bind(self, frame, program) -> None:
        """Bind the storage and uniforms the resolve reads."""
        self._method.bind_composite(frame, program)

    def after_composite(self, frame) -> None:
        """Read what the composite counted into the frame's stats."""
        self._method.after_composite(frame)

    def draw(self, frame) -> bool:
        """Store the transparent fragments now (methods that draw in the composite); True asks to draw again."""
        self._method.prepare(frame)
        self._method.render_transparent(frame)
        frame.ctx.memory_barrier()
        return self._method.finish(frame)


RESOURCE_TYPES: dict[str, tuple[type, ...]] = {
    "draw_list": (list,),
    "host_layer": (HostLayer, type(None)),  # None: the frame is drawn over nothing of the host's
    "lights": (list,),
    "gbuffer": (GBuffer,),
    "light_grid": (LightGrid,),
    "transparent": (TransparentStore, type(None)),  # None: the frame has no transparent draw
    "hdr": (moderngl.Texture,),  # linear colour
    "ldr": (moderngl.Texture,),  # display-referred 8-bit colour
}
IMAGES = ("hdr", "ldr")  # the frame's colour is the image written last


class ResourceError(RuntimeError):
    """A pass used a resource it did not declare, or wrote a value of the wrong type."""


@dataclass
class FrameResources:
    """The frame's resources by name; access is checked against the running pass's declaration."""

    _values: dict[str, Any] = field(default_factory=dict)
    _pass: str | None = None  # the pass running now (None: the renderer, between passes)
    _reads: tuple[str, ...] = ()
    _writes: tuple[str, ...] = ()
    output: moderngl.Texture | None = None  # the image written last: the frame's colour

    def enter(self, name: str | None, reads: tuple[str, ...] = (), writes: tuple[str, ...] = ()) -> None:
        """Declare the pass that runs next (None: no pass, every read allowed, no write)."""
        self._pass, self._reads, self._writes = name, reads, writes

    def __getitem__(self, name: str):
        if self._pass is not None and name not in self._reads and name not in self._writes:
            raise ResourceError(f"pass '{self._pass}' reads '{name}', which it does not declare in reads")
        try:
            return self._values[name]
        except KeyError:
            raise ResourceError(f"'{name}' was read before any pass wrote it this frame") from None

    def get(self, name: str, default=None):
        """The resource, or `default` when no pass wrote it this frame."""
        return self[name] if name in self._values else default

    def __setitem__(self, name: str, value) -> None:
        if self._pass is not None and name not in self._writes:
            raise ResourceError(f"pass '{self._pass}' writes '{name}', which it does not declare in writes")
        kinds = RESOURCE_TYPES.get(name)
        if kinds is None:
            raise ResourceError(f"unknown resource '{name}' (known: {', '.join(RESOURCE_TYPES)})")
        if not isinstance(value, kinds):
            raise ResourceError(f"resource '{name}' must be {' or '.join(k.__name__ for k in kinds)}, got {value!r}")
        self._values[name] = value
        if name in IMAGES:
            self.output = value
