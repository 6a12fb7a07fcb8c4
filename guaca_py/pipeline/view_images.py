"""The images of a render_views() call's views: each view but the last keeps a copy of the pipeline's output.

The passes keep one output image between frames, and the next view draws over it; a copy on the
GPU (a framebuffer-to-texture copy, no CPU wait) keeps each earlier view's image until the
renderer's next call. One texture per view index, made again only when the frame's size or format
changes, so a frame loop of the same views allocates nothing.
"""

from __future__ import annotations

import moderngl


class ViewImages:
    """A texture per view index holding that view's image, filled by a GPU copy."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self._textures: dict[int, moderngl.Texture] = {}

    def keep(self, index: int, image: moderngl.Texture) -> moderngl.Texture:
        """Copy `image` (a frame's output) into view `index`'s texture and return that texture."""
        held = self._textures.get(index)
        if held is None or (held.size, held.components, held.dtype) != (image.size, image.components, image.dtype):
            if held is not None:
                held.release()
            held = self._textures[index] = self.ctx.texture(image.size, image.components, dtype=image.dtype)
        source = self.ctx.framebuffer(color_attachments=[image])  # released at once: nothing cached to go stale
        try:
            self.ctx.copy_framebuffer(held, source)
        finally:
            source.release()
        return held

    def release(self) -> None:
        """Free the textures."""
        for tex in self._textures.values():
            tex.release()
        self._textures.clear()
