"""Scene files: YAML text to a Scene, where every error names file, line and key; `load` for any file.

`load(path)` (`guaca_py.load`) reads scene YAML here and hands glTF and mesh files to
scene/files.py; `load_scene` is the same function under its older name.

Scene file format
-----------------

A scene file is a YAML mapping with four optional top-level keys::

    camera:                       # defaults shown
      position: [0, 1, 5]
      target: [0, 0, 0]
      up: [0, 1, 0]
      fov_y: 60                   # vertical field of view in degrees, 0 < fov_y < 180
      near: 0.1                   # 0 < near < far
      far: 100
    background: [0.1, 0.1, 0.1]   # linear RGB clear colour
    lights:
      - {type: point, position: [2, 3, 2], color: [1, 1, 1], intensity: 20, radius: 10}
      - {type: spot, position: [0, 4, 0], direction: [0, -1, 0], color: [1, 0.9, 0.8],
         intensity: 30, radius: 12, inner_angle_deg: 15, outer_angle_deg: 25}
      - {type: directional, direction: [-1, -1, -0.5], color: [0.4, 0.4, 0.5], intensity: 1}
      - {type: ambient, color: [0.2, 0.2, 0.25], intensity: 1}
    nodes:
      - name: pane
        mesh: {primitive: quad, size: [2, 2]}       # or {file: models/bunny.obj}
        transform: {translation: [0, 0, 0], rotation_deg: [0, 30, 0], scale: [1, 1, 1]}
        material: {description: unlit, uniforms: {color: [1, 0, 0], alpha: 0.5}}
        children: []                                # nodes, same format, relative to this one

Lights
    ``type`` is ``point`` (the default), ``spot``, ``directional`` or ``ambient`` (light from
    every direction: a surface reflects color * intensity * its albedo). Every light takes
    ``color`` (RGB, >= 0, default [1, 1, 1]) and ``intensity`` (>= 0, default 1). Point and
    spot lights take ``position`` and ``radius`` (range, > 0, default 10); spot and
    directional lights take ``direction`` (where the light travels; normalised on load);
    spot lights take the cone half-angles ``inner_angle_deg`` <= ``outer_angle_deg`` < 90
    (defaults 20 and 30). A key that does not apply to the light's type is an error.

Nodes
    All node keys are optional; a node without ``mesh`` is a group. ``name`` defaults to
    the node's key path (e.g. ``nodes[1].children[0]``). ``transform`` applies scale, then
    rotation about X, then Y, then Z (degrees), then translation; ``scale`` may be one
    number. Children inherit their parent's transform.

Meshes
    ``{primitive: KIND, ...params}`` builds a procedural mesh: ``quad`` (size [w, h], XY plane
    facing +Z), ``plane`` (size [w, d], subdivisions; XZ plane facing +Y), ``box``
    (size [x, y, z]), ``sphere`` (radius, segments, rings), ``cylinder`` (radius, height,
    segments, capped; along Y). ``{file: PATH}`` loads OBJ, PLY or STL through trimesh.
    Identical meshes are loaded once and shared between nodes. ``{file: x.glb}`` (or .gltf)
    keeps the file's node hierarchy as the node's first children, with the file's materials
    (scene/gltf.py); a ``material`` on the node replaces them all.

Materials
    ``{description: NAME, uniforms: {...}}`` or just ``NAME``. Names and uniforms are checked
    by the renderer, not here. Uniform numbers become floats, lists become tuples of floats,
    and strings ending in an image suffix (.png, .jpg, .jpeg, .bmp, .gif, .tga, .tif, .tiff,
    .webp) are texture paths, stored as absolute paths.

Relative paths (mesh files, textures) resolve against the scene file's directory.
Each MaterialInstance gets ``source = (file, line)`` (line of its ``material`` key) and
``uniform_lines = {name: line}``; each Node gets ``source = (file, line)``, so later
errors can cite the scene file.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import ArgumentError, ConfigError
from ..numeric import Range, number_hint
from ..yaml_source import compose, file_problem, nesting_error, read_text, resolved
from .graph import LIGHT_TYPES, MAX_WORLD, Camera, Light, MaterialInstance, MeshData, Node, Scene, Transform
from .mesh_io import load_mesh_file
from .nodes import MAX_CONE_DEG, _scaled_unit
from .primitives import PRIMITIVE_KINDS, make_primitive
from .texture import TEXTURE_SUFFIXES

TOP_KEYS = ("camera", "background", "lights", "nodes")
CAMERA_KEYS = ("position", "target", "up", "fov_y", "near", "far")
NODE_KEYS = ("name", "mesh", "transform", "material", "children")
TRANSFORM_KEYS = ("translation", "rotation_deg", "scale")
MATERIAL_KEYS = ("description", "uniforms")
LIGHT_KEYS = {
    "point": ("type", "position", "color", "intensity", "radius"),
    "spot": ("type", "position", "direction", "color", "intensity", "radius", "inner_angle_deg", "outer_angle_deg"),
    "directional": ("type", "direction", "color", "intensity"),
    "ambient": ("type", "color", "intensity"),
}
MAX_SCENE_DEPTH = 100  # levels of children; the loader, the graph walk and the draw list recurse per level
DEPTH_BITS = 24  # the G-buffer depth and gl_FragCoord.z both resolve 2**-24 steps near 1

_TAG = "tag:yaml.org,2002:"


@dataclass(frozen=True)
class _At:
    """A YAML value with its key path and the line to cite (its key's line for mapping values)."""

    node: yaml.Node
    key: str
    line: int


def _child_key(parent: str, name: str | int) -> str:
    """Join key paths: ('nodes', 2) -> 'nodes[2]', ('nodes[2]', 'mesh') -> 'nodes[2].mesh'."""
    if isinstance(name, int):
        return f"{parent}[{name}]"
    return f"{parent}.{name}" if parent else name


def _kind(node: yaml.Node) -> str:
    """Human word for a YAML node's type, for 'expected X, got Y' messages."""
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return f"a list of {len(node.value)}"
    short = node.tag.rsplit(":", 1)[-1]
    return "nothing (null)" if short == "null" else f"{short} {node.value!r}"


class _Reader:
    """Turns composed YAML nodes into scene objects, keeping file/line for every error."""

    def __init__(self, file: str, base_dir: Path):
        self.file, self.base_dir = file, base_dir
        self._construct = yaml.constructor.SafeConstructor()
        self._meshes: dict[Any, MeshData] = {}  # shared so identical meshes upload once

    # ---- generic helpers ---------------------------------------------------------------

    def error(self, at: _At, reason: str, hint: str | None = None) -> ConfigError:
        """ConfigError citing this scene file, the value's line and key path."""
        return ConfigError(reason, self.file, at.line, at.key or None, hint)

    def mapping(self, at: _At, allowed: tuple[str, ...], what: str) -> dict[str, _At]:
        """Entries of a mapping; unknown or duplicate keys are errors at the key's line."""
        if not isinstance(at.node, yaml.MappingNode):
            raise self.error(
                at, f"expected a mapping for {what}, got {_kind(at.node)}", f"valid keys: {', '.join(allowed)}"
            )
        out: dict[str, _At] = {}
        for k, v in at.node.value:
            line = k.start_mark.line + 1
            if not isinstance(k, yaml.ScalarNode):
                raise self.error(_At(k, at.key, line), f"keys in {what} must be plain names")
            name = k.value
            entry = _At(v, _child_key(at.key, name), line)
            if name not in allowed:
                raise self.error(entry, f"unknown key {name!r} in {what}", f"valid keys: {', '.join(allowed)}")
            if name in out:
                raise self.error(entry, f"duplicate key {name!r} in {what}", f"first given on line {out[name].line}")
            out[name] = entry
        return out

    def items(self, at: _At, what: str) -> list[_At]:
        """Items of a sequence, each citing its own line."""
        if not isinstance(at.node, yaml.SequenceNode):
            raise self.error(
                at,
                f"expected a list of {what}, got {_kind(at.node)}",
                f"write {at.key.rsplit('.', 1)[-1]}: [] or a '- ' item per entry",
            )
        return [_At(v, _child_key(at.key, i), v.start_mark.line + 1) for i, v in enumerate(at.node.value)]

    def plain(self, node: yaml.Node) -> Any:
        """Python value of a node (lists, dicts, numbers, strings) without file context."""
        return self._construct.construct_object(node, deep=True)

    def number(self, at: _At, lo: float | None = None, hi: float | None = None, lo_open: bool = False) -> float:
        """A finite number, optionally within [lo, hi] (or (lo, hi] with lo_open)."""
        node = at.node
        if not (isinstance(node, yaml.ScalarNode) and node.tag in (_TAG + "int", _TAG + "float")):
            scalar = node.value if isinstance(node, yaml.ScalarNode) else None
            raise self.error(at, f"expected a number, got {_kind(node)}", number_hint(scalar))
        value = float(self.plain(node))
        if not math.isfinite(value):
            raise self.error(at, f"expected a finite number, got {node.value}")
        bounds = Range(lo, hi, lo_open)
        if not bounds.contains(value):
            raise self.error(at, f"{value:g} is out of range {bounds}")
        return value

    def vector(self, at: _At, n: int = 3, non_negative: bool = False) -> tuple[float, ...]:
        """A list of exactly n finite numbers."""
        example = "[1, 1, 1]" if n == 3 else str([0] * n)
        if not isinstance(at.node, yaml.SequenceNode):
            raise self.error(at, f"expected a list of {n} numbers, got {_kind(at.node)}", f"e.g. {example}")
        if len(at.node.value) != n:
            raise self.error(at, f"expected {n} numbers, got {len(at.node.value)}", f"e.g. {example}")
        values = tuple(
            self.number(_At(v, _child_key(at.key, i), v.start_mark.line + 1), lo=0.0 if non_negative else None)
            for i, v in enumerate(at.node.value)
        )
        return values

    def direction(self, at: _At) -> tuple[float, float, float]:
        """A non-zero 3-vector, normalised."""
        v = np.asarray(self.vector(at), dtype=np.float64)
        unit = _scaled_unit(v) if float(np.max(np.abs(v))) >= 1e-9 else None  # scaled first: 1e300 does not overflow
        if unit is None:
            raise self.error(at, "direction must not be zero", "e.g. [0, -1, 0] points straight down")
        return tuple(float(x) for x in unit)

    def string(self, at: _At) -> str:
        """A scalar's text (names may look like numbers; keep what was written)."""
        if not isinstance(at.node, yaml.ScalarNode) or at.node.tag == _TAG + "null" or at.node.value == "":
            raise self.error(at, f"expected text, got {_kind(at.node)}")
        return at.node.value

    def path(self, at: _At) -> Path:
        """A file path resolved against the scene file's directory."""
        text = self.string(at)
        try:
            p = Path(text).expanduser()
        except RuntimeError:  # '~nobody/x': no such user's home; the path is read as written
            p = Path(text)
        return resolved(p if p.is_absolute() else self.base_dir / p)

    # ---- scene parts ---------------------------------------------------------------------

    def scene(self, root: yaml.Node | None) -> Scene:
        """The whole document."""
        scene = Scene()
        if root is None:  # empty file: an empty default scene
            return scene
        top = self.mapping(_At(root, "", root.start_mark.line + 1), TOP_KEYS, "the scene")
        if "camera" in top:
            scene.camera = self.camera(top["camera"])
        if "background" in top:
            scene.background = self.vector(top["background"], non_negative=True)
        if "lights" in top:
            scene.lights = [self.light(at) for at in self.items(top["lights"], "lights")]
        if "nodes" in top:
            scene.nodes = [self.node(at) for at in self.items(top["nodes"], "nodes")]
        return scene

    def camera(self, at: _At) -> Camera:
        """camera: {position, target, up, fov_y, near, far}."""
        f = self.mapping(at, CAMERA_KEYS, "camera")
        cam = Camera()
        for key in ("position", "target", "up"):
            if key in f:
                setattr(cam, key, self.vector(f[key]))
        if "fov_y" in f:
            cam.fov_y = self.number(f["fov_y"], 0.0, 179.9, lo_open=True)
        if "near" in f:
            cam.near = self.number(f["near"], 0.0, lo_open=True)
        if "far" in f:
            cam.far = self.number(f["far"], 0.0, lo_open=True)
        if cam.far <= cam.near:
            raise self.error(
                f.get("far", f.get("near", at)), f"far ({cam.far:g}) must be greater than near ({cam.near:g})"
            )
        if cam.far / cam.near > 2.0**DEPTH_BITS:
            # one depth step spans z**2 / (near * 2**24): beyond near * 2**24 a single step covers
            # the whole distance, surfaces collapse onto the far plane and vanish
            raise self.error(
                f.get("near", f.get("far", at)),
                f"far / near = {cam.far / cam.near:.3g} exhausts the {DEPTH_BITS}-bit depth buffer "
                f"(surfaces beyond {cam.near * 2.0**DEPTH_BITS:.3g} units collapse onto the far plane)",
                f"raise near to at least {cam.far / 2.0**DEPTH_BITS:.3g}, better far / 1e5 = {cam.far / 1e5:.3g}",
            )
        view = np.subtract(cam.target, cam.position)
        if np.linalg.norm(view) < 1e-9:
            raise self.error(f.get("target", at), "camera target equals its position", "move the target")
        if np.linalg.norm(np.cross(view, cam.up)) < 1e-9 * np.linalg.norm(view) * max(np.linalg.norm(cam.up), 1e-9):
            raise self.error(
                f.get("up", at),
                "camera 'up' is zero or parallel to the view direction",
                "pick an up vector not along target - position, e.g. [0, 0, -1] when looking down",
            )
        return cam

    def light(self, at: _At) -> Light:
        """One entry of lights: its keys depend on its type."""
        everything = tuple(dict.fromkeys(k for keys in LIGHT_KEYS.values() for k in keys))
        f = self.mapping(at, everything, "a light")
        kind = self.string(f["type"]) if "type" in f else "point"
        if kind not in LIGHT_TYPES:
            raise self.error(f["type"], f"unknown light type {kind!r}", f"valid types: {', '.join(LIGHT_TYPES)}")
        for name, entry in f.items():
            if name not in LIGHT_KEYS[kind]:
                raise self.error(
                    entry,
                    f"{name!r} does not apply to {kind} lights",
                    f"valid keys for {kind}: {', '.join(LIGHT_KEYS[kind])}",
                )
        light = Light(type=kind)
        if "position" in f:
            light.position = self.vector(f["position"])
        if "direction" in f:
            light.direction = self.direction(f["direction"])
        if "color" in f:
            light.color = self.vector(f["color"], non_negative=True)
        if "intensity" in f:
            light.intensity = self.number(f["intensity"], 0.0)
        if "radius" in f:
            light.radius = self.number(f["radius"], 0.0, lo_open=True)
        if "inner_angle_deg" in f:
            light.inner_angle_deg = self.number(f["inner_angle_deg"], 0.0, MAX_CONE_DEG)
        if "outer_angle_deg" in f:
            light.outer_angle_deg = self.number(f["outer_angle_deg"], 0.0, MAX_CONE_DEG, lo_open=True)
        if kind == "spot" and light.inner_angle_deg > light.outer_angle_deg:
            raise self.error(
                f.get("inner_angle_deg", f.get("outer_angle_deg", at)),
                f"inner_angle_deg ({light.inner_angle_deg:g}) exceeds outer_angle_deg ({light.outer_angle_deg:g})",
                "the inner cone must fit inside the outer one",
            )
        return light

    def node(self, at: _At, open_: tuple = ()) -> Node:
        """One node and, recursively, its children (`open_`: the YAML nodes of its ancestors)."""
        if any(n is at.node for n in open_):
            raise nesting_error(at.node, self.file, at.key, cycle=True)
        if len(open_) >= MAX_SCENE_DEPTH:
            parts = at.key.split(".")
            key = f"{parts[0]}.(...{len(parts) - 2} levels...).{parts[-1]}"
            raise ConfigError(
                f"nodes nested deeper than {MAX_SCENE_DEPTH} levels",
                self.file,
                at.line,
                key,
                "flatten the hierarchy (bake transforms) or split the scene",
            )
        open_ = open_ + (at.node,)
        f = self.mapping(at, NODE_KEYS, "a node")
        node = Node(name=self.string(f["name"]) if "name" in f else at.key)
        if "transform" in f:
            node.transform = self.transform(f["transform"])
        gltf = self.gltf(f["mesh"]) if "mesh" in f else None
        if "mesh" in f and gltf is None:
            node.mesh = self.mesh(f["mesh"])
        if "material" in f:
            node.material = self.material(f["material"])
        if gltf is not None:  # the file's own hierarchy becomes this node's first children
            node.children = gltf.nodes
            for sub, _ in node.walk():
                if sub.mesh is not None and node.material is not None:
                    sub.material = node.material  # a material given in the scene overrides the file's
            node.material = None
        if "children" in f:
            node.children = node.children + [self.node(c, open_) for c in self.items(f["children"], "child nodes")]
        node.source = (self.file, at.line)  # for renderer errors about this node
        return node

    def transform(self, at: _At) -> Transform:
        """transform: {translation, rotation_deg, scale (vector or one number)}."""
        f = self.mapping(at, TRANSFORM_KEYS, "a transform")
        t = Transform()
        if "translation" in f:
            t.translation = self.vector(f["translation"])
        if "rotation_deg" in f:
            t.rotation_deg = self.vector(f["rotation_deg"])
        if "scale" in f:
            s = f["scale"]
            scale = (self.number(s),) * 3 if isinstance(s.node, yaml.ScalarNode) else self.vector(s)
            if any(abs(c) > MAX_WORLD for c in scale):
                raise self.error(
                    s,
                    f"scale {max(abs(c) for c in scale):.3g} exceeds {MAX_WORLD:.0e}: float32 positions and "
                    "the rasterizer's clipper cannot hold such coordinates (objects vanish)",
                    "model in units that keep coordinates within 1e7 (e.g. kilometres instead of metres)",
                )
            if any(abs(c) < 1e-12 for c in scale):
                raise self.error(
                    s,
                    "scale components must be non-zero",
                    "a zero scale flattens the object and breaks its normals; hide it another way",
                )
            t.scale = scale
        return t

    def gltf(self, at: _At):
        """GltfContent for mesh: {file: *.glb|*.gltf}, else None (other meshes are read by mesh())."""
        from .gltf import GLTF_SUFFIXES, load_gltf

        if not isinstance(at.node, yaml.MappingNode):
            return None
        entries = {k.value: v for k, v in at.node.value if isinstance(k, yaml.ScalarNode)}
        if set(entries) != {"file"} or not str(entries["file"].value).lower().endswith(GLTF_SUFFIXES):
            return None
        f = self.mapping(at, ("file",), "a file mesh")
        return load_gltf(self.path(f["file"]), self.file, f["file"].line, f["file"].key)

    def mesh(self, at: _At) -> MeshData:
        """mesh: {primitive: kind, params...} or {file: path}."""
        if not isinstance(at.node, yaml.MappingNode):
            raise self.error(
                at,
                f"expected a mapping for mesh, got {_kind(at.node)}",
                "write {primitive: box, size: [1, 1, 1]} or {file: model.obj}",
            )
        keys = [k.value for k, _ in at.node.value]
        if ("primitive" in keys) == ("file" in keys):
            raise self.error(
                at,
                "a mesh needs exactly one of 'primitive' or 'file'",
                f"primitives: {', '.join(PRIMITIVE_KINDS)}; files: .obj .ply .stl .glb .gltf",
            )
        if "file" in keys:
            f = self.mapping(at, ("file",), "a file mesh")
            path = self.path(f["file"])
            if path not in self._meshes:
                self._meshes[path] = load_mesh_file(path, self.file, f["file"].line, f["file"].key)
            return self._meshes[path]
        # Primitive parameters are validated by make_primitive; only their lines are needed here.
        entries = {k.value: _At(v, _child_key(at.key, k.value), k.start_mark.line + 1) for k, v in at.node.value}
        kind_at = entries.pop("primitive")
        kind = self.string(kind_at)
        params = {name: self.plain(e.node) for name, e in entries.items()}
        try:
            cache_key = (kind, repr(sorted(params.items())))
            if cache_key not in self._meshes:
                self._meshes[cache_key] = make_primitive(kind, **params)
            return self._meshes[cache_key]
        except ConfigError as exc:
            where = kind_at if exc.key == "primitive" else entries.get(exc.key, at)
            raise self.error(where, exc.reason, exc.hint) from None

    def material(self, at: _At) -> MaterialInstance:
        """material: {description, uniforms} or a bare description name."""
        if isinstance(at.node, yaml.ScalarNode):
            inst = MaterialInstance(description=self.string(at))
            uniform_lines: dict[str, int] = {}
        else:
            f = self.mapping(at, MATERIAL_KEYS, "a material")
            if "description" not in f:
                raise self.error(
                    at,
                    "material needs a 'description' (the material name)",
                    "e.g. material: {description: pbr, uniforms: {albedo: [1, 0, 0]}}",
                )
            inst = MaterialInstance(description=self.string(f["description"]))
            uniform_lines = {}
            if "uniforms" in f:
                u = f["uniforms"]
                if not isinstance(u.node, yaml.MappingNode):
                    raise self.error(
                        u, f"expected a mapping for uniforms, got {_kind(u.node)}", "e.g. uniforms: {alpha: 0.5}"
                    )
                names = tuple(k.value for k, _ in u.node.value)
                for name, entry in self.mapping(u, names, "uniforms").items():
                    inst.uniforms[name] = self.uniform(entry)
                    uniform_lines[name] = entry.line
        inst.source = (self.file, at.line)  # the renderer cites this when validating
        inst.uniform_lines = uniform_lines
        return inst

    def uniform(self, at: _At) -> Any:
        """A uniform value: bool, float, tuple of floats (nested for matrices) or string/texture."""
        node = at.node
        if isinstance(node, yaml.SequenceNode):
            if not node.value:
                raise self.error(at, "uniform value is an empty list")
            return tuple(
                self.uniform(_At(v, _child_key(at.key, i), v.start_mark.line + 1)) for i, v in enumerate(node.value)
            )
        if isinstance(node, yaml.MappingNode) or node.tag == _TAG + "null":
            raise self.error(
                at,
                f"unsupported uniform value: {_kind(node)}",
                "use a number, true/false, a list of numbers or a texture path",
            )
        if node.tag == _TAG + "bool":
            return bool(self.plain(node))
        if node.tag in (_TAG + "int", _TAG + "float"):
            return self.number(at)
        text = node.value
        if text.lower().endswith(TEXTURE_SUFFIXES):
            path = self.path(at)
            problem = file_problem(path)  # a FIFO or a device said so, not "not found" (and never opened)
            if problem is not None:
                raise self.error(
                    at,
                    f"texture file {problem}: {path}",
                    "relative paths are resolved against the scene file's directory"
                    if problem == "not found"
                    else "name a regular image file",
                )
            return str(path)
        return text


def load_scene_text(text: str, source_name: str = "<string>", base_dir: str | Path | None = None) -> Scene:
    """Parse scene YAML; source_name is cited in errors, relative paths resolve against base_dir."""
    root = compose(text, source_name)  # a syntax error is a ConfigError at its line and column
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    return _Reader(source_name, base.resolve()).scene(root)


def load(path: str | Path) -> Scene:
    """Scene YAML, a glTF file (.gltf/.glb) or a mesh file (OBJ/MTL, PLY, STL, ...) as a Scene.

    Scene files: relative paths inside them resolve against their directory. Model files are
    read by scene/files.py: their own camera (or one framing the model) and the default lights.
    """
    from .files import load_model, model_kind

    if not isinstance(path, (str, os.PathLike)) or isinstance(os.fspath(path), bytes):
        raise ArgumentError(f"load takes a file path (str or Path), got {type(path).__name__}", key="path")
    p = Path(path)
    problem = file_problem(p)  # a FIFO, a device or a folder is named as what it is, and never opened
    if problem is not None:
        raise ConfigError(
            f"scene file {problem}: {p}", p, hint="check the path" if problem == "not found" else "name a regular file"
        )
    if model_kind(p) != "yaml":
        return load_model(p)
    scene = load_scene_text(read_text(p), str(p), p.parent)
    scene.source = p.resolve()
    return scene


#: the scene-file reader's first name: the same function, so a .glb given to it is read as glTF
load_scene = load


def demo_scene() -> Scene:
    """The built-in demo: ground, opaque objects, intersecting transparent objects, coloured lights."""
    res = resources.files("guaca_py.data").joinpath("demo_scene.yaml")
    with resources.as_file(res) as p:
        return load_scene(p)
