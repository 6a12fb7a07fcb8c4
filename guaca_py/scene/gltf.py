"""glTF 2.0 (.glb / .gltf) files as scene nodes: node hierarchy, meshes, PBR materials, camera.

trimesh parses the file; scene/trimesh_scene.py keeps its node graph (local matrices,
parent/child order) instead of flattening it and maps each glTF material onto the built-in
`gltf_opaque` / `gltf_mask` / `gltf_blend` materials (its module docstring has the table).
This module adds what trimesh drops: the factors as the file wrote them (trimesh stores 8-bit
values; the file's floats are used where the material has a unique name) and the camera's
world transform (trimesh keeps only the camera node's local matrix, so a camera under a
scaled or moved parent would look from the wrong place).
"""

from __future__ import annotations

import base64
import json
import math
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pyglm import glm

from ..errors import ConfigError
from .mesh_io import MESH_FORMATS_HINT, check_file, file_error
from .nodes import Camera, MeshData, Node, scene_bounds
from .texture import decode_image
from .trimesh_scene import camera_from_matrix, far_past, nodes_from_trimesh, warn_scene

GLTF_SUFFIXES = (".glb", ".gltf")


@dataclass
class GltfContent:
    """What a glTF file holds: root nodes (with children), its first camera if any."""

    nodes: list[Node]
    camera: Camera | None = None
    meshes: dict[str, MeshData] = field(default_factory=dict)


#: the deepest node chain read (a deeper or cyclic graph is refused, not recursed into)
MAX_NODE_DEPTH = 256
#: glTF extensions a file may list in extensionsRequired (the spec says to refuse any other)
SUPPORTED_REQUIRED: frozenset[str] = frozenset()
_DEPTH_BITS = 24  # the depth buffer's bits: far / near beyond 2**24 collapses surfaces (as for YAML cameras)


def _parse_document(data: bytes) -> tuple[dict, bytes | None]:
    """(JSON document, GLB binary chunk or None); ValueError saying what is wrong with the container."""
    if data[:4] != b"glTF":
        doc = json.loads(data)
        if not isinstance(doc, dict):
            raise ValueError("the JSON document is not an object")
        return doc, None
    if len(data) < 20:
        raise ValueError(f"the binary glTF is truncated ({len(data)} bytes, a header needs 20)")
    _magic, _version, total = struct.unpack_from("<III", data, 0)
    if total > len(data):
        raise ValueError(f"the binary glTF header claims {total} bytes but the file has {len(data)}")
    chunks, at = [], 12
    while at + 8 <= total:
        length, kind = struct.unpack_from("<II", data, at)
        if at + 8 + length > total:
            raise ValueError(f"a chunk at byte {at} claims {length} bytes, past the end of the file ({total} bytes)")
        chunks.append((kind, data[at + 8 : at + 8 + length]))
        at += 8 + length
    if not chunks or chunks[0][0] != 0x4E4F534A:  # 'JSON'
        raise ValueError("the binary glTF does not start with a JSON chunk")
    doc = json.loads(chunks[0][1])
    if not isinstance(doc, dict):
        raise ValueError("the JSON document is not an object")
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == 0x004E4942 else None  # 'BIN\0'
    return doc, binary


def _finite(value, count: int | None = None) -> bool:
    """`value` is a finite number (count None) or a list of `count` finite numbers."""
    items = [value] if count is None else value
    if count is not None and (not isinstance(value, list) or len(value) != count):
        return False
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in items)


def _items(doc: dict, key: str, fail) -> list:
    """doc[key] as a list of objects, or a located error."""
    value = doc.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise fail(f"'{key}' must be a list of objects", "export the file again; it does not follow glTF 2.0")
    return value


def _index(value, count: int, where: str, fail) -> int:
    """`value` as an index below `count`, or a located error naming `where`."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < count:
        raise fail(f"{where} = {value!r} is not an index below {count}", "export the file again")
    return value


def _check_uri(uri, base: Path, where: str, fail) -> Path | None:
    """The local file an external `uri` names (checked to be a regular file), or None for a data: URI."""
    from urllib.parse import unquote

    if not isinstance(uri, str):
        raise fail(f"{where} must be a string, got {uri!r}", "export the file again")
    if uri.startswith("data:"):
        return None
    if "://" in uri:
        raise fail(f"{where} = {uri!r}: only local files and data: URIs are read", "download the file next to the glTF")
    target = base / unquote(uri)
    check_file(target, fail, where)
    return target


def _check_nodes(doc: dict, nodes: list, fail) -> None:
    """Children in range, each node with at most one parent, no cycles, no chain deeper than MAX_NODE_DEPTH."""
    parent: dict[int, int] = {}
    for i, node in enumerate(nodes):
        children = node.get("children", [])
        if not isinstance(children, list):
            raise fail(f"nodes[{i}].children must be a list of node indices", "export the file again")
        for c in children:
            c = _index(c, len(nodes), f"nodes[{i}].children", fail)
            if c == i:
                raise fail(f"nodes[{i}] is its own child", "a glTF node graph must be a tree; export the file again")
            if c in parent:
                raise fail(
                    f"nodes[{c}] has two parents (nodes[{parent[c]}] and nodes[{i}])",
                    "a glTF node graph must be a tree (spec 3.5.2); export the file again",
                )
            parent[c] = i
        for key, count in (("translation", 3), ("rotation", 4), ("scale", 3), ("matrix", 16)):
            if key in node and not _finite(node[key], count):
                raise fail(
                    f"nodes[{i}].{key} must be {count} finite numbers, got {node[key]!r}", "export the file again"
                )
    for i in range(len(nodes)):  # walk up from every node: a cycle or an over-deep chain ends the walk
        at, depth = i, 0
        while at in parent:
            at, depth = parent[at], depth + 1
            if at == i:
                raise fail(
                    f"nodes[{i}] is its own ancestor (a cycle)",
                    "a glTF node graph must be a tree; export the file again",
                )
            if depth > MAX_NODE_DEPTH:
                raise fail(
                    f"nodes[{i}] is more than {MAX_NODE_DEPTH} levels deep",
                    f"flatten the hierarchy; chains deeper than {MAX_NODE_DEPTH} nodes are refused",
                )
    for s, scene in enumerate(_items(doc, "scenes", fail)):
        for r in scene.get("nodes", []) if isinstance(scene.get("nodes", []), list) else [None]:
            _index(r, len(nodes), f"scenes[{s}].nodes", fail)


def _flattened(node: dict) -> bool:
    """The node's own scale or matrix is zero along an axis (checked finite already)."""
    if "matrix" in node:
        return abs(np.linalg.det(np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4))) == 0.0
    return any(v == 0 for v in node.get("scale", (1.0, 1.0, 1.0)))


def _check_camera(cam: dict, where: str, fail) -> None:
    """A glTF camera's numbers, checked as a YAML camera's are (field of view, near, far, depth precision)."""
    persp = cam.get("perspective")
    if cam.get("type") != "perspective" or not isinstance(persp, dict):
        return  # orthographic or incomplete: warned and replaced by a framing camera (_file_camera)
    yfov = persp.get("yfov")
    if not _finite(yfov) or not 0.0 < yfov < math.radians(179.9):
        raise fail(
            f"{where}.perspective.yfov = {yfov!r} must be a number of radians between 0 and pi (0 < yfov < 3.14)",
            "set the camera's vertical field of view, e.g. 0.8",
        )
    near, far = persp.get("znear"), persp.get("zfar")
    if not _finite(near) or near <= 0.0:
        raise fail(f"{where}.perspective.znear = {near!r} must be a positive number", "e.g. 0.1")
    if far is not None:
        if not _finite(far) or far <= near:
            raise fail(f"{where}.perspective.zfar = {far!r} must be greater than znear ({near:g})", "e.g. 1000")
        if far / near > 2.0**_DEPTH_BITS:
            raise fail(
                f"{where}: zfar / znear = {far / near:.3g} exhausts the {_DEPTH_BITS}-bit depth buffer",
                f"raise znear to at least {far / 2.0**_DEPTH_BITS:.3g}",
            )


_TEXTURE_SLOTS = (
    "pbrMetallicRoughness.baseColorTexture",
    "pbrMetallicRoughness.metallicRoughnessTexture",
    "normalTexture",
    "occlusionTexture",
    "emissiveTexture",
)


def _check_textures(doc: dict, fail) -> None:
    """Every texture a material names exists, and every texture's image and sampler (trimesh drops a dangling one)."""
    textures, images = _items(doc, "textures", fail), _items(doc, "images", fail)
    samplers = _items(doc, "samplers", fail)
    for i, mat in enumerate(_items(doc, "materials", fail)):
        for slot in _TEXTURE_SLOTS:
            ref = mat
            for part in slot.split("."):
                ref = ref.get(part) if isinstance(ref, dict) else None
            if ref is None:
                continue
            if not isinstance(ref, dict):
                raise fail(f"materials[{i}].{slot} must be an object with an index", "export the file again")
            _index(ref.get("index"), len(textures), f"materials[{i}].{slot}.index", fail)
    for t, texture in enumerate(textures):
        if "source" in texture:
            _index(texture["source"], len(images), f"textures[{t}].source", fail)
        if "sampler" in texture:
            _index(texture["sampler"], len(samplers), f"textures[{t}].sampler", fail)


def _check_materials(doc: dict, fail) -> None:
    """Material factors finite and in range (a NaN alpha or colour renders as nothing or noise)."""
    _check_textures(doc, fail)
    for i, mat in enumerate(_items(doc, "materials", fail)):
        pbr = mat.get("pbrMetallicRoughness", {})
        pbr = pbr if isinstance(pbr, dict) else {}
        checks = [
            ("pbrMetallicRoughness.baseColorFactor", pbr.get("baseColorFactor"), 4, 1.0),
            ("pbrMetallicRoughness.metallicFactor", pbr.get("metallicFactor"), None, 1.0),
            ("pbrMetallicRoughness.roughnessFactor", pbr.get("roughnessFactor"), None, 1.0),
            ("emissiveFactor", mat.get("emissiveFactor"), 3, 1.0),
            ("alphaCutoff", mat.get("alphaCutoff"), None, math.inf),
        ]
        for key, value, count, top in checks:
            if value is None:
                continue
            values = value if count is not None and isinstance(value, list) else [value]
            if not _finite(value, count) or not all(0.0 <= v <= top for v in values):
                size = "a number" if count is None else f"{count} numbers"
                span = "0 or more" if top == math.inf else "between 0 and 1"
                raise fail(f"materials[{i}].{key} must be {size} {span}, got {value!r}", "export the file again")


def _check_document(p: Path, doc: dict, buffers: _Buffers, fail) -> None:
    """Refuse what the glTF spec says a loader must refuse or what would render wrong, naming the object path."""
    required = doc.get("extensionsRequired", [])
    if not isinstance(required, list):
        raise fail("extensionsRequired must be a list of names", "export the file again")
    unknown = [e for e in required if e not in SUPPORTED_REQUIRED]
    if unknown:
        raise fail(
            f"extensionsRequired names {', '.join(map(str, unknown))}, which guaca_py does not support",
            "the glTF spec says a loader must refuse such a file; export it without the extension",
        )
    for i, buf in enumerate(_items(doc, "buffers", fail)):
        if "uri" in buf:
            _check_uri(buf["uri"], p.parent, f"buffers[{i}].uri", fail)
    _check_accessors(doc, buffers, fail)
    nodes = _items(doc, "nodes", fail)
    _check_nodes(doc, nodes, fail)
    meshes = _items(doc, "meshes", fail)
    for i, node in enumerate(nodes):
        if "mesh" in node:
            _index(node["mesh"], len(meshes), f"nodes[{i}].mesh", fail)
        if "rotation" in node and sum(v * v for v in node["rotation"]) < 1e-12:
            raise fail(f"nodes[{i}].rotation is a zero quaternion", "a rotation is a unit quaternion [x, y, z, w]")
    if "scene" in doc:
        _index(doc["scene"], len(_items(doc, "scenes", fail)), "scene", fail)
    cameras = _items(doc, "cameras", fail)
    for i, node in enumerate(nodes):
        if "camera" in node:
            c = _index(node["camera"], len(cameras), f"nodes[{i}].camera", fail)
            _check_camera(cameras[c], f"nodes[{i}].camera (cameras[{c}])", fail)
        if "mesh" in node and _flattened(node):
            warn_scene(f"{p.name}: nodes[{i}] is scaled to zero on an axis; its mesh draws nothing")
    _check_materials(doc, fail)
    _check_images(p, doc, buffers, fail)


_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def _natural(value) -> bool:
    """A non-negative integer (not a bool)."""
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _check_accessors(doc: dict, buffers: _Buffers, fail) -> None:
    """Buffers hold their byteLength, buffer views lie in their buffers, accessors in their views (spec 3.6)."""
    listed, views = _items(doc, "buffers", fail), _items(doc, "bufferViews", fail)
    sizes = []
    for i, buf in enumerate(listed):
        if not _natural(buf.get("byteLength")):
            raise fail(f"buffers[{i}].byteLength must be a non-negative integer", "export the file again")
        try:
            held = len(buffers.get(doc, i))
        except (OSError, ValueError, IndexError) as exc:
            raise fail(f"buffers[{i}] cannot be read: {exc}", "export the file again") from None
        if held < buf["byteLength"]:
            raise fail(
                f"buffers[{i}] holds {held} bytes, less than its byteLength {buf['byteLength']}",
                "export the file again",
            )
        sizes.append(buf["byteLength"])
    for i, view in enumerate(views):
        b = _index(view.get("buffer"), len(listed), f"bufferViews[{i}].buffer", fail)
        start, length = view.get("byteOffset", 0), view.get("byteLength")
        if not (_natural(start) and _natural(length)) or start + length > sizes[b]:
            raise fail(
                f"bufferViews[{i}] (byteOffset {start!r}, byteLength {length!r}) lies outside buffers[{b}] ({sizes[b]} bytes)",
                "export the file again",
            )
    for i, acc in enumerate(_items(doc, "accessors", fail)):
        count, kind, comp = acc.get("count"), acc.get("type"), acc.get("componentType")
        if (
            not (_natural(count) and isinstance(kind, str) and _natural(comp))
            or kind not in _TYPE_COMPONENTS
            or comp not in _COMPONENT_BYTES
        ):
            raise fail(
                f"accessors[{i}] needs a count, a type and a componentType glTF defines", "export the file again"
            )
        if "sparse" in acc:
            _check_sparse(i, acc, views, fail)
        if "bufferView" not in acc or count == 0:
            continue
        v = _index(acc["bufferView"], len(views), f"accessors[{i}].bufferView", fail)
        element = _TYPE_COMPONENTS[kind] * _COMPONENT_BYTES[comp]
        stride = views[v].get("byteStride", element)
        offset = acc.get("byteOffset", 0)
        if not (_natural(offset) and _natural(stride)):
            raise fail(
                f"accessors[{i}] byteOffset and byteStride must be non-negative integers", "export the file again"
            )
        if stride < element:  # elements would overlap (0: every element the first)
            raise fail(
                f"bufferViews[{v}].byteStride {stride} is less than an element of accessors[{i}] ({element} bytes)",
                "export the file again",
            )
        if offset + stride * (count - 1) + element > views[v]["byteLength"]:
            raise fail(
                f"accessors[{i}] ({count} x {kind}) reaches past bufferViews[{v}] ({views[v]['byteLength']} bytes)",
                "export the file again",
            )


def _check_sparse(i: int, acc: dict, views: list, fail) -> None:
    """A sparse accessor's count, index type and both arrays within their buffer views (spec 3.6.2.3)."""
    sparse, where = acc["sparse"], f"accessors[{i}].sparse"
    if not (
        isinstance(sparse, dict)
        and _natural(sparse.get("count"))
        and sparse["count"] >= 1
        and isinstance(sparse.get("indices"), dict)
        and isinstance(sparse.get("values"), dict)
    ):
        raise fail(f"{where} needs a count of at least 1, indices and values", "export the file again")
    n = sparse["count"]
    if n > acc["count"]:
        raise fail(f"{where}.count {n} exceeds the accessor's count {acc['count']}", "export the file again")
    comp = sparse["indices"].get("componentType")
    if comp not in _INDEX_TYPES:
        raise fail(
            f"{where}.indices.componentType = {comp!r} is not 5121, 5123 or 5125 (an unsigned byte, short or int)",
            "export the file again",
        )
    element = _TYPE_COMPONENTS[acc["type"]] * _COMPONENT_BYTES[acc["componentType"]]
    for part, size in (("indices", _COMPONENT_BYTES[comp]), ("values", element)):
        spec = sparse[part]
        v = _index(spec.get("bufferView"), len(views), f"{where}.{part}.bufferView", fail)
        offset = spec.get("byteOffset", 0)
        if not _natural(offset) or offset + n * size > views[v]["byteLength"]:
            raise fail(
                f"{where}.{part} ({n} x {size} bytes from byteOffset {offset!r}) reaches past bufferViews[{v}] "
                f"({views[v]['byteLength']} bytes)",
                "export the file again",
            )


_DTYPES = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_INDEX_TYPES = (5121, 5123, 5125)  # unsigned byte, short, int: what indices may be


@dataclass
class _Buffers:
    """One load's buffers, each read (a file) or decoded (a data: URI) once however many accessors use it."""

    base: Path  # the folder external URIs are relative to
    binary: bytes | None  # the GLB binary chunk
    _held: dict[str | None, bytes] = field(default_factory=dict)

    def get(self, doc: dict, i: int) -> bytes:
        """The bytes of doc's buffers[i]: the GLB binary chunk, a data: URI, or a local file (already checked).

        Held by URI, so the rewritten copy of a document (`_rewritten`) shares what the original read.
        """
        uri = doc["buffers"][i].get("uri")
        if uri not in self._held:
            self._held[uri] = self._read(uri)
        return self._held[uri]

    def _read(self, uri: str | None) -> bytes:
        """The bytes `uri` names, read from its source (no buffer held)."""
        from urllib.parse import unquote

        if uri is None:
            return self.binary or b""
        if uri.startswith("data:"):
            return base64.b64decode(uri.split(",", 1)[1])
        return (self.base / unquote(uri)).read_bytes()


def _view_rows(doc: dict, buffers: _Buffers, view: int, offset: int, count: int, row: int, stride=None):
    """`count` rows of `row` bytes from bufferViews[view] at `offset`, `stride` apart (tightly packed when None)."""
    bv = doc["bufferViews"][view]
    data = buffers.get(doc, bv.get("buffer", 0))
    stride = stride or row
    start = bv.get("byteOffset", 0) + offset
    if count == 0:
        return np.zeros((0, row), np.uint8)
    flat = np.frombuffer(data, np.uint8, (count - 1) * stride + row, start)
    return np.lib.stride_tricks.as_strided(flat, (count, row), (stride, 1)).copy()


def _accessor_array(doc: dict, buffers: _Buffers, i: int, fail) -> np.ndarray:
    """accessors[i] (checked already) as a (count, components) array of its type, sparse substitutions applied.

    A sparse accessor without a bufferView starts from zeros (spec 3.6.2.3); a substituted
    index at or past the accessor's count is a located error.
    """
    acc = doc["accessors"][i]
    dtype, n, count = np.dtype(_DTYPES[acc["componentType"]]), _TYPE_COMPONENTS[acc["type"]], acc["count"]
    if "bufferView" in acc:
        view = doc["bufferViews"][acc["bufferView"]]
        rows = _view_rows(
            doc,
            buffers,
            acc["bufferView"],
            acc.get("byteOffset", 0),
            count,
            n * dtype.itemsize,
            view.get("byteStride"),
        )
        out = rows.view(dtype).reshape(count, n)
    else:
        out = np.zeros((count, n), dtype)
    sparse = acc.get("sparse")
    if sparse:
        m, at, values = sparse["count"], sparse["indices"], sparse["values"]
        index_type = np.dtype(_DTYPES[at["componentType"]])
        idx = _view_rows(doc, buffers, at["bufferView"], at.get("byteOffset", 0), m, index_type.itemsize)
        idx = idx.view(index_type).reshape(m).astype(np.int64)
        if int(idx.max()) >= count:
            raise fail(
                f"accessors[{i}].sparse.indices holds {int(idx.max())}, not below the accessor's count {count}",
                "export the file again",
            )
        vals = _view_rows(doc, buffers, values["bufferView"], values.get("byteOffset", 0), m, n * dtype.itemsize)
        out[idx] = vals.view(dtype).reshape(m, n)
    return out


def _as_float(acc: dict, data: np.ndarray) -> np.ndarray:
    """An integer vertex attribute as float32: `normalized` ones scaled to [0, 1] (or [-1, 1]) as the spec says."""
    if data.dtype.kind == "f" or not acc.get("normalized"):
        return data.astype(np.float32)
    top = float(np.iinfo(data.dtype).max)
    return np.maximum(data.astype(np.float64) / top, -1.0).astype(np.float32)


def _strip_and_fan_indices(doc: dict, buffers: _Buffers, prim: dict, mode: int, fail) -> np.ndarray:
    """The triangle-list indices of a TRIANGLE_STRIP (5) or TRIANGLE_FAN (6) primitive (spec 3.7.2.1)."""
    accessors = doc["accessors"]
    if "indices" in prim:
        idx = _accessor_array(doc, buffers, prim["indices"], fail).reshape(-1).astype(np.int64)
    else:
        idx = np.arange(accessors[prim["attributes"]["POSITION"]]["count"], dtype=np.int64)
    n = len(idx) - 2
    if n < 1:
        return np.zeros((0, 3), np.uint32)
    k = np.arange(n)
    if mode == 6:  # fan: (0, k+1, k+2)
        tris = np.stack([np.full(n, idx[0]), idx[k + 1], idx[k + 2]], axis=1)
    else:  # strip: odd triangles swap their first two vertices to keep the winding
        odd = k % 2 == 1
        a, b = np.where(odd, idx[k + 1], idx[k]), np.where(odd, idx[k], idx[k + 1])
        tris = np.stack([a, b, idx[k + 2]], axis=1)
    return tris.astype(np.uint32)


def _append_accessor(out: dict, data: np.ndarray, fields: dict) -> dict:
    """An accessor over `data` in a new data: buffer of `out`, with `fields` (its type, min, max...)."""
    raw = np.ascontiguousarray(data).tobytes()
    out["buffers"].append({"byteLength": len(raw), "uri": _DATA_PREFIX + base64.b64encode(raw).decode()})
    out["bufferViews"].append({"buffer": len(out["buffers"]) - 1, "byteLength": len(raw)})
    return {**fields, "bufferView": len(out["bufferViews"]) - 1, "byteOffset": 0}


_DATA_PREFIX = "data:application/octet-stream;base64,"
#: vertex attributes trimesh reads as numbers: an integer one (a normalized TEXCOORD or COLOR) is
#: handed to it as floats, which trimesh would otherwise use raw (u8 texture coordinates 0..255)
_FLOAT_ATTRIBUTES = ("POSITION", "NORMAL", "TEXCOORD_", "COLOR_")


def _root_nodes(nodes: list) -> list[int]:
    """The nodes no other node has as a child: a file without scenes shows these (trimesh and the camera alike)."""
    children = {c for n in nodes for c in n.get("children", [])}
    return [i for i in range(len(nodes)) if i not in children]


def _rewritten(doc: dict, buffers: _Buffers, fail) -> dict | None:
    """A copy of `doc` in the form trimesh reads correctly, or None when `doc` is already in it.

    Sparse accessors become dense, integer vertex attributes floats (normalized ones scaled),
    strip and fan primitives triangle lists; each rewritten accessor's data goes in a data:
    buffer of its own. A file without scenes gets one of its root nodes.
    """
    import copy

    accessors = _items(doc, "accessors", fail)
    prims = [
        (m, k, prim)
        for m, mesh in enumerate(_items(doc, "meshes", fail))
        for k, prim in enumerate(mesh.get("primitives", []) if isinstance(mesh.get("primitives"), list) else [])
        if isinstance(prim, dict)
    ]
    attributes = {
        a
        for _, _, prim in prims
        if isinstance(prim.get("attributes"), dict)
        for name, a in prim["attributes"].items()
        if name.startswith(_FLOAT_ATTRIBUTES) and _natural(a) and a < len(accessors)
    }
    dense = [i for i, acc in enumerate(accessors) if "sparse" in acc]
    floats = [i for i in sorted(attributes) if accessors[i].get("componentType") != 5126]
    strips = [(m, k) for m, k, prim in prims if prim.get("mode") in (5, 6)]
    nodes = _items(doc, "nodes", fail)
    sceneless = not doc.get("scenes") and bool(nodes)  # trimesh then reads nothing at all
    if not (dense or floats or strips or sceneless):
        return None
    out = copy.deepcopy(doc)
    if sceneless:
        out["scenes"], out["scene"] = [{"nodes": _root_nodes(nodes)}], 0
    for key in ("buffers", "bufferViews", "accessors"):
        out.setdefault(key, [])
    for i in sorted(set(dense) | set(floats)):
        acc = accessors[i]
        data = _accessor_array(doc, buffers, i, fail)
        fields = {k: v for k, v in acc.items() if k not in ("sparse", "bufferView", "byteOffset")}
        if i in floats:
            data = _as_float(acc, data)
            fields.update(componentType=5126, normalized=False)
            fields.pop("min", None), fields.pop("max", None)  # bounds of the integers, not of the floats
        out["accessors"][i] = _append_accessor(out, data, fields)
    for m, k in strips:
        prim = out["meshes"][m]["primitives"][k]
        try:
            tris = _strip_and_fan_indices(out, buffers, prim, prim["mode"], fail)
        except (KeyError, IndexError, TypeError, ValueError, OSError) as exc:
            raise fail(
                f"meshes[{m}].primitives[{k}]: cannot read its indices ({exc})", "export the file again"
            ) from None
        out["accessors"].append(
            _append_accessor(out, tris, {"componentType": 5125, "count": tris.size, "type": "SCALAR"})
        )
        prim["indices"], prim["mode"] = len(out["accessors"]) - 1, 4
    return out


def _load_trimesh(p: Path, doc: dict, buffers: _Buffers, fail):
    """trimesh's scene of the file; what it would misread is handed to it rewritten (`_rewritten`)."""
    import io

    import trimesh

    rewritten = _rewritten(doc, buffers, fail)
    binary = buffers.binary
    if rewritten is None:
        # the container by its magic bytes, not its name (a binary glTF named .gltf, JSON named .glb)
        with p.open("rb") as f:
            kind = "glb" if f.read(4) == b"glTF" else "gltf"
        return trimesh.load(str(p), file_type=kind, force="scene", process=False)
    text = json.dumps(rewritten).encode()
    if binary is None:
        source, kind = io.BytesIO(text), "gltf"
    else:
        text += b" " * (-len(text) % 4)
        binary += b"\0" * (-len(binary) % 4)
        total = 12 + 8 + len(text) + 8 + len(binary)
        source = io.BytesIO(
            struct.pack("<III", 0x46546C67, 2, total)
            + struct.pack("<II", len(text), 0x4E4F534A)
            + text
            + struct.pack("<II", len(binary), 0x004E4942)
            + binary
        )
        kind = "glb"
    resolver = trimesh.resolvers.FilePathResolver(str(p))
    return trimesh.load(source, file_type=kind, force="scene", process=False, resolver=resolver)


def _check_images(p: Path, doc: dict, buffers: _Buffers, fail) -> None:
    """Every image decodes to a bounded size (header read first); a bad one is a located error, not dropped."""
    views = _items(doc, "bufferViews", fail)
    # only images a texture samples as its core `source`: one named only by an extension (a KTX2
    # beside a PNG fallback) is not read by trimesh, so it need not be readable here either
    used = {t.get("source") for t in _items(doc, "textures", fail) if _natural(t.get("source"))}
    for i, image in enumerate(_items(doc, "images", fail)):
        if i not in used:
            continue
        where = f"images[{i}]" + (f" ({image['name']})" if isinstance(image.get("name"), str) else "")
        if "uri" in image:
            source = _check_uri(image["uri"], p.parent, f"images[{i}].uri", fail)
            if source is None:  # a data: URI: decoded here too, a small one can claim a huge image
                try:
                    source = base64.b64decode(image["uri"].split(",", 1)[1])
                except (IndexError, ValueError):
                    raise fail(f"images[{i}].uri is not a base64 data: URI", "export the file again") from None
        elif "bufferView" in image:
            v = _index(image["bufferView"], len(views), f"images[{i}].bufferView", fail)
            view = views[v]
            b = _index(view.get("buffer", 0), len(doc.get("buffers", [])), f"bufferViews[{v}].buffer", fail)
            try:
                data = buffers.get(doc, b)
            except (OSError, ValueError, IndexError) as exc:
                raise fail(f"buffers[{b}] (of {where}) cannot be read: {exc}", "export the file again") from None
            start, length = view.get("byteOffset", 0), view.get("byteLength", 0)
            if not (_finite(start) and _finite(length)) or start < 0 or length < 0 or start + length > len(data):
                raise fail(f"bufferViews[{v}] (of {where}) lies outside its buffer", "export the file again")
            source = data[int(start) : int(start + length)]
        else:
            continue
        try:
            decode_image(source, where)
        except ValueError as exc:
            raise fail(str(exc), "re-export the texture as a PNG or JPEG no larger than the limit") from None


def _exact_factors(doc: dict) -> dict[str, dict]:
    """Material name -> its pbr factors as written in the file (only for names used once)."""
    mats = doc.get("materials") or []
    names = [m.get("name") for m in mats]
    out = {}
    for m in mats:
        name = m.get("name")
        if name and names.count(name) == 1:
            pbr = m.get("pbrMetallicRoughness")
            pbr = pbr if isinstance(pbr, dict) else {}
            out[name] = {
                "base_color": pbr.get("baseColorFactor"),
                "metallic": pbr.get("metallicFactor"),
                "roughness": pbr.get("roughnessFactor"),
                "emissive": m.get("emissiveFactor"),
            }
    return out


def _node_local(node: dict) -> glm.dmat4:
    """A glTF node's local matrix: `matrix` (column-major), else T * R * S."""
    if "matrix" in node:
        return glm.dmat4(np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T)
    t = glm.dvec3(*node.get("translation", (0.0, 0.0, 0.0)))
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    s = glm.dvec3(*node.get("scale", (1.0, 1.0, 1.0)))
    return glm.translate(t) * glm.mat4_cast(glm.dquat(w, x, y, z)) * glm.scale(s)


def camera_node(doc: dict) -> tuple[dict, np.ndarray] | None:
    """The first camera of the file's scene in document order: (its glTF camera object, its world matrix).

    The world matrix is the product of the local matrices from the scene's root down to the
    camera's node.
    """
    nodes, cameras = doc.get("nodes") or [], doc.get("cameras") or []
    scenes = doc.get("scenes") or []
    index = doc.get("scene", 0)
    try:
        if scenes:
            roots = list(scenes[index].get("nodes", []))
        else:
            roots = _root_nodes(nodes)
        stack = [(i, glm.dmat4(1.0)) for i in reversed(roots)]
        seen: set[int] = set()
        while stack:
            i, parent = stack.pop()
            if i in seen or not 0 <= i < len(nodes):
                continue
            seen.add(i)
            node = nodes[i]
            world = parent * _node_local(node)
            cam = node.get("camera")
            if cam is not None and 0 <= cam < len(cameras):
                return cameras[cam], np.array(world)
            stack.extend((c, world) for c in reversed(node.get("children", [])))
    except (TypeError, ValueError, IndexError, KeyError, AttributeError):
        return None  # a malformed node graph: trimesh has already read what it could
    return None


def _file_camera(doc: dict, label: str, lo: np.ndarray, hi: np.ndarray) -> Camera | None:
    """The file's first camera at its world transform, or None (none, orthographic, or degenerate)."""
    found = camera_node(doc)
    if found is None:
        return None
    gcam, world = found
    persp = gcam.get("perspective") if isinstance(gcam, dict) else None
    if gcam.get("type") != "perspective" or not isinstance(persp, dict) or "yfov" not in persp:
        warn_scene(
            f"{label}: its camera is {gcam.get('type', 'incomplete')!r}, only perspective cameras are supported; "
            "a camera framing the model is used"
        )
        return None
    near = float(persp.get("znear") or 0.01)
    far = float(persp.get("zfar") or 0.0)  # absent: an infinite projection; this one ends past the model
    if far <= near:
        far = max(far_past(world[:3, 3], lo, hi), near * 10.0)
    fov_y = min(max(math.degrees(float(persp["yfov"])), 1e-3), 179.0)
    camera = camera_from_matrix(world, fov_y, near, far)
    if camera is None:
        warn_scene(
            f"{label}: its camera's node is scaled to zero or not finite, so it has no view direction; "
            "a camera framing the model is used"
        )
    return camera


def load_gltf(
    path: str | Path, file_for_errors: str | Path | None = None, line: int | None = None, key: str | None = None
) -> GltfContent:
    """Read a .glb/.gltf file into root Nodes with the file's hierarchy, materials and camera."""

    p = Path(path)
    cited = file_error(p, file_for_errors, line, key)

    def fail(reason: str, hint: str) -> ConfigError:
        # cited at the scene's line: the reason names the glTF file the object path belongs to
        return cited(reason if file_for_errors is None or str(p) in reason else f"{p}: {reason}", hint)

    check_file(p, fail, "glTF file")
    try:
        doc, binary = _parse_document(p.read_bytes())
    except (OSError, ValueError, struct.error, RecursionError) as exc:
        raise fail(f"cannot read glTF file {p}: {exc}", MESH_FORMATS_HINT) from None
    buffers = _Buffers(p.parent, binary)  # this load's alone: a file changed between loads is read again
    try:
        _check_document(p, doc, buffers, fail)
    except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:  # a wrong type in a field
        raise fail(f"cannot read glTF file {p}: a field has the wrong type ({exc})", "export the file again") from None
    try:
        tscene = _load_trimesh(p, doc, buffers, fail)
    except ConfigError:
        raise
    except Exception as exc:  # trimesh raises many types for unreadable input; all mean "bad file"
        raise fail(f"cannot read glTF file {p}: {exc}", MESH_FORMATS_HINT) from exc
    roots = nodes_from_trimesh(tscene, str(p), fail, _exact_factors(doc))
    meshes = {id(n.mesh): n.mesh for root in roots for n, _ in root.walk() if n.mesh is not None}
    content = GltfContent(roots, meshes={m.name: m for m in meshes.values()})
    content.camera = _file_camera(doc, p.name, *scene_bounds(roots))
    return content
