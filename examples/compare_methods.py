"""Two transparency methods side by side in one host framebuffer: exact A-buffer vs plain blending.

Each Renderer draws into its half of the same framebuffer (`viewport=`); the difference image
shows where unsorted blending gets the order of overlapping transparent surfaces wrong.

    python examples/compare_methods.py --left presort_lf_et --right unsorted_blend --out compare.png
"""

from __future__ import annotations

import argparse

import moderngl
import numpy as np

from guaca_py import Renderer
from guaca_py.scene.loader import demo_scene


def main(argv: list[str] | None = None) -> dict:
    """Render both halves; returns the RMSE and maximum difference between them (8-bit units)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--left", default="presort_lf_et")
    ap.add_argument("--right", default="unsorted_blend")
    ap.add_argument("--width", type=int, default=256, help="width of each half")
    ap.add_argument("--height", type=int, default=192)
    ap.add_argument("--out", default="compare.png")
    args = ap.parse_args(argv)

    ctx = moderngl.create_context(standalone=True, backend="egl", require=450)
    w, h = args.width, args.height
    fbo = ctx.framebuffer([ctx.texture((2 * w, h), 4)])
    scene = demo_scene()
    left = Renderer("default", ctx=ctx, method=args.left)
    right = Renderer("default", ctx=ctx, method=args.right)
    left.render(scene, w, h, target=fbo, viewport=(0, 0, w, h), read_back=False)
    right.render(scene, w, h, target=fbo, viewport=(w, 0, w, h), read_back=False)
    img = np.frombuffer(fbo.read(components=3), np.uint8).reshape(h, 2 * w, 3)[::-1]
    diff = np.abs(img[:, :w].astype(int) - img[:, w:].astype(int))
    figures = {"rmse": float(np.sqrt((diff.astype(float) ** 2).mean())), "max": int(diff.max())}
    from PIL import Image

    Image.fromarray(np.ascontiguousarray(img)).save(args.out)
    print(f"{args.out}: {args.left} (left) vs {args.right} (right): RMSE {figures['rmse']:.2f}, max {figures['max']}")
    for r in (left, right):
        r.release()
    ctx.release()
    return figures


if __name__ == "__main__":
    main()
