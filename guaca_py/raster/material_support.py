"""Which material visibility methods the compute rasterizer can host, and their compute source.

A compute kernel has no fragment quads: no dFdx/dFdy/fwidth, no implicit texture LOD, no
gl_FragCoord/gl_FrontFacing/gl_PrimitiveID, no discard. The one common case is provided:
`texture(sampler, gua_texcoords)` becomes `textureGrad` with the rasterizer's own fine quad
differences of gua_texcoords. Anything else makes the material need `raster: hardware`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..materials import glsl
from ..materials.description import MaterialDescription


@dataclass(frozen=True)
class ComputeMaterial:
    """Visibility sources rewritten for the compute host, or why the material needs hardware."""

    sources: dict[str, str]  # method name -> source
    tc_derivatives: bool  # the host must provide gua_texcoords_dx/dy
    problem: str | None  # None when the compute rasterizer can run the material


def compute_material(mat: MaterialDescription) -> ComputeMaterial:
    """The material's visibility methods as the compute host runs them (see module docstring)."""
    sources: dict[str, str] = {}
    derivatives = False
    for m in mat.methods.get("visibility", []):
        feature, lod = glsl.fragment_only_feature(m.code), glsl.implicit_lod_sampling(m.code)
        if feature or lod:
            what = feature or f"{lod}() with implicit LOD on coordinates other than gua_texcoords"
            return ComputeMaterial(
                {},
                False,
                f"material '{mat.name}' ({mat.path}) method '{m.name}' uses {what}, which a compute kernel "
                "cannot provide: it needs transparency.raster: hardware",
            )
        derivatives = derivatives or glsl.samples_at_texcoords(m.code)
        sources[m.name] = glsl.sample_grad_at_texcoords(m.source)  # the source keeps its lines for errors
    return ComputeMaterial(sources, derivatives, None)
