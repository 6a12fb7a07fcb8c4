"""The draw record: the packer's bytes read back member by member through the GL compiler's own std430 layout."""

from pathlib import Path

import numpy as np

from guaca_py.materials.description import MaterialDescription, UniformSpec
from guaca_py.raster.draw_record import HEAD_BYTES, RECORD_ALIGN, head_bytes, material_bytes, record_layout
from guaca_py.shaders import ShaderLibrary, mat_bytes
from guaca_py.shaders.slots import Buffer

# every value type a record holds, in an order that leaves holes std430 must skip (vec3 after a float)
SPECS = {
    "a_float": ("float", 0.25),
    "a_vec3": ("vec3", [1.0, 2.0, 3.0]),
    "an_int": ("int", -7),
    "a_vec2": ("vec2", [4.5, -5.5]),
    "a_mat4": ("mat4", [float(i) for i in range(16)]),
    "a_tex": ("sampler2D", "x.png"),  # not in the record
    "a_vec4": ("vec4", [6.0, 7.0, 8.0, 9.0]),
}

# each member copied to 4 words of the output, as bits: a float read back through a float store could be flushed
# (a denormal) or its NaN bits made canonical on a GPU
KERNEL = """#version 450 core
layout(local_size_x = 1) in;
{% include "raster/draw_record.glsl.j2" %}
layout(std430, binding = 0) writeonly buffer Out { uint o[]; };
void put(int k, uvec4 v) { o[4 * k] = v.x; o[4 * k + 1] = v.y; o[4 * k + 2] = v.z; o[4 * k + 3] = v.w; }
void putf(int k, vec4 v) { put(k, floatBitsToUint(v)); }
void main() {
    for (int c = 0; c < 4; ++c) putf(c, gua_model_matrix[c]);
    for (int c = 0; c < 4; ++c) putf(4 + c, gua_normal_matrix[c]);
    put(8, uvec4(floatBitsToUint(gua_depth_range), gua_vertex_count, gua_tri_count));
    put(9, uvec4(uint(gua_draw_index), floatBitsToUint(a_float), uint(an_int), 0u));
    putf(10, vec4(a_vec3, 0.0));
    putf(11, vec4(a_vec2, 0.0, 0.0));
    putf(12, a_vec4);
    for (int c = 0; c < 4; ++c) putf(13 + c, a_mat4[c]);
}
"""


def material() -> MaterialDescription:
    uniforms = {n: UniformSpec(n, t, v) for n, (t, v) in SPECS.items()}
    return MaterialDescription("record_test", uniforms, {}, Path("record_test.json"))


def test_offsets_follow_std430():
    layout = record_layout(material())
    offsets = {name: offset for name, _, offset in layout.members}
    # a float right after the head, a vec3 at the next 16, an int in the vec3's fourth word
    assert offsets == {"a_float": 148, "a_vec3": 160, "an_int": 172, "a_vec2": 176, "a_mat4": 192, "a_vec4": 256}
    assert layout.size == 272 and layout.stride == 2 * RECORD_ALIGN
    assert "a_tex" not in layout.glsl and "vec3 a_vec3;" in layout.glsl


def test_the_kernel_reads_what_the_packer_wrote(gl_context):
    mat = material()
    layout = record_layout(mat)
    values = {n: v for n, (_, v) in SPECS.items()}
    model = np.arange(16, dtype=np.float64).reshape(4, 4) + 1.0
    normal = np.linalg.inv(model + np.eye(4) * 5).T
    record = head_bytes(mat_bytes(model), mat_bytes(normal), (0.5, 9.0), 1234, 567, 89) + material_bytes(layout, values)
    assert len(record) == layout.size and record_layout(mat).size > HEAD_BYTES
    lib = ShaderLibrary(gl_context)
    src = lib.env.from_string(KERNEL).render(material_record_members=layout.glsl)
    shader = gl_context.compute_shader(src)
    out = gl_context.buffer(reserve=17 * 16)
    # the record at an offset, as the rasterizer binds a call's second draw
    records = gl_context.buffer(bytes(layout.stride) + record + bytes(layout.stride - len(record)))
    records.bind_to_storage_buffer(Buffer.RASTER_DRAW, offset=layout.stride, size=layout.stride)
    out.bind_to_storage_buffer(0)
    shader.run(1)
    bits = np.frombuffer(out.read(), np.int32).reshape(17, 4)
    got = bits.view(np.float32)
    np.testing.assert_array_equal(got[0:4], model.T.astype(np.float32))  # columns
    np.testing.assert_array_equal(got[4:8], normal.T.astype(np.float32))
    assert tuple(got[8, :2]) == (0.5, 9.0) and tuple(bits[8, 2:]) == (1234, 567)
    assert bits[9, 0] == 89 and got[9, 1] == 0.25 and bits[9, 2] == -7
    np.testing.assert_array_equal(got[10, :3], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(got[11, :2], [4.5, -5.5])
    np.testing.assert_array_equal(got[12], [6.0, 7.0, 8.0, 9.0])
    np.testing.assert_array_equal(got[13:17], np.arange(16, dtype=np.float32).reshape(4, 4).T)
    for obj in (shader, out, records):
        obj.release()
