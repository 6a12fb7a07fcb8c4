"""Reading users' files so config errors can cite file:line: their UTF-8 text, and YAML that keeps line numbers.

Every file a user names is opened here (`read_text`): only regular files, within a size bound,
so a FIFO, a device or a directory is refused instead of blocking or reading forever. YAML is
parsed by libyaml where PyYAML has it (`yaml.CSafeLoader`; ten times faster than the pure-Python
parser on large scenes) and composed into nodes by `compose`, which bounds the work before any
object is built: nesting depth, alias uses and the nodes aliases repeat ("billion laughs").
"""

from __future__ import annotations

import gc
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml
from yaml.events import (
    AliasEvent,
    DocumentEndEvent,
    DocumentStartEvent,
    MappingEndEvent,
    MappingStartEvent,
    ScalarEvent,
    SequenceEndEvent,
    SequenceStartEvent,
    StreamEndEvent,
    StreamStartEvent,
)

from .errors import ConfigError

#: libyaml's parser where PyYAML was built with it; the events (and their line marks) are the same
PARSER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

MAX_NESTING = 64  # pipeline YAML and material JSON are shallow; deeper means a generated mistake
#: levels of YAML collections in a scene: each level of scene nodes takes two (a node, its children),
#: so 100 levels of nodes with their contents take 206; no more, as the scene loader reads values
#: recursively, about four Python frames per level
MAX_YAML_DEPTH = 208
MAX_ALIAS_USES = 1_000_000
#: nodes that aliases may repeat in all: this many, or one per character of a larger file
ALIAS_EXPANSION_FLOOR = 100_000
MAX_INT_DIGITS = 64  # far beyond any count or size; Python refuses int() of 4,300 digits with a ValueError

_TAG = "tag:yaml.org,2002:"
_STR, _INT, _FLOAT, _BOOL, _NULL = (_TAG + t for t in ("str", "int", "float", "bool", "null"))
_SEQ, _MAP = _TAG + "seq", _TAG + "map"
_EXPLICIT_SCALAR_TAGS = (_STR, _INT, _FLOAT, _BOOL, _NULL)


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


def nesting_error(node: yaml.Node, file: str, key: str, cycle: bool, limit: int = MAX_NESTING) -> ConfigError:
    """The error for an alias that contains itself, or for nesting past `limit` levels."""
    if cycle:
        return ConfigError(
            "an alias refers to a node that contains it (a cycle)",
            file,
            node.start_mark.line + 1,
            key or None,
            "YAML aliases (*name) may only repeat finished nodes",
        )
    return ConfigError(
        f"nested deeper than {limit} levels", file, node.start_mark.line + 1, key or None, "flatten the file"
    )


class _Open:
    """A collection being composed: its node, anchor, nodes so far (aliases expanded) and pending key."""

    __slots__ = ("node", "anchor", "size", "key")

    def __init__(self, node: yaml.Node, anchor: str | None):
        self.node, self.anchor, self.size, self.key = node, anchor, 1, None


class _Composer:
    """yaml.compose over the parser's events, without recursion and with every bound checked on the way.

    Aliases are counted as they come, each by the number of nodes it repeats (known once its anchored
    node is complete, memoised per anchor): a bomb is refused after reading its few lines, before
    anything is expanded. An alias to a node still open is a cycle, refused the same way.
    """

    def __init__(self, text: str, file: str, max_depth: int):
        self.loader = PARSER(text)
        self.file, self.max_depth = file, max_depth
        self.expansion_limit = max(ALIAS_EXPANSION_FLOOR, len(text))
        self.anchors: dict[str, yaml.Node] = {}
        self.sizes: dict[str, int] = {}  # anchor -> nodes it stands for, once complete
        self.aliases = self.repeated = 0
        self.tags: dict[str, str] = {}  # plain scalar text -> resolved tag (scenes repeat values a lot)
        self.stack: list[_Open] = []

    def key_path(self) -> str:
        """Key path of the node being added to the innermost open collection ('nodes[3].mesh')."""
        path: list = []
        for frame in self.stack:
            if isinstance(frame.node, yaml.MappingNode):
                if frame.key is None:  # the key itself is being read
                    break
                path.append(frame.key.value)
            else:
                path.append(len(frame.node.value))
        if len(path) > 8:  # a runaway nesting: its first and last keys say where
            last = path[-1]
            tail = f"[{last}]" if isinstance(last, int) else f".{last}"
            return f"{key_name(tuple(path[:2]))}.(...{len(path) - 3} levels...){tail}"
        return key_name(tuple(path))

    def error(self, mark, reason: str, hint: str | None = None) -> ConfigError:
        """A ConfigError at `mark`'s line and the current key path."""
        return ConfigError(reason, self.file, mark.line + 1, self.key_path() or None, hint)

    def tag(self, event: ScalarEvent) -> str:
        """The scalar's tag: explicit ones checked, implicit ones resolved; dates, merges and '=' stay text."""
        tag = event.tag
        if tag is None or tag == "!":
            if not event.implicit[0]:
                return _STR  # quoted, or '!': text
            tag = self.tags.get(event.value)
            if tag is None:
                tag = self.loader.resolve(yaml.ScalarNode, event.value, (True, False))
                if tag not in _EXPLICIT_SCALAR_TAGS:  # timestamp, merge ('<<'), value ('='): no key wants them
                    tag = _STR
                self.tags[event.value] = tag
        elif tag not in _EXPLICIT_SCALAR_TAGS:
            raise self.error(event.start_mark, f"unsupported YAML tag {tag}", "write plain values without tags")
        elif tag != _STR:
            try:  # '!!float abc' would otherwise fail wherever the value is read
                construct_scalar(yaml.ScalarNode(tag, event.value))
            except (ValueError, TypeError, KeyError, yaml.YAMLError):
                name = tag.removeprefix(_TAG)
                raise self.error(event.start_mark, f"{event.value!r} is not a valid !!{name}", "drop the tag") from None
        if tag == _INT and sum(c.isdigit() for c in event.value) > MAX_INT_DIGITS:
            raise self.error(event.start_mark, f"an integer of {len(event.value)} digits is out of range")
        return tag

    def collection_tag(self, event, default: str) -> str:
        """A sequence's or mapping's tag: only the plain ones."""
        if event.tag in (None, "!", default):
            return default
        raise self.error(event.start_mark, f"unsupported YAML tag {event.tag}", "write plain values without tags")

    def anchor(self, event, node: yaml.Node) -> None:
        """Register `node` under the event's anchor (a duplicate anchor is an error, as in PyYAML)."""
        if event.anchor is None:
            return
        if event.anchor in self.anchors:
            raise yaml.composer.ComposerError(
                f"found duplicate anchor {event.anchor!r}; first occurrence",
                self.anchors[event.anchor].start_mark,
                "second occurrence",
                event.start_mark,
            )
        self.anchors[event.anchor] = node

    def alias(self, event: AliasEvent) -> tuple[yaml.Node, int]:
        """The node an alias repeats and its size; refuses cycles and expansion past the bounds."""
        name = event.anchor
        if name not in self.anchors:
            raise yaml.composer.ComposerError(None, None, f"found undefined alias {name!r}", event.start_mark)
        node = self.anchors[name]
        if name not in self.sizes:  # still open: the alias is inside the node it names
            raise nesting_error(node, self.file, self.key_path(), cycle=True)
        self.aliases += 1
        self.repeated += self.sizes[name]
        if self.aliases > MAX_ALIAS_USES:
            raise self.error(
                event.start_mark,
                f"more than {MAX_ALIAS_USES:,} alias uses (*name)",
                "write the repeated values out, or generate the file without aliases",
            )
        if self.repeated > self.expansion_limit:
            raise self.error(
                event.start_mark,
                f"aliases repeat more than {self.expansion_limit:,} nodes (*{name} alone stands for "
                f"{self.sizes[name]:,})",
                f"aliases may repeat {ALIAS_EXPANSION_FLOOR:,} nodes, or one per character of a larger file",
            )
        return node, self.sizes[name]

    def add(self, node: yaml.Node, size: int) -> bool:
        """Put a complete node into the innermost open collection; True when it is the document's root."""
        if not self.stack:
            return True
        parent = self.stack[-1]
        parent.size += size
        if isinstance(parent.node, yaml.MappingNode):
            if parent.key is None:
                if not isinstance(node, yaml.ScalarNode):
                    kind = "a list" if isinstance(node, yaml.SequenceNode) else "a mapping"
                    raise self.error(node.start_mark, f"a mapping key must be a plain name, got {kind}")
                parent.key = node
            else:
                parent.node.value.append((parent.key, node))
                parent.key = None
        else:
            parent.node.value.append(node)
        return False

    def document(self) -> yaml.Node | None:
        """The single document's root node, or None for an empty stream."""
        get, check = self.loader.get_event, self.loader.check_event
        get()  # StreamStartEvent
        if check(StreamEndEvent):
            get()
            return None
        start = get()  # DocumentStartEvent
        root = self.node()
        get()  # DocumentEndEvent
        if not check(StreamEndEvent):
            event = get()
            raise yaml.composer.ComposerError(
                "expected a single document in the stream", start.start_mark, "but found another document",
                event.start_mark,
            )  # fmt: skip
        return root

    def node(self) -> yaml.Node:
        """Compose the next node from the events, iteratively."""
        get = self.loader.get_event
        while True:
            event = get()
            kind = type(event)
            if kind is ScalarEvent:
                style = event.style or None  # libyaml says '' for plain scalars, PyYAML None
                node = yaml.ScalarNode(self.tag(event), event.value, event.start_mark, event.end_mark, style)
                self.anchor(event, node)
                if event.anchor is not None:
                    self.sizes[event.anchor] = 1
                size = 1
            elif kind is AliasEvent:
                node, size = self.alias(event)
            elif kind is SequenceStartEvent or kind is MappingStartEvent:
                if len(self.stack) >= self.max_depth:
                    raise ConfigError(
                        f"nested deeper than {self.max_depth} levels",
                        self.file,
                        event.start_mark.line + 1,
                        self.key_path() or None,
                        "flatten the file",
                    )
                if kind is SequenceStartEvent:
                    tag, cls = self.collection_tag(event, _SEQ), yaml.SequenceNode
                else:
                    tag, cls = self.collection_tag(event, _MAP), yaml.MappingNode
                node = cls(tag, [], event.start_mark, None, flow_style=event.flow_style)
                self.anchor(event, node)
                self.stack.append(_Open(node, event.anchor))
                continue
            elif kind is SequenceEndEvent or kind is MappingEndEvent:
                frame = self.stack.pop()
                node, size = frame.node, frame.size
                node.end_mark = event.end_mark
                if frame.anchor is not None:
                    self.sizes[frame.anchor] = size
            elif kind in (StreamStartEvent, StreamEndEvent, DocumentStartEvent, DocumentEndEvent):
                raise yaml.composer.ComposerError(None, None, "unexpected end of the document", event.start_mark)
            else:
                raise yaml.composer.ComposerError(None, None, f"unexpected {kind.__name__}", event.start_mark)
            if self.add(node, size):
                return node


@contextmanager
def bulk_allocation() -> Iterator[None]:
    """Pause the cyclic garbage collector while a large file becomes objects (none of them garbage).

    Each of its passes walks every live object: reading a 100k-node scene with it running
    takes three times as long.
    """
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if collecting:
            gc.enable()


def compose(text: str, file: str, max_depth: int = MAX_YAML_DEPTH) -> yaml.Node | None:
    """yaml.compose with bounded work: nesting past `max_depth`, alias cycles and alias bombs are ConfigErrors.

    Syntax errors are ConfigErrors too, worded by `syntax_error`; the node graph keeps the line
    marks every later error cites. Aliased nodes are shared, as yaml.compose shares them.
    """
    try:
        composer = _Composer(text, file, max_depth)  # the pure-Python reader checks characters here already
        try:
            with bulk_allocation():
                return composer.document()
        finally:
            composer.loader.dispose()
    except yaml.YAMLError as exc:
        raise syntax_error(exc, text, file) from None


_CONSTRUCT = yaml.constructor.SafeConstructor()


def construct_scalar(node: yaml.ScalarNode) -> Any:
    """The Python value of a scalar node of a plain tag (str, int, float, bool, null), not memoised."""
    # SafeConstructor.construct_object would keep every node it ever saw in its memo
    return _CONSTRUCT.yaml_constructors[node.tag](_CONSTRUCT, node)


def _convert(node: yaml.Node, path: tuple, lines: dict, file: str, done: dict) -> Any:
    """Plain Python data of a composed node; a repeated (aliased) node is converted once and shared."""
    if id(node) in done:
        return done[id(node)]
    lines.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        out: dict = {}
        first: dict[str, int] = {}
        for k, v in node.value:
            key, line = k.value, k.start_mark.line + 1
            if key in first:
                raise ConfigError(
                    f"duplicate key '{key}'", file, line, key_name(path + (key,)), f"first given on line {first[key]}"
                )
            first[key] = line
            lines[path + (key,)] = line
            out[key] = _convert(v, path + (key,), lines, file, done)
    elif isinstance(node, yaml.SequenceNode):
        out = [_convert(v, path + (i,), lines, file, done) for i, v in enumerate(node.value)]
    elif node.tag == _STR:
        out = node.value
    elif node.tag == _BOOL and node.value.lower() not in ("true", "false"):
        out = node.value  # YAML 1.2 booleans only: 'off'/'on'/'yes'/'no' stay strings (mode: off)
    else:
        out = construct_scalar(node)  # compose checked that the tag's constructor takes the value
    if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
        done[id(node)] = out
    return out


def syntax_error(exc: yaml.YAMLError, text: str, file: str) -> ConfigError:
    """A YAML syntax error as a one-line ConfigError: the file, the problem's line and column, what to check."""
    hint = "check indentation, colons, quotes and brackets around this line"
    if isinstance(exc, yaml.reader.ReaderError):  # a character YAML does not allow: no mark, a position
        char = exc.character
        code = ord(char) if isinstance(char, str) else int(char)
        said = f"character #x{code:04x} is not allowed ({exc.reason})"
        at = max(exc.position, 0)
        line, column = text.count("\n", 0, at) + 1, at - (text.rfind("\n", 0, at) + 1) + 1
        hint = "remove it; YAML text holds no control characters but tab, line feed and carriage return"
    elif isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        context = exc.context
        if context and exc.context_mark and mark and exc.context_mark.line != mark.line:
            context += f" (started on line {exc.context_mark.line + 1})"  # where the unclosed thing began
        said = "; ".join(s for s in (context, exc.problem) if s) or str(exc)
        line, column = (mark.line + 1, mark.column + 1) if mark else (None, None)
    else:
        said, line, column = str(exc), None, None
    said = " ".join(said.split())  # PyYAML's own text spans lines
    where = "" if column is None else f" at column {column}"
    return ConfigError(f"invalid YAML{where}: {said}", file, line, hint=hint)


def load_yaml_text(text: str, file: str, max_depth: int = MAX_NESTING) -> Located:
    """Parse YAML text; syntax errors become ConfigError with the line of the problem."""
    root = compose(text, file, max_depth)
    lines: dict[tuple, int] = {}
    data = _convert(root, (), lines, file, {}) if root is not None else {}
    return Located(data, lines, file)


def yaml_value(text: str, file: str, max_depth: int = MAX_NESTING):
    """The plain value of a short YAML text (None when it holds none), read as files are: bounded, YAML 1.2 booleans."""
    root = compose(text, file, max_depth)
    return None if root is None else _convert(root, (), {}, file, {})


def _size_text(n: int) -> str:
    """Bytes as '64 KiB' or '1 MiB' (bounds are powers of two)."""
    return f"{n // 2**20} MiB" if n >= 2**20 and n % 2**20 == 0 else f"{n // 1024} KiB" if n % 1024 == 0 else f"{n} B"


def resolved(path: Path) -> Path:
    """`path` absolute with its links resolved; as written (made absolute) when that fails.

    A symbolic-link loop makes Path.resolve raise (RuntimeError before Python 3.13): the path is
    kept so that reading it reports the loop (`file_problem`, `read_bytes`) with the file that named it.
    """
    try:
        return path.resolve()
    except (OSError, RuntimeError):
        return Path(os.path.abspath(path))


def kind_problem(mode: int) -> str | None:
    """What a file of stat mode `mode` is when it is no regular file ('is a FIFO, not a regular file'), else None."""
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a directory"
    if stat.S_ISFIFO(mode):
        return "is a FIFO, not a regular file"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "is a device, not a regular file"
    return "is not a regular file"


def file_problem(path: str | Path) -> str | None:
    """Why `path` cannot be read as a regular file (missing, a FIFO, a device, a folder, a NUL, a loop), or None.

    Checked with os.stat before any open: opening a FIFO blocks until a writer comes, forever.
    """
    text = os.fspath(path)
    if "\0" in text:
        return "contains a NUL character"
    if not text:
        return "is empty"
    try:
        mode = os.stat(text).st_mode
    except FileNotFoundError:
        return "not found"
    except OSError as exc:  # a symlink loop (ELOOP), a name too long, a folder without permission
        return exc.strerror.lower() if exc.strerror else str(exc)
    except ValueError as exc:
        return str(exc)
    problem = kind_problem(mode)
    if problem is None and not os.access(text, os.R_OK):
        return "is not readable (permission denied)"
    return problem


def read_bytes(
    path: str | Path,
    max_bytes: int | None = None,
    cite: str | Path | None = None,
    line: int | None = None,
    key: str | None = None,
    what: str = "file",
) -> bytes:
    """The bytes of the regular file `path`, at most `max_bytes`; anything else is a ConfigError.

    A FIFO, a device, a directory, a path holding a NUL character, a missing or unreadable file
    and a file beyond `max_bytes` are refused naming `path`, cited at `cite`/`line`/`key` where the
    path was named by another file. The file is opened without blocking, so a FIFO with no writer
    is refused instead of waiting for one.
    """
    p = Path(path)
    where = (p, None, None) if cite is None else (cite, line, key)

    def refuse(reason: str, hint: str | None = None) -> ConfigError:
        return ConfigError(reason, *where, hint)

    if "\0" in str(p):
        raise refuse(f"{what} path {str(p)!r} contains a NUL character", "check the path")
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise refuse(f"{what} not found: {p}", "check the path") from None
    except PermissionError:
        raise refuse(f"cannot read {what} {p}: permission denied", "check the file's permissions") from None
    except OSError as exc:
        raise refuse(f"cannot open {what} {p}: {exc.strerror or exc}", "check the path") from None
    try:
        info = os.fstat(fd)
        problem = kind_problem(info.st_mode)
        if problem is not None:
            raise refuse(f"{what} {p} {problem}", f"name a regular {what}")
        if max_bytes is not None and info.st_size > max_bytes:
            raise refuse(
                f"{what} {p} holds {info.st_size:,} bytes, more than {_size_text(max_bytes)}",
                f"{what}s are bounded to {_size_text(max_bytes)}",
            )
        chunks, total = [], 0
        while True:  # read to the end, not to st_size: the file may still be growing
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            total += len(chunk)
            if max_bytes is not None and total > max_bytes:
                raise refuse(f"{what} {p} holds more than {_size_text(max_bytes)}", f"{what}s are bounded to that")
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise refuse(f"cannot read {what} {p}: {exc.strerror or exc}") from None
    finally:
        os.close(fd)


def read_text(
    path: str | Path,
    cite: str | Path | None = None,
    line: int | None = None,
    key: str | None = None,
    max_bytes: int | None = None,
    what: str = "file",
) -> str:
    """A regular file's UTF-8 text (see `read_bytes`); other bytes are a ConfigError naming the byte and its line.

    The error cites `path` at the byte's line, or, where the file was named by another one
    (a material's method source), `cite` at `line` and `key`.
    """
    p = Path(path)
    data = read_bytes(p, max_bytes, cite, line, key, what)
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


MAX_CONFIG_BYTES = 1 << 20  # pipelines and material descriptions: a few KiB each


def load_yaml_file(path: str | Path, max_depth: int = MAX_NESTING, max_bytes: int | None = None) -> Located:
    """Read and parse a YAML file (missing, unreadable, too large or not a regular file → ConfigError)."""
    p = Path(path)
    return load_yaml_text(read_text(p, max_bytes=max_bytes), str(p), max_depth)
