"""The interface every transparency method implements inside the deferred pipeline."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

from ..errors import UnsupportedMethodError
from ..pipeline.settings import NUMBER, Setting, unit_interval
from ..raster.choice import RASTER_ORDER_SETTING, RASTER_SETTING, auto_order

if TYPE_CHECKING:
    from ..context import Capabilities
    from ..pipeline.frame import FrameContext


# Extensions that only mean something in a fragment shader; the composite resolve is compute.
_FRAGMENT_ONLY_EXTENSIONS = ("GL_ARB_fragment_shader_interlock", "GL_EXT_shader_framebuffer_fetch")
# settings every method accepts under `transparency:`
COMMON_SETTINGS: dict[str, Setting] = {
    "threshold": Setting(NUMBER, 0.98, "saturation threshold for early termination", check=unit_interval),
    "raster": RASTER_SETTING,
    "raster_order": RASTER_ORDER_SETTING,
}


@dataclass(frozen=True)
class MethodSpec:
    """One transparency method as `transparency.method` names it, registered with `register("method")`.

    A method is the class that implements it (`impl`, derived from TransparencyMethod) and the
    record of options that class is built with: one class serves every method that differs from
    another only by options (the seven one-pass A-buffer methods are one class). Call a spec as
    a class: `spec(settings, caps)` is the method. The implementation's own facts (exact,
    compute_raster, ...) read through, so the spec answers what `guaca methods` and the checks
    before a method is built ask.
    """

    id: str
    summary: str
    impl: type[TransparencyMethod]
    options: Any = None  # the implementation's record of options for this method
    settings: Mapping[str, Setting] = field(default_factory=dict)  # beyond COMMON_SETTINGS
    # geometry passes a frame with transparent draws takes, or None where the scene decides
    # (peeling); geometry_passes_rule then says how, for `guaca methods`
    geometry_passes: int | None = 1
    geometry_passes_rule: str = ""

    def __call__(self, settings: dict, caps: Capabilities) -> TransparencyMethod:
        """The method, with validated `settings` (see Renderer's method_settings), for the device of `caps`."""
        return self.impl(self, settings, caps)

    def settings_schema(self) -> dict[str, Setting]:
        """Settings accepted under `transparency:` for this method (common ones included)."""
        return {**COMMON_SETTINGS, **self.settings}

    def unsupported_reason(self, caps: Capabilities) -> str | None:
        """Why this device cannot run the method, or None when it can."""
        return self.impl.unsupported_reason(caps, self.options)

    @property
    def exact(self) -> bool:
        """Whether the method's image is exact (else an approximation)."""
        return self.impl.exact

    @property
    def compute_raster(self) -> bool:
        """Whether it takes fragments from the compute rasterizer."""
        return self.impl.compute_raster

    @property
    def supports_antialiasing(self) -> bool:
        """Whether its fragments carry coverage masks (antialiasing.samples > 1)."""
        return self.impl.supports_antialiasing

    @property
    def antialiasing_refusal(self) -> str:
        """Why it cannot take antialiasing.samples > 1, where it cannot."""
        return self.impl.antialiasing_refusal


class TransparencyMethod:
    """A strategy for transparent fragments: how the geometry pass stores them, how composite resolves them.

    Life cycle per frame: prepare() → render_transparent() (draws the transparent draw list
    one or more times) → finish() (reads counters; may ask for a re-render) → the composite pass
    includes resolve_template() and calls bind_composite().

    Methods that shade while they draw (peeling: shade each peeled layer, then peel the next)
    set `geometry_in_composite`: their prepare/render_transparent/finish then run at the start
    of the composite pass, when lights are culled (frame.bind_lights(prog) binds them and
    frame.shading_vars() gives the template variables of shading/lighting.glsl.j2).

    Buffers, images and textures bind at the named slots of guaca_py/shaders/slots.py (the
    "method" groups there), never at numbers of their own.

    Each concrete class derives from this one directly and is registered through MethodSpec
    records, one per method id it implements; what its methods share beyond this interface it
    holds as components or plain functions, not as base classes.
    """

    exact: ClassVar[bool] = True
    geometry_in_composite: ClassVar[bool] = False
    compute_raster: ClassVar[bool] = False  # takes fragments from the compute rasterizer (docs/raster.md)
    # antialiasing.samples > 1 (docs/antialiasing.md): nodes carry coverage masks, resolved per sample
    supports_antialiasing: ClassVar[bool] = False
    antialiasing_refusal: ClassVar[str] = "its fragments carry no coverage mask"
    aa_samples: int = 1  # samples per pixel (antialiasing.samples), set by the renderer
    early_termination: bool = False  # insertion stops where the pixel is saturated in front
    # why `raster: auto` should take the compute rasterizer for draws of every triangle size (set
    # by a method whose fragment-shader path would be slow with the choices it made), or None
    auto_compute_reason: str | None = None

    def pool_fragments(self, pixels: int) -> int | None:
        """Most fragments the method's storage holds for `pixels` rendered pixels (None: it stores no list)."""
        return None

    def raster_order(self, pixels: int = 0) -> str:
        """The compute rasterizer's triangle order for a frame of `pixels`: the `raster_order` setting, or for `auto` the measured rule."""
        order = self.settings.get("raster_order", "auto")
        if order != "auto":
            return order
        # Orders (raster/order.comp.j2): "depth" (front to back with early termination, back to
        # front without), "mesh" (index order), "tile" (screen tiles, by depth within each).
        # On the H100 (docs/decisions.md, 2026-11-23 "the compute rasterizer's triangle order"), depth
        # order let early termination cull most: presort_cs_et hairball_v2 25.2 ms against 48.8 in tile order.
        # Without it, tile order keeps each pixel's nodes and its neighbours' in one short run of
        # the pool, where insertion walks and the composite read them: hairball_v2 presort_lf 161 ->
        # 28.4 ms, post_sort 330 (mesh order) -> 29.3, post_merge16 787 -> 93; the dragons lose
        # ~1 ms (post_sort 3.4 -> 4.4), Sponza is within 0.5 ms either way. Past 2048² that locality
        # outweighs early termination's culling too (raster/choice.py, LARGE_FRAME_PIXELS).
        return auto_order(self.early_termination, pixels)

    def __init__(self, spec: MethodSpec, settings: dict, caps: Capabilities):
        self.spec = spec
        self.settings = settings
        self.caps = caps

    @property
    def id(self) -> str:
        """The method's id (transparency.method)."""
        return self.spec.id

    @property
    def geometry_passes(self) -> int | None:
        """Geometry passes a frame with transparent draws takes, or None where the scene decides."""
        return self.spec.geometry_passes

    @classmethod
    def unsupported_reason(cls, caps: Capabilities, options: Any) -> str | None:
        """Why this device cannot run the method built with `options`, or None when it can."""
        return None

    def compute_raster_refusal(self) -> str | None:
        """Why this method cannot take compute-rasterized fragments, or None when it can."""
        if self.compute_raster:
            return None
        return (
            "it draws through the fragment pipeline (peeling passes, counted storage or hardware "
            "blending); only the one-pass A-buffer methods insert compute-rasterized fragments"
        )

    # --- geometry pass -------------------------------------------------------------
    def fragment_template(self) -> str:
        """Template included by transparent geometry programs; defines gua_submit_transparent()."""
        raise NotImplementedError

    def template_vars(self) -> dict:
        """Variables for this method's templates (also part of the program cache key)."""
        return {}

    def extensions(self) -> str:
        """GLSL #extension lines the method's code needs."""
        return ""

    def resolve_extensions(self) -> str:
        """The #extension lines of extensions() that the compute resolve can use (fragment-only ones dropped)."""
        return "".join(
            line + "\n"
            for line in self.extensions().splitlines()
            if line.strip() and not any(f in line for f in _FRAGMENT_ONLY_EXTENSIONS)
        )

    def prepare(self, frame: FrameContext) -> None:
        """Allocate/clear per-frame storage before transparent geometry is drawn."""

    def render_transparent(self, frame: FrameContext) -> None:
        """Draw the transparent draw list (frame.draw_transparent) as many times as the method needs."""
        raise NotImplementedError

    def finish(self, frame: FrameContext) -> bool:
        """Read counters into frame.stats; return True to ask for the frame to be rendered again."""
        return False

    # --- composite pass ------------------------------------------------------------
    def resolve_template(self) -> str:
        """Template included by the composite pass; defines gua_resolve_transparent()."""
        raise NotImplementedError

    def bind_composite(self, frame: FrameContext, program) -> None:
        """Bind storage and uniforms the resolve code reads."""

    def after_composite(self, frame: FrameContext) -> None:
        """Read what the composite pass counted (e.g. fragments a resolve had to truncate) into frame.stats."""

    def composite_threshold(self) -> float:
        """Accumulated alpha at which the composite stops walking fragments."""
        return float(self.settings.get("threshold", 1.0))

    def memory(self) -> dict:
        """Bytes allocated and used by each buffer the method holds."""
        return {}

    def release(self) -> None:
        """Free GPU storage."""


# Methods with a per-pixel critical section (presort_cs*, kbuffer) share this setting.
LOCK_SETTING = Setting(
    (str,),
    "auto",
    "critical section: 'interlock' (ARB_fragment_shader_interlock), "
    "'spin' (per-pixel spin lock) or 'auto' (interlock where the device has it)",
    choices=("auto", "interlock", "spin"),
)


def resolve_lock(method_id: str, lock: str, caps: Capabilities) -> str:
    """The critical section a method runs with: 'interlock' or 'spin'; a missing interlock is refused."""
    if lock == "interlock" and not caps.fragment_interlock:
        raise UnsupportedMethodError(
            f"method '{method_id}' with lock 'interlock' cannot run on {caps.gl_renderer}: "
            "no GL_ARB_fragment_shader_interlock (use lock 'spin' or 'auto')"
        )
    # a contended spin lock serializes badly on GPUs (measured: the k-buffer took 854 ms of
    # geometry at 1024² on the H100 demo); the ordered interlock is the hardware's critical section
    return lock if lock != "auto" else ("interlock" if caps.fragment_interlock else "spin")
