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


# ---- bounds on what the driver's compiler is given -----------------------------------------------
# A 1 KB chain of macros expanding each other ten-fold made a driver's compiler take 45 s and
# 8.4 GB; a 20,000-term expression crashed llvmpipe's (its recursion overflows the stack; 14,000
# terms still compiled). The bounds hold a material's code well below both.
MAX_CODE_BYTES = 64 * 1024  #: a material's methods together
MAX_STATEMENTS = 2_000  #: statements (';') in a material's methods together
MAX_TOKENS = 20_000  #: tokens after macro expansion in a material's methods together
MAX_NESTING = 64  #: brackets and macros within macros

_TOKEN = re.compile(
    r"[A-Za-z_]\w*|(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\w*|##|<<=|>>=|&&|\|\||\+\+|--|<<|>>|[-+*/%<>=!&|^]=|\S"
)
_DEFINE = re.compile(r"^\s*#\s*define\s+([A-Za-z_]\w*)(\([^)]*\))?(.*)$", re.S)
_OPEN, _CLOSE = {"(": ")", "[": "]", "{": "}"}, {")", "]", "}"}


class CodeBoundError(ValueError):
    """Material code the bounds refuse (size, statements, expansion or a macro that cannot be bounded)."""


def tokenize(code: str) -> list[str]:
    """GLSL tokens of comment-free `code` (numbers and operators roughly: only their count matters)."""
    return _TOKEN.findall(code)


def _logical_lines(code: str) -> list[str]:
    """Lines of `code` with backslash continuations joined, as the preprocessor reads them."""
    return re.sub(r"\\\r?\n", " ", code).split("\n")


def macro_names(code: str) -> list[str]:
    """Names comment-free `code` #defines, in order, each once."""
    names = (m.group(1) for line in _logical_lines(code) if (m := _DEFINE.match(line)))
    return list(dict.fromkeys(names))


class _Expansion:
    """Upper bounds on the tokens macros expand to, as linear forms in their arguments' sizes.

    An invocation F(a, b) expands to at most c + k0*|a| + k1*|b| tokens, (c, k) computed once per
    macro from its body (other macros in it expanded by their own forms). Counting never expands,
    so a bomb costs its own length to measure. Refused, because no bound follows from the text:
    recursion, token pasting, a body calling its parameter or naming a function-like macro without
    its arguments (the call would be assembled while rescanning).
    """

    def __init__(self, defs: dict[str, list[tuple[list[str] | None, list[str]]]], cap: int):
        self.defs, self.cap = defs, cap
        self.forms: dict[str, tuple[int, list[int]]] = {}
        self.open: list[str] = []

    def form(self, name: str) -> tuple[int, list[int]]:
        """(c, k): `name` with arguments of sizes s expands to at most c + sum(k*s) tokens."""
        if name in self.forms:
            return self.forms[name]
        if name in self.open:
            chain = " -> ".join(self.open[self.open.index(name) :] + [name])
            raise CodeBoundError(f"macro '{name}' expands recursively ({chain})")
        if len(self.open) >= MAX_NESTING:
            raise CodeBoundError(f"macros nested deeper than {MAX_NESTING} levels (via '{name}')")
        self.open.append(name)
        c, k = 0, []
        for params, body in self.defs[name]:  # several #defines (in #if branches): the largest
            index = {p: i for i, p in enumerate(params or [])}
            bc, bk = self.seq(body, index, strict=True)
            c, k = max(c, bc), [max(a, b) for a, b in zip(k + [0] * len(bk), bk + [0] * len(k))]
        self.open.pop()
        self.forms[name] = (c, k)
        return c, k

    def seq(self, toks: list[str], params: dict[str, int], strict: bool) -> tuple[int, list[int]]:
        """The form of a token sequence over `params` (a body's parameters; none in plain code)."""
        c, k, i, n, cap = 0, [0] * len(params), 0, len(toks), self.cap
        while i < n:
            t = toks[i]
            after = toks[i + 1] if i + 1 < n else None
            if t == "##" and strict:
                raise CodeBoundError("token pasting (##) in a material macro")
            if t in params:
                if after == "(":
                    raise CodeBoundError(f"a macro calls its parameter '{t}'")
                k[params[t]] = min(cap, k[params[t]] + 1)
                i += 1
                continue
            defs = self.defs.get(t)
            if defs is None:
                c, i = min(cap, c + 1), i + 1
                continue
            if defs[0][0] is not None:  # function-like
                if after != "(":
                    if strict:
                        raise CodeBoundError(f"macro '{t}' named without its arguments inside a macro")
                    c, i = min(cap, c + 1), i + 1
                    continue
                args, i = _arguments(toks, i + 1)
                mc, mk = self.form(t)
                c = min(cap, c + mc)
                for q, arg in enumerate(args[: len(mk)]):
                    ac, ak = self.seq(arg, params, strict=True)
                    c = min(cap, c + mk[q] * ac)
                    k = [min(cap, a + mk[q] * b) for a, b in zip(k, ak)]
            else:
                c, i = min(cap, c + self.form(t)[0]), i + 1
        return c, k


def _arguments(toks: list[str], open_at: int) -> tuple[list[list[str]], int]:
    """The arguments of the call whose '(' is at `open_at`, and the index after its ')'."""
    args: list[list[str]] = [[]]
    depth = 0
    for i in range(open_at, len(toks)):
        t = toks[i]
        if t == "(":
            depth += 1
            if depth == 1:
                continue
        elif t == ")":
            depth -= 1
            if depth == 0:
                return args, i + 1
        elif t == "," and depth == 1:
            args.append([])
            continue
        args[-1].append(t)
    return args, len(toks)


def code_size(code: str) -> tuple[int, int]:
    """(statements, tokens after macro expansion) of comment-free `code`; CodeBoundError where unbounded.

    The token count is an upper bound (every #if branch counted), capped just past MAX_TOKENS.
    """
    defs: dict[str, list[tuple[list[str] | None, list[str]]]] = {}
    plain: list[str] = []
    for line in _logical_lines(code):
        m = _DEFINE.match(line)
        if m:
            params = None if m.group(2) is None else [p.strip() for p in m.group(2)[1:-1].split(",") if p.strip()]
            defs.setdefault(m.group(1), []).append((params, tokenize(m.group(3))))
        elif not line.lstrip().startswith("#"):
            plain.extend(tokenize(line))
    for name, versions in defs.items():
        if len({v[0] is None for v in versions}) > 1:
            raise CodeBoundError(f"macro '{name}' is defined both with and without parameters")
    depth = 0
    for t in plain:  # the counting below recurses per bracket level
        if t in _OPEN:
            depth += 1
            if depth > MAX_NESTING:
                raise CodeBoundError(f"brackets nested deeper than {MAX_NESTING} levels")
        elif t in _CLOSE:
            depth = max(0, depth - 1)
    tokens, _ = _Expansion(defs, MAX_TOKENS + 1).seq(plain, {}, strict=False)
    return plain.count(";"), tokens
