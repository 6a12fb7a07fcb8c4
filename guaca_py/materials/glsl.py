"""What a material method's GLSL does, read from its text with regular expressions.

Two readers ask: the material description (does a method write `gua_alpha`, and how: decides
whether an instance is transparent) and the compute rasterizer's material support (does a
method use fragment-only features, and where does it sample at `gua_texcoords`). Both search
the method's code with comments removed (`strip_comments`, done once per method in
`description.Method.code`); only `sample_grad_at_texcoords` rewrites a source, and it keeps
the comments so error lines still match the file.
"""

from __future__ import annotations

import re

_COMMENT_BLOCK = re.compile(r"/\*.*?\*/", re.S)
_COMMENT_LINE = re.compile(r"//[^\n]*")
_IDENTIFIER = re.compile(r"^[A-Za-z_]\w*$")

_ALPHA_WRITE = re.compile(r"\bgua_alpha\s*([-+*/]?=)(?!=)\s*([^;]*);")
_LITERAL_ONE = re.compile(r"^\(?\s*1(\.0*)?f?\s*\)?$")
# gua_alpha handed to a function (an `inout`/`out` parameter may write it) or touched by ++/--
_ALPHA_UNSURE = re.compile(r"[(,]\s*gua_alpha\s*[,)]|\+\+\s*gua_alpha|gua_alpha\s*(\+\+|--)|--\s*gua_alpha")
# the preprocessor can write gua_alpha under another name
_PREPROCESSOR = re.compile(r"^\s*#\s*(define|if|ifdef|ifndef|include)\b", re.M)

# fragment-only built-ins and functions, by what a user would search the material for
_FRAGMENT_ONLY = re.compile(
    r"\b(dFdx\w*|dFdy\w*|fwidth\w*|interpolateAt\w+|gl_FragCoord|gl_FrontFacing|gl_PrimitiveID|"
    r"gl_HelperInvocation|gl_SampleID|gl_SamplePosition|gl_SampleMaskIn|gl_Layer|discard)\b"
)
_TEXTURE_AT_TEXCOORDS = re.compile(r"\btexture\s*\(\s*(\w+)\s*,\s*gua_texcoords\s*\)")
_GRAD = r"textureGrad(\1, gua_texcoords, gua_texcoords_dx, gua_texcoords_dy)"
_IMPLICIT_LOD = re.compile(r"\b(texture|textureOffset|textureProj|textureProjOffset)\s*\(")


def strip_comments(source: str) -> str:
    """`source` without /* */ and // comments (for searching; line numbers are not kept)."""
    return _COMMENT_LINE.sub("", _COMMENT_BLOCK.sub("", source))


def is_identifier(name: str) -> bool:
    """Whether `name` is a GLSL identifier."""
    return bool(_IDENTIFIER.match(name))


def defines_void_function(source: str, name: str) -> bool:
    """Whether `source` defines `void name()` (a method's required signature)."""
    return bool(re.search(rf"\bvoid\s+{re.escape(name)}\s*\(\s*\)", source))


def alpha_writes(code: str) -> list[tuple[str, str]]:
    """(operator, right-hand side) of every assignment to gua_alpha in comment-free `code`."""
    return [(op, rhs.strip()) for op, rhs in _ALPHA_WRITE.findall(code)]


def alpha_unreadable(code: str) -> bool:
    """Whether comment-free `code` may change gua_alpha other than by an assignment `alpha_writes` sees.

    gua_alpha handed to a function, incremented or decremented, or any preprocessor
    conditional, define or include (which can spell gua_alpha another way).
    """
    return bool(_ALPHA_UNSURE.search(code) or _PREPROCESSOR.search(code))


def is_literal_one(expr: str) -> bool:
    """Whether a GLSL expression is the literal 1 (1, 1.0, 1.f, (1.0) ...)."""
    return bool(_LITERAL_ONE.match(expr))


def fragment_only_feature(code: str) -> str | None:
    """The first fragment-only built-in or function comment-free `code` uses (dFdx, gl_FragCoord, discard...)."""
    hit = _FRAGMENT_ONLY.search(code)
    return hit.group(1) if hit else None


def implicit_lod_sampling(code: str) -> str | None:
    """A texture function comment-free `code` calls with implicit LOD, other than texture(s, gua_texcoords)."""
    hit = _IMPLICIT_LOD.search(_TEXTURE_AT_TEXCOORDS.sub("", code))
    return hit.group(1) if hit else None


def samples_at_texcoords(code: str) -> bool:
    """Whether comment-free `code` calls texture(sampler, gua_texcoords)."""
    return bool(_TEXTURE_AT_TEXCOORDS.search(code))


def sample_grad_at_texcoords(source: str) -> str:
    """`source` with texture(s, gua_texcoords) as textureGrad on gua_texcoords_dx/dy (comments kept)."""
    return _TEXTURE_AT_TEXCOORDS.sub(_GRAD, source)
