"""Write a scene with many point (and optionally spot) lights over opaque and transparent geometry.

Usage: python benchmarks/scenes/many_lights.py [OUT.yaml] [--lights 1000] [--seed 0] [--spot-fraction 0]
(default OUT: benchmarks/scenes/many_lights.yaml). A ground plane, a grid of opaque boxes and
spheres, and rows of transparent panes and spheres (pbr, alpha 0.35-0.6) under small-range
lights scattered just above the ground, so each screen tile sees only a few of them.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

HALF = 10.0  # the lit area is [-HALF, HALF] in x and z


def _r(v, nd: int = 3) -> list[float]:
    return [round(float(x), nd) for x in np.atleast_1d(v)]


def many_lights_doc(n_lights: int = 1000, seed: int = 0, spot_fraction: float = 0.0) -> dict:
    """The scene as a YAML-ready dict (the loader's format: camera, background, lights, nodes)."""
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
        f"# Generated by benchmarks/scenes/many_lights.py --lights {n_lights} --seed {seed}"
        f"{f' --spot-fraction {spot_fraction}' if spot_fraction else ''}\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(head + yaml.dump(doc, Dumper=_Flow, sort_keys=False, width=200))
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", type=Path, default=Path(__file__).with_name("many_lights.yaml"))
    ap.add_argument("--lights", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--spot-fraction", type=float, default=0.0)
    a = ap.parse_args(argv)
    print(write_scene(a.out, a.lights, a.seed, a.spot_fraction))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
