"""A material composed into a shader skeleton, and its uniform values set: one place for every skeleton.

The hardware geometry programs and the compute rasterizer's kernels both take a material's
displacement and visibility methods, its uniform declarations and its textures through here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from ..shaders import ShaderLibrary, SourceMap, mat_bytes, set_uniforms
from ..shaders.slots import Texture
from .draw_record import record_layout


def material_vars(
    material,
    smap: SourceMap,
    stage: str | None,
    sources: Mapping[str, str] | None = None,
    record: bool = False,
) -> dict:
    """Template variables of `material` for a skeleton stage that runs its `stage` methods (None: none).

    The methods' code is bracketed for `smap` so compiler messages cite the material's files;
    `sources` replaces a method's code by name (the compute rasterizer's rewritten visibility code).
    `record`: the values go into the draw's record block (raster/draw_record.glsl.j2), only the
    samplers stay uniforms.
    """
    specs = material.uniforms.values()
    if record:
        out = {
            "material_uniforms": "\n".join(u.glsl_decl() for u in specs if u.type == "sampler2D"),
            "material_record_members": record_layout(material).glsl,
        }
    else:
        out = {"material_uniforms": "\n".join(u.glsl_decl() for u in specs)}
    if stage is None:
        return out
    label = f"material '{material.name}'"
    methods = material.methods.get(stage, [])
    out[f"{stage}_methods"] = "".join(
        smap.insert((sources or {}).get(m.name, m.source), m.file, m.first_line, f"{label} method '{m.name}'")
        for m in methods
    )
    out[f"{stage}_calls"] = [m.name for m in methods]
    return out


def material_program(
    programs: ShaderLibrary,
    material,
    skeleton: Mapping[str, tuple[str, str | None, dict]],
    what: str = "",
    sources: Mapping[str, str] | None = None,
    record: bool = False,
):
    """Compile (once) `material` composed into `skeleton`: {GL stage: (template, material stage, variables)};
    `record`: its values read from the draw's record (material_vars)."""
    smap = SourceMap()
    stages = {
        gl_stage: (template, {**variables, **material_vars(material, smap, mstage, sources, record)})
        for gl_stage, (template, mstage, variables) in skeleton.items()
    }
    return programs.program(stages, smap, label=f"material '{material.name}' ({material.path}){what}")


def apply_material(textures, draw, programs: Iterable, samplers_only: bool = False) -> None:
    """Bind the draw's material textures to their units and set its uniform values on `programs`.

    Every sampler gets its own unit whether or not a given program reads it, so the values hold
    for every program of the material (the compute rasterizer sets its samplers on four kernels);
    the values are converted once for all of them. `samplers_only`: the other values are in the
    draw's record (raster/draw_record.py).
    """
    unit = Texture.MATERIALS
    values = []
    for name, spec in draw.material.uniforms.items():
        value = draw.values[name]
        if spec.type == "sampler2D":
            textures.get(value, draw.material.path.parent).use(location=unit)
            value, unit = unit, unit + 1
        elif samplers_only:
            continue
        elif spec.type == "mat4":
            value = mat_bytes(value)
        elif isinstance(value, list):
            value = tuple(value)
        values.append((name, value))
    for prog in programs:
        set_uniforms(prog, values)
