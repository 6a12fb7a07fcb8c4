"""Procedural meshes (quad, plane, box, sphere, cylinder) with CCW front faces seen from outside."""

from __future__ import annotations

import math
from collections.abc import Callable
from numbers import Integral, Real
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..numeric import POSITIVE, Range
from .graph import MeshData

# Caps keep a typo like `segments: 100000` from silently allocating gigabytes.
_MAX_SEGMENTS = 4096
_MAX_SUBDIVISIONS = 2048


def _mesh(name: str, positions, normals, texcoords, indices) -> MeshData:
    """Pack arrays into a MeshData with the dtypes the renderer uploads directly."""
    return MeshData(
        positions=np.ascontiguousarray(positions, dtype=np.float32).reshape(-1, 3),
        normals=np.ascontiguousarray(normals, dtype=np.float32).reshape(-1, 3),
        texcoords=np.ascontiguousarray(texcoords, dtype=np.float32).reshape(-1, 2),
        indices=np.ascontiguousarray(indices, dtype=np.uint32).reshape(-1, 3),
        name=name,
    )


def _quad(size) -> MeshData:
    """Rectangle in the XY plane centred on the origin, facing +Z."""
    hw, hh = size[0] / 2.0, size[1] / 2.0
    pos = [(-hw, -hh, 0.0), (hw, -hh, 0.0), (hw, hh, 0.0), (-hw, hh, 0.0)]
    nrm = [(0.0, 0.0, 1.0)] * 4
    uv = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    return _mesh("quad", pos, nrm, uv, [(0, 1, 2), (0, 2, 3)])


def _plane(size, subdivisions: int) -> MeshData:
    """Rectangle in the XZ plane centred on the origin, facing +Y, split into a grid."""
    n = subdivisions
    t = np.linspace(0.0, 1.0, n + 1)
    fu, fv = np.meshgrid(t, t, indexing="xy")  # fv runs along +Z, row-major rows
    x = (fu - 0.5) * size[0]
    z = (fv - 0.5) * size[1]
    pos = np.stack([x, np.zeros_like(x), z], axis=-1).reshape(-1, 3)
    nrm = np.tile([0.0, 1.0, 0.0], (pos.shape[0], 1))
    # v grows towards -Z so the texture reads upright when seen from above with -Z "up".
    uv = np.stack([fu, 1.0 - fv], axis=-1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    a = (j * (n + 1) + i).ravel()
    b, c, d = a + 1, a + n + 2, a + n + 1  # +X, +X+Z, +Z neighbours of a
    tris = np.concatenate([np.stack([a, d, c], 1), np.stack([a, c, b], 1)])
    return _mesh("plane", pos, nrm, uv, tris)


def _box(size) -> MeshData:
    """Axis-aligned box centred on the origin; 4 vertices per face so normals stay flat."""
    half = np.asarray(size, dtype=np.float64) / 2.0
    # (outward normal, screen-up axis of that face); screen-right = up x normal, so right x up = normal.
    faces = [
        ((1, 0, 0), (0, 1, 0)),
        ((-1, 0, 0), (0, 1, 0)),
        ((0, 0, 1), (0, 1, 0)),
        ((0, 0, -1), (0, 1, 0)),
        ((0, 1, 0), (0, 0, -1)),
        ((0, -1, 0), (0, 0, 1)),
    ]
    pos, nrm, uv, tris = [], [], [], []
    for k, (n, v) in enumerate(faces):
        n, v = np.asarray(n, float), np.asarray(v, float)
        u = np.cross(v, n)
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            pos.append((n + su * u + sv * v) * half)
            nrm.append(n)
            uv.append(((su + 1) / 2, (sv + 1) / 2))
        base = 4 * k
        tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return _mesh("box", pos, nrm, uv, tris)


def _ring_dirs(segments: int) -> tuple[np.ndarray, np.ndarray]:
    """sin/cos of the azimuth for segments+1 columns (the seam column is duplicated for UVs)."""
    phi = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    s, c = np.sin(phi), np.cos(phi)
    s[-1], c[-1] = s[0], c[0]  # exact seam so the duplicate is bit-identical
    return s, c


def _sphere(radius: float, segments: int, rings: int) -> MeshData:
    """UV sphere centred on the origin with poles on the Y axis."""
    sp, cp = _ring_dirs(segments)
    theta = np.linspace(0.0, math.pi, rings + 1)
    st, ct = np.sin(theta), np.cos(theta)
    st[0] = st[-1] = 0.0  # exact poles
    ct[0], ct[-1] = 1.0, -1.0
    # Azimuth 0 points at +Z and grows towards +X, so columns run left to right seen from outside.
    dirs = np.stack([np.outer(st, sp), np.repeat(ct[:, None], segments + 1, 1), np.outer(st, cp)], -1)
    dirs = dirs.reshape(-1, 3)
    u, v = np.meshgrid(np.arange(segments + 1) / segments, 1.0 - np.arange(rings + 1) / rings)
    uv = np.stack([u, v], -1).reshape(-1, 2)
    tris = []
    w = segments + 1
    for r in range(rings):
        for s in range(segments):
            a, d = r * w + s, r * w + s + 1  # upper row
            b, c = a + w, d + w  # lower row
            if r != rings - 1:  # bottom row: b and c are both the pole
                tris.append((a, b, c))
            if r != 0:  # top row: a and d are both the pole
                tris.append((a, c, d))
    return _mesh("sphere", dirs * radius, dirs, uv, tris)


def _cylinder(radius: float, height: float, segments: int, capped: bool) -> MeshData:
    """Cylinder along Y centred on the origin, optionally closed with flat caps."""
    sp, cp = _ring_dirs(segments)
    hh = height / 2.0
    w = segments + 1
    radial = np.stack([sp, np.zeros(w), cp], -1)
    pos = [np.concatenate([radial * radius + [0, hh, 0], radial * radius - [0, hh, 0]])]
    nrm = [np.concatenate([radial, radial])]
    u = np.arange(w) / segments
    uv = [np.concatenate([np.stack([u, np.ones(w)], -1), np.stack([u, np.zeros(w)], -1)])]
    tris = []
    for s in range(segments):
        a, d, b, c = s, s + 1, s + w, s + 1 + w  # a/d top row, b/c bottom row
        tris += [(a, b, c), (a, c, d)]
    if capped:
        base = 2 * w
        for sign in (1.0, -1.0):
            ring = radial[:-1] * radius + [0, sign * hh, 0]
            pos.append(np.vstack([[0, sign * hh, 0], ring]))
            nrm.append(np.tile([0.0, sign, 0.0], (segments + 1, 1)))
            # Map the disc to the texture so it reads upright from outside each cap.
            cap_uv = np.stack([0.5 + 0.5 * sp[:-1], 0.5 - 0.5 * sign * cp[:-1]], -1)
            uv.append(np.vstack([[0.5, 0.5], cap_uv]))
            for s in range(segments):
                p, q = base + 1 + s, base + 1 + (s + 1) % segments
                tris.append((base, p, q) if sign > 0 else (base, q, p))
            base += segments + 1
    return _mesh("cylinder", np.vstack(pos), np.vstack(nrm), np.vstack(uv), tris)


# ---- parameter validation ---------------------------------------------------------------


def _bad(kind: str, key: str, reason: str, hint: str) -> ConfigError:
    """A ConfigError for one primitive parameter (the loader adds file and line)."""
    return ConfigError(f"{kind}: {reason}", key=key, hint=hint)


def _is_number(v: Any) -> bool:
    """Real number that is not a bool (YAML `true` must not pass as 1)."""
    return isinstance(v, Real) and not isinstance(v, bool) and math.isfinite(float(v))


def _size(n: int) -> Callable[[str, str, Any], list[float]]:
    """Validator for an n-component positive size (a single number means all components)."""

    def check(kind: str, key: str, v: Any) -> list[float]:
        if _is_number(v):
            v = [v] * n
        if not isinstance(v, (list, tuple)) or len(v) != n or not all(_is_number(x) for x in v):
            raise _bad(kind, key, f"expected a list of {n} numbers, got {v!r}", f"e.g. {key}: {[1] * n}")
        if not all(POSITIVE.contains(x) for x in v):
            raise _bad(
                kind, key, f"all components must be {POSITIVE.requirement()}, got {list(v)}", "use positive extents"
            )
        return [float(x) for x in v]

    return check


def _positive(kind: str, key: str, v: Any) -> float:
    """Validator for a positive finite number."""
    if not _is_number(v) or not POSITIVE.contains(v):
        raise _bad(kind, key, f"expected a number {POSITIVE.requirement()}, got {v!r}", f"e.g. {key}: 1.0")
    return float(v)


def _count(lo: int, hi: int) -> Callable[[str, str, Any], int]:
    """Validator for an integer in [lo, hi]."""

    bounds = Range(lo, hi)

    def check(kind: str, key: str, v: Any) -> int:
        if not isinstance(v, Integral) or isinstance(v, bool) or not bounds.contains(v):
            raise _bad(kind, key, f"expected an integer {bounds.requirement()}, got {v!r}", f"e.g. {key}: {lo * 4}")
        return int(v)

    return check


def _flag(kind: str, key: str, v: Any) -> bool:
    """Validator for a boolean."""
    if not isinstance(v, bool):
        raise _bad(kind, key, f"expected true or false, got {v!r}", f"e.g. {key}: true")
    return v


# kind -> (builder, {param: (validator, default)}); defaults make a ~1 unit object at the origin.
_KINDS: dict[str, tuple[Callable[..., MeshData], dict[str, tuple[Callable, Any]]]] = {
    "quad": (_quad, {"size": (_size(2), [1.0, 1.0])}),
    "plane": (_plane, {"size": (_size(2), [1.0, 1.0]), "subdivisions": (_count(1, _MAX_SUBDIVISIONS), 1)}),
    "box": (_box, {"size": (_size(3), [1.0, 1.0, 1.0])}),
    "sphere": (
        _sphere,
        {
            "radius": (_positive, 0.5),
            "segments": (_count(3, _MAX_SEGMENTS), 32),
            "rings": (_count(2, _MAX_SEGMENTS), 16),
        },
    ),
    "cylinder": (
        _cylinder,
        {
            "radius": (_positive, 0.5),
            "height": (_positive, 1.0),
            "segments": (_count(3, _MAX_SEGMENTS), 32),
            "capped": (_flag, True),
        },
    ),
}

PRIMITIVE_KINDS: tuple[str, ...] = tuple(_KINDS)


def primitive_params(kind: str) -> dict[str, Any]:
    """Parameter names of a primitive kind with their defaults."""
    if kind not in _KINDS:
        raise ConfigError(
            f"unknown primitive {kind!r}", key="primitive", hint=f"valid kinds: {', '.join(PRIMITIVE_KINDS)}"
        )
    return {k: d for k, (_, d) in _KINDS[kind][1].items()}


def make_primitive(kind: str, **params: Any) -> MeshData:
    """Build a primitive mesh; bad kind or parameters raise ConfigError with the valid choices."""
    if not isinstance(kind, str) or kind not in _KINDS:
        raise ConfigError(
            f"unknown primitive {kind!r}", key="primitive", hint=f"valid kinds: {', '.join(PRIMITIVE_KINDS)}"
        )
    builder, spec = _KINDS[kind]
    args = {}
    for key, value in params.items():
        if key not in spec:
            raise _bad(kind, key, f"unknown parameter {key!r}", f"valid parameters for {kind}: {', '.join(spec)}")
        args[key] = spec[key][0](kind, key, value)
    for key, (_, default) in spec.items():
        args.setdefault(key, default)
    return builder(**args)
