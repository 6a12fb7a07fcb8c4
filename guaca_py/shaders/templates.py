"""Render GLSL from Jinja2 templates; map compiler messages back to material files."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import jinja2
import numpy as np

from ..context import is_software
from ..errors import ShaderCompileError
from ..frozen import PLAIN, freeze
from ..resources import builtin_dir
from . import slots

_BEGIN, _END = "// @gua-source-begin ", "// @gua-source-end"
# Mesa: "0:12(5): error: ..."   NVIDIA: "0(12) : error C1008: ..."
_MSG = re.compile(r"^\s*(?:ERROR:\s*)?(\d+)[:(](\d+)\)?(?:\(\d+\))?\s*:?\s*(.*)$")


@dataclass
class SourceMap:
    """Remembers where inserted code came from: source id → (file, first line, label).

    Drivers disagree on `#line` source-string numbers (Mesa drops them), so inserted code is
    bracketed by comment markers instead and generated line numbers are mapped back here.
    """

    origins: dict[int, tuple[Path, int, str]] = field(default_factory=dict)

    def insert(self, code: str, file: Path, first_line: int, label: str) -> str:
        """Bracket `code` with markers so compiler messages can cite `file` lines."""
        sid = len(self.origins) + 1
        self.origins[sid] = (file, first_line, label)
        return f"{_BEGIN}{sid}\n{code}\n{_END}\n"

    def locate(self, src: str, line: int) -> tuple[Path, int, str] | None:
        """(file, line, label) of generated line `line` when it lies in inserted code."""
        lines = src.split("\n")
        sid, start = None, 0
        for i, text in enumerate(lines[:line], 1):
            if text.startswith(_BEGIN):
                sid, start = int(text[len(_BEGIN) :]), i
            elif text.startswith(_END):
                sid = None
        if sid is None or sid not in self.origins or line == start:
            return None
        file, first, label = self.origins[sid]
        return file, first + (line - start - 1), label


def explain_compile_error(message: str, sources: dict[str, str], smap: SourceMap, program: str) -> str:
    """Turn a compiler log into lines citing material files or generated template lines."""
    lines_out = []
    stage_src = None
    for raw in message.splitlines():
        for stage, src in sources.items():
            if raw.strip().startswith(stage):
                stage_src = src
        m = _MSG.match(raw)
        if not m:
            continue
        line, msg = int(m.group(2)), m.group(3).strip()
        if "error" not in msg.lower():
            continue  # warnings about the generated interface are noise here
        origin = smap.locate(stage_src, line) if stage_src is not None else None
        if origin is not None:
            file, fline, label = origin
            lines_out.append(f"{file}:{fline}: in {label}: {msg}")
        else:
            ctx = ""
            if stage_src is not None:
                src_lines = stage_src.split("\n")
                if 0 < line <= len(src_lines):
                    ctx = f"  | {src_lines[line - 1].strip()}"
            lines_out.append(f"<generated {program}>:{line}: {msg}{ctx}")
    if not lines_out:
        lines_out.append(message.strip())
    return "\n".join(lines_out)


class ShaderLibrary:
    """Jinja2 environment over the built-in templates (user directories first) plus compilation."""

    def __init__(self, ctx, extra_dirs: list[str | Path] | None = None):
        self.ctx = ctx
        dirs = [str(d) for d in (extra_dirs or [])] + [str(builtin_dir("shader_templates"))]
        self.env = jinja2.Environment(
            loader=jinja2.FileSystemLoader(dirs),
            undefined=jinja2.StrictUndefined,
            keep_trailing_newline=True,
            trim_blocks=True,
            lstrip_blocks=True,
        )
        self.env.globals.update(slots.template_globals())  # binding slots by name: {{ Buffer.LIGHTS }}
        # common/pack.glsl.j2's half rounding: integer arithmetic where a pack costs several times more
        # (CPU rasterizers); elsewhere the device's own pack and unpack, whose rounding it must match
        # (NVIDIA's packHalf2x16 does not round to nearest even, so an emulation would differ there)
        self.env.globals["gua_round_half_emulated"] = is_software(ctx)
        self._programs: dict = {}

    def render(self, template: str, **variables) -> str:
        """Render one template to GLSL text."""
        return self.env.get_template(template).render(**variables)

    def program(self, stages: dict[str, tuple[str, dict]], smap: SourceMap | None = None, label: str = "program"):
        """Compile (once) a program from {stage: (template, variables)}; stage names are moderngl's.

        The cache key is derived from the stages' templates and variables (material code reaches
        the templates as variables, so it is part of the key): callers never build keys by hand.
        """
        key = program_key(stages)
        prog = self._programs.get(key)
        if prog is not None:
            return prog
        smap = smap or SourceMap()
        sources = {stage: self.render(tpl, **vars_) for stage, (tpl, vars_) in stages.items()}
        try:
            if "compute_shader" in sources:
                prog = self.ctx.compute_shader(sources["compute_shader"])
            else:
                prog = self.ctx.program(**sources)
        except Exception as exc:  # moderngl raises moderngl.Error with the driver's log
            # one line, the first error's file and line first (the command line's errors are one line each)
            found = [f for f in explain_compile_error(str(exc), sources, smap, label).splitlines() if f.strip()]
            more = f"; {len(found) - 1} more: " + "; ".join(f.strip() for f in found[1:]) if len(found) > 1 else ""
            first = found[0].strip() if found else "the driver gave no log"
            raise ShaderCompileError(f"{first} (GLSL compilation of {label} failed{more})") from exc
        prog._gua_sources = sources
        self._programs[key] = prog
        return prog

    def release(self) -> None:
        """Free every compiled program."""
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()

    def compute(self, template: str, **variables):
        """Compile (once per template and variables) a compute shader."""
        return self.program({"compute_shader": (template, variables)}, label=template)


def program_key(stages: dict[str, tuple[str, dict]]) -> tuple:
    """The cache key of a program: each stage's template and its variables, frozen.

    Derived on every look-up (each frame, per material and kernel): scalars, nearly all of the
    variables, go in as they are, without a call each.
    """
    return tuple(
        sorted(
            (stage, tpl, tuple(sorted((k, v if type(v) in PLAIN else freeze(v)) for k, v in vars_.items())))
            for stage, (tpl, vars_) in stages.items()
        )
    )


def mat_bytes(m) -> bytes:
    """A row-major 4x4 matrix (an array, nested or 16 flat numbers) as the column-major float32 bytes GL expects."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float32).reshape(4, 4).T).tobytes()


def uniform_names(prog) -> frozenset[str]:
    """The names of a program's uniforms and blocks, gathered once per program.

    moderngl's Program has no __contains__, so `name in prog` walks every member: thousands of
    steps a frame for scenes of many draws.
    """
    try:
        return prog._gua_names
    except AttributeError:
        names = prog._gua_names = frozenset(prog)
        prog._gua_held = {}
        return names


_UNSET = object()
# value types a uniform takes as they are (compared by equality); others are converted first
_PLAIN = frozenset((int, float, bool, bytes, tuple))


def set_uniform(prog, name: str, value) -> bool:
    """Set uniform `name` (bytes: its raw data) where the program uses it; returns whether it does.

    A GL program keeps its uniforms between draws and frames, so a value this helper already gave
    the program is not written again: a static scene's camera and materials need no writes after
    the first frame, where each write costs moderngl several Python calls, thousands a frame in
    scenes of many draws. Values are bytes, numbers or tuples (compared by equality). What it
    remembers is what the program holds only if a name is never written around it: the programs a
    frame draws or dispatches per draw write every uniform through here.
    """
    if name not in uniform_names(prog):
        return False
    if type(value) not in _PLAIN:
        if hasattr(value, "tolist"):  # numpy arrays and scalars: plain Python values compare as one
            value = value.tolist()
        if isinstance(value, list):
            value = tuple(value)
    held = prog._gua_held
    if held.get(name, _UNSET) != value:
        if isinstance(value, bytes):
            prog[name].write(value)
        else:
            prog[name].value = value
        held[name] = value
    return True


def set_uniforms(prog, items) -> None:
    """set_uniform() for each (name, value) pair of `items`.

    The check for an unchanged value is done here in one step: a frame passes hundreds of values
    that the program already holds (per-draw loops over a kernel's uniforms).
    """
    names = uniform_names(prog)
    held = prog._gua_held
    for name, value in items:
        if name in names and not (type(value) in _PLAIN and held.get(name, _UNSET) == value):
            set_uniform(prog, name, value)
