"""The renderer: builds the pass pipeline from a config and turns scenes into frames."""

from __future__ import annotations

import copy
import threading
import time
import weakref
from collections.abc import Sequence
from pathlib import Path

import moderngl
import numpy as np

from . import antialiasing
from .antialiasing_auto import COVERAGE_SAMPLES, AutoAntialiasing
from .context import create_context
from .errors import ArgumentError, ConfigError, GuacaError, UnsupportedMethodError
from .gpu_resources import MeshCache, TextureCache
from .gpu_timer import TimerQuery
from .host_state import ContextGuard, native, native_handle, on_context
from .limits import check_resolution
from .materials import MaterialRegistry
from .methods import auto, method_class, require_method_id
from .pipeline.assemble import assemble
from .pipeline.config import PipelineConfig, load_pipeline
from .pipeline.device import Antialiasing, Device
from .pipeline.draw_cache import DrawCache
from .pipeline.drawlist import build_draw_list
from .pipeline.frame import FrameContext, FrameResult
from .pipeline.retry import settle
from .pipeline.settings import resolve_settings
from .pipeline.view_images import ViewImages
from .present import Presenter, host_target
from .raster.router import RasterRouter
from .registry import settings_schema
from .scene.files import as_scene
from .scene.graph import Camera, Scene
from .scene.views import check_cameras
from .shaders import ShaderLibrary


def method_settings(
    mid: str,
    base: dict,
    overrides: dict | None = None,
    source: str = "<method>",
    overrides_source: str = "method_overrides",
) -> dict:
    """Settings for method `mid`: keys of `base` (from `source`) it accepts, then `overrides`, each validated.

    A bad override is reported under `overrides_source` (the argument or command-line option it
    came from), not under the pipeline file, which may hold no such value.
    """
    schema = settings_schema(mid)

    def error(where):
        return lambda k, r, h: ConfigError(r, where, None, f"transparency.{k}", h)

    out = resolve_settings(schema, {k: v for k, v in base.items() if k in schema}, error(source))
    if overrides:
        checked = resolve_settings(schema, overrides, error(overrides_source))
        out.update({k: checked[k] for k in overrides})
    out["method"] = mid
    return out


def _image_and_linear(data: bytes, linear: bool, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray | None]:
    """RGBA pixels read from GL (row 0 at the bottom) as (uint8 image, float32 linear colour or None), row 0 at the top."""
    w, h = size
    if linear:
        lin = np.frombuffer(data, dtype=np.float32).reshape(h, w, 4)[::-1, :, :3]
        img = np.clip(np.rint(np.clip(lin, 0.0, 1.0) * 255.0), 0, 255).astype(np.uint8)
        return np.ascontiguousarray(img), np.ascontiguousarray(lin)
    return np.ascontiguousarray(np.frombuffer(data, dtype=np.uint8).reshape(h, w, 4)[::-1, :, :3]), None


class Renderer:
    """Renders Scenes through a pipeline config. Reuse one Renderer across frames.

    With `ctx=None` it makes its own headless context (freed by release()); with a host's
    moderngl context it draws there, and every public call makes that context current and
    gives the host back the GL state it found (guaca_py/host_state.py lists what that covers).
    """

    moderngl = moderngl

    def __init__(
        self,
        pipeline: str | Path | PipelineConfig = "default",
        ctx=None,
        *,
        method: str | None = None,
        method_overrides: dict | None = None,
        material_paths: list[str | Path] | None = None,
        template_paths: list[str | Path] | None = None,
        disable: tuple[str, ...] = (),
        restore_host_state: bool = True,
        fuse_passes: bool = True,
    ):
        if ctx is not None and not isinstance(ctx, moderngl.Context):
            raise ConfigError(
                f"must be a moderngl.Context, got {type(ctx).__name__}",
                key="ctx",
                hint="or None for a context of its own",
            )
        if ctx is not None and isinstance(ctx.mglo, moderngl.InvalidObject):
            raise ConfigError("the moderngl context was released", key="ctx", hint="pass a live context, or None")
        if not isinstance(pipeline, (str, Path, PipelineConfig)):
            raise ArgumentError(
                f"must be a pipeline name, a path or a PipelineConfig, got {type(pipeline).__name__}", key="pipeline"
            )
        # one folder given as a string is one folder, not a list of one-letter ones
        material_paths = [material_paths] if isinstance(material_paths, (str, Path)) else material_paths
        template_paths = [template_paths] if isinstance(template_paths, (str, Path)) else template_paths
        release_dropped()
        previous = native().current()  # creating a context makes it current: the host's comes back
        self.fuse_passes = fuse_passes  # False keeps every pass separate (comparisons, debugging)
        self.owns_context = ctx is None
        # an EGL context is current in one thread at a time: the renderer's own stays with the thread that made it
        self.thread = threading.get_ident() if self.owns_context else None
        self.released = False
        if self.owns_context:
            self.ctx, self.caps = create_context(None, disable)  # a new context is current
            self._gl = ContextGuard(self.ctx, restore_state=False)
        else:
            # a host that sets all of its state before each of its draws may skip the snapshot (~1 ms a call)
            self._gl = ContextGuard(ctx, restore_state=restore_host_state)
            with self._gl():  # capabilities (and moderngl's cached ctx.info) must come from this context
                self.ctx, self.caps = create_context(ctx, disable)
        try:
            with self._gl():
                self._build(pipeline, method, method_overrides, material_paths, template_paths)
        except BaseException:
            if self.owns_context:
                self.ctx.release()
            raise
        else:
            # a renderer dropped without release() frees its GPU objects (and its own context) when
            # collected: the finalizer holds the instance's attributes, never the instance
            # (queued by the collector, freed at the next Renderer's construction: GL calls made at an
            # arbitrary allocation would run in the middle of whatever GL work the thread is doing)
            self._finalizer = weakref.finalize(self, _DROPPED.append, self.__dict__)
            self._finalizer.atexit = False  # at exit the process's contexts go with it; nothing to free
        finally:
            if previous is not None and self.owns_context:
                native().make_current(previous)

    def _build(self, pipeline, method, method_overrides, material_paths, template_paths) -> None:
        self.config = load_pipeline(pipeline)
        programs = ShaderLibrary(self.ctx, template_paths)
        aa = self.config.antialiasing
        # antialiasing: auto renders 4 samples or supersample 2, chosen per frame; the first frame takes 4 samples
        self.aa_auto = self._auto_antialiasing(programs) if aa["auto"] else None
        self._aa_choice: dict | None = None  # antialiasing: auto's choice for the current call, reported per frame
        if self.aa_auto is not None:
            chosen = self.aa_auto.coverage or self.aa_auto.supersampled
        else:
            chosen = self._antialiasing(aa["samples"], aa["supersample"], programs)
        self.device = Device(self.ctx, self.caps, programs, MeshCache(self.ctx), TextureCache(self.ctx), chosen)
        self.materials = MaterialRegistry(material_paths)
        self.presenter = Presenter(self.device)
        self.draw_cache = DrawCache()
        self.frame_serial = 0  # render calls made; a FrameResult's texture is valid while this is unchanged
        self._queries: dict[tuple[str, int, int], object] = {}  # timer queries by (pass, view, call parity)
        self._frame_index = 0
        self._previous_timers: dict[int, dict] = {}  # per view: the pass timers of the previous call
        self.view_images = ViewImages(self.ctx)  # render_views(): the images of all views but the last
        self.raster = RasterRouter(self.device)  # hardware or compute rasterization of transparent draws
        self.set_method(method or self.config.transparency["method"], method_overrides)
        self.passes = assemble(self.config, self.device, self.fuse_passes)

    def _antialiasing(self, samples: int, supersample: int, programs) -> Antialiasing:
        """The device's rendering of `samples` per pixel (refused above its limit) at `supersample`."""
        return Antialiasing(
            # samples per pixel the G-buffer and coverage masks hold (a device may round antialiasing.samples up)
            samples=antialiasing.check_device(self.ctx, samples, self.caps.gl_renderer, programs),
            asked=samples,
            # where those samples lie (the compute rasterizer tests coverage there): the probe that
            # counted them, cached; made here, as it binds a framebuffer and a storage buffer of its own
            positions=antialiasing.sample_positions(self.ctx, samples, programs) if samples > 1 else (),
            supersample=supersample,
        )

    def _auto_antialiasing(self, programs) -> AutoAntialiasing:
        """antialiasing: auto's two modes on this device (4 samples, or its most where fewer; none without MSAA)."""
        most = max(s for s in antialiasing.SAMPLE_COUNTS if s <= max(1, antialiasing.device_samples(self.ctx)))
        n = min(COVERAGE_SAMPLES, most)
        return AutoAntialiasing(self._antialiasing(n, 1, programs) if n > 1 else None)

    @property
    def shaders(self) -> ShaderLibrary:
        """The program builder: templates to compiled programs, cached by their variables."""
        return self.device.programs

    @property
    def samples(self) -> int:
        """Samples per pixel the frame holds (antialiasing.samples, as the device renders it)."""
        return self.device.samples

    @property
    def meshes(self) -> MeshCache:
        """GPU meshes, shared by content."""
        return self.device.meshes

    @property
    def textures(self) -> TextureCache:
        """GPU textures of materials."""
        return self.device.textures

    @on_context
    def set_method(self, mid: str, overrides: dict | None = None) -> None:
        """Switch the transparency method (settings shared with the config carry over).

        `auto` picks the fastest exact method measured on this kind of device (methods/auto.py);
        `method_auto` says which and why, and the frame stats repeat it.
        """
        require_method_id(mid, "method")  # a pipeline file's method was checked with its line when read
        if overrides is not None and not isinstance(overrides, dict):
            raise ArgumentError(f"must be a dict of settings, got {type(overrides).__name__}", key="method_overrides")
        self.method_auto = None
        if mid == auto.AUTO:
            method_settings(mid, {}, overrides)  # checked as settings of any method auto may pick
            mid, self.method_auto = auto.choose(self.caps, self.samples)
            taken = method_class(mid).settings_schema()
            overrides = {k: v for k, v in (overrides or {}).items() if k in taken}
        cls = method_class(mid)
        reason = cls.unsupported_reason(self.caps)
        if reason:
            raise UnsupportedMethodError(f"method '{mid}' cannot run on {self.caps.gl_renderer}: {reason}")
        if self.aa_auto is None:
            antialiasing.check_method(cls, self.samples)
        else:  # a method without coverage masks renders supersampled under antialiasing: auto
            self.aa_auto.method_changed(cls)
        method = cls(method_settings(mid, self.config.transparency, overrides, self.config.source), self.caps)
        method.aa_samples = self.device.samples  # coverage masks in its nodes; the compute rasterizer has none
        refusal = method.compute_raster_refusal() if method.settings["raster"] == "compute" else None
        if refusal:
            raise UnsupportedMethodError(
                f"method '{mid}' cannot take transparency.raster: compute: {refusal}; use raster: hardware or auto"
            )
        if getattr(self, "method", None) is not None:
            self.method.release()
        self.method = method

    def pass_named(self, name: str):
        """The pass instance called `name` (compulsory passes always exist)."""
        return next(p for p in self.passes if p.name == name)

    # ------------------------------------------------------------------ frames
    def _timed(self, name: str, view: int, fn):
        """Run `fn` (pass `name` of view `view`); returns a callable giving its time in ms, and the timer kind.

        GPU timer queries are read only after the whole frame was submitted (reading one waits for
        the GPU). Two query objects per pass and view alternate from call to call, so a frame loop
        without read-back can report the previous frame's times without waiting for this one.
        """
        if self.caps.gpu_timers:
            key = (name, view, self._frame_index % 2)
            q = self._queries.get(key)
            if q is None:
                q = self._queries[key] = TimerQuery(self.ctx)
            with q:
                fn()
            return (lambda: q.elapsed / 1e6), "gpu"
        self.ctx.finish()
        t0 = time.perf_counter()
        fn()
        self.ctx.finish()
        ms = (time.perf_counter() - t0) * 1e3
        return (lambda: ms), "wall"

    @on_context
    def render(
        self,
        scene: Scene,
        width: int | None = None,
        height: int | None = None,
        *,
        target=None,
        viewport: tuple[int, int, int, int] | None = None,
        over_target: bool = False,
        read_back: bool = True,
        stats: bool = True,
    ) -> FrameResult:
        """Render one frame of `scene`; optionally draw it into `target`; read it back unless `read_back=False`.

        `target` is a moderngl Framebuffer (e.g. the host's screen) or Texture the frame is
        drawn into (scaled to `viewport`, default the whole target) without leaving the GPU.
        `over_target=True` composes the frame with what the target already holds (a Framebuffer
        with a colour and a depth attachment, the frame's size or a `viewport` of it): its depth,
        made with this scene camera's matrices (`camera_matrices`), hides guaca's fragments behind
        it; its colour is the background (the scene's is not drawn) and stays where nothing of
        guaca covers it; guaca's opaque depth is written back into its depth attachment.
        `FrameResult.image` is then the composed picture, read from the target's rectangle
        (with `read_back=False`: as the target holds it when read); `FrameResult.texture` is
        guaca's layer alone (premultiplied colour and coverage).
        With `read_back=False` nothing is copied to the CPU: `FrameResult.texture` holds the
        frame until the next render and `FrameResult.image` reads it on first access.
        `stats=False` skips per-pass timing (no timer queries or GPU syncs); the counters the
        transparency method gathers are still reported. With `stats=True` and `read_back=False`
        on a GPU, the per-pass times are the previous frame's (`stats["passes_of"]`), so reading
        them never waits for this frame.
        """
        scene, w, h = self._scene_and_size(scene, width, height)
        if viewport is not None:
            _check_viewport(viewport)
        host = host_target(target, w, h, viewport) if over_target else None  # refused before any work
        frame = self._frame(scene, self._draw_list(scene), w, h, host=host, read_back=read_back, stats=stats)
        self._end_call()
        tex = frame.resources.output
        if target is not None:
            self.presenter.draw(tex, target, viewport, over=host is not None)
        if host is not None:  # the host keeps drawing with guaca's opaque surfaces in its depth
            self.presenter.write_host_depth(host, frame.resources["gbuffer"])
        reader = self._reader(tex, self.frame_serial) if host is None else self._target_reader(host)
        result = FrameResult(None, dict(frame.stats), texture=tex, reader=reader)
        if read_back:
            result.read()
        return result

    @on_context
    def render_views(
        self,
        scene: Scene,
        cameras: Sequence[Camera],
        width: int | None = None,
        height: int | None = None,
        *,
        read_back: bool = True,
        stats: bool = True,
    ) -> list[FrameResult]:
        """Render `scene` once per camera of `cameras` (its own camera unused): one FrameResult per view, in order.

        The views share one draw list (built once per call) and the renderer's storage: the
        transparent pool holds the largest view's fragments and is not made again between views:
        a view costs its own geometry and fragments, nothing is uploaded, compiled or allocated
        for it. Each view has its own
        image and statistics (`stats["view"]`: its index and the number of views). `read_back`
        and `stats` are render()'s; with `read_back=False` nothing waits for the GPU between
        views, every view's `FrameResult.texture` stays valid until the renderer's next call, and
        the counters and times a view reports are the same view's of the previous call.
        `guaca_py.scene.views` makes camera sets: `stereo_pair`, `camera_row`, `cube_map`.
        """
        scene, w, h = self._scene_and_size(scene, width, height)
        cameras = check_cameras(cameras)
        draws = self._draw_list(scene)  # the views differ only in their camera
        kept = []
        for i, camera in enumerate(cameras):
            view = copy.copy(scene)  # shallow: the same nodes and lights, seen through this camera
            view.camera = camera
            frame = self._frame(view, draws, w, h, view=(i, len(cameras)), read_back=read_back, stats=stats)
            tex = frame.resources.output
            if i < len(cameras) - 1:  # the next view draws over the pipeline's image: this one keeps a copy
                tex = self.view_images.keep(i, tex)
            kept.append((frame.stats, tex))
        self._end_call()
        results = [FrameResult(None, dict(s), texture=t, reader=self._reader(t, self.frame_serial)) for s, t in kept]
        if read_back:
            for result in results:
                result.read()
        return results

    def _scene_and_size(self, scene, width, height) -> tuple[Scene, int, int]:
        """The scene (a trimesh scene or mesh converted), checked, and the frame's size within the device's limits."""
        try:
            scene = as_scene(scene)  # a trimesh scene or mesh converts (once per content); anything else is named
        except TypeError as exc:
            raise ArgumentError(str(exc), key="scene") from None
        scene.check()  # the data classes are mutable: a camera or light changed since construction is checked here
        self._aa_choice = None
        if self.aa_auto is not None:  # this call's mode, from what the previous frame measured
            # the method's pool rule (a method without one carries no coverage masks: it is supersampled anyway)
            pool = self.method.pool_fragments if self.method.supports_antialiasing else None
            self.device.antialiasing, self._aa_choice = self.aa_auto.choose(pool)
            self.method.aa_samples = self.device.samples
        k = self.device.antialiasing.supersample  # the frame renders at k times the size, box filtered down
        w, h = check_resolution(
            self.caps.limits,
            self.config.resolution[0] if width is None else width,
            self.config.resolution[1] if height is None else height,
            supersample=k,
        )
        return scene, w, h

    def _draw_list(self, scene: Scene) -> list:
        """The scene's draw list (matrices and materials of unchanged nodes from the draw cache)."""
        try:
            return build_draw_list(scene, self.materials, self.draw_cache)
        except (AttributeError, TypeError, RecursionError):
            scene.check_structure()  # a part of the wrong type, a cycle: named here (not checked on every frame)
            raise

    def _frame(
        self,
        scene: Scene,
        draws: list,
        w: int,
        h: int,
        *,
        host=None,
        view: tuple[int, int] | None = None,
        read_back: bool,
        stats: bool,
    ) -> FrameContext:
        """Run the passes over one view of `scene` (`view`: its index and the call's number of views)."""
        index, views = view or (0, 1)
        k = self.device.antialiasing.supersample  # the frame renders at k times the size, box filtered down
        frame = FrameContext(
            self.device, self.method, self.raster, scene, k * w, k * h, draws, *self.camera_matrices(scene, w, h)
        )
        frame.late_counters = not read_back
        frame.view_index, frame.view_count = index, views
        frame.resources.enter(None)
        frame.resources["draw_list"] = draws
        frame.resources["lights"] = list(scene.lights)
        frame.resources["host_layer"] = self.presenter.read_host_layer(host) if host is not None else None
        frame.stats.update(
            {
                "method": self.method.id,
                "insertion_path": self.caps.insertion_path,
                "device": self.caps.gl_renderer,
                "resolution": [w, h],
                "render_resolution": [k * w, k * h],
                "draws": len(draws),
                "transparent_draws": len(frame.transparent_draws),
                "passes": {},
                "regrown": 0,
            }
        )
        if view is not None:
            frame.stats["view"] = {"index": index, "views": views}
        if self.method_auto is not None:
            frame.stats["method_auto"] = self.method_auto
        t0 = time.perf_counter()
        timers = {}
        kind = "off"
        for p in self.passes:
            if p.fused_into is not None:  # an earlier pass did its work (its time is in that pass's)
                continue
            frame.resources.enter(p.name, p.reads, p.writes)

            def attempt(p=p) -> bool:
                nonlocal kind
                warned = len(frame.stats.get("warnings", []))
                if stats:
                    timers[p.name], kind = self._timed(p.name, index, lambda: p.execute(frame))
                else:
                    p.execute(frame)
                    timers[p.name], kind = (lambda: 0.0), "off"
                p.collect(frame)  # after the timer: its reads may wait for the GPU
                if frame.rerender:
                    frame.rerender = False
                    del frame.stats.get("warnings", [])[warned:]  # that attempt's overflow is repaired
                    return True
                return False

            settle(attempt, frame.stats)
            frame.stats["timer"] = kind
        frame.resources.enter(None)
        if read_back or not stats:
            self._previous_timers.clear()  # a later loop starts afresh, not from times of older frames
        previous = self._previous_timers.pop(index, None)  # this view's, of the previous call
        if not stats:
            frame.stats["passes"] = {name: {"ms": 0.0} for name in timers}
        elif read_back or kind != "gpu" or previous is None:
            frame.stats["passes"] = {name: {"ms": round(t(), 4)} for name, t in timers.items()}
        else:  # the previous frame's queries: finished or nearly, so reading them does not stall this one
            frame.stats["passes"] = {name: {"ms": round(t(), 4)} for name, t in previous.items()}
            frame.stats["passes_of"] = "previous frame"
        if any(p.fused_into for p in self.passes):  # in pipeline order; a fused pass's time is in its host's
            timed = frame.stats["passes"]
            frame.stats["passes"] = {
                p.name: timed[p.name] if p.fused_into is None else {"ms": 0.0, "fused_into": p.fused_into}
                for p in self.passes
            }
            for p in self.passes:
                if p.fused_into is not None:
                    frame.stats["passes"][p.fused_into]["includes"] = p.name
        if stats and not read_back:
            self._previous_timers[index] = timers
        frame.stats.section("memory").update(self.method.memory() if frame.transparent_draws else {})
        if self._aa_choice is not None:  # why this frame's mode, and what the next call decides from
            frame.stats["antialiasing"]["auto"] = self._aa_choice
            if index == views - 1:  # one mode per call: its last view measures for the next call
                self.aa_auto.record(frame)
        declared = self.method.geometry_passes
        frame.stats.setdefault("geometry_passes", declared if frame.transparent_draws and declared is not None else 1)
        if kind == "gpu" and any(p["ms"] >= 4294.9 for p in frame.stats["passes"].values()):
            frame.stats.warn(
                "a pass took longer than the 32-bit GPU timer result can hold (4.29 s); its time is clipped"
            )
        frame.stats["frame_wall_ms"] = round((time.perf_counter() - t0) * 1e3, 3)
        return frame

    def _end_call(self) -> None:
        """After the frames of one render call: caches age by one frame, earlier FrameResults' textures expire."""
        self._frame_index += 1
        self.device.meshes.end_frame()
        self.device.textures.end_frame()
        self.frame_serial += 1

    @staticmethod
    def camera_matrices(scene: Scene, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """(view, projection) of the frame: 4x4 float64, row-major, for column vectors (clip = P @ V @ world).

        OpenGL conventions: the camera looks down -Z, clip z in [-w, w], so with the default depth
        range and clip control the depth buffer holds [0, 1]. A host drawing the opaque layer for
        `render(..., over_target=True)` uses exactly these; a GLSL mat4 takes
        `m.T.astype("f4").tobytes()` (GLSL matrices are column-major).
        """
        cam = scene.camera
        return cam.view_matrix(), cam.projection_matrix(width / height)

    def _reader(self, tex, serial: int):
        """A function reading `tex` (the frame numbered `serial`) back as (image, linear or None)."""

        @on_context
        def read(self) -> tuple[np.ndarray, np.ndarray | None]:
            if self.frame_serial != serial or tex.glo <= 0:
                raise GuacaError(
                    "this frame's texture was reused by a later render (or the renderer was released); "
                    "read frame.image before the next render, or render with read_back=True"
                )
            return _image_and_linear(tex.read(), tex.dtype == "f4", tex.size)

        return lambda: read(self)

    def _target_reader(self, host):
        """A function reading the frame's rectangle of an over_target framebuffer: the composed picture."""

        @on_context
        def read(self) -> tuple[np.ndarray, np.ndarray | None]:
            linear = host.fbo.color_attachments[0].dtype in ("f2", "f4")  # a float target holds linear values
            data = host.fbo.read(viewport=host.viewport, components=4, dtype="f4" if linear else "f1")
            return _image_and_linear(data, linear, host.viewport[2:])

        return lambda: read(self)

    def release(self) -> None:
        """Free every GPU resource the renderer holds, and its context when it made its own."""
        if self._finalizer.detach() is not None:  # once: a second release() does nothing
            _release_parts(self.__dict__)


def _check_viewport(viewport) -> None:
    """Refuse a viewport that is not (x, y, width, height) of whole numbers, x and y >= 0, width and height >= 1."""

    def whole(v) -> bool:  # 4.0 from a host's float arithmetic is a size; 4.5 or True is not
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
            return False
        return float(v).is_integer()

    try:
        ok = len(viewport) == 4 and all(whole(v) for v in viewport)
    except TypeError:
        ok = False
    if not ok or min(viewport[:2]) < 0 or min(viewport[2:]) < 1:
        raise ArgumentError(
            f"must be (x, y, width, height) integers, x and y >= 0, width and height >= 1; got {viewport!r}",
            key="viewport",
        )


_DROPPED: list[dict] = []  # attributes of renderers collected without release(), waiting to be freed


def release_dropped() -> None:
    """Free the GPU objects of renderers collected without release() (each new Renderer does this first)."""
    while _DROPPED:
        _release_parts(_DROPPED.pop())


def _release_parts(parts: dict) -> None:
    """Release a renderer's GPU objects (given its attributes), then its context when it made it.

    Run by release() or, for a renderer dropped without it, by release_dropped(). GL objects go with
    their context current; a host's context is made current for it and left alive. A renderer
    collected in a thread other than its context's cannot make that context current there: its
    objects then go when that context is released.
    """
    ctx, gl = parts["ctx"], parts["_gl"]
    parts["released"] = True
    parts["frame_serial"] += 1  # outstanding FrameResults can no longer read their texture
    if isinstance(ctx.mglo, moderngl.InvalidObject):  # the context went first: so did our objects
        return
    owner = parts["thread"]
    if owner is not None and owner != threading.get_ident():
        return
    previous = native().current()
    with gl():
        for p in parts["passes"]:
            p.release()
        parts["presenter"].release()
        parts["view_images"].release()
        parts["method"].release()
        parts["raster"].release()
        for q in parts["_queries"].values():
            q.release()
        parts["_queries"].clear()
        parts["device"].release()
    if parts["owns_context"]:
        ctx.release()
        if previous is not None and native_handle(previous) != gl.handle:
            native().make_current(previous)
