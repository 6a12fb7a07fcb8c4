"""Find material descriptions by name: built-ins plus user search paths."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import ConfigError
from ..resources import builtin_dir
from ..yaml_source import MAX_CONFIG_BYTES, read_text
from .description import MaterialDescription, load_material, parse_json


def _declared_name(path: Path) -> str:
    """The file's "name" (what scenes look it up by), or its stem when it has none or cannot be read yet.

    Read as load_material reads it (regular files only, bounded size and nesting), so a FIFO or a
    bomb among the .json files cannot stall or crash listing the others.
    """
    try:
        data = parse_json(read_text(path, max_bytes=MAX_CONFIG_BYTES, what="material file"), path)
    except ConfigError:
        return path.stem  # load_material reports what is wrong when the material is used
    name = data.get("name") if isinstance(data, dict) else None
    return name if isinstance(name, str) and name else path.stem


class MaterialRegistry:
    """Loads each material description once; user directories shadow built-ins.

    A material is found by its "name" (the file stem when it has none). Two files that claim the
    same name in the user directories are an error naming both: which one a scene meant is unknowable.
    """

    def __init__(self, search_paths: list[str | Path] | None = None):
        user = [Path(p) for p in (search_paths or [])]
        for d in user:
            if not d.is_dir():
                raise ConfigError(
                    "material directory not found", d, key="material_paths", hint="give an existing directory"
                )
            try:  # glob() would silently find nothing in a folder it may not list
                os.listdir(d)
            except OSError as exc:
                raise ConfigError(
                    f"cannot list material directory: {exc.strerror or exc}",
                    d,
                    key="material_paths",
                    hint="check the folder's permissions",
                ) from None
        self.search_paths = user + [builtin_dir("materials")]
        self._user_count = len(user)
        self._cache: dict[str, MaterialDescription] = {}
        self._index: dict[str, Path] | None = None

    def _build_index(self) -> dict[str, Path]:
        index: dict[str, Path] = {}
        stems: dict[str, Path] = {}
        for i, d in enumerate(self.search_paths):
            if not d.is_dir():
                continue
            seen_here: dict[str, Path] = {}
            for p in sorted(d.glob("*.json")):
                name = _declared_name(p)
                first = index.get(name) or seen_here.get(name)
                if first is not None and (i < self._user_count or first.parent == d):
                    raise ConfigError(
                        f"material name '{name}' is defined twice: also in {first}",
                        p,
                        key="name",
                        hint='give each material a unique "name" (user directories may shadow built-ins only)',
                    )
                seen_here[name] = p
            for name, p in seen_here.items():
                index.setdefault(name, p)  # earlier directories shadow later ones (user over built-in)
                stems.setdefault(p.stem, p)
        for stem, p in stems.items():
            index.setdefault(stem, p)  # the file stem still finds a material whose name differs, unless taken
        return index

    def names(self) -> list[str]:
        """All material names visible on the search path."""
        if self._index is None:
            self._index = self._build_index()
        return sorted(self._index)

    def get(self, name: str, where: tuple = (None, None)) -> MaterialDescription:
        """The description called `name` (a name on the search path or a path to a .json file)."""
        if name in self._cache:
            return self._cache[name]
        if name.endswith(".json"):
            path = Path(name) if Path(name).exists() else None  # load_material refuses what is no regular file
        else:
            if self._index is None:
                self._index = self._build_index()
            path = self._index.get(name)
        if path is not None:
            self._cache[name] = load_material(path)
            return self._cache[name]
        raise ConfigError(
            f"unknown material '{name}'",
            where[0],
            where[1],
            "material.description",
            f"known materials: {', '.join(self.names())}",
        )
