"""What every pass, method and rasterizer may use of the GPU: built once by the Renderer, handed down."""

from __future__ import annotations

from dataclasses import dataclass, field

import moderngl

from ..context import Capabilities
from ..gpu_resources import MeshCache, TextureCache
from ..shaders import ShaderLibrary


@dataclass(frozen=True)
class Antialiasing:
    """The frame's samples per pixel and how they are placed (`antialiasing:` of the pipeline config)."""

    samples: int = 1  # samples the G-buffer and coverage masks hold (a device may round the asked count up)
    asked: int = 1  # antialiasing.samples as configured
    positions: tuple[tuple[float, float], ...] = ()  # where the device puts them (0..1, y up); () with one
    supersample: int = 1  # antialiasing.supersample: rendered pixels per output pixel along each axis


@dataclass
class Device:
    """The GL context, its capabilities, the one program builder and the GPU caches of meshes and textures."""

    ctx: moderngl.Context
    caps: Capabilities
    programs: ShaderLibrary
    meshes: MeshCache
    textures: TextureCache
    antialiasing: Antialiasing = field(default_factory=Antialiasing)
    _fullscreen_vaos: dict[int, moderngl.VertexArray] = field(default_factory=dict)

    @property
    def samples(self) -> int:
        """Samples per pixel of the frame (1 without antialiasing)."""
        return self.antialiasing.samples

    def fullscreen(self, prog) -> None:
        """Draw one screen-covering triangle with `prog` (one attribute-less vertex array per program)."""
        vao = self._fullscreen_vaos.get(prog.glo)
        if vao is None:
            vao = self._fullscreen_vaos[prog.glo] = self.ctx.vertex_array(prog, [])
        vao.render(moderngl.TRIANGLES, vertices=3)

    def release(self) -> None:
        """Free the caches, the full-screen vertex arrays and every compiled program."""
        self.meshes.release()
        self.textures.release()
        for vao in self._fullscreen_vaos.values():
            vao.release()
        self._fullscreen_vaos.clear()
        self.programs.release()
