"""Load and validate one material description: typed uniforms and GLSL stage methods."""

from __future__ import annotations

import json
import math
import numbers
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..numeric import Range, gpu_number_problem, number_hint
from ..shaders.slots import Texture
from ..yaml_source import MAX_CONFIG_BYTES, MAX_NESTING, read_text, resolved
from . import glsl

#: sampler2D uniforms a material may declare: each takes its own texture unit of Texture.MATERIALS
#: (raster/material_program.py: apply_material)
MAX_SAMPLERS = Texture.TABLE["MATERIALS"].count
#: uniform type -> number of floats (sampler2D holds a texture path instead)
UNIFORM_SIZES = {"float": 1, "int": 1, "vec2": 2, "vec3": 3, "vec4": 4, "mat4": 16, "sampler2D": 0}
STAGES = ("displacement", "visibility")
_TOP_KEYS = {"name", "description", "uniforms", "displacement", "visibility", "transparent"}
_SPEC_KEYS = {"type", "default", "range"}
_METHOD_KEYS = {"name", "source", "file"}


@dataclass
class UniformSpec:
    """A typed material uniform with its default value."""

    name: str
    type: str
    default: object
    range: tuple[float | None, float | None] | None = None  # every component's bounds (None: open)

    def glsl_decl(self) -> str:
        """GLSL declaration of this uniform."""
        return f"uniform {self.type} {self.name};"


@dataclass
class Method:
    """One GLSL method (a `void NAME()` function on the gua_* interface) of a stage.

    `source` ends with an `#undef` of every macro the method defines, so its macros cannot reach
    the shader code after it: the bounds on a material's code (glsl.MAX_TOKENS) then cover every
    expansion of them.
    """

    name: str
    stage: str
    source: str
    file: Path  # where the source text lives (JSON or .glsl)
    first_line: int  # line in `file` where the source starts
    code: str = field(init=False, repr=False)  # the source without comments, what analysis searches

    def __post_init__(self):
        self.code = glsl.strip_comments(self.source)


@dataclass
class MaterialDescription:
    """A material: name, typed uniforms with defaults, displacement and visibility methods."""

    name: str
    uniforms: dict[str, UniformSpec]
    methods: dict[str, list[Method]]
    path: Path
    doc: str = ""
    transparent: bool | None = None  # stated in the file; None: decided from the code
    _alpha_writes: list[tuple[str, str]] = field(default_factory=list, repr=False)
    _unsure: bool = field(default=False, repr=False)

    def __post_init__(self):
        for m in self.methods.get("displacement", []) + self.methods.get("visibility", []):
            self._alpha_writes += glsl.alpha_writes(m.code)
            self._unsure = self._unsure or glsl.alpha_unreadable(m.code)

    def is_transparent(self, values: dict) -> bool:
        """Whether an instance with these uniform values can produce alpha < 1.

        Opaque when no method writes gua_alpha, when every write assigns the literal 1,
        or when every write assigns a float uniform whose instance value is 1 (constant
        alpha materials such as `pbr` with alpha 1). Anything else is decided per fragment.
        A file's `"transparent": true|false` overrides this; code the classifier cannot read
        for certain (gua_alpha passed to a function, preprocessor directives) keeps the
        A-buffer path: slower where it was not needed, never wrong.
        """
        if self.transparent is not None:
            return self.transparent
        if self._unsure:
            return True
        for op, rhs in self._alpha_writes:
            if op == "=" and glsl.is_literal_one(rhs):
                continue
            if (
                op in ("=", "*=")
                and glsl.is_identifier(rhs)
                and rhs in self.uniforms
                and self.uniforms[rhs].type == "float"
                and float(values.get(rhs, 1.0)) >= 1.0
            ):
                continue
            return True
        return False

    def resolve_values(self, overrides: dict, where: tuple[str | Path | None, int | None] = (None, None)) -> dict:
        """Defaults merged with instance overrides, type-checked; errors cite the instance."""
        file, line = where
        out = {n: u.default for n, u in self.uniforms.items()}
        for key, value in (overrides or {}).items():
            if key not in self.uniforms:
                raise ConfigError(
                    f"material '{self.name}' has no uniform '{key}'",
                    file,
                    line,
                    key,
                    f"known uniforms: {', '.join(self.uniforms) or 'none'}",
                )
            spec = self.uniforms[key]
            value = check_value(spec.type, value, file, line, key)
            out[key] = check_range(spec, value, file, line, f"material '{self.name}' ({Path(self.path).name})")
        return out


def _is_number(v) -> bool:
    """A real number (Python's or numpy's), not a bool."""
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))


def check_value(typ: str, value, file, line, key):
    """Validate one uniform value against its type; returns the normalized value.

    Numbers must be finite and fit the 32-bit type the GPU receives (ints in int32, floats
    within float32's range), so nothing past this point can overflow or turn infinite.
    """
    size = UNIFORM_SIZES[typ]
    if typ == "sampler2D":
        if not isinstance(value, str) and not hasattr(value, "pixels"):  # path/name or scene.texture.TextureImage
            raise ConfigError(f"sampler2D needs a texture path string, got {value!r}", file, line, key)
        return value
    if typ in ("float", "int"):
        if not _is_number(value):
            raise ConfigError(
                f"expected {typ}, got {type(value).__name__} {value!r}", file, line, key, number_hint(value)
            )
        if typ == "int" and not (isinstance(value, numbers.Integral) or float(value).is_integer()):
            raise ConfigError(f"expected int, got {value!r}", file, line, key)
        problem = gpu_number_problem(value, integer=typ == "int")
        if problem:
            raise ConfigError(problem, file, line, key)
        return int(value) if typ == "int" else float(value)
    items = value.tolist() if isinstance(value, np.ndarray) else value
    flat: list = []
    if isinstance(items, (list, tuple)):
        for v in items:  # a mat4 may be written as 4 rows
            flat.extend(v if isinstance(v, (list, tuple)) else [v])
    if len(flat) != size or not all(_is_number(v) for v in flat):
        raise ConfigError(f"expected {typ} ({size} numbers), got {value!r}", file, line, key)
    for v in flat:
        problem = gpu_number_problem(v)
        if problem:
            raise ConfigError(f"component {problem}", file, line, key)
    return [float(v) for v in flat]


def check_range(spec: UniformSpec, value, file, line, declared_by: str = "the material"):
    """`value` (already type-checked) when every component lies in the uniform's declared range."""
    if spec.range is None:
        return value
    bounds = Range(*spec.range)
    for v in value if isinstance(value, list) else [value]:
        if not bounds.contains(v):
            raise ConfigError(
                f"{value!r} is outside {bounds}, the range {declared_by} declares for it",
                file,
                line,
                spec.name,
            )
    return value


def _parse_range(raw, typ: str, path: Path, line: int, uname: str) -> tuple[float | None, float | None]:
    """A uniform's `"range": [lo, hi]` (either bound may be null); only numeric uniforms have one."""
    if typ == "sampler2D":
        raise ConfigError("a sampler2D uniform has no range", path, line, uname, "leave 'range' out")
    ok = isinstance(raw, list) and len(raw) == 2
    ok = ok and all(b is None or (_is_number(b) and math.isfinite(b)) for b in raw)
    if not ok or (None not in raw and raw[0] > raw[1]):
        raise ConfigError(
            f"'range' must be [low, high] with low <= high (null: no bound; finite numbers otherwise), got {raw!r}",
            path,
            line,
            uname,
            'e.g. "range": [0, 1]; every component of a vector is checked against it',
        )
    return (None if raw[0] is None else float(raw[0]), None if raw[1] is None else float(raw[1]))


def _key_line(text: str, key: str) -> int | None:
    pos = text.find(f'"{key}"')
    return _line_of(text, pos) if pos >= 0 else None


def _line_of(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _source_start(text: str, spos: int) -> int:
    """Offset of the first source character after '"source":' (inside a list of lines, its first string)."""
    colon = text.find(":", spos)
    rest = text[colon + 1 :].lstrip()
    start = len(text) - len(rest)
    return text.find('"', start) if rest.startswith("[") else start


def _method(entry, stage: str, i: int, path: Path, text: str, search_from: int) -> tuple[Method, int]:
    key = f"{stage}[{i}]"
    if not isinstance(entry, dict) or "name" not in entry or not ({"source", "file"} & set(entry)):
        raise ConfigError(
            "a method needs 'name' and either 'source' or 'file'",
            path,
            None,
            key,
            'e.g. {"name": "my_method", "source": "void my_method() { gua_alpha = 0.5; }"}',
        )
    name = entry["name"]
    if not isinstance(name, str) or not glsl.is_identifier(name):
        raise ConfigError(f"method name {name!r} is not a GLSL identifier", path, None, key)
    pos = text.find(f'"{name}"', search_from)
    pos = pos if pos >= 0 else search_from
    line = _line_of(text, pos)
    extra = sorted(set(entry) - _METHOD_KEYS)
    if extra:
        raise ConfigError(f"unknown key '{extra[0]}' in method '{name}'", path, line, key, "known: name, source, file")
    if {"source", "file"} <= set(entry):
        raise ConfigError("a method takes either 'source' or 'file', not both", path, line, key)
    if "file" in entry:
        given = entry["file"]
        if not isinstance(given, str) or not given.strip():
            raise ConfigError(f"'file' must be a path to a .glsl file, got {given!r}", path, line, key)
        src_path = path.parent / given
        if "\0" not in given:
            src_path = resolved(src_path)
        source = read_text(src_path, path, line, key, max_bytes=glsl.MAX_CODE_BYTES, what="method source file")
        file, first = src_path, 1
    else:
        src = entry["source"]
        lines_ok = isinstance(src, list) and all(isinstance(x, str) for x in src)
        source = "\n".join(src) if lines_ok else src
        if not isinstance(source, str):
            raise ConfigError("'source' must be a string or a list of lines", path, line, key)
        spos = text.find('"source"', pos)
        spos = spos if spos >= 0 else pos
        # a list of lines starts on the line after '"source": ['
        first = _line_of(text, _source_start(text, spos))
        file = path
    if not glsl.defines_void_function(source, name):
        raise ConfigError(
            f"method source does not define 'void {name}()'",
            file,
            first,
            key,
            "each method is a GLSL function named like the method, taking no arguments",
        )
    macros = glsl.macro_names(glsl.strip_comments(source))
    if macros:  # an empty line first: a define ending in a backslash would swallow the #undef
        source += "\n\n" + "\n".join(f"#undef {m}" for m in macros)
    return Method(name, stage, source, file, first), pos + 1


def _check_code(methods: list[Method], path: Path) -> None:
    """Refuse a material whose methods together exceed the bounds on code given to the driver's compiler."""
    size = statements = tokens = 0
    for m in methods:
        where = (m.file, m.first_line, f"{m.stage} method '{m.name}'")
        size += len(m.source.encode("utf-8"))
        try:
            count, expanded = glsl.code_size(m.code)
        except glsl.CodeBoundError as exc:
            raise ConfigError(str(exc), *where, "write the code out, or use a plain macro or a function") from None
        statements, tokens = statements + count, tokens + expanded
        for total, bound, what in (
            (size, glsl.MAX_CODE_BYTES, f"{glsl.MAX_CODE_BYTES // 1024} KiB of code"),
            (statements, glsl.MAX_STATEMENTS, f"{glsl.MAX_STATEMENTS:,} statements"),
            (tokens, glsl.MAX_TOKENS, f"{glsl.MAX_TOKENS:,} tokens after macro expansion"),
        ):
            if total > bound:
                raise ConfigError(
                    f"material '{path.name}' holds more than {what} (bounded so the driver's compiler "
                    "cannot hang or crash)",
                    *where,
                    "split the work into fewer, shorter expressions; use loops and functions, not repetition",
                )


class _Duplicate(ValueError):
    """A key given twice in one JSON object."""


class _LongNumber(ValueError):
    """An integer with more digits than any count or value needs."""


def _pairs(pairs: list) -> dict:
    """A JSON object's dict; a key given twice is refused (json keeps the last one without a word)."""
    out: dict = {}
    for k, v in pairs:
        if k in out:
            raise _Duplicate(k)
        out[k] = v
    return out


def _int(text: str) -> int:
    """A JSON integer; one of more than 64 digits is refused (int() fails at 4,300 with a ValueError)."""
    if len(text) > 64:
        raise _LongNumber(text)
    return int(text)


_JSON_NESTING = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def parse_json(text: str, path: Path):
    """json.loads with a nesting bound checked first (json recurses per level), located errors."""
    depth = 0
    for m in _JSON_NESTING.finditer(text):
        t = m.group()
        if t in "[{":
            depth += 1
            if depth > MAX_NESTING:
                raise ConfigError(
                    f"nested deeper than {MAX_NESTING} levels", path, _line_of(text, m.start()), hint="flatten the file"
                )
        elif t in "]}":
            depth -= 1
    try:
        return json.loads(text, object_pairs_hook=_pairs, parse_int=_int)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"invalid JSON: {exc.msg}", path, exc.lineno, hint=f"column {exc.colno}") from None
    except _Duplicate as exc:
        k = exc.args[0]
        hits = [m.start() for m in re.finditer(re.escape(json.dumps(k)) + r"\s*:", text)]
        line = _line_of(text, hits[1]) if len(hits) > 1 else None
        raise ConfigError(f"duplicate key '{k}'", path, line, k, "give each key once") from None
    except _LongNumber as exc:
        number = exc.args[0]
        line = _line_of(text, max(text.find(number), 0))
        raise ConfigError(f"an integer of {len(number)} digits is out of range", path, line) from None
    except (ValueError, RecursionError) as exc:  # anything else json refuses: still the file's fault
        raise ConfigError(f"invalid JSON: {exc}", path) from None


def load_material(path: str | Path) -> MaterialDescription:
    """Parse a material JSON file; every problem raises ConfigError with file and line."""
    path = Path(path)
    text = read_text(path, max_bytes=MAX_CONFIG_BYTES, what="material file")
    data = parse_json(text, path)
    if not isinstance(data, dict):
        raise ConfigError("a material description is a JSON object", path, 1)
    unknown = set(data) - _TOP_KEYS
    if unknown:
        k = sorted(unknown)[0]
        raise ConfigError(
            f"unknown key '{k}'",
            path,
            _line_of(text, max(text.find(json.dumps(k)), 0)),
            k,
            f"known keys: {', '.join(sorted(_TOP_KEYS))}",
        )
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise ConfigError(f"'name' must be a non-empty string, got {name!r}", path, _key_line(text, "name"), "name")
    doc = data.get("description", "")
    if not isinstance(doc, str):
        raise ConfigError(
            f"'description' must be text, got {doc!r}", path, _key_line(text, "description"), "description"
        )
    transparent = data.get("transparent")
    if transparent is not None and not isinstance(transparent, bool):
        raise ConfigError(
            f"'transparent' must be true or false, got {transparent!r}",
            path,
            _key_line(text, "transparent"),
            "transparent",
            "leave it out to let the material's code decide",
        )
    raw_uniforms = data.get("uniforms") or {}
    if not isinstance(raw_uniforms, dict):
        raise ConfigError(
            f"'uniforms' must be an object of name: {{type, default}}, got {type(raw_uniforms).__name__}",
            path,
            _key_line(text, "uniforms"),
            "uniforms",
            'e.g. "uniforms": {"alpha": {"type": "float", "default": 0.5}}',
        )
    uniforms: dict[str, UniformSpec] = {}
    for uname, spec in raw_uniforms.items():
        line = _line_of(text, max(text.find(json.dumps(uname)), 0))
        if not glsl.is_identifier(uname) or uname.startswith("gua_"):
            raise ConfigError(
                f"uniform name {uname!r} is not allowed",
                path,
                line,
                uname,
                "use a GLSL identifier not starting with gua_",
            )
        typ = spec.get("type") if isinstance(spec, dict) else None
        if not isinstance(typ, str) or typ not in UNIFORM_SIZES:
            raise ConfigError(
                f"uniform needs a 'type' out of {', '.join(UNIFORM_SIZES)}, got {typ!r}", path, line, uname
            )
        extra = sorted(set(spec) - _SPEC_KEYS)
        if extra:  # a misspelt "default" would otherwise leave the uniform at zero without a word
            raise ConfigError(
                f"unknown key '{extra[0]}' in uniform '{uname}'", path, line, uname, "known: type, default, range"
            )
        default = spec.get(
            "default",
            "white" if typ == "sampler2D" else (0.0 if UNIFORM_SIZES[typ] == 1 else [0.0] * UNIFORM_SIZES[typ]),
        )
        bounds = _parse_range(spec["range"], typ, path, line, uname) if "range" in spec else None
        u = UniformSpec(uname, typ, check_value(typ, default, path, line, uname), bounds)
        uniforms[uname] = u
        check_range(u, u.default, path, line, "its 'range'")  # the default too
        if typ == "sampler2D" and sum(u.type == "sampler2D" for u in uniforms.values()) > MAX_SAMPLERS:
            raise ConfigError(
                f"more than {MAX_SAMPLERS} sampler2D uniforms",
                path,
                line,
                uname,
                f"a material's textures take texture units {Texture.MATERIALS} to "
                f"{Texture.MATERIALS + MAX_SAMPLERS - 1} (the others are the passes'); "
                "pack several maps into the channels of one texture",
            )
    methods: dict[str, list[Method]] = {}
    pos = 0
    for stage in STAGES:
        entries = data.get(stage) or []
        if not isinstance(entries, list):
            raise ConfigError(f"'{stage}' must be a list of methods", path, _key_line(text, stage), stage)
        stage_pos = text.find(f'"{stage}"')
        pos = stage_pos if stage_pos >= 0 else pos
        methods[stage] = []
        for i, entry in enumerate(entries):
            m, pos = _method(entry, stage, i, path, text, pos)
            methods[stage].append(m)
    _check_code(methods["displacement"] + methods["visibility"], path)
    return MaterialDescription(name, uniforms, methods, path, doc, transparent)
