"""Reading users' files so config errors can cite file:line: their UTF-8 text, and YAML that keeps line numbers."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError


class Located:
    """Parsed YAML value plus the line of every mapping key and sequence item."""

    def __init__(self, data: Any, lines: dict[tuple, int], file: str):
        self.data, self.lines, self.file = data, lines, file

    def line(self, path: tuple) -> int | None:
        """Line of the entry at key path `path` (falls back to the nearest parent)."""
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return self.lines.get((), 1)

    def error(self, path: tuple, reason: str, hint: str | None = None) -> ConfigError:
        """A ConfigError citing the file, the line and the dotted key of `path`."""
        return ConfigError(reason, self.file, self.line(path), key_name(path), hint)


def key_name(path: tuple) -> str:
    """Render a key path like ('passes', 2, 'mode') as 'passes[2].mode'."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


MAX_NESTING = 64  # config files are shallow; deeper means an alias cycle or a generated mistake


def compose(text: str, file: str) -> yaml.Node | None:
    """yaml.compose with room for MAX-nested documents; deeper ones are a ConfigError, not a RecursionError.

    PyYAML's composer recurses several frames per level, so a 300-level scene exhausts Python's
    default limit before the loaders can report the nesting at its line.
    """
    old = sys.getrecursionlimit()
    sys.setrecursionlimit(max(old, 20000))
    try:
        return yaml.compose(text, Loader=yaml.SafeLoader)
    except RecursionError:
        raise ConfigError(
            "nested too deeply for the YAML parser", file, hint=f"keep nesting under {MAX_NESTING} levels"
        ) from None
    finally:
        sys.setrecursionlimit(old)


def nesting_error(node: yaml.Node, file: str, key: str, cycle: bool) -> ConfigError:
    """The error for an alias that contains itself, or for nesting past MAX_NESTING."""
    if cycle:
        return ConfigError(
            "an alias refers to a node that contains it (a cycle)",
            file,
            node.start_mark.line + 1,
            key or None,
            "YAML aliases (*name) may only repeat finished nodes",
        )
    return ConfigError(
        f"nested deeper than {MAX_NESTING} levels", file, node.start_mark.line + 1, key or None, "flatten the file"
    )


def _convert(node: yaml.Node, path: tuple, lines: dict, file: str = "<yaml>", open_: tuple = ()) -> Any:
    lines.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
        if any(n is node for n in open_) or len(open_) >= MAX_NESTING:
            raise nesting_error(node, file, key_name(path), any(n is node for n in open_))
        open_ = open_ + (node,)
    if isinstance(node, yaml.MappingNode):
        out = {}
        for k, v in node.value:
            key = k.value
            lines[path + (key,)] = k.start_mark.line + 1
            out[key] = _convert(v, path + (key,), lines, file, open_)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_convert(v, path + (i,), lines, file, open_) for i, v in enumerate(node.value)]
    if node.tag == "tag:yaml.org,2002:str":
        return node.value
    if node.tag == "tag:yaml.org,2002:bool" and node.value.lower() not in ("true", "false"):
        return node.value  # YAML 1.2 booleans only: 'off'/'on'/'yes'/'no' stay strings (mode: off)
    return yaml.safe_load(yaml.serialize(node))


def load_yaml_text(text: str, file: str) -> Located:
    """Parse YAML text; syntax errors become ConfigError with the line of the problem."""
    try:
        root = compose(text, file)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        raise ConfigError(
            f"invalid YAML: {getattr(exc, 'problem', exc)}", file, line, hint="check indentation and brackets"
        ) from exc
    lines: dict[tuple, int] = {}
    data = _convert(root, (), lines, file) if root is not None else {}
    return Located(data, lines, file)


def read_text(path: str | Path, cite: str | Path | None = None, line: int | None = None, key: str | None = None) -> str:
    """A file's UTF-8 text; other bytes are a ConfigError naming the byte and its line.

    The error cites `path` at the byte's line, or, where the file was named by another one
    (a material's method source), `cite` at `line` and `key`.
    """
    p = Path(path)
    data = p.read_bytes()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        bad_line = data.count(b"\n", 0, exc.start) + 1
        raise ConfigError(
            f"{p.name} is not UTF-8 text (byte 0x{data[exc.start]:02x} on line {bad_line})",
            p if cite is None else cite,
            bad_line if cite is None else line,
            key,
            "save the file as UTF-8",
        ) from None


def load_yaml_file(path: str | Path) -> Located:
    """Read and parse a YAML file (missing file → ConfigError)."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError("file not found", p, hint="check the path")
    return load_yaml_text(read_text(p), str(p))
