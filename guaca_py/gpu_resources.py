"""GPU-side copies of meshes and textures, shared by content and freed when frames stop using them."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from .errors import ConfigError, LimitError
from .yaml_source import file_problem

_BUILTIN_TEXELS = {"white": (255, 255, 255, 255), "black": (0, 0, 0, 255), "normal": (128, 128, 255, 255)}
#: an entry unused for this many frames is freed (a few, so alternating scenes do not thrash)
KEEP_FRAMES = 3


def mesh_digest(mesh) -> str:
    """Content digest of a MeshData: computed (and the arrays checked) once while its arrays stay the same objects.

    Replacing an array (or the MeshData) is seen; editing an array in place is not: treat
    uploaded arrays as immutable and assign new ones instead.
    """
    return mesh.derived("digest", _content_digest)


def _content_digest(mesh) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in (mesh.positions, mesh.normals, mesh.texcoords, mesh.indices):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        if a.size:  # memoryview cannot cast an empty array; its shape said all
            h.update(memoryview(a).cast("B"))
    return h.hexdigest()


class _FrameCache:
    """Entries keyed by content; each remembers the last frame that used it."""

    def __init__(self, keep_frames: int = KEEP_FRAMES):
        self.keep_frames = keep_frames
        self.frame = 0
        self._last_used: dict = {}

    def _touch(self, key) -> None:
        self._last_used[key] = self.frame

    def end_frame(self) -> int:
        """Free what the last `keep_frames` frames did not use; returns how many entries were freed."""
        stale = [k for k, f in self._last_used.items() if f <= self.frame - self.keep_frames]
        for k in stale:
            self._free(k)
            del self._last_used[k]
        self.frame += 1
        return len(stale)

    def _free(self, key) -> None:
        raise NotImplementedError

    def __len__(self) -> int:
        return len(self._last_used)

    def release(self) -> None:
        """Free every entry."""
        for k in list(self._last_used):
            self._free(k)
        self._last_used.clear()


class MeshCache(_FrameCache):
    """Interleaved vertex + index buffers per mesh content, and one VAO per (mesh, program)."""

    def __init__(self, ctx, keep_frames: int = KEEP_FRAMES):
        super().__init__(keep_frames)
        self.ctx = ctx
        self._buffers: dict[str, tuple] = {}
        self._vaos: dict[str, dict[int, object]] = {}
        self.uploads = 0  # meshes uploaded so far (tests and stats: work proportional to change)

    def buffers(self, mesh) -> tuple:
        """(vertex buffer of interleaved position, normal, texcoord float32s; uint32 index buffer), by content."""
        key = mesh_digest(mesh)
        self._touch(key)
        if key not in self._buffers:
            inter = np.hstack([mesh.positions, mesh.normals, mesh.texcoords]).astype(np.float32)
            self._buffers[key] = (
                self.ctx.buffer(inter.tobytes()),
                self.ctx.buffer(np.ascontiguousarray(mesh.indices, dtype=np.uint32).tobytes()),
            )
            self.uploads += 1
        return self._buffers[key]

    def vao(self, mesh, prog):
        """VAO drawing `mesh` with `prog` (attributes the program does not use are skipped)."""
        vbo, ibo = self.buffers(mesh)
        vaos = self._vaos.setdefault(mesh_digest(mesh), {})
        vao = vaos.get(prog.glo)
        if vao is None:
            vao = vaos[prog.glo] = self.ctx.vertex_array(
                prog,
                [(vbo, "3f 3f 2f", "in_position", "in_normal", "in_texcoord")],
                ibo,
                index_element_size=4,
                skip_errors=True,
            )
        return vao

    def _free(self, key) -> None:
        for v in self._vaos.pop(key, {}).values():
            v.release()
        for b in self._buffers.pop(key, ()):
            b.release()


class TextureCache(_FrameCache):
    """RGBA8 textures with mipmaps by path, in-memory TextureImage (by content) or built-in name."""

    def __init__(self, ctx, keep_frames: int = KEEP_FRAMES):
        super().__init__(keep_frames)
        self.ctx = ctx
        self._tex: dict[str, object] = {}

    def get(self, name, base: Path | None = None):
        """The texture for a sampler value: a path, white/black/normal, or a TextureImage."""
        key = getattr(name, "digest", None) or str(name)
        self._touch(key)
        if key in self._tex:
            return self._tex[key]
        device = int(self.ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
        if hasattr(name, "pixels"):
            if max(name.size) > device:  # the driver would make an incomplete texture without an error
                raise LimitError(
                    f"is {name.size[0]}x{name.size[1]}; the device's largest texture is {device}x{device}",
                    key=f"TextureImage {name.name!r}",
                    hint="scale the image down",
                )
            tex = self._upload(name.pixels)
        elif name in _BUILTIN_TEXELS:
            tex = self.ctx.texture((1, 1), 4, bytes(_BUILTIN_TEXELS[name]))
        else:
            from .scene.texture import MAX_TEXTURE_SIDE, read_texture_file

            relative = not Path(name).is_absolute() and base is not None
            path = base / name if relative else Path(name)
            problem = file_problem(path)
            if problem is not None:
                # a scene's values with an image suffix are absolute by now (scene/loader.py); others are relative
                # to the material that declares the sampler, as its defaults are
                where = f"relative names are looked for beside the material ({base})" if relative else "check the path"
                raise ConfigError(f"texture {problem}", path, hint=where)
            limit = "the device's largest" if device <= MAX_TEXTURE_SIDE else "the largest read"
            tex = self._upload(read_texture_file(path, min(device, MAX_TEXTURE_SIDE), limit))
        self._tex[key] = tex
        return tex

    def _upload(self, pixels: np.ndarray):
        """An RGBA8 texture with mipmaps of `pixels` (rows from the top, height x width x 4)."""
        img = np.ascontiguousarray(pixels[::-1])  # row 0 at the top -> GL's bottom-up rows
        tex = self.ctx.texture((img.shape[1], img.shape[0]), 4, img.tobytes())
        tex.build_mipmaps()
        return tex

    def _free(self, key) -> None:
        tex = self._tex.pop(key, None)
        if tex is not None:
            tex.release()
