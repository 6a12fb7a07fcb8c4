"""Scenes the benchmarks build in code: many lights, full-screen quad stacks, triangles of one size, a field of models.

The many-lights scene is also a file (benchmarks/scenes/many_lights.yaml, which a test renders):
    python -m guaca_py.benchmarking.scenes OUT.yaml [--lights 1000] [--seed 0] [--spot-fraction 0]
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import numpy as np
import yaml

from ..scene.graph import Camera, MaterialInstance, MeshData, Node, Scene, Transform
from ..scene.nodes import scene_bounds

HALF = 10.0  # the lit area is [-HALF, HALF] in x and z


def _r(v, nd: int = 3) -> list[float]:
    """Values rounded to `nd` decimals: the YAML stays short."""
    return [round(float(x), nd) for x in np.atleast_1d(v)]


def many_lights_doc(n_lights: int = 1000, seed: int = 0, spot_fraction: float = 0.0) -> dict:
    """Many lights over opaque and transparent geometry, as a YAML-ready dict (the loader's format).

    A ground plane, a grid of opaque boxes and spheres, and rows of transparent panes and spheres
    (pbr, alpha 0.35-0.6) under small-range lights scattered just above the ground, so each screen
    tile sees only a few of them.
    """
    rng = np.random.default_rng(seed)
    nodes = [
        {
            "name": "ground",
            "mesh": {"primitive": "plane", "size": [2 * HALF + 4, 2 * HALF + 4]},
            "material": {"description": "pbr", "uniforms": {"albedo": [0.6, 0.6, 0.6], "roughness": 0.7}},
        }
    ]
    for i, x in enumerate(np.linspace(-HALF + 2, HALF - 2, 5)):
        for j, z in enumerate(np.linspace(-HALF + 2, HALF - 2, 4)):
            box = (i + j) % 2 == 0
            mesh = (
                {"primitive": "box", "size": [1.2, 1.2, 1.2]}
                if box
                else {"primitive": "sphere", "radius": 0.7, "segments": 24, "rings": 12}
            )
            nodes.append(
                {
                    "name": f"solid_{i}_{j}",
                    "mesh": mesh,
                    "transform": {"translation": _r([x, 0.6 if box else 0.7, z]), "rotation_deg": [0, 20 * i, 0]},
                    "material": {
                        "description": "pbr",
                        "uniforms": {
                            "albedo": _r(rng.uniform(0.3, 0.9, 3)),
                            "roughness": _r(rng.uniform(0.2, 0.8))[0],
                            "metalness": float((i * 4 + j) % 3 == 0),
                        },
                    },
                }
            )
    for k, z in enumerate(np.linspace(-HALF + 4, HALF - 3, 4)):  # transparent panes facing the camera
        nodes.append(
            {
                "name": f"pane_{k}",
                "mesh": {"primitive": "quad", "size": [2 * HALF - 2, 2.5]},
                "transform": {"translation": _r([0, 1.4, z]), "rotation_deg": [0, 0, 0]},
                "material": {
                    "description": "pbr",
                    "uniforms": {
                        "albedo": _r(rng.uniform(0.2, 1.0, 3)),
                        "roughness": 0.25,
                        "alpha": _r(rng.uniform(0.35, 0.6))[0],
                    },
                },
            }
        )
    for k in range(6):  # transparent spheres between the solids
        nodes.append(
            {
                "name": f"bubble_{k}",
                "mesh": {"primitive": "sphere", "radius": 0.9, "segments": 24, "rings": 12},
                "transform": {
                    "translation": _r([rng.uniform(-HALF + 1, HALF - 1), 1.0, rng.uniform(-HALF + 1, HALF - 1)])
                },
                "material": {
                    "description": "pbr",
                    "uniforms": {"albedo": _r(rng.uniform(0.2, 1.0, 3)), "roughness": 0.2, "alpha": 0.4},
                },
            }
        )
    lights = []
    for _ in range(n_lights):
        pos = _r([rng.uniform(-HALF, HALF), rng.uniform(0.3, 2.0), rng.uniform(-HALF, HALF)])
        color = _r(rng.uniform(0.2, 1.0, 3))
        if rng.random() < spot_fraction:
            d = rng.normal(size=3)
            d[1] = -abs(d[1]) - 1.0
            lights.append(
                {
                    "type": "spot",
                    "position": pos,
                    "direction": _r(d / np.linalg.norm(d)),
                    "color": color,
                    "intensity": _r(rng.uniform(0.6, 2.0))[0],
                    "radius": _r(rng.uniform(1.5, 3.5))[0],
                    "inner_angle_deg": 15,
                    "outer_angle_deg": _r(rng.uniform(25, 60))[0],
                }
            )
        else:
            lights.append(
                {
                    "type": "point",
                    "position": pos,
                    "color": color,
                    "intensity": _r(rng.uniform(0.3, 1.0))[0],
                    "radius": _r(rng.uniform(1.0, 2.0))[0],
                }
            )
    return {
        "camera": {"position": [0, 9, 15], "target": [0, 0, -1], "up": [0, 1, 0], "fov_y": 55, "near": 0.1, "far": 60},
        "background": [0.02, 0.02, 0.03],
        "lights": lights,
        "nodes": nodes,
    }


class _Flow(yaml.SafeDumper):
    """Block style for the document, flow style for leaf mappings/lists (one light per line)."""


def _represent_dict(dumper, data):
    leaf = all(not isinstance(v, dict) or k in ("uniforms",) for k, v in data.items()) and "name" not in data
    return dumper.represent_mapping("tag:yaml.org,2002:map", data.items(), flow_style=leaf)


def _represent_list(dumper, data):
    return dumper.represent_sequence(
        "tag:yaml.org,2002:seq", data, flow_style=not any(isinstance(v, dict) for v in data)
    )


_Flow.add_representer(dict, _represent_dict)
_Flow.add_representer(list, _represent_list)


def write_scene(path: Path, n_lights: int = 1000, seed: int = 0, spot_fraction: float = 0.0) -> Path:
    """Write the scene YAML to `path`."""
    doc = many_lights_doc(n_lights, seed, spot_fraction)
    head = (
        f"# Generated by python -m guaca_py.benchmarking.scenes OUT.yaml --lights {n_lights} --seed {seed}"
        f"{f' --spot-fraction {spot_fraction}' if spot_fraction else ''}\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(head + yaml.dump(doc, Dumper=_Flow, sort_keys=False, width=200))
    return path


def quad_stack(layers: int) -> Scene:
    """`layers` full-screen unlit quads at alpha 0.5, drawn back to front."""
    p = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32) * 4.0
    mesh = MeshData(
        p,
        np.tile(np.float32([0, 0, 1]), (4, 1)),
        np.float32([[0, 0], [1, 0], [1, 1], [0, 1]]),
        np.uint32([[0, 1, 2], [0, 2, 3]]),
        "stack_quad",
    )
    nodes = []
    for i in range(layers):
        z = -1.0 - 2.0 * (layers - 1 - i) / max(1, layers)  # back to front
        color = [(i * 37 % 11) / 10, (i * 17 % 7) / 6, (i * 5 % 3) / 2]
        nodes.append(
            Node(
                f"layer{i}",
                mesh=mesh,
                transform=Transform(translation=[0, 0, z]),
                material=MaterialInstance("unlit", {"color": color, "alpha": 0.5}),
            )
        )
    cam = Camera(position=[0, 0, 1], target=[0, 0, 0], up=[0, 1, 0], fov_y=90, near=0.1, far=10)
    return Scene(nodes=nodes, camera=cam, lights=[], background=[0, 0, 0])


TRIANGLES_EYE_Z, TRIANGLES_FOV_Y = 5.0, 50.0  # the camera of triangle_scene()


def triangle_scene(area_px: float, count: int, size: int, seed: int = 0) -> Scene:
    """`count` random unlit triangles (alpha 0.5) of about `area_px` px² each on screen, spread over a square view."""
    rng = np.random.default_rng(seed)
    depth = TRIANGLES_EYE_Z - rng.uniform(-0.5, 0.5, count)  # distance to the eye
    half = math.tan(math.radians(TRIANGLES_FOV_Y / 2))
    px = 2.0 * depth * half / size  # world size of a pixel there
    # a triangle of random shape (aspect up to 4:1) and orientation, scaled to the area
    ang = rng.uniform(0, 2 * np.pi, count)
    aspect = rng.uniform(1.0, 4.0, count)
    base = np.sqrt(2.0 * area_px * aspect) * px
    height = 2.0 * area_px * px * px / base
    apex = rng.uniform(-0.5, 0.5, count) * base
    local = np.stack(
        [
            np.stack([-base / 2, np.zeros(count)], 1),
            np.stack([base / 2, np.zeros(count)], 1),
            np.stack([apex, height], 1),
        ],
        axis=1,
    )  # (count, 3, 2), counter-clockwise
    rot = np.stack([np.stack([np.cos(ang), -np.sin(ang)], 1), np.stack([np.sin(ang), np.cos(ang)], 1)], 1)
    xy = np.einsum("nij,nkj->nki", rot, local)
    centre = rng.uniform(-0.5, 0.5, (count, 1, 2)) * (depth * 2.0 * half)[:, None, None]
    z = (TRIANGLES_EYE_Z - depth)[:, None, None] * np.ones((count, 3, 1))
    pos = np.concatenate([xy + centre, z], axis=2).reshape(-1, 3).astype(np.float32)
    mesh = MeshData(
        pos,
        np.tile(np.float32([0, 0, 1]), (len(pos), 1)),
        np.zeros((len(pos), 2), np.float32),
        np.arange(len(pos), dtype=np.uint32).reshape(-1, 3),
        f"triangles_{area_px:g}px",
    )
    node = Node("triangles", mesh=mesh, material=MaterialInstance("unlit", {"color": [0.8, 0.5, 0.2], "alpha": 0.5}))
    cam = Camera(
        position=(0, 0, TRIANGLES_EYE_Z), target=(0, 0, 0), up=(0, 1, 0), fov_y=TRIANGLES_FOV_Y, near=0.1, far=100
    )
    return Scene(camera=cam, background=(0.0, 0.0, 0.0), nodes=[node])


FIELD_TURNS_DEG = (0, 25, -20, 40, -35, 10)  # each copy of a field turned a little more


def field_doc(source: Path, scene: Scene, count: int, mesh_ref: str) -> dict:
    """A square field of `count` copies of scene file `source`'s first file mesh, as a YAML-ready dict.

    `scene` is `source` loaded (for the mesh's size); `mesh_ref` is how the field's YAML names
    the mesh file (a path relative to where it is written). Every copy names the same file, so
    the loader reads it once and the renderer uploads it once (meshes are shared by content).
    The copies keep the first node's scale, height and material kind, stand on a grid 1.3 of
    their footprint apart, turned and coloured in turn (the source's colours, its alpha), and are
    seen from the source camera's direction, far enough for the whole field to fill the view.
    """
    doc = yaml.safe_load(source.read_text())
    index = next(
        (i for i, n in enumerate(doc.get("nodes") or []) if isinstance(n.get("mesh"), dict) and "file" in n["mesh"]),
        None,
    )
    if index is None:
        raise SystemExit(f"{source}: no node with a mesh file to make a field of")
    template = doc["nodes"][index]
    lo, hi = scene_bounds([scene.nodes[index]])
    spacing = 1.3 * float(max(hi[0] - lo[0], hi[2] - lo[2]))
    centre = (lo + hi) / 2
    transform = dict(template.get("transform") or {})
    t0 = np.array(transform.get("translation", [0, 0, 0]), float)
    turn0 = np.array(transform.get("rotation_deg", [0, 0, 0]), float)
    materials = [n.get("material") for n in doc["nodes"] if isinstance(n.get("mesh"), dict) and n.get("material")]
    cols = math.ceil(math.sqrt(count))
    rows = math.ceil(count / cols)
    nodes = []
    for k in range(count):
        gx, gz = k % cols, k // cols
        x, z = (gx - (cols - 1) / 2) * spacing, (gz - (rows - 1) / 2) * spacing
        place = t0 + np.array([x - centre[0], 0.0, -z - centre[2]])
        turn = turn0 + np.array([0.0, FIELD_TURNS_DEG[k % len(FIELD_TURNS_DEG)], 0.0])
        nodes.append(
            {
                "name": f"copy_{k}",
                "mesh": {"file": mesh_ref},
                "transform": {**transform, "translation": _r(place), "rotation_deg": _r(turn)},
                **({"material": materials[k % len(materials)]} if materials else {}),
            }
        )
    cam = doc.get("camera") or {}
    eye, target = np.array(cam.get("position", [0, 1, 5]), float), np.array(cam.get("target", [0, 0, 0]), float)
    fov = float(cam.get("fov_y", 60))
    reach = 0.5 * math.hypot(cols * spacing, rows * spacing, float(hi[1] - lo[1]))  # half the field's diagonal
    distance = 0.8 * reach / math.sin(math.radians(fov) / 2)  # the field fills most of the view
    look_at = np.array([0.0, float(centre[1]), 0.0])
    position = look_at + (eye - target) / np.linalg.norm(eye - target) * distance
    camera = {
        "position": _r(position),
        "target": _r(look_at),
        "up": cam.get("up", [0, 1, 0]),
        "fov_y": fov,
        "near": _r(distance / 100)[0],
        "far": _r(distance + 4 * reach)[0],
    }
    out = {"camera": camera, "background": doc.get("background", [0.05, 0.05, 0.06]), "lights": doc.get("lights", [])}
    return {**out, "nodes": nodes}


def write_field(source: Path, scene: Scene, count: int, out_dir: Path) -> Path:
    """Write field_<count>.yaml (field_doc) into `out_dir`, naming the mesh by a path relative to it."""
    doc = yaml.safe_load(source.read_text())
    file = next(n["mesh"]["file"] for n in doc["nodes"] if isinstance(n.get("mesh"), dict) and "file" in n["mesh"])
    mesh = Path(file) if Path(file).is_absolute() else source.parent / file
    out_dir.mkdir(parents=True, exist_ok=True)
    field = field_doc(source, scene, count, os.path.relpath(mesh.absolute(), out_dir.absolute()))
    path = out_dir / f"field_{count}.yaml"
    head = f"# {count} copies of {source.name}'s mesh: guaca_py.benchmarking.scenes.write_field\n"
    path.write_text(head + yaml.dump(field, Dumper=_Flow, sort_keys=False, width=200))
    return path


def main(argv: list[str] | None = None) -> int:
    """Write the many-lights scene YAML."""
    ap = argparse.ArgumentParser(description="Write the many-lights scene (benchmarks/light_culling.py's) as YAML.")
    ap.add_argument("out", type=Path, help="e.g. benchmarks/scenes/many_lights.yaml")
    ap.add_argument("--lights", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--spot-fraction", type=float, default=0.0)
    a = ap.parse_args(argv)
    print(write_scene(a.out, a.lights, a.seed, a.spot_fraction))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
