"""Embedding guaca_py in a host application that owns the OpenGL context.

The host draws its own things (here: a background gradient and a marker triangle with its own
shader), asks guaca_py for the transparent, lit frame straight into its framebuffer, then
draws on top again (a "UI" bar). guaca_py makes its context current and restores every piece
of GL state it touched, so the host code never re-sets anything after a guaca frame.

    python examples/embed_host_app.py --frames 30 --out host.png

In a windowed application replace the offscreen framebuffer by the window's (`ctx.screen`,
or `wnd.fbo` with moderngl-window) and `fbo.read` by swapping buffers.
"""

from __future__ import annotations

import argparse
import math

import moderngl
import numpy as np

from guaca_py import Renderer
from guaca_py.scene.loader import demo_scene

# The host's own shader (guaca_py keeps its GLSL in templates; a host writes what it likes).
HOST_VS = """#version 330
in vec2 in_pos;
in vec3 in_color;
out vec3 v_color;
void main() { v_color = in_color; gl_Position = vec4(in_pos, 0.0, 1.0); }
"""
HOST_FS = """#version 330
in vec3 v_color;
out vec4 color;
void main() { color = vec4(v_color, 0.8); }
"""


class HostApp:
    """A stand-in for the user's application: its context, framebuffer and drawing."""

    def __init__(self, width: int, height: int):
        self.ctx = moderngl.create_context(standalone=True, backend="egl", require=450)
        self.size = (width, height)
        self.fbo = self.ctx.framebuffer([self.ctx.texture(self.size, 4)], self.ctx.depth_renderbuffer(self.size))
        self.prog = self.ctx.program(vertex_shader=HOST_VS, fragment_shader=HOST_FS)
        # a UI bar along the bottom, drawn after guaca's frame with the host's blending
        bar = np.array(
            [[-1, -1, 0.1, 0.1, 0.2], [1, -1, 0.1, 0.1, 0.2], [1, -0.8, 0.2, 0.2, 0.4], [-1, -0.8, 0.2, 0.2, 0.4]],
            dtype=np.float32,
        )
        self.bar = self.ctx.vertex_array(
            self.prog,
            [(self.ctx.buffer(bar.tobytes()), "2f 3f", "in_pos", "in_color")],
            self.ctx.buffer(np.array([0, 1, 2, 0, 2, 3], dtype=np.int32).tobytes()),
        )
        # the host's state, set once, as real applications do
        self.fbo.use()
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA

    def draw_ui(self) -> None:
        """The host's own draw, relying on the state it set in __init__."""
        self.bar.render(moderngl.TRIANGLES)

    def read(self) -> np.ndarray:
        """The host framebuffer as an image (row 0 at the top)."""
        w, h = self.size
        return np.frombuffer(self.fbo.read(components=3), np.uint8).reshape(h, w, 3)[::-1].copy()

    def release(self) -> None:
        """Free the host's objects and context."""
        self.ctx.release()


def main(argv: list[str] | None = None) -> np.ndarray:
    """Run the host loop; returns the last host image."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--out", default="host.png")
    args = ap.parse_args(argv)

    host = HostApp(args.width, args.height)
    renderer = Renderer("default", ctx=host.ctx)  # adopt the host's context
    scene = demo_scene()
    glass = next(n for n, _ in scene.walk() if n.material and n.material.uniforms.get("alpha", 1.0) < 1.0)
    for i in range(args.frames):
        # animate: orbit the camera, pulse a transparent object's alpha
        a = 2 * math.pi * i / max(args.frames, 1)
        scene.camera.position = (6 * math.sin(a), 3.0, 6 * math.cos(a))
        glass.material.uniforms["alpha"] = 0.35 + 0.25 * math.sin(3 * a)
        # guaca draws into the host's framebuffer; nothing is read back to the CPU
        renderer.render(scene, *host.size, target=host.fbo, read_back=False, stats=False)
        host.draw_ui()  # host drawing right after guaca, with the host's own state intact
    image = host.read()
    from PIL import Image

    Image.fromarray(image).save(args.out)
    print(f"{args.frames} frames, last one written to {args.out}")
    renderer.release()
    host.release()
    return image


if __name__ == "__main__":
    main()
