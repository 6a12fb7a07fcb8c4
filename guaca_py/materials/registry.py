"""Find material descriptions by name: built-ins plus user search paths."""

from __future__ import annotations

from pathlib import Path

from ..errors import ConfigError
from ..resources import builtin_dir
from .description import MaterialDescription, load_material


class MaterialRegistry:
    """Loads each material description once; user directories shadow built-ins."""

    def __init__(self, search_paths: list[str | Path] | None = None):
        self.search_paths = [Path(p) for p in (search_paths or [])] + [builtin_dir("materials")]
        self._cache: dict[str, MaterialDescription] = {}

    def names(self) -> list[str]:
        """All material names visible on the search path."""
        return sorted({p.stem for d in self.search_paths if d.is_dir() for p in d.glob("*.json")})

    def get(self, name: str, where: tuple = (None, None)) -> MaterialDescription:
        """The description called `name` (a name on the search path or a path to a .json file)."""
        if name in self._cache:
            return self._cache[name]
        candidates = [Path(name)] if name.endswith(".json") else [d / f"{name}.json" for d in self.search_paths]
        for c in candidates:
            if c.is_file():
                self._cache[name] = load_material(c)
                return self._cache[name]
        raise ConfigError(
            f"unknown material '{name}'",
            where[0],
            where[1],
            "material.description",
            f"known materials: {', '.join(self.names())}",
        )
