"""gua_round_half (common/pack.glsl.j2) against the half-precision pack and unpack it stands for."""

from __future__ import annotations

import numpy as np

from guaca_py.shaders import ShaderLibrary

SOURCE = """#version 450 core
layout(local_size_x = 64) in;
{% include "common/frame_uniforms.glsl.j2" %}
{% include "common/pack.glsl.j2" %}
layout(std430, binding = 0) buffer In { vec4 gua_in[]; };
layout(std430, binding = 1) buffer Out { uvec4 gua_out[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec4 v = gua_in[i];
    vec4 stored = vec4(unpackHalf2x16(packHalf2x16(v.xy)), unpackHalf2x16(packHalf2x16(v.zw)));
    gua_out[i] = floatBitsToUint(stored) ^ floatBitsToUint(gua_round_half(v));
}
"""


def test_round_half_matches_pack_and_unpack(gl_context):
    # payload-stored layers are shaded from packHalf2x16'd colours, layers shaded while drawn from
    # gua_round_half'd ones: the two must agree to the bit, or the same surface shades differently
    rng = np.random.default_rng(5)
    halves = rng.uniform(-1.0, 1.0, 1 << 16).astype(np.float16).astype(np.float32).view(np.uint32)
    values = np.concatenate(
        [
            rng.uniform(0.0, 1.0, 1 << 16).astype(np.float32),
            (10.0 ** rng.uniform(-9.0, 5.5, 1 << 16) * rng.choice([-1.0, 1.0], 1 << 16)).astype(np.float32),
            (halves + np.uint32(0x1000)).view(np.float32),  # exactly halfway: ties to even
            (halves + np.uint32(0x0FFF)).view(np.float32),
            (halves + np.uint32(0x1001)).view(np.float32),
            np.float32([0.0, -0.0, 6.1035156e-05, 6.1e-05, 5.96e-08, 2.98e-08, 65504.0, 65519.0, 65520.0, 1e9]),
        ]
    )
    values = np.concatenate([values, np.zeros((-len(values)) % 256, np.float32)])
    lib = ShaderLibrary(gl_context)
    shader = gl_context.compute_shader(lib.env.from_string(SOURCE).render())
    src, out = gl_context.buffer(values.tobytes()), gl_context.buffer(reserve=values.nbytes)
    src.bind_to_storage_buffer(0)
    out.bind_to_storage_buffer(1)
    shader.run(len(values) // 4 // 64)
    differing = np.frombuffer(out.read(), np.uint32) != 0
    assert not differing.any(), values[differing][:8]
    for obj in (shader, src, out):
        obj.release()
