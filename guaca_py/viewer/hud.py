"""The viewer's status line: text rendered with Pillow into a texture, blended over the frame."""

from __future__ import annotations

import functools
from pathlib import Path

import moderngl
import numpy as np

from ..shaders import ShaderLibrary
from ..shaders.slots import Texture

FONT_SIZE = 13
LINE_HEIGHT = 16
#: colour of a line by its kind: the status, and notes that ask to be seen (a screenshot was saved)
LINE_COLORS = {"status": (255, 255, 255, 255), "note": (255, 220, 60, 255)}
MONO_FONT = "DejaVuSansMono.ttf"


@functools.cache
def hud_font():
    """A monospaced TrueType font (the system's or matplotlib's DejaVu Sans Mono), else Pillow's own at FONT_SIZE."""
    from PIL import ImageFont

    candidates = [MONO_FONT]  # Pillow looks in the system's font folders
    try:
        import matplotlib

        candidates.append(str(Path(matplotlib.get_data_path()) / "fonts" / "ttf" / MONO_FONT))
    except ImportError:
        pass
    for path in candidates:
        try:
            return ImageFont.truetype(path, FONT_SIZE)
        except OSError:
            continue
    try:
        return ImageFont.load_default(size=FONT_SIZE)  # Pillow >= 10.1: a scalable font
    except TypeError:
        return ImageFont.load_default()


def draw_line(draw, xy: tuple[int, int], text: str, font, fill) -> None:
    """Draw `text` with every space at least a digit wide (proportional fonts' thin spaces run words together)."""
    space, digit = font.getlength(" "), font.getlength("0")
    if space >= digit:
        draw.text(xy, text, fill=fill, font=font)
        return
    x, y = xy
    for word in text.split(" "):
        if word:
            draw.text((x, y), word, fill=fill, font=font)
            x += font.getlength(word)
        x += digit


def text_image(lines: list[str | tuple[str, str]], width: int) -> np.ndarray:
    """RGBA pixels (row 0 at the top, premultiplied) of `lines` on translucent black.

    A line is its text, or (text, kind) with kind a key of LINE_COLORS (default "status").
    """
    from PIL import Image, ImageDraw

    font = hud_font()
    height = LINE_HEIGHT * len(lines) + 4
    img = Image.new("RGBA", (max(width, 1), height), (0, 0, 0, 160))
    draw = ImageDraw.Draw(img)
    for i, line in enumerate(lines):
        text, kind = (line, "status") if isinstance(line, str) else line
        draw_line(draw, (6, 2 + i * LINE_HEIGHT), text, font, LINE_COLORS[kind])
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

    def draw(self, fbo, lines: list[str | tuple[str, str]]) -> None:
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
