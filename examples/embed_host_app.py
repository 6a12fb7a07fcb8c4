"""Embedding guaca_py in a host application that owns the OpenGL context and composes with it.

Each frame the host draws its own opaque world first (a background gradient and a marker
triangle standing in the scene, with its own shader and depth test), then asks guaca_py for
the transparent, lit objects over it: `render(..., target=fbo, over_target=True)` takes the
host's colour as the background and its depth as the opaque layer (glass in front of the
marker shows it through, glass behind it is hidden) and writes guaca's opaque depth back. The
host then keeps drawing: a pin that guaca's metal sphere hides where it stands in front of it,
and a UI bar on top. guaca_py makes its context current and restores every piece of GL state
it touched, so the host never re-sets anything after a guaca frame.

    python examples/embed_host_app.py --frames 30 --out host.png

The host draws its world with the scene camera's matrices (`Renderer.camera_matrices`) and the
standard depth range, which is what guaca's depth test against the host's depth needs
(docs/embedding.md, "Composing with the host's frame"). In a windowed application draw into a
framebuffer like this one and copy it to the window (`ctx.copy_framebuffer(ctx.screen, fbo)`);
a window's default framebuffer has no depth attachment guaca can read.
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
in vec3 in_pos;
in vec3 in_color;
uniform mat4 mvp;
out vec3 v_color;
void main() { v_color = in_color; gl_Position = mvp * vec4(in_pos, 1.0); }
"""
HOST_FS = """#version 330
in vec3 v_color;
uniform float alpha;
out vec4 color;
void main() { color = vec4(v_color, alpha); }
"""
IDENTITY = np.eye(4, dtype=np.float32)
GUACA_NODES = ("glass_cluster", "metal_sphere")  # the host draws its own ground and background
GRADIENT = ((0.10, 0.12, 0.30), (0.55, 0.65, 0.85))  # bottom and top colour of the host's background
MARKER = (1.0, 0.55, 0.05)  # the host's opaque marker triangle, through the middle of the glass
PIN = (0.95, 0.95, 0.2)  # drawn after guaca's frame, partly behind guaca's metal sphere


class HostApp:
    """A stand-in for the user's application: its context, framebuffer and drawing."""

    def __init__(self, width: int, height: int):
        self.ctx = moderngl.create_context(standalone=True, backend="egl", require=450)
        self.size = (width, height)
        # colour and depth the host draws into, and guaca composes with (over_target)
        self.fbo = self.ctx.framebuffer([self.ctx.texture(self.size, 4)], self.ctx.depth_renderbuffer(self.size))
        self.prog = self.ctx.program(vertex_shader=HOST_VS, fragment_shader=HOST_FS)
        (b0, b1, b2), (t0, t1, t2) = GRADIENT
        self.gradient = self._mesh(
            [[-1, -1, 0, b0, b1, b2], [1, -1, 0, b0, b1, b2], [1, 1, 0, t0, t1, t2], [-1, 1, 0, t0, t1, t2]]
        )
        # world space: a tall triangle standing at the glass cluster's centre, facing the camera's start
        self.marker = self._mesh([[-1.4, 0.0, 0.0, *MARKER], [1.4, 0.0, 0.0, *MARKER], [0.0, 2.6, 0.0, *MARKER]])
        # world space: a pin just behind guaca's metal sphere (at x 2.5, z -1.0, radius 0.6)
        self.pin = self._mesh([[2.1, 0.0, -1.9, *PIN], [2.9, 0.0, -1.9, *PIN], [2.5, 2.0, -1.9, *PIN]])
        # a UI bar along the bottom, drawn last with the host's blending
        ui = (0.1, 0.1, 0.2), (0.2, 0.2, 0.4)
        self.bar = self._mesh([[-1, -1, 0, *ui[0]], [1, -1, 0, *ui[0]], [1, -0.8, 0, *ui[1]], [-1, -0.8, 0, *ui[1]]])
        # the host's state, set once, as real applications do
        self.fbo.use()
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        self.ctx.depth_func = "<"

    def _mesh(self, vertices: list) -> moderngl.VertexArray:
        """A vertex array of position+colour vertices: one triangle, or a quad (as two)."""
        vbo = self.ctx.buffer(np.array(vertices, dtype=np.float32).tobytes())
        idx = [0, 1, 2] if len(vertices) == 3 else [0, 1, 2, 0, 2, 3]
        return self.ctx.vertex_array(
            self.prog, [(vbo, "3f 3f", "in_pos", "in_color")], self.ctx.buffer(np.array(idx, dtype=np.int32).tobytes())
        )

    def _draw(self, vao: moderngl.VertexArray, mvp: np.ndarray, alpha: float, depth: bool) -> None:
        self.prog["mvp"].write(mvp.T.astype("f4").tobytes())  # GLSL matrices are column-major
        self.prog["alpha"] = alpha
        if depth:
            self.ctx.enable(moderngl.DEPTH_TEST)
        vao.render(moderngl.TRIANGLES)
        self.ctx.disable(moderngl.DEPTH_TEST)

    def draw_world(self, view: np.ndarray, projection: np.ndarray) -> None:
        """The host's opaque layer: the gradient (depth left at the far plane), then the marker with depth."""
        self.fbo.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
        self._draw(self.gradient, IDENTITY, 1.0, depth=False)
        self._draw(self.marker, projection @ view, 1.0, depth=True)

    def draw_after(self, view: np.ndarray, projection: np.ndarray) -> None:
        """After guaca's frame: the pin (depth-tested against guaca's opaque surfaces too), then the UI bar."""
        self._draw(self.pin, projection @ view, 1.0, depth=True)
        self._draw(self.bar, IDENTITY, 0.8, depth=False)

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
    scene.nodes = [n for n in scene.nodes if n.name in GUACA_NODES]
    glass = next(n for n, _ in scene.walk() if n.material and n.material.uniforms.get("alpha", 1.0) < 1.0)
    for i in range(args.frames):
        # animate: swing the camera a little, pulse a transparent object's alpha
        a = 2 * math.pi * i / max(args.frames, 1)
        scene.camera.position = (1.5 * math.sin(a), 2.2, 4.6)
        glass.material.uniforms["alpha"] = 0.35 + 0.25 * math.sin(3 * a)
        view, projection = renderer.camera_matrices(scene, *host.size)  # the camera guaca will use
        host.draw_world(view, projection)
        # guaca composes with the host's colour and depth, in the host's framebuffer; nothing is read back
        renderer.render(scene, *host.size, target=host.fbo, over_target=True, read_back=False, stats=False)
        host.draw_after(view, projection)  # host drawing right after guaca, with its own state intact
    image = host.read()
    from PIL import Image

    Image.fromarray(image).save(args.out)
    print(f"{args.frames} frames, last one written to {args.out}")
    renderer.release()
    host.release()
    return image


if __name__ == "__main__":
    main()
