"""Scene graph data model: nodes with transforms, meshes, materials, camera and lights."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], dtype=np.float64)


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], dtype=np.float64)


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=np.float64)


@dataclass
class Transform:
    """Translation, Euler rotation in degrees (applied X, then Y, then Z) and scale."""

    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def matrix(self) -> np.ndarray:
        """Local-to-parent 4x4 float64 matrix: T * Rz * Ry * Rx * S (column vectors)."""
        rx, ry, rz = (math.radians(v) for v in self.rotation_deg)
        m = np.eye(4)
        m[:3, :3] = _rot_z(rz) @ _rot_y(ry) @ _rot_x(rx) @ np.diag(np.asarray(self.scale, dtype=np.float64))
        m[:3, 3] = self.translation
        return m


@dataclass
class MeshData:
    """Indexed triangle mesh in object space; normals and texcoords are always present."""

    positions: np.ndarray  # (N, 3) float32
    normals: np.ndarray  # (N, 3) float32, unit length
    texcoords: np.ndarray  # (N, 2) float32
    indices: np.ndarray  # (M, 3) uint32
    name: str = "mesh"

    @property
    def triangle_count(self) -> int:
        """Number of triangles."""
        return int(self.indices.shape[0])

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
        world = (parent if parent is not None else np.eye(4)) @ self.transform.matrix()
        yield self, world
        for child in self.children:
            yield from child.walk(world)


@dataclass
class Camera:
    """Right-handed look-at camera; fov_y is the vertical field of view in degrees."""

    position: tuple[float, float, float] = (0.0, 1.0, 5.0)
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y: float = 60.0
    near: float = 0.1
    far: float = 100.0

    def view_matrix(self) -> np.ndarray:
        """World-to-view 4x4 float64 matrix (camera looks down -Z)."""
        # plain float arithmetic: numpy's cross and norm on 3-vectors cost ~200 Python calls a frame
        ex, ey, ez = (float(v) for v in self.position)
        fx, fy, fz = (float(t) - e for t, e in zip(self.target, (ex, ey, ez)))
        n = math.sqrt(fx * fx + fy * fy + fz * fz)
        fx, fy, fz = fx / n, fy / n, fz / n
        ux, uy, uz = (float(v) for v in self.up)
        sx, sy, sz = fy * uz - fz * uy, fz * ux - fx * uz, fx * uy - fy * ux
        n = math.sqrt(sx * sx + sy * sy + sz * sz)
        sx, sy, sz = sx / n, sy / n, sz / n
        ux, uy, uz = sy * fz - sz * fy, sz * fx - sx * fz, sx * fy - sy * fx
        return np.array(
            [
                [sx, sy, sz, -(sx * ex + sy * ey + sz * ez)],
                [ux, uy, uz, -(ux * ex + uy * ey + uz * ez)],
                [-fx, -fy, -fz, fx * ex + fy * ey + fz * ez],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """OpenGL perspective 4x4 float64 matrix (clip z in [-w, w])."""
        t = 1.0 / math.tan(math.radians(self.fov_y) / 2.0)
        n, f = self.near, self.far
        m = np.zeros((4, 4))
        m[0, 0], m[1, 1] = t / aspect, t
        m[2, 2], m[2, 3] = (f + n) / (n - f), 2 * f * n / (n - f)
        m[3, 2] = -1.0
        return m


LIGHT_TYPES = ("point", "spot", "directional")
#: farthest a scene's coordinates may reach from the origin: float32 positions step by 1 at 1.7e7,
#: and llvmpipe's clipper drops triangles past ~1e8 (the loader checks scales, the draw list extents)
MAX_WORLD = 1.0e7


@dataclass
class Light:
    """A point, spot or directional light. Color is linear RGB; intensity scales it.

    Point/spot lights have a finite range `radius` with a smooth falloff to zero there;
    spot lights use `direction` and inner/outer cone half-angles in degrees; directional
    lights use `direction` (the direction light travels) and ignore position and radius.
    """

    type: str = "point"
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: tuple[float, float, float] = (0.0, -1.0, 0.0)
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    radius: float = 10.0
    inner_angle_deg: float = 20.0
    outer_angle_deg: float = 30.0


@dataclass
class Scene:
    """Everything a frame needs: camera, background, lights and the node tree."""

    camera: Camera = field(default_factory=Camera)
    background: tuple[float, float, float] = (0.1, 0.1, 0.1)
    lights: list[Light] = field(default_factory=list)
    nodes: list[Node] = field(default_factory=list)
    source: Path | None = None

    def walk(self):
        """Yield (node, world matrix) for every node in the scene, in document order."""
        for n in self.nodes:
            yield from n.walk()
