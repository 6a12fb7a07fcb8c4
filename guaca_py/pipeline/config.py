"""Load and validate pipeline configs (pipelines/*.yaml): ordered passes with settings."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .. import antialiasing
from ..errors import ConfigError
from ..registry import AUTO, METHODS, PASSES, settings_schema, unknown_method
from ..resources import builtin_pipeline
from ..yaml_source import MAX_CONFIG_BYTES, Located, load_yaml_file, load_yaml_text
from .settings import Setting, positive, resolve_settings

COMPULSORY = ("geometry", "light_culling", "composite")
_TOP = {"name", "resolution", "transparency", "antialiasing", "passes"}


@dataclass
class PassConfig:
    """One pass entry: its type name and validated settings."""

    name: str
    settings: dict
    line: int | None = None


@dataclass
class PipelineConfig:
    """A validated pipeline: resolution, transparency method settings and ordered passes."""

    name: str
    resolution: tuple[int, int]
    transparency: dict
    passes: list[PassConfig] = field(default_factory=list)
    source: str = "<config>"
    # guaca_py/antialiasing.py: every setting at its default unless the file gives it
    antialiasing: dict = field(default_factory=lambda: {k: s.default for k, s in antialiasing.SETTINGS.items()})

    def pass_settings(self, name: str) -> dict | None:
        """Settings of the first pass called `name`, or None if absent."""
        return next((p.settings for p in self.passes if p.name == name), None)


def _size(v) -> str | None:
    ok = (
        isinstance(v, list)
        and len(v) == 2
        and all(isinstance(x, int) and not isinstance(x, bool) and 0 < x <= 16384 for x in v)
    )
    return None if ok else "must be [width, height] with integers in 1..16384"


def parse_pipeline(doc: Located) -> PipelineConfig:
    """Validate a parsed pipeline document; errors cite file, line and key."""
    data = doc.data
    if not isinstance(data, dict):
        raise doc.error((), "a pipeline config is a mapping with 'passes'")
    for key in data:
        if key not in _TOP:
            raise doc.error((key,), f"unknown key '{key}'", f"known keys: {', '.join(sorted(_TOP))}")
    res = data.get("resolution", [512, 512])
    if _size(res):
        raise doc.error(("resolution",), _size(res))
    # transparency: method id + generic and method-specific settings
    given_tr = data.get("transparency")
    if given_tr is not None and not isinstance(given_tr, dict):
        raise doc.error(("transparency",), f"must be a mapping like {{method: presort_lf_et}}, got {given_tr!r}")
    tr = dict(given_tr or {})
    mid = tr.pop("method", "presort_lf_et")
    if not isinstance(mid, str) or (mid != AUTO and mid not in METHODS):
        raise doc.error(("transparency", "method"), *unknown_method(mid))
    schema = settings_schema(mid)
    settings = resolve_settings(schema, tr, lambda k, r, h: doc.error(("transparency", k), r, h))
    if mid == AUTO:  # the values given; the method picked on the device fills in its own defaults
        settings = {k: settings[k] for k in tr}
    aa = antialiasing.parse(
        data.get("antialiasing"), lambda k, r, h: doc.error(("antialiasing",) + ((k,) if k else ()), r, h)
    )
    passes_raw = data.get("passes")
    if not isinstance(passes_raw, list) or not passes_raw:
        raise doc.error(
            ("passes",),
            "missing or empty 'passes' list",
            f"a pipeline needs at least {', '.join(COMPULSORY)} in this order",
        )
    passes: list[PassConfig] = []
    for i, entry in enumerate(passes_raw):
        if isinstance(entry, str):
            name, given = entry, {}
        elif isinstance(entry, dict) and len(entry) == 1:
            name, given = next(iter(entry.items()))
            given = given or {}
        else:
            raise doc.error(("passes", i), "each pass is a name or a one-key mapping {name: {settings}}")
        if not isinstance(name, str) or name not in PASSES:
            raise doc.error(("passes", i), *PASSES.unknown(name))
        if not isinstance(given, dict):
            raise doc.error(("passes", i, name), "pass settings must be a mapping")
        st = resolve_settings(
            PASSES.get(name).SETTINGS, given, lambda k, r, h, i=i, name=name: doc.error(("passes", i, name, k), r, h)
        )
        passes.append(PassConfig(name, st, doc.line(("passes", i))))
    names = [p.name for p in passes]
    for c in COMPULSORY:
        if c not in names:
            raise doc.error(
                ("passes",),
                f"compulsory pass '{c}' is missing",
                f"passes must start with {', '.join(COMPULSORY)} in this order",
            )
    head = names[: len(COMPULSORY)]
    if tuple(head) != COMPULSORY:
        bad = next(i for i, n in enumerate(head) if n != COMPULSORY[i])
        raise doc.error(
            ("passes", bad),
            f"wrong pass order: found '{head[bad]}' where '{COMPULSORY[bad]}' belongs",
            f"passes must start with {', '.join(COMPULSORY)} in this order, post passes after",
        )
    for i, n in enumerate(names):
        if n in names[:i]:
            raise doc.error(
                ("passes", i),
                f"pass '{n}' appears twice (first as passes[{names.index(n)}])",
                "list each pass once; its settings go in that one entry",
            )
    settings["method"] = mid
    name = data.get("name", Path(doc.file).stem)
    if isinstance(name, bool) or not isinstance(name, (str, int, float)) or name == "":
        raise doc.error(("name",), f"'name' must be text, got {name!r}")
    name = str(name)
    return PipelineConfig(name, (res[0], res[1]), settings, passes, doc.file, aa)


def load_pipeline(spec: str | Path | PipelineConfig = "default") -> PipelineConfig:
    """A PipelineConfig from a built-in name ('default', 'exact'), a YAML path, or itself."""
    if isinstance(spec, PipelineConfig):
        return spec
    if not isinstance(spec, (str, Path)) or not str(spec):
        raise ConfigError(
            f"expected a pipeline name or a path to a .yaml file, got {spec!r}",
            key="pipeline",
            hint="one of: default, exact, or a path to a .yaml file",
        )
    p = Path(spec)
    if not p.suffix and not p.exists():
        p = builtin_pipeline(str(spec))
        if not p.is_file():
            raise ConfigError(
                f"no built-in pipeline '{spec}' and no such file",
                key="pipeline",
                hint="give a path to a .yaml file or one of: default, exact",
            )
    return parse_pipeline(load_yaml_file(p, max_bytes=MAX_CONFIG_BYTES))


def pipeline_from_text(text: str, name: str = "<string>") -> PipelineConfig:
    """Parse a pipeline from YAML text (for embedding applications and tests)."""
    return parse_pipeline(load_yaml_text(text, name))


__all__ = ["PipelineConfig", "PassConfig", "load_pipeline", "pipeline_from_text", "COMPULSORY", "Setting", "positive"]
