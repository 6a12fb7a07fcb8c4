"""The parts of a scene graph: transforms, meshes, material instances, nodes, camera and lights.

`guaca_py.scene.graph` adds the Scene that holds them (and re-exports them); the readers of
files and trimesh scenes build these parts without depending on the Scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pyglm import glm

from ..errors import ConfigError
from ..frozen import field_key
from ..numeric import FLOAT32_MAX  # the largest magnitude a vertex attribute may hold: the GPU gets float32


class ValueConfigError(ConfigError, ValueError):
    """A value of the wrong shape or range given to a scene part (still a ValueError, as numpy's own checks raise)."""


_AXES = (glm.dvec3(1.0, 0.0, 0.0), glm.dvec3(0.0, 1.0, 0.0), glm.dvec3(0.0, 0.0, 1.0))


def _checked_matrix(matrix) -> np.ndarray:
    """A 4x4 float64 copy of `matrix` (anything numpy reads: nested lists, arrays, PyGLM matrices)."""
    m = np.array(matrix, dtype=np.float64)
    if m.shape == (16,):
        m = m.reshape(4, 4)
    if m.shape != (4, 4):
        raise ValueConfigError(f"a transform matrix is 4x4, got shape {m.shape}", key="Transform.matrix")
    if not np.all(np.isfinite(m)):
        raise ValueConfigError("a transform matrix must be finite (no NaN or inf)", key="Transform.matrix")
    return m


class Transform:
    """A node's local-to-parent transform: translation, Euler rotation in degrees (applied X, then Y,
    then Z) and scale; or any 4x4 matrix (`Transform(matrix=m)`, `Transform.from_matrix(m)`).

    A matrix, when given, is the transform: translation, rotation_deg and scale are then unused.
    It is anything numpy reads as 4x4 (or 16 numbers row by row), acting on column vectors: the
    translation is column 3, as in trimesh's graph and PyGLM's matrices.
    """

    def __init__(
        self,
        translation: tuple[float, float, float] = (0.0, 0.0, 0.0),
        rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
        scale: tuple[float, float, float] = (1.0, 1.0, 1.0),
        *,
        matrix=None,
    ):
        for key, v in (("translation", translation), ("rotation_deg", rotation_deg), ("scale", scale)):
            if _vector3(v) is None:
                raise ValueConfigError(f"must be 3 finite numbers, got {v!r}", key=f"Transform.{key}")
        self.translation, self.rotation_deg, self.scale = translation, rotation_deg, scale
        self._matrix = None if matrix is None else _checked_matrix(matrix)
        self._glm = None if self._matrix is None else glm.dmat4(self._matrix)

    @classmethod
    def from_matrix(cls, matrix) -> Transform:
        """A transform given as a 4x4 local-to-parent matrix (e.g. a glTF or trimesh node's)."""
        return cls(matrix=matrix)

    @property
    def has_matrix(self) -> bool:
        """True when the transform was given as a matrix rather than translation, rotation and scale."""
        return self._matrix is not None

    def glm_matrix(self) -> glm.dmat4:
        """Local-to-parent matrix as a PyGLM dmat4: T * Rz * Ry * Rx * S, or the given matrix."""
        if self._glm is not None:
            return self._glm
        rx, ry, rz = (math.radians(v) for v in self.rotation_deg)
        m = glm.translate(glm.dvec3(*self.translation))
        m = glm.rotate(m, rz, _AXES[2])
        m = glm.rotate(m, ry, _AXES[1])
        m = glm.rotate(m, rx, _AXES[0])
        return glm.scale(m, glm.dvec3(*self.scale))

    def matrix(self) -> np.ndarray:
        """Local-to-parent 4x4 float64 matrix: T * Rz * Ry * Rx * S (column vectors), or the given matrix."""
        return self._matrix.copy() if self._matrix is not None else np.array(self.glm_matrix())

    def check(self) -> None:
        """Refuse translation, rotation_deg or scale changed since construction to anything but 3 finite numbers."""
        if self._matrix is None:
            for key in ("translation", "rotation_deg", "scale"):
                v = getattr(self, key)
                if _vector3(v) is None:
                    raise ValueConfigError(f"must be 3 finite numbers, got {v!r}", key=f"Transform.{key}")

    def key(self) -> tuple:
        """Hashable key of the transform's values (caches compare values, never object identity)."""
        if self._matrix is not None:
            return ("matrix", self._matrix.tobytes())
        try:
            return (_freeze(self.translation), _freeze(self.rotation_deg), _freeze(self.scale))
        except (TypeError, ValueError):  # a field set to something that is not numbers: named
            self.check()
            raise

    def __eq__(self, other) -> bool:
        return isinstance(other, Transform) and self.key() == other.key()

    __hash__ = None  # mutable, like the dataclass it replaced

    def __repr__(self) -> str:
        if self._matrix is not None:
            return f"Transform(matrix={self._matrix.tolist()})"
        return f"Transform(translation={self.translation}, rotation_deg={self.rotation_deg}, scale={self.scale})"


def _freeze(v) -> tuple:
    """A 3-vector as a hashable tuple (tuples as they are: the common case, once a node a frame)."""
    return v if type(v) is tuple else tuple(float(x) for x in v)


@dataclass
class MeshData:
    """Indexed triangle mesh in object space; normals and texcoords are always present.

    The arrays may be replaced after construction (`mesh.positions = new`): the renderer checks
    them again, once, before the next frame uses them. Editing an array in place is not seen:
    treat uploaded arrays as immutable and assign new ones instead.
    """

    positions: np.ndarray  # (N, 3) float32
    normals: np.ndarray  # (N, 3) float32, unit length
    texcoords: np.ndarray  # (N, 2) float32
    indices: np.ndarray  # (M, 3) uint32, or (3M,)
    name: str = "mesh"

    def __post_init__(self):
        self.check()
        self.__dict__["_gua_derived"] = (self._arrays(), {})

    def _arrays(self) -> tuple:
        return (self.positions, self.normals, self.texcoords, self.indices)

    def derived(self, name: str, compute):
        """`compute(self)`, memoised while the mesh holds the same four array objects (a content digest, a reach).

        When any array was replaced since the last call, the arrays are checked again first
        (`check`, ConfigError naming the mesh) and every memoised value is dropped: each costs
        one pass over the arrays per change, never one per frame.
        """
        values = self._held()[1]
        if name not in values:
            values[name] = compute(self)
        return values[name]

    def checked(self) -> MeshData:
        """This mesh, its arrays checked again (ConfigError naming it) if any was replaced since the last look."""
        self._held()
        return self

    def _held(self) -> tuple:
        """(the arrays last checked, the values derived from them), renewed and checked when an array was replaced."""
        arrays = self._arrays()
        held = self.__dict__.get("_gua_derived")
        if held is None or any(a is not b for a, b in zip(arrays, held[0])):
            self.check()
            held = self.__dict__["_gua_derived"] = (arrays, {})
        return held

    def check(self) -> None:
        """Refuse arrays of the wrong shape, non-finite positions and indices outside the vertex list (ConfigError)."""

        def fail(reason: str) -> ConfigError:
            return ConfigError(
                f"mesh '{self.name}': {reason}",
                hint="MeshData takes (N, 3) positions and normals, (N, 2) texcoords and (M, 3) integer indices below N",
            )

        arrays = {}
        for field_name, cols in (("positions", 3), ("normals", 3), ("texcoords", 2), ("indices", 3)):
            a = getattr(self, field_name)
            shape = getattr(a, "shape", None)
            if field_name == "indices" and shape is not None and len(shape) == 1 and shape[0] % 3 == 0:
                pass  # a flat index list, three a triangle, draws the same
            elif shape is None or len(shape) != 2 or shape[1] != cols:
                raise fail(
                    f"{field_name} must have shape (n, {cols}), got {shape if shape is not None else type(a).__name__}"
                )
            arrays[field_name] = a
        n = arrays["positions"].shape[0]
        for field_name in ("normals", "texcoords"):
            if arrays[field_name].shape[0] != n:
                raise fail(f"{field_name} has {arrays[field_name].shape[0]} rows for {n} positions")
        idx = arrays["indices"]
        if idx.size and not np.issubdtype(idx.dtype, np.integer):
            raise fail(f"indices must be integers, got {idx.dtype}")
        if idx.size and (int(idx.min()) < 0 or int(idx.max()) >= n):
            raise fail(f"indices must lie in [0, {n}), found {int(idx.min())}..{int(idx.max())}")
        for field_name in ("positions", "normals", "texcoords"):
            a = arrays[field_name]
            if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
                raise fail(f"{field_name} must hold real numbers, got {a.dtype}")
            if not np.all(np.isfinite(a)):
                raise fail(f"{field_name} must be finite (no NaN or inf)")
            if a.size and a.dtype.itemsize > 4 and float(np.max(np.abs(a))) > FLOAT32_MAX:
                raise fail(f"{field_name} hold values beyond float32's range (the GPU would read inf)")

    @property
    def triangle_count(self) -> int:
        """Number of triangles (an index list of shape (M, 3) or flat (3M,))."""
        return int(np.size(self.indices)) // 3

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned (min, max) corners in object space."""
        return self.positions.min(axis=0), self.positions.max(axis=0)


@dataclass
class MaterialInstance:
    """A material description (by name) plus per-instance uniform overrides."""

    description: str = "unlit"
    uniforms: dict = field(default_factory=dict)


@dataclass
class Node:
    """A scene-graph node: transform, optional mesh+material, children."""

    name: str = "node"
    transform: Transform = field(default_factory=Transform)
    mesh: MeshData | None = None
    material: MaterialInstance | None = None
    children: list[Node] = field(default_factory=list)

    def walk(self, parent: np.ndarray | None = None):
        """Yield (node, world matrix) for this node and all descendants, depth first, in order."""
        for node, world in self._walk(None if parent is None else glm.dmat4(np.asarray(parent, dtype=np.float64))):
            yield node, np.array(world)

    def _walk(self, parent: glm.dmat4 | None):
        """(node, PyGLM world matrix) pairs: the products stay in PyGLM, numpy only at the boundary."""
        local = self.transform.glm_matrix()
        world = local if parent is None else parent * local
        yield self, world
        for child in self.children:
            yield from child._walk(world)


class _ValueMemo:
    """Values derived from a data class's fields (a check's pass, matrices), kept while the fields hold the same
    values (frozen.field_key): a renderer checks its camera and lights every frame (the classes are mutable)."""

    def value_key(self) -> tuple:
        """The fields' values as a hashable key (equal keys: equal values)."""
        return field_key(self)

    def _memo(self) -> dict:
        key = field_key(self)
        memo = self.__dict__.get("_gua_memo")
        if memo is None or memo["key"] != key:
            memo = self.__dict__["_gua_memo"] = {"key": key}
        return memo

    def _checked_memo(self, where: str) -> dict:
        """The memo after the class's `_check(where)`, skipped where the same values passed it before."""
        memo = self._memo()
        if not memo.get("checked"):
            self._check(where)
            memo["checked"] = True
        return memo

    def checked_before(self) -> bool:
        """Whether the fields hold values that passed the check before (nothing to look at again)."""
        return bool(self._memo().get("checked"))

    def mark_checked(self) -> None:
        """Note that the current values passed a check made elsewhere (a scene's vectorised test of its lights)."""
        self._memo()["checked"] = True


@dataclass
class Camera(_ValueMemo):
    """Right-handed look-at camera; fov_y is the vertical field of view in degrees."""

    position: tuple[float, float, float] = (0.0, 1.0, 5.0)
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y: float = 60.0
    near: float = 0.1
    far: float = 100.0

    def check(self, where: str = "camera") -> None:
        """Refuse a camera no frame can be made from (ConfigError naming `where`, the field and what to do)."""
        self._checked_memo(where)  # a frame checks its camera several times, a frame loop every frame

    def _check(self, where: str) -> None:
        def fail(key: str, reason: str, hint: str) -> ConfigError:
            return ConfigError(reason, key=f"{where}.{key}", hint=hint)

        vecs = {}
        for key in ("position", "target", "up"):
            v = _vector3(getattr(self, key))
            if v is None:
                raise fail(key, f"must be 3 finite numbers, got {getattr(self, key)!r}", "e.g. (0, 1, 5)")
            vecs[key] = v
        fov = _number(self.fov_y)
        if fov is None or not 0.0 < fov < 180.0:
            raise fail("fov_y", f"must be a number of degrees in (0, 180), got {self.fov_y!r}", "e.g. 60")
        near, far = _number(self.near), _number(self.far)
        if near is None or near <= 0.0:
            raise fail("near", f"must be a finite number > 0, got {self.near!r}", "e.g. 0.1")
        if far is None or far <= near:
            raise fail(
                "far", f"must be a finite number greater than near ({self.near!r}), got {self.far!r}", "e.g. 100"
            )
        view = _scaled_unit(vecs["target"] - vecs["position"])
        if view is None:
            raise fail("target", "must differ from the camera position", "look at a point away from the camera")
        up = _scaled_unit(vecs["up"])
        if up is None or np.linalg.norm(np.cross(view, up)) < 1e-6:
            raise fail(
                "up",
                f"{self.up!r} is zero or parallel to the view direction",
                "e.g. (0, 1, 0), or (0, 0, 1) looking down",
            )

    def view_matrix(self) -> np.ndarray:
        """World-to-view 4x4 float64 matrix (camera looks down -Z)."""
        memo = self._checked_memo("camera")
        m = memo.get("view")
        if m is None:
            # up only gives a direction: scaled to unit length first, so 1e300 does not overflow the cross products
            up = _scaled_unit(_vector3(self.up))
            eye, target, up = (glm.dvec3(*v) for v in (self.position, self.target, up))
            m = memo["view"] = np.array(glm.lookAtRH(eye, target, up))
        return m.copy()  # the caller's to change

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """OpenGL perspective 4x4 matrix (clip z in [-w, w]) as float64; its values are float32, what GL receives."""
        memo = self._checked_memo("camera")
        key = ("projection", float(aspect))
        m = memo.get(key)
        if m is None:
            # PyGLM builds projections in single precision only; the GPU reads them so anyway
            m = glm.perspectiveRH_NO(math.radians(self.fov_y), float(aspect), float(self.near), float(self.far))
            m = memo[key] = np.array(m, dtype=np.float64)
        return m.copy()


LIGHT_TYPES = ("point", "spot", "directional", "ambient")
#: farthest a scene's coordinates may reach from the origin: float32 positions step by 1 at 1.7e7,
#: and llvmpipe's clipper drops triangles past ~1e8 (the loader checks scales, the draw list extents)
MAX_WORLD = 1.0e7
#: largest colour component times intensity of a light, and largest background component: the
#: shading sums and squares these in float32 (max 3.4e38), so far larger values overflow to black
MAX_RADIANCE = 1.0e6
#: widest spot-light cone half-angle in degrees (at 90 the cone is a half-space, its falloff undefined)
MAX_CONE_DEG = 89.9


@dataclass
class Light(_ValueMemo):
    """A point, spot, directional or ambient light. Color is linear RGB; intensity scales it.

    Point/spot lights have a finite range `radius` with a smooth falloff to zero there;
    spot lights use `direction` and inner/outer cone half-angles in degrees; directional
    lights use `direction` (the direction light travels) and ignore position and radius;
    an ambient light is light arriving equally from every direction (a surface reflects
    color * intensity * its albedo) and uses neither position, direction nor radius.
    """

    type: str = "point"
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: tuple[float, float, float] = (0.0, -1.0, 0.0)
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    radius: float = 10.0
    inner_angle_deg: float = 20.0
    outer_angle_deg: float = 30.0

    def __post_init__(self):
        self.check()

    def check(self, where: str = "light") -> None:
        """Refuse NaN, infinite or overflowing values and a direction of length zero (ConfigError naming `where`).

        Colour times intensity is bounded by MAX_RADIANCE: beyond it the shading's float32
        arithmetic overflows and lit surfaces turn black. Skipped where the same values passed before.
        """
        self._checked_memo(where)

    def _check(self, where: str) -> None:
        def fail(key: str, reason: str, hint: str) -> ConfigError:
            return ConfigError(reason, key=f"{where}.{key}", hint=hint)

        if self.type not in LIGHT_TYPES:
            raise fail("type", f"unknown light type {self.type!r}", f"one of {', '.join(LIGHT_TYPES)}")
        intensity = _number(self.intensity)
        if intensity is None:
            raise fail("intensity", f"must be a finite number, got {self.intensity!r}", "e.g. 1.0")
        color = _vector3(self.color)
        if color is None:
            raise fail("color", f"must be 3 finite numbers, got {self.color!r}", "linear RGB, e.g. (1, 1, 1)")
        if float(np.max(np.abs(color))) * abs(intensity) > MAX_RADIANCE:
            raise fail(
                "intensity",
                f"color {tuple(color.tolist())} times intensity {intensity:g} exceeds {MAX_RADIANCE:g}",
                "scale the light down (the shading's float32 arithmetic overflows beyond this)",
            )
        if _vector3(self.position) is None:
            raise fail("position", f"must be 3 finite numbers, got {self.position!r}", "e.g. (0, 3, 0)")
        direction = _vector3(self.direction)
        if self.type in ("spot", "directional") and (direction is None or _scaled_unit(direction) is None):
            raise fail(
                "direction", f"must be 3 finite numbers, not all zero, got {self.direction!r}", "e.g. (0, -1, 0)"
            )
        for key in ("radius", "inner_angle_deg", "outer_angle_deg"):
            if _number(getattr(self, key)) is None:
                raise fail(key, f"must be a finite number, got {getattr(self, key)!r}", "see the Light docstring")
        # the ranges scene files are held to: a negative light would subtract, a radius of 0 divide by zero
        if intensity < 0.0:
            raise fail("intensity", f"must be >= 0, got {self.intensity!r}", "e.g. 1.0")
        if float(np.min(color)) < 0.0:
            raise fail("color", f"components must be >= 0, got {self.color!r}", "linear RGB, e.g. (1, 1, 1)")
        if self.type in ("point", "spot") and not self.radius > 0.0:
            raise fail("radius", f"must be > 0, got {self.radius!r}", "the light's range, e.g. 10")
        if self.type == "spot":
            inner, outer = float(self.inner_angle_deg), float(self.outer_angle_deg)
            if not 0.0 < outer <= MAX_CONE_DEG:
                raise fail("outer_angle_deg", f"must be in (0, {MAX_CONE_DEG}], got {outer:g}", "e.g. 30")
            if not 0.0 <= inner <= outer:
                raise fail(
                    "inner_angle_deg",
                    f"must be in [0, outer_angle_deg ({outer:g})], got {inner:g}",
                    "the inner cone must fit inside the outer one",
                )


def _number(x) -> float | None:
    """`x` as a finite float, or None (booleans, strings and arrays are not numbers here)."""
    if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
        return None
    v = float(x)
    return v if math.isfinite(v) else None


def _vector3(v) -> np.ndarray | None:
    """`v` as 3 finite float64 numbers, or None."""
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    return a if a.shape == (3,) and np.all(np.isfinite(a)) else None


def _scaled_unit(v: np.ndarray) -> np.ndarray | None:
    """`v` at unit length, divided by its largest component first (no overflow at 1e300); None when zero."""
    big = float(np.max(np.abs(v)))
    if big == 0.0 or not math.isfinite(big):
        return None
    v = v / big
    return v / np.linalg.norm(v)


def scene_bounds(nodes: list[Node]) -> tuple[np.ndarray, np.ndarray]:
    """World-space axis-aligned bounds of every mesh under `nodes`."""
    corners = []
    for root in nodes:
        for node, world in root.walk():
            if node.mesh is None or len(node.mesh.positions) == 0:
                continue
            lo, hi = node.mesh.bounds()
            box = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            corners.append((box @ world.T)[:, :3])
    if not corners:
        return np.zeros(3), np.zeros(3)
    pts = np.vstack(corners)
    return pts.min(axis=0), pts.max(axis=0)
