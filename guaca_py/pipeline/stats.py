"""The frame's statistics: a recorder whose top-level keys are one fixed, documented schema."""

from __future__ import annotations

# Every top-level key a frame's stats may hold, and what it holds. A write of any other key raises:
# a misspelt key would otherwise become a silent new entry that no reader looks at.
SCHEMA: dict[str, str] = {
    "method": "transparency method id",
    "method_auto": "why `method: auto` picked the method (the device's measured table)",
    "insertion_path": "A-buffer insertion: 64bit or 32bit",
    "device": "GL renderer string",
    "resolution": "[width, height]",
    "render_resolution": "[width, height] rendered: the resolution times antialiasing.supersample",
    "draws": "draws in the frame",
    "transparent_draws": "draws whose material instance can produce alpha < 1",
    "passes": "per pass: {'ms': time, ...} ('fused_into'/'includes' for fused passes)",
    "passes_of": "'previous frame' when the pass times are the previous frame's",
    "timer": "how pass times were taken: gpu, wall or off",
    "frame_wall_ms": "wall time of the frame's passes (the whole frame of render(), one view of render_views())",
    "view": "render_views(): this view's index and the number of views of the call",
    "regrown": "frames rendered again because storage grew",
    "geometry_passes": "geometry passes over the transparent draws",
    "fragments": "transparent fragments: stored, dropped, overflow, culled by early termination",
    "fragments_of": "'previous frame' when counters are read a frame late",
    "memory": "bytes each buffer holds: {name: bytes}",
    "warnings": "things the frame did not do as asked (overflow, clipped timers, unsupported views)",
    "antialiasing": "samples per pixel (and samples asked), supersampling factor",
    "raster": "which rasterizer drew the transparent draws and why; compute rasterizer totals",
    "lights": "light culling: visible, shaded, mode, grid size and layers",
    "critical_section": "the lock a critical-section method ran with",
    "peeling": "peeling passes and layers",
    "truncated": "fragments a fixed-size resolve had to leave out",
    "debug_views": "per debug view: what it showed",
    "skipped": "per pass: why it did nothing this frame",
    "timing": "how approximate methods' extra passes were timed",
}


class FrameStats(dict):
    """A frame's statistics: a dict whose top-level keys must be in SCHEMA."""

    @staticmethod
    def _check(key: str) -> None:
        if key not in SCHEMA:
            raise KeyError(f"frame stats have no key '{key}' (known: {', '.join(SCHEMA)})")

    def __setitem__(self, key: str, value) -> None:
        self._check(key)
        super().__setitem__(key, value)

    def setdefault(self, key: str, default=None):
        """dict.setdefault, for a key of the schema."""
        self._check(key)
        return super().setdefault(key, default)

    def update(self, *args, **kwargs) -> None:
        """dict.update, every key checked against the schema."""
        for key, value in dict(*args, **kwargs).items():
            self[key] = value

    def section(self, key: str) -> dict:
        """The dict under `key` (made empty on first use)."""
        return self.setdefault(key, {})

    def warn(self, message: str) -> None:
        """Record something the frame did not do as asked."""
        self.setdefault("warnings", []).append(message)

    def memory(self, name: str, nbytes: int) -> None:
        """Record the bytes buffer `name` holds."""
        self.section("memory")[name] = int(nbytes)
