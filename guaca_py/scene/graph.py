"""Scene graph data model: the Scene (camera, background, lights, node tree) and its parts.

The parts (Transform, MeshData, MaterialInstance, Node, Camera, Light) live in
`guaca_py.scene.nodes` and are re-exported here, where code has always imported them from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .nodes import (
    LIGHT_TYPES,
    MAX_CONE_DEG,
    MAX_RADIANCE,
    MAX_WORLD,
    Camera,
    Light,
    MaterialInstance,
    MeshData,
    Node,
    Transform,
    scene_bounds,
)

#: up to this many lights, a scene's check skips each light whose values passed before; beyond, one
#: vectorised test of all of them costs less than comparing each one's values (docs/decisions.md, 2026-12-07)
FEW_LIGHTS = 32


@dataclass
class Scene:
    """Everything a frame needs: camera, background, lights and the node tree."""

    camera: Camera = field(default_factory=Camera)
    background: tuple[float, float, float] = (0.1, 0.1, 0.1)
    lights: list[Light] = field(default_factory=list)
    nodes: list[Node] = field(default_factory=list)
    source: Path | None = None

    def __post_init__(self):
        self.check_background()

    def check_background(self) -> None:
        """Refuse a background that is not 3 finite numbers in [-MAX_RADIANCE, MAX_RADIANCE] (ConfigError)."""
        try:
            bg = np.asarray(self.background, dtype=np.float64)
        except (TypeError, ValueError):
            bg = None
        if bg is None or bg.shape != (3,) or not np.all(np.isfinite(bg)) or np.max(np.abs(bg)) > MAX_RADIANCE:
            raise ConfigError(
                f"must be 3 finite numbers of magnitude at most {MAX_RADIANCE:g}, got {self.background!r}",
                key="background",
                hint="linear RGB, e.g. (0.1, 0.1, 0.1)",
            )

    def check_structure(self) -> None:
        """Refuse parts of the wrong type: a camera that is not a Camera, a node that is not a Node... (ConfigError)."""
        if not isinstance(self.camera, Camera):
            raise ConfigError(f"must be a Camera, got {type(self.camera).__name__}", key="camera")
        for key, kind in (("lights", Light), ("nodes", Node)):
            items = getattr(self, key)
            if not isinstance(items, list):
                raise ConfigError(f"must be a list of {kind.__name__}s, got {type(items).__name__}", key=key)
            if key == "nodes":
                _check_tree(items)
                continue
            for i, item in enumerate(items):
                if not isinstance(item, kind):
                    raise ConfigError(f"must be a {kind.__name__}, got {type(item).__name__}", key=f"{key}[{i}]")

    def check(self) -> None:
        """Refuse a camera, lights or background no frame can be drawn with (each names its field, and the file)."""
        try:
            if not isinstance(self.camera, Camera) or not isinstance(self.lights, list):
                self.check_structure()
            if not all(isinstance(light, Light) for light in self.lights):
                self.check_structure()
            self.camera.check()
            self.check_background()
            # a few lights: those whose values passed before are not looked at again (the vectorised test has a
            # fixed cost); many: all in one vectorised test. The per-light check runs only to name a culprit.
            few = len(self.lights) <= FEW_LIGHTS
            pending = [light for light in self.lights if not light.checked_before()] if few else self.lights
            if pending and not _lights_plausible(pending):
                for i, light in enumerate(self.lights):
                    light.check(f"lights[{i}]")
            if few:
                for light in pending:
                    light.mark_checked()
        except ConfigError as exc:
            if self.source is None or exc.file is not None:
                raise
            raise ConfigError(exc.reason, self.source, None, exc.key, exc.hint) from None

    def walk(self):
        """Yield (node, world matrix) for every node in the scene, in document order."""
        for n in self.nodes:
            yield from n.walk()

    @classmethod
    def from_trimesh(cls, scene) -> Scene:
        """A trimesh.Scene (or one trimesh.Trimesh) as a Scene, its node graph kept.

        Nodes keep their parent/child structure and 4x4 local matrices; the scene's camera (with
        its world transform) becomes the camera, else one framing the model; PBR, OBJ/MTL and
        colour materials keep their colours, textures and alpha (scene/trimesh_scene.py has the
        table). Lights: the default rig (a key and a fill directional light and an ambient term).
        """
        from .framing import camera_and_lights
        from .trimesh_scene import trimesh_contents

        nodes, camera = trimesh_contents(scene)
        camera, lights = camera_and_lights(nodes, camera, "trimesh scene")
        return cls(camera=camera, lights=lights, nodes=nodes)


#: deepest node tree a frame walks: scene files nest 100 levels and glTF files 256 below them; the draw
#: list recurses about one Python frame a level, and Python stops at 1000
MAX_TREE_DEPTH = 500


def _short(path: str) -> str:
    """A key path of many levels as its first and last parts: 'nodes[0].(...498 levels...).children[0]'."""
    parts = path.split(".")
    return path if len(parts) <= 8 else f"{parts[0]}.(...{len(parts) - 2} levels...).{parts[-1]}"


def _check_parts(node, where: str) -> None:
    """A node's own parts of the right types (ConfigError naming their path), not its children."""
    if not isinstance(node, Node):
        raise ConfigError(f"must be a Node, got {type(node).__name__}", key=_short(where))
    for attr, kind, optional in (
        ("transform", Transform, False),
        ("mesh", MeshData, True),
        ("material", MaterialInstance, True),
    ):
        value = getattr(node, attr)
        if not isinstance(value, kind) and not (optional and value is None):
            raise ConfigError(f"must be a {kind.__name__}, got {type(value).__name__}", key=_short(f"{where}.{attr}"))
    mat = node.material
    if mat is not None and not isinstance(mat.description, str):
        raise ConfigError(
            f"must be a material name, got {type(mat.description).__name__}",
            key=_short(f"{where}.material.description"),
        )
    if mat is not None and not (isinstance(mat.uniforms, dict) and all(isinstance(k, str) for k in mat.uniforms)):
        raise ConfigError(
            f"must be a dict of uniform names to values, got {type(mat.uniforms).__name__}",
            key=_short(f"{where}.material.uniforms"),
        )
    if not isinstance(node.children, list):
        raise ConfigError(
            f"must be a list of Nodes, got {type(node.children).__name__}", key=_short(f"{where}.children")
        )


def _check_tree(nodes: list, where: str = "nodes") -> None:
    """Every node's parts, no node below itself, no path deeper than MAX_TREE_DEPTH; walked without recursion.

    A node may appear in several places (each is drawn); its subtree is checked once, its height kept.
    """
    open_, height = set(), {}  # nodes on the current path; subtree heights of finished nodes
    stack = [(node, f"{where}[{i}]", 1, False) for i, node in reversed(list(enumerate(nodes)))]
    while stack:
        node, path, depth, leaving = stack.pop()
        if leaving:
            open_.discard(id(node))
            height[id(node)] = 1 + max((height.get(id(c), 0) for c in node.children), default=0)
            continue
        if id(node) in open_:
            raise ConfigError(
                "is a node that contains it (a cycle in the node tree)",
                key=_short(path),
                hint="a node may appear in several places, but never below itself",
            )
        if id(node) not in height:
            _check_parts(node, path)
        if depth - 1 + height.get(id(node), 1) > MAX_TREE_DEPTH:
            raise ConfigError(
                f"nodes nested deeper than {MAX_TREE_DEPTH} levels", key=_short(path), hint="flatten the hierarchy"
            )
        if id(node) in height:
            continue
        open_.add(id(node))
        stack.append((node, path, depth, True))
        stack.extend(
            (c, f"{path}.children[{i}]", depth + 1, False) for i, c in reversed(list(enumerate(node.children)))
        )


def _lights_plausible(lights: list[Light]) -> bool:
    """True when every light passes Light.check: one vectorised test per field (4096 lights in ~10 ms)."""
    if not lights:
        return True
    try:
        num = np.array(
            [(l.intensity, l.radius, l.inner_angle_deg, l.outer_angle_deg) for l in lights], dtype=np.float64
        )
        vec = np.array([(l.color, l.position, l.direction) for l in lights], dtype=np.float64)
    except (TypeError, ValueError):  # a string, or a vector of the wrong length
        return False
    if vec.shape != (len(lights), 3, 3) or not (np.all(np.isfinite(num)) and np.all(np.isfinite(vec))):
        return False
    if any(l.type not in LIGHT_TYPES or isinstance(l.intensity, bool) for l in lights):
        return False
    if np.any(np.max(np.abs(vec[:, 0]), axis=1) * np.abs(num[:, 0]) > MAX_RADIANCE):
        return False
    aimed = np.array([l.type in ("spot", "directional") for l in lights])
    if np.any(aimed & np.all(vec[:, 2] == 0.0, axis=1)):
        return False
    if np.any(num[:, 0] < 0.0) or np.any(vec[:, 0] < 0.0):  # negative intensity or colour
        return False
    ranged = np.array([l.type in ("point", "spot") for l in lights])
    spot = np.array([l.type == "spot" for l in lights])
    inner, outer = num[:, 2], num[:, 3]
    cone = (outer > 0.0) & (outer <= MAX_CONE_DEG) & (inner >= 0.0) & (inner <= outer)
    return not (np.any(ranged & ~(num[:, 1] > 0.0)) or np.any(spot & ~cone))


__all__ = [
    "LIGHT_TYPES",
    "MAX_TREE_DEPTH",
    "MAX_RADIANCE",
    "MAX_WORLD",
    "Camera",
    "Light",
    "MaterialInstance",
    "MeshData",
    "Node",
    "Scene",
    "Transform",
    "scene_bounds",
]
