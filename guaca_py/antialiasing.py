"""`antialiasing: {samples: N, supersample: K}`: the settings, the device's limits and which methods take coverage.

With N > 1 samples the G-buffer is multisampled, each A-buffer node carries its fragment's
coverage mask (gl_SampleMaskIn) and the composite blends every node into the samples it covers,
then averages them (docs/antialiasing.md). Methods that cannot carry coverage refuse N > 1.
With K > 1 the frame renders at K times the width and height and the composite averages each
K x K block of rendered pixels into one output pixel (every method takes it). `antialiasing: auto`
chooses one of the two per frame (guaca_py/antialiasing_auto.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .errors import ConfigError, UnsupportedMethodError
from .pipeline.settings import Setting, resolve_settings
from .shaders.slots import Buffer, Texture

SAMPLE_COUNTS = (1, 2, 4, 8)
SUPERSAMPLE_FACTORS = (1, 2, 3, 4)
SETTINGS = {
    "samples": Setting(
        (int,),
        1,
        "samples per pixel: 1 (no MSAA) or 2/4/8 (multisampled G-buffer, coverage-aware A-buffer)",
        choices=SAMPLE_COUNTS,
    ),
    "supersample": Setting(
        (int,),
        1,
        "1 (off) or 2/3/4: render at that many times the width and height, then average each block "
        "of rendered pixels into one output pixel (box filter, linear colour)",
        choices=SUPERSAMPLE_FACTORS,
    ),
    "auto": Setting(
        (bool,),
        False,
        "choose per frame between 4 coverage samples and supersample 2 from the previous frame's "
        "measurements (`antialiasing: auto` is short for {auto: true}; docs/antialiasing.md)",
    ),
}
AUTO = "auto"  # `antialiasing: auto`
CHOSEN_BY_AUTO = ("samples", "supersample")  # the settings auto decides per frame
# Every node packs its mask into the free upper 16 bits of payload word 6 (common/payload_pack):
# the node keeps its size, so memory per fragment is unchanged by antialiasing.
SUGGESTION = "presort_lf_et (or another one-pass A-buffer method: presort_lf, presort_lf_merge2_et, " + (
    "presort_cs, presort_cs_et, post_sort, post_merge16)"
)


def _spelled_out(given: object) -> object:
    """`given` with `auto` written as the mapping it is short for and None as no settings; anything else as given."""
    if given is None:
        return {}
    return {"auto": True} if given == AUTO else given


def parse(given, error) -> dict:
    """Validated `antialiasing:` settings; `error(key, reason, hint)` builds the exception."""
    given = _spelled_out(given)
    if not isinstance(given, dict):
        raise error(None, "must be a mapping like {samples: 4}, or auto", None)
    out = resolve_settings(SETTINGS, given, error)
    fixed = [k for k in CHOSEN_BY_AUTO if out[k] != SETTINGS[k].default]
    if out["auto"] and fixed:
        raise error(
            "auto", f"chooses {' and '.join(CHOSEN_BY_AUTO)} itself, per frame; {fixed[0]} is given too", "give one"
        )
    return out


def device_samples(ctx) -> int:
    """Most samples this device renders into both colour and depth textures."""
    info = ctx.info
    keys = ("GL_MAX_SAMPLES", "GL_MAX_COLOR_TEXTURE_SAMPLES", "GL_MAX_DEPTH_TEXTURE_SAMPLES")
    return min(int(info.get(k) or 1) for k in keys)


def check_device(ctx, samples: int, renderer_name: str, shaders) -> int:
    """The samples per pixel the device renders for `samples` asked (some round up); refuses too many."""
    most = device_samples(ctx)
    if samples > most:
        raise UnsupportedMethodError(
            f"antialiasing.samples {samples} cannot run on {renderer_name}: it renders at most {most} samples "
            f"per pixel (GL_MAX_COLOR/DEPTH_TEXTURE_SAMPLES); use samples: {max(s for s in SAMPLE_COUNTS if s <= most)}"
        )
    return samples if samples <= 1 else len(sample_positions(ctx, samples, shaders))


_positions: dict[tuple[int, int], tuple[tuple[float, float], ...]] = {}
_MAX_SAMPLES = 64  # room for every sample a texture may really have


def sample_positions(ctx, samples: int, shaders) -> tuple[tuple[float, float], ...]:
    """Where in the pixel (0..1, y up) the device puts each sample of a texture asked for `samples`.

    As many as it really allocates: a device may round a count up (Mesa llvmpipe makes 4 of 2), and
    the G-buffer, the coverage masks and the resolve then hold the larger count. The compute
    rasterizer tests coverage at these points, so its masks name the same samples as the hardware's.
    Binds a framebuffer, Texture.SAMPLE_PROBE and Buffer.SAMPLE_POSITIONS: call it before a frame, not inside one.
    """
    key = (id(ctx), samples)
    if key not in _positions:
        tex = ctx.texture((1, 1), 4, dtype="f4", samples=samples)
        fbo = ctx.framebuffer(color_attachments=[tex])
        draw = shaders.program(
            {
                "vertex_shader": ("antialiasing/sample_position.vert.j2", {}),
                "fragment_shader": ("antialiasing/sample_position.frag.j2", {}),
            },
            label="antialiasing/sample_position",
        )
        vao = ctx.vertex_array(draw, [])
        fbo.use()
        fbo.clear(-1.0, -1.0, 0.0, 0.0)
        vao.render(vertices=3)
        read = shaders.compute("antialiasing/read_positions.comp.j2")
        buf = ctx.buffer(reserve=8 + 8 * _MAX_SAMPLES)  # the count, then vec2s from offset 8 (std430)
        tex.use(location=Texture.SAMPLE_PROBE)
        read["gua_probe"] = Texture.SAMPLE_PROBE
        buf.bind_to_storage_buffer(Buffer.SAMPLE_POSITIONS)
        read.run(1, 1, 1)
        ctx.memory_barrier()
        data = buf.read()
        count = max(samples, int(np.frombuffer(data[:4], dtype=np.int32)[0]))
        xy = np.frombuffer(data[8:], dtype=np.float32)[: 2 * count].reshape(count, 2)
        _positions[key] = tuple((float(x), float(y)) for x, y in xy)
        for obj in (buf, vao, fbo, tex):
            obj.release()
    return _positions[key]


def method_refusal(method_cls, samples: int) -> str | None:
    """Why method `method_cls` cannot render with `samples` per pixel, or None when it can."""
    if samples <= 1 or method_cls.supports_antialiasing:
        return None
    return (
        f"method '{method_cls.id}' does not support antialiasing.samples {samples}: "
        f"{method_cls.antialiasing_refusal}; use {SUGGESTION}, or antialiasing.samples 1"
    )


def check_method(method_cls, samples: int) -> None:
    """Raise UnsupportedMethodError when the method cannot take coverage masks."""
    reason = method_refusal(method_cls, samples)
    if reason:
        raise UnsupportedMethodError(reason)


def with_settings(config, given: dict | str, source: str):
    """A copy of PipelineConfig `config` with `antialiasing:` settings `given` (from `source`) over its own.

    What is given wins: `auto` over the config's samples and supersample, either of those over its `auto`.
    """

    def error(key, reason, hint):
        return ConfigError(reason, source, None, "antialiasing" + (f".{key}" if key else ""), hint)

    given = _spelled_out(given)
    parse(given, error)  # a bad value is reported under `source`, not under the pipeline file
    base = dict(config.antialiasing)
    if given.get("auto"):
        base.update({k: SETTINGS[k].default for k in CHOSEN_BY_AUTO})
    elif any(k in given for k in CHOSEN_BY_AUTO):
        base["auto"] = False
    return dataclasses.replace(config, antialiasing=parse({**base, **given}, error))


def with_samples(config, samples: int, source: str = "the samples argument"):
    """A copy of PipelineConfig `config` rendering `samples` per pixel (`source`: where the number came from)."""
    return with_settings(config, {"samples": samples}, source)


def with_supersample(config, factor: int, source: str = "the supersample argument"):
    """A copy of PipelineConfig `config` rendering at `factor` times its width and height, box filtered down."""
    return with_settings(config, {"supersample": factor}, source)
