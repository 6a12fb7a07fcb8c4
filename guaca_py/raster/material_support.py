"""Which material visibility methods the compute rasterizer can host, and their compute source.

A compute kernel has no fragment quads: no dFdx/dFdy/fwidth, no implicit texture LOD, no
gl_FragCoord/gl_FrontFacing/gl_PrimitiveID, no discard. The one common case is provided:
`texture(sampler, gua_texcoords)` becomes `textureGrad` with the rasterizer's own fine quad
differences of gua_texcoords. Anything else makes the material need `raster: hardware`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..materials.description import MaterialDescription, _strip_comments

# fragment-only built-ins and functions, by what a user would search the material for
_FRAGMENT_ONLY = re.compile(
    r"\b(dFdx\w*|dFdy\w*|fwidth\w*|interpolateAt\w+|gl_FragCoord|gl_FrontFacing|gl_PrimitiveID|"
    r"gl_HelperInvocation|gl_SampleID|gl_SamplePosition|gl_SampleMaskIn|gl_Layer|discard)\b"
)
_TEXTURE_AT_TEXCOORDS = re.compile(r"\btexture\s*\(\s*(\w+)\s*,\s*gua_texcoords\s*\)")
_GRAD = r"textureGrad(\1, gua_texcoords, gua_texcoords_dx, gua_texcoords_dy)"
_IMPLICIT_LOD = re.compile(r"\b(texture|textureOffset|textureProj|textureProjOffset)\s*\(")


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
        code = _strip_comments(m.source)  # only to search: the source keeps its lines for error messages
        hit = _FRAGMENT_ONLY.search(code)
        lod = _IMPLICIT_LOD.search(_TEXTURE_AT_TEXCOORDS.sub("", code))
        if hit or lod:
            what = (
                hit.group(1) if hit else f"{lod.group(1)}() with implicit LOD on coordinates other than gua_texcoords"
            )
            return ComputeMaterial(
                {},
                False,
                f"material '{mat.name}' ({mat.path}) method '{m.name}' uses {what}, which a compute kernel "
                "cannot provide: it needs transparency.raster: hardware",
            )
        derivatives = derivatives or bool(_TEXTURE_AT_TEXCOORDS.search(code))
        sources[m.name] = _TEXTURE_AT_TEXCOORDS.sub(_GRAD, m.source)
    return ComputeMaterial(sources, derivatives, None)
