"""OpenGL context creation/adoption and one-time capability detection."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from .errors import DeviceError
from .limits import DeviceLimits, query_limits

_INSTALL_HINT = (
    "guaca_py needs OpenGL 4.5 core through EGL. On Debian/Ubuntu install Mesa's EGL and "
    "software rasterizer: `apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri`; on NVIDIA "
    "machines make sure the driver's EGL vendor file is visible (__EGL_VENDOR_LIBRARY_FILENAMES)."
)


@dataclass(frozen=True)
class Capabilities:
    """What the device can do; drives which shader variants and methods are built."""

    gl_renderer: str  # GL_RENDERER: the device's name
    vendor: str
    version: str
    atomic_int64: bool  # 64-bit atomics on SSBOs (NV_shader_atomic_int64 + ARB_gpu_shader_int64)
    fragment_interlock: bool  # ARB_fragment_shader_interlock
    conservative_raster: bool  # NV_conservative_raster
    gpu_timers: bool  # timer queries measure real GPU time (not on software rasterizers)
    software: bool  # llvmpipe / softpipe / swrast
    framebuffer_fetch: bool = False  # EXT_shader_framebuffer_fetch: ordered read-modify-write of colour targets
    limits: DeviceLimits | None = None  # buffer and render-target sizes (guaca_py/limits.py)
    shader_ballot: bool = False  # ARB_shader_ballot + ARB_gpu_shader_int64: per-subgroup aggregation of atomics

    def __post_init__(self):
        # Capabilities(**caps.as_dict()) round-trips: as_dict turns the limits into a plain dict
        if isinstance(self.limits, dict):
            object.__setattr__(self, "limits", DeviceLimits(**self.limits))

    def as_dict(self) -> dict:
        """Plain dict for JSON output."""
        return asdict(self)

    @property
    def insertion_path(self) -> str:
        """Which lock-free A-buffer insertion the device runs: '64bit' or '32bit'."""
        return "64bit" if self.atomic_int64 else "32bit"


def is_software(ctx) -> bool:
    """Whether the context renders on the CPU (Mesa llvmpipe and its kin)."""
    renderer = ctx.info.get("GL_RENDERER", "?").lower()
    return any(k in renderer for k in ("llvmpipe", "softpipe", "swrast", "lavapipe"))


def detect_capabilities(ctx, disable: tuple[str, ...] = ()) -> Capabilities:
    """Read extensions once; `disable` forces features off (for testing fallbacks)."""
    ext = ctx.extensions
    info = ctx.info
    renderer = info.get("GL_RENDERER", "?")
    software = is_software(ctx)
    caps = dict(
        atomic_int64="GL_NV_shader_atomic_int64" in ext and "GL_ARB_gpu_shader_int64" in ext,
        fragment_interlock="GL_ARB_fragment_shader_interlock" in ext,
        conservative_raster="GL_NV_conservative_raster" in ext,
        gpu_timers=("GL_ARB_timer_query" in ext or ctx.version_code >= 330) and not software,
        framebuffer_fetch="GL_EXT_shader_framebuffer_fetch" in ext,
        shader_ballot="GL_ARB_shader_ballot" in ext and "GL_ARB_gpu_shader_int64" in ext,
    )
    for name in disable:
        if name not in caps:
            raise DeviceError(f"unknown capability '{name}' (known: {', '.join(caps)})")
        caps[name] = False
    return Capabilities(
        gl_renderer=renderer,
        vendor=info.get("GL_VENDOR", "?"),
        version=info.get("GL_VERSION", "?"),
        software=software,
        limits=query_limits(ctx, software),
        **caps,
    )


def create_context(ctx=None, disable: tuple[str, ...] = ()):
    """Return (moderngl context, Capabilities): adopt `ctx` or make a standalone headless EGL one."""
    try:
        import moderngl
    except ImportError as exc:  # pragma: no cover - dependency is declared
        raise DeviceError(f"moderngl is not installed ({exc}); `pip install guaca_py` installs it") from exc
    if ctx is None:
        try:
            ctx = moderngl.create_context(standalone=True, backend="egl", require=450)
        except Exception as exc:
            raise DeviceError(f"could not create a headless OpenGL 4.5 context: {exc}. {_INSTALL_HINT}") from exc
    elif ctx.version_code < 450:
        raise DeviceError(f"the adopted context is OpenGL {ctx.version_code}; guaca_py needs 4.5")
    return ctx, detect_capabilities(ctx, disable)


def probe_capabilities(disable: tuple[str, ...] = ()) -> Capabilities:
    """Capabilities of a fresh headless context, released again; whatever context was current stays current."""
    from .host_state import native

    previous = native().current()
    ctx, caps = create_context(None, disable)
    ctx.release()
    if previous is not None:
        native().make_current(previous)
    return caps
