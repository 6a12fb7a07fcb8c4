"""Model files as Scenes: glTF (.gltf/.glb) and every mesh format trimesh reads (OBJ/MTL, PLY, STL, ...).

`guaca_py.load` (scene/loader.py) sends every file that is not scene YAML here. Such files get
their own camera when it sees the model and the default light rig (scene/framing.py).
`as_scene` accepts a Scene or a trimesh scene wherever a Scene is expected.
"""

from __future__ import annotations

import weakref
from pathlib import Path

from ..yaml_source import file_problem
from .framing import camera_and_lights
from .gltf import GLTF_SUFFIXES, load_gltf
from .graph import Scene
from .mesh_io import check_file, file_error, load_checked
from .nodes import Node
from .trimesh_scene import nodes_from_trimesh

#: suffixes read as scene YAML; glTF by GLTF_SUFFIXES; anything trimesh reads as a mesh file
YAML_SUFFIXES = (".yaml", ".yml")
#: the mesh formats named in messages (trimesh reads more: .off, .dae, .3mf, ...)
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".dae", ".3mf")


def _is_gltf(p: Path) -> bool:
    """A .gltf/.glb suffix, or a binary glTF's magic bytes under another name."""
    if p.suffix.lower() in GLTF_SUFFIXES:
        return True
    if file_problem(p) is not None:
        return False  # never open a FIFO or device to sniff it; the reader refuses it by name
    try:
        with p.open("rb") as f:
            return f.read(4) == b"glTF"
    except OSError:
        return False


def model_kind(path: str | Path) -> str:
    """'yaml', 'gltf' or 'mesh': which reader `load` uses for the file at `path`."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in YAML_SUFFIXES:
        return "yaml"
    if _is_gltf(p):
        return "gltf"
    if suffix in MESH_SUFFIXES:
        return "mesh"
    if suffix:
        import trimesh

        if suffix.lstrip(".") in trimesh.available_formats():
            return "mesh"
    return "yaml"


def load_model(path: str | Path) -> Scene:
    """A glTF or mesh file (OBJ with its MTL materials, PLY, STL, ...) as a Scene with camera and lights."""
    p = Path(path)
    if model_kind(p) == "gltf":
        content = load_gltf(p)
        nodes, camera = content.nodes, content.camera
    else:
        nodes, camera = load_mesh_scene(p), None
    camera, lights = camera_and_lights(nodes, camera, p.name)
    return Scene(camera=camera, lights=lights, nodes=nodes, source=p.resolve())


def load_mesh_scene(path: str | Path) -> list[Node]:
    """A mesh file as root Nodes with the file's parts and materials (an OBJ's MTL: colours, map_Kd, dissolve)."""
    import trimesh  # imported lazily: scenes made only of primitives never pay for it

    p = Path(path)
    fail = file_error(p, None, None, None)
    check_file(p, fail, "mesh file")
    loaded = load_checked(p, trimesh, fail, force="scene")
    return nodes_from_trimesh(loaded, str(p), fail)


_CONVERTED: dict[int, tuple] = {}  # id -> (weak reference, trimesh content hash, Scene)


def as_scene(scene) -> Scene:
    """`scene` itself when it is a Scene; a trimesh.Scene or Trimesh converted (once per content); else TypeError.

    The conversion is kept per object while trimesh reports the same content hash, so a frame
    loop that passes the same trimesh scene converts (and uploads) it once.
    """
    if isinstance(scene, Scene):
        return scene
    if (type(scene).__module__ or "").startswith("trimesh"):
        key, state = id(scene), hash(scene)
        hit = _CONVERTED.get(key)
        if hit is not None and hit[0]() is scene and hit[1] == state:
            return hit[2]
        converted = Scene.from_trimesh(scene)
        _CONVERTED[key] = (weakref.ref(scene, lambda _ref, k=key: _CONVERTED.pop(k, None)), state, converted)
        return converted
    if isinstance(scene, (str, Path)):
        raise TypeError(f"render takes a Scene, got the path {str(scene)!r}: load it with guaca_py.load(path)")
    raise TypeError(
        f"render takes a guaca_py Scene, got {type(scene).__name__}: build one with guaca_py.load(path) "
        "or Scene.from_trimesh(trimesh_scene)"
    )
