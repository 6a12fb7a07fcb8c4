"""The viewer's status line: text rendered with Pillow into a texture, blended over the frame."""

from __future__ import annotations

import moderngl
import numpy as np

from ..shaders import ShaderLibrary
from ..shaders.slots import Texture

LINE_HEIGHT = 14


def text_image(lines: list[str], width: int) -> np.ndarray:
    """RGBA pixels (row 0 at the top, premultiplied) of `lines` in white on translucent black."""
    from PIL import Image, ImageDraw, ImageFont

    height = LINE_HEIGHT * len(lines) + 4
    img = Image.new("RGBA", (max(width, 1), height), (0, 0, 0, 150))
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default()
    for i, line in enumerate(lines):
        draw.text((4, 2 + i * LINE_HEIGHT), line, fill=(255, 255, 255, 255), font=font)
    px = np.asarray(img).astype(np.float32)
    px[:, :, :3] *= px[:, :, 3:4] / 255.0  # premultiply
    return px.astype(np.uint8)


class Hud:
    """Draws text lines at the top of a framebuffer (host code: it runs on the window's context)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.shaders = ShaderLibrary(ctx)
        self.prog = self.shaders.program(
            {
                "vertex_shader": ("composite/fullscreen.vert.j2", {}),
                "fragment_shader": ("present/overlay.frag.j2", {}),
            },
            label="overlay",
        )
        self.vao = ctx.vertex_array(self.prog, [])
        self.tex = None

    def draw(self, fbo, lines: list[str]) -> None:
        """Blend the text over the top rows of `fbo`."""
        w, h = fbo.size
        px = text_image(lines, w)
        size = (px.shape[1], px.shape[0])
        if self.tex is None or self.tex.size != size:
            if self.tex is not None:
                self.tex.release()
            self.tex = self.ctx.texture(size, 4)
        self.tex.write(px.tobytes())
        rect = (0, max(h - size[1], 0), size[0], size[1])
        fbo.use()
        prev_viewport = fbo.viewport
        self.ctx.viewport = rect
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        self.tex.use(location=Texture.PRESENT_INPUT)
        self.prog["gua_input"] = Texture.PRESENT_INPUT
        self.prog["gua_viewport"] = tuple(float(v) for v in rect)
        self.vao.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.disable(moderngl.BLEND)
        self.ctx.viewport = prev_viewport

    def release(self) -> None:
        """Free the texture, program and VAO."""
        for obj in (self.tex, self.vao):
            if obj is not None:
                obj.release()
        self.shaders.release()
