"""Small unlit scenes built in code, which the CPU reference renders exactly (tests and benchmarks share them)."""

from __future__ import annotations

import colorsys
from collections.abc import Sequence

import numpy as np

from ..scene.graph import Camera, MaterialInstance, MeshData, Node, Scene, Transform


def unlit(color: tuple[float, float, float], alpha: float = 1.0) -> MaterialInstance:
    """An unlit material instance with the given color and alpha."""
    return MaterialInstance(description="unlit", uniforms={"color": [float(c) for c in color], "alpha": float(alpha)})


def quad_mesh(half_w: float, half_h: float, name: str = "quad") -> MeshData:
    """A quad in the object XY plane centred on the origin, facing +Z, as two triangles."""
    pos = np.array(
        [[-half_w, -half_h, 0], [half_w, -half_h, 0], [half_w, half_h, 0], [-half_w, half_h, 0]], dtype=np.float32
    )
    return MeshData(
        positions=pos,
        normals=np.tile(np.array([0, 0, 1], dtype=np.float32), (4, 1)),
        texcoords=np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float32),
        indices=np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32),
        name=name,
    )


def triangle_mesh(p0: Sequence[float], p1: Sequence[float], p2: Sequence[float], name: str = "triangle") -> MeshData:
    """A single triangle with its face normal on all three vertices."""
    pos = np.array([p0, p1, p2], dtype=np.float64)
    n = np.cross(pos[1] - pos[0], pos[2] - pos[0])
    n /= np.linalg.norm(n)
    return MeshData(
        positions=pos.astype(np.float32),
        normals=np.tile(n.astype(np.float32), (3, 1)),
        texcoords=np.array([[0, 0], [1, 0], [0, 1]], dtype=np.float32),
        indices=np.array([[0, 1, 2]], dtype=np.uint32),
        name=name,
    )


def _ordered(nodes: list[Node], order: str, seed: int, forward: str, reverse: str) -> list[Node]:
    """Reorder nodes for submission: as built, reversed, or shuffled with `seed`."""
    if order == forward:
        return list(nodes)
    if order == reverse:
        return nodes[::-1]
    if order == "shuffled":
        return [nodes[i] for i in np.random.default_rng(seed).permutation(len(nodes))]
    raise ValueError(f"order must be {forward!r}, {reverse!r} or 'shuffled', got {order!r}")


def origin_camera() -> Camera:
    """The camera of the small reference scenes: at +5 Z looking at the origin."""
    return Camera(position=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y=50.0, near=0.1, far=100.0)


def layered_quads_scene(
    n_layers: int = 12, order: str = "front_to_back", seed: int = 0, with_opaque: bool = True
) -> Scene:
    """Stack of tilted transparent quads between z=2 and z=-3, plus an optional opaque quad mid-stack."""
    # Geometry comes from a fixed stream so every `order`/`seed` draws the identical scene.
    rng = np.random.default_rng(20240611)
    zs = np.linspace(2.0, -3.0, n_layers) if n_layers > 1 else np.array([0.0])
    nodes: list[Node] = []
    for i, z in enumerate(zs):
        rgb = colorsys.hsv_to_rgb(i / n_layers, 0.75, 0.9)
        alpha = rng.uniform(0.2, 0.7)
        half = rng.uniform(0.6, 1.6, size=2)
        offset = rng.uniform(-0.8, 0.8, size=2)
        # Tilt of at most 4 degrees keeps neighbouring layers (>= 0.45 apart for 12) from crossing.
        tilt = rng.uniform(-4.0, 4.0, size=2)
        nodes.append(
            Node(
                name=f"layer{i:02d}",
                transform=Transform(
                    translation=(float(offset[0]), float(offset[1]), float(z)),
                    rotation_deg=(float(tilt[0]), float(tilt[1]), 0.0),
                ),
                mesh=quad_mesh(float(half[0]), float(half[1]), name=f"layer{i:02d}"),
                material=unlit(rgb, alpha),
            )
        )
    if with_opaque:
        mid = n_layers // 2
        z = 0.5 * (zs[mid - 1] + zs[mid]) if n_layers > 1 else -0.5
        opaque = Node(
            name="opaque",
            transform=Transform(translation=(0.55, -0.35, float(z)), rotation_deg=(3.0, -2.0, 0.0)),
            mesh=quad_mesh(0.9, 0.7, name="opaque"),
            material=unlit((0.95, 0.92, 0.85), 1.0),
        )
        nodes.insert(mid, opaque)
    return Scene(
        camera=origin_camera(),
        background=(0.05, 0.08, 0.12),
        nodes=_ordered(nodes, order, seed, "front_to_back", "back_to_front"),
    )


def interpenetrating_scene(order: str = "forward", seed: int = 0) -> Scene:
    """Three large mutually intersecting transparent triangles under a transformed parent, plus an opaque one in front."""
    specs = [
        (((-2.0, -1.5, -1.0), (2.0, -1.2, 1.0), (0.2, 1.8, 0.1)), (0.9, 0.2, 0.2), 0.5),
        (((-1.8, 1.2, 0.9), (2.1, 1.5, -0.8), (-0.3, -1.9, -0.1)), (0.2, 0.8, 0.3), 0.4),
        (((-2.2, -0.4, 1.1), (2.0, 0.3, -1.2), (0.4, -1.9, -0.5)), (0.2, 0.3, 0.9), 0.6),
    ]
    children = [
        Node(name=f"tri{i}", mesh=triangle_mesh(*pts, name=f"tri{i}"), material=unlit(c, a))
        for i, (pts, c, a) in enumerate(specs)
    ]
    children.append(
        Node(
            name="opaque_front",
            mesh=triangle_mesh((0.3, -0.2, 1.5), (1.6, -0.4, 1.6), (1.0, 1.0, 1.4), name="opaque_front"),
            material=unlit((0.9, 0.9, 0.3), 1.0),
        )
    )
    # A non-trivial parent transform checks that world matrices are composed, not just local ones.
    group = Node(
        name="group",
        transform=Transform(translation=(0.1, -0.1, -0.5), rotation_deg=(0.0, 10.0, 15.0)),
        children=_ordered(children, order, seed, "forward", "reverse"),
    )
    return Scene(camera=origin_camera(), background=(0.05, 0.08, 0.12), nodes=[group])
