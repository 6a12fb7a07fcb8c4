"""A scene edited every frame: move nodes, change uniforms, add and remove nodes, swap meshes.

GPU work follows the change: meshes are uploaded once per distinct content (a rebuilt but
identical mesh costs nothing) and freed a few frames after no scene uses them.

    python examples/animate_scene.py --frames 120 --out animated.png
"""

from __future__ import annotations

import argparse
import math

from guaca_py import Renderer
from guaca_py.scene.graph import Camera, Light, MaterialInstance, Node, Scene, Transform
from guaca_py.scene.primitives import make_primitive


def build_scene() -> Scene:
    """A floor, an opaque box and a ring of transparent spheres."""
    floor = Node("floor", mesh=make_primitive("plane", size=[8, 8]), material=MaterialInstance("pbr", {}))
    box = Node(
        "box",
        Transform((0.0, 0.5, 0.0)),
        make_primitive("box", size=[1, 1, 1]),
        MaterialInstance("pbr", {"albedo": [0.8, 0.3, 0.1]}),
    )
    ring = [
        Node(
            f"ball{k}",
            mesh=make_primitive("sphere", radius=0.4),
            material=MaterialInstance("pbr", {"albedo": [0.2, 0.4 + 0.1 * k, 0.9], "alpha": 0.5}),
        )
        for k in range(5)
    ]
    return Scene(
        camera=Camera(position=(0, 3, 6), target=(0, 0.5, 0), fov_y=50),
        lights=[Light("point", (2, 4, 2), intensity=30, radius=15), Light("directional", direction=(-1, -2, -1))],
        nodes=[floor, box, *ring],
    )


def animate(scene: Scene, i: int, frames: int, shapes: list) -> None:
    """Edit the scene for frame i."""
    t = i / max(frames, 1) * 2 * math.pi
    balls = [n for n in scene.nodes if n.name.startswith("ball")]
    for k, ball in enumerate(balls):  # move nodes
        a = t + k * 2 * math.pi / len(balls)
        ball.transform = Transform((2 * math.cos(a), 0.6 + 0.3 * math.sin(2 * a), 2 * math.sin(a)))
        ball.material.uniforms["alpha"] = 0.3 + 0.3 * (1 + math.sin(a)) / 2  # change a uniform
    scene.nodes[1].transform = Transform((0, 0.5, 0), (0, math.degrees(t), 0))
    scene.nodes[1].mesh = shapes[(i // 10) % len(shapes)]  # swap a mesh
    if i % 20 == 10:  # add a node ...
        scene.nodes.append(
            Node("spark", Transform((0, 2, 0)), make_primitive("box", size=[0.3, 0.3, 0.3]), MaterialInstance("unlit"))
        )
    elif i % 20 == 0:  # ... and remove it again
        scene.nodes = [n for n in scene.nodes if n.name != "spark"]


def main(argv: list[str] | None = None) -> dict:
    """Render the animation; returns the renderer's mesh-cache figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--out", default="animated.png")
    args = ap.parse_args(argv)

    renderer = Renderer("default")
    scene = build_scene()
    shapes = [make_primitive("box", size=[1, 1, 1]), make_primitive("cylinder", radius=0.5, height=1.0)]
    for i in range(args.frames):
        animate(scene, i, args.frames, shapes)
        last = i == args.frames - 1
        frame = renderer.render(scene, args.width, args.height, read_back=last, stats=last)
    frame.save(args.out)
    figures = {"frames": args.frames, "mesh_uploads": renderer.meshes.uploads, "meshes_on_gpu": len(renderer.meshes)}
    print(f"{args.out}: " + ", ".join(f"{k} {v}" for k, v in figures.items()))
    renderer.release()
    return figures


if __name__ == "__main__":
    main()
