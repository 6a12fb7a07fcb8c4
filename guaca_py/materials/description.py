"""Load and validate one material description: typed uniforms and GLSL stage methods."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..numeric import Range, number_hint
from ..shaders.slots import Texture
from ..yaml_source import read_text
from . import glsl

#: sampler2D uniforms a material may declare: each takes its own texture unit of Texture.MATERIALS
#: (raster/material_program.py: apply_material)
MAX_SAMPLERS = Texture.TABLE["MATERIALS"].count
#: uniform type -> number of floats (sampler2D holds a texture path instead)
UNIFORM_SIZES = {"float": 1, "int": 1, "vec2": 2, "vec3": 3, "vec4": 4, "mat4": 16, "sampler2D": 0}
STAGES = ("displacement", "visibility")
_TOP_KEYS = {"name", "description", "uniforms", "displacement", "visibility", "transparent"}
_SPEC_KEYS = {"type", "default", "range"}


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
    """One GLSL method (a `void NAME()` function on the gua_* interface) of a stage."""

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


def check_value(typ: str, value, file, line, key):
    """Validate one uniform value against its type; returns the normalized value."""
    size = UNIFORM_SIZES[typ]
    if typ == "sampler2D":
        if not isinstance(value, str) and not hasattr(value, "pixels"):  # path/name or scene.texture.TextureImage
            raise ConfigError(f"sampler2D needs a texture path string, got {value!r}", file, line, key)
        return value
    if typ in ("float", "int"):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(
                f"expected {typ}, got {type(value).__name__} {value!r}", file, line, key, number_hint(value)
            )
        if typ == "int" and not float(value).is_integer():
            raise ConfigError(f"expected int, got {value!r}", file, line, key)
        return int(value) if typ == "int" else float(value)
    arr = np.asarray(value, dtype=object).ravel() if isinstance(value, (list, tuple)) else None
    if arr is None or arr.size != size or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in arr):
        raise ConfigError(f"expected {typ} ({size} numbers), got {value!r}", file, line, key)
    return [float(v) for v in arr]


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
    ok = ok and all(b is None or (isinstance(b, (int, float)) and not isinstance(b, bool)) for b in raw)
    if not ok or (None not in raw and raw[0] > raw[1]):
        raise ConfigError(
            f"'range' must be [low, high] with low <= high (null: no bound), got {raw!r}",
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
    if "file" in entry:
        src_path = (path.parent / entry["file"]).resolve()
        if not src_path.is_file():
            raise ConfigError(f"method source file not found: {src_path}", path, _line_of(text, pos), key)
        source, file, first = read_text(src_path, path, _line_of(text, pos), key), src_path, 1
    else:
        src = entry["source"]
        lines_ok = isinstance(src, list) and all(isinstance(x, str) for x in src)
        source = "\n".join(src) if lines_ok else src
        if not isinstance(source, str):
            raise ConfigError("'source' must be a string or a list of lines", path, _line_of(text, pos), key)
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
    return Method(name, stage, source, file, first), pos + 1


def load_material(path: str | Path) -> MaterialDescription:
    """Parse a material JSON file; every problem raises ConfigError with file and line."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("material file not found", path)
    text = read_text(path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"invalid JSON: {exc.msg}", path, exc.lineno, hint=f"column {exc.colno}") from exc
    if not isinstance(data, dict):
        raise ConfigError("a material description is a JSON object", path, 1)
    unknown = set(data) - _TOP_KEYS
    if unknown:
        k = sorted(unknown)[0]
        raise ConfigError(
            f"unknown key '{k}'",
            path,
            _line_of(text, max(text.find(f'"{k}"'), 0)),
            k,
            f"known keys: {', '.join(sorted(_TOP_KEYS))}",
        )
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise ConfigError(f"'name' must be a non-empty string, got {name!r}", path, _key_line(text, "name"), "name")
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
        line = _line_of(text, max(text.find(f'"{uname}"'), 0))
        if not glsl.is_identifier(uname) or uname.startswith("gua_"):
            raise ConfigError(
                f"uniform name {uname!r} is not allowed",
                path,
                line,
                uname,
                "use a GLSL identifier not starting with gua_",
            )
        if not isinstance(spec, dict) or spec.get("type") not in UNIFORM_SIZES:
            raise ConfigError(f"uniform needs a 'type' out of {', '.join(UNIFORM_SIZES)}", path, line, uname)
        extra = sorted(set(spec) - _SPEC_KEYS)
        if extra:  # a misspelt "default" would otherwise leave the uniform at zero without a word
            raise ConfigError(
                f"unknown key '{extra[0]}' in uniform '{uname}'", path, line, uname, "known: type, default, range"
            )
        default = spec.get(
            "default",
            "white"
            if spec["type"] == "sampler2D"
            else (0.0 if UNIFORM_SIZES[spec["type"]] == 1 else [0.0] * UNIFORM_SIZES[spec["type"]]),
        )
        bounds = _parse_range(spec["range"], spec["type"], path, line, uname) if "range" in spec else None
        u = UniformSpec(uname, spec["type"], check_value(spec["type"], default, path, line, uname), bounds)
        uniforms[uname] = u
        check_range(u, u.default, path, line, "its 'range'")  # the default too
        if spec["type"] == "sampler2D" and sum(u.type == "sampler2D" for u in uniforms.values()) > MAX_SAMPLERS:
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
            raise ConfigError(f"'{stage}' must be a list of methods", path, None, stage)
        stage_pos = text.find(f'"{stage}"')
        pos = stage_pos if stage_pos >= 0 else pos
        methods[stage] = []
        for i, entry in enumerate(entries):
            m, pos = _method(entry, stage, i, path, text, pos)
            methods[stage].append(m)
    return MaterialDescription(name, uniforms, methods, path, data.get("description", ""), transparent)
