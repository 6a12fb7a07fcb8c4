"""GPU-side copies of meshes and textures, uploaded once and shared by all programs."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import ConfigError

_BUILTIN_TEXELS = {"white": (255, 255, 255, 255), "black": (0, 0, 0, 255), "normal": (128, 128, 255, 255)}


class MeshCache:
    """Interleaved vertex + index buffers per MeshData, and one VAO per (mesh, program)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._buffers: dict[int, tuple] = {}
        self._vaos: dict[tuple[int, int], object] = {}

    def buffers(self, mesh) -> tuple:
        """(vertex buffer of interleaved position, normal, texcoord float32s; uint32 index buffer)."""
        if id(mesh) not in self._buffers:
            inter = np.hstack([mesh.positions, mesh.normals, mesh.texcoords]).astype(np.float32)
            self._buffers[id(mesh)] = (
                mesh,
                self.ctx.buffer(inter.tobytes()),
                self.ctx.buffer(np.ascontiguousarray(mesh.indices, dtype=np.uint32).tobytes()),
            )
        return self._buffers[id(mesh)][1:]

    def vao(self, mesh, prog):
        """VAO drawing `mesh` with `prog` (attributes the program does not use are skipped)."""
        key = (id(mesh), prog.glo)
        if key not in self._vaos:
            vbo, ibo = self.buffers(mesh)
            self._vaos[key] = self.ctx.vertex_array(
                prog,
                [(vbo, "3f 3f 2f", "in_position", "in_normal", "in_texcoord")],
                ibo,
                index_element_size=4,
                skip_errors=True,
            )
        return self._vaos[key]

    def release(self) -> None:
        """Free all buffers and VAOs."""
        for v in self._vaos.values():
            v.release()
        for _, vbo, ibo in self._buffers.values():
            vbo.release()
            ibo.release()
        self._vaos.clear()
        self._buffers.clear()


class TextureCache:
    """RGBA8 textures with mipmaps loaded by path (or the built-in names white/black/normal)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._tex: dict[str, object] = {}

    def get(self, name: str, base: Path | None = None):
        """The texture for a sampler value."""
        if name in self._tex:
            return self._tex[name]
        if name in _BUILTIN_TEXELS:
            tex = self.ctx.texture((1, 1), 4, bytes(_BUILTIN_TEXELS[name]))
        else:
            from PIL import Image

            path = Path(name) if Path(name).is_absolute() or base is None else base / name
            if not path.is_file():
                raise ConfigError(f"texture not found: {path}", hint="paths in scenes resolve against the scene file")
            try:
                img = Image.open(path).convert("RGBA").transpose(Image.Transpose.FLIP_TOP_BOTTOM)
            except (OSError, ValueError, Image.DecompressionBombError) as exc:
                raise ConfigError(
                    f"texture {path} is not a readable image ({exc})", path, hint="use a PNG or JPEG file"
                ) from None
            most = int(self.ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
            if max(img.size) > most:
                raise ConfigError(
                    f"texture {path} is {img.size[0]}x{img.size[1]}; the device's largest is {most}x{most}",
                    path,
                    hint="scale the image down",
                )
            tex = self.ctx.texture(img.size, 4, img.tobytes())
            tex.build_mipmaps()
        self._tex[name] = tex
        return tex

    def release(self) -> None:
        """Free all textures."""
        for t in self._tex.values():
            t.release()
        self._tex.clear()
