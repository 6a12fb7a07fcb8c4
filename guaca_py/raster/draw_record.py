"""The compute rasterizer's per-draw record (raster/draw_record.glsl.j2): its std430 layout and its bytes.

A call's draws get one record each, written in one buffer update and bound draw by draw: the
kernels of a draw read their matrices, counts, depth range, draw index and the material's values
from it instead of from uniforms written per kernel and draw.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from ..materials.description import MaterialDescription
from ..shaders import mat_bytes

# the head every kernel declares: model and normal matrices (64 B each), then this tail
_TAIL = struct.Struct("<2f2Ii")  # gua_depth_range, gua_vertex_count, gua_tri_count, gua_draw_index
HEAD_BYTES = 128 + _TAIL.size
# Records start at multiples of this: the largest GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT the GL spec
# allows, so no query is needed (a 64-draw call takes 16 KiB).
RECORD_ALIGN = 256
# std430 base alignment and size in bytes of each value type a record holds (sampler2D stays a uniform)
_STD430 = {"float": (4, 4), "int": (4, 4), "vec2": (8, 8), "vec3": (16, 12), "vec4": (16, 16), "mat4": (16, 64)}


@dataclass(frozen=True)
class RecordLayout:
    """Where a material's values lie in its draws' records, and their declarations in the block."""

    members: tuple[tuple[str, str, int], ...]  # (name, GLSL type, byte offset in the record)
    size: int  # bytes of the record, head included
    glsl: str  # the members' declarations, in order

    @property
    def stride(self) -> int:
        """Bytes from one record to the next when every record of a call has this layout."""
        return -(-self.size // RECORD_ALIGN) * RECORD_ALIGN


def record_layout(material: MaterialDescription) -> RecordLayout:
    """The std430 layout of `material`'s values after the head, in declaration order."""
    members, offset = [], HEAD_BYTES
    for name, spec in material.uniforms.items():
        if spec.type not in _STD430:
            continue  # a sampler: a uniform beside the block
        align, size = _STD430[spec.type]
        offset = -(-offset // align) * align
        members.append((name, spec.type, offset))
        offset += size
    glsl = "\n".join(f"    {t} {n};" for n, t, _ in members)
    return RecordLayout(tuple(members), offset, glsl)


def material_bytes(layout: RecordLayout, values: dict) -> bytes:
    """The record's bytes past the head for a draw's resolved material `values`."""
    out = bytearray(layout.size - HEAD_BYTES)
    for name, kind, offset in layout.members:
        value, at = values[name], offset - HEAD_BYTES
        if kind == "mat4":
            out[at : at + 64] = mat_bytes(value)
        elif kind == "int":
            struct.pack_into("<i", out, at, int(value))
        else:
            flat = [value] if kind == "float" else list(value)
            struct.pack_into(f"<{len(flat)}f", out, at, *map(float, flat))
    return bytes(out)


def head_bytes(
    model: bytes, normal: bytes, depth_range: tuple[float, float], vertices: int, triangles: int, index: int
) -> bytes:
    """The head of a draw's record: matrices as GL bytes (column-major float32), then the per-draw numbers."""
    return model + normal + _TAIL.pack(depth_range[0], depth_range[1], vertices, triangles, index)
