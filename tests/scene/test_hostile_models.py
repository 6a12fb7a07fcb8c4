"""Hostile glTF, mesh and texture files: each is refused with an error naming the file and object, or warned."""

from __future__ import annotations

import base64
import io
import json
import math
import os
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from guaca_py.cli import main
from guaca_py.errors import ConfigError
from guaca_py.scene.gltf import MAX_NODE_DEPTH, load_gltf
from guaca_py.scene.texture import MAX_TEXTURE_SIDE, decode_image


def _data_uri(data: bytes) -> str:
    return "data:application/octet-stream;base64," + base64.b64encode(data).decode()


def quad_doc(indices=(0, 1, 2, 0, 2, 3), mode: int | None = None) -> dict:
    """A glTF document with one unit quad (positions and uint16 indices in a data: buffer)."""
    pos = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32).tobytes()
    idx = np.array(indices, np.uint16).tobytes()
    prim = {"attributes": {"POSITION": 0}, "indices": 1}
    if mode is not None:
        prim["mode"] = mode
    return {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(pos + idx), "uri": _data_uri(pos + idx)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
            {"buffer": 0, "byteOffset": len(pos), "byteLength": len(idx)},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": len(indices), "type": "SCALAR"},
        ],
        "meshes": [{"primitives": [prim]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }


def write(tmp_path, doc: dict, name: str = "m.gltf"):
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def refused(path, *fragments: str) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        load_gltf(path)
    text = str(info.value)
    assert path.name in text
    for fragment in fragments:
        assert fragment in text, text
    return info.value


def with_camera(yfov=0.8, znear=0.1, zfar=100.0, node=None) -> dict:
    doc = quad_doc()
    persp = {"yfov": yfov, "znear": znear}
    if zfar is not None:
        persp["zfar"] = zfar
    doc["cameras"] = [{"type": "perspective", "perspective": persp}]
    doc["nodes"].append({"camera": 0, "translation": [0, 0, 5], **(node or {})})
    doc["scenes"][0]["nodes"].append(1)
    return doc


def test_valid_quad_loads(tmp_path):
    content = load_gltf(write(tmp_path, quad_doc()))
    assert [m.indices.shape for m in content.meshes.values()] == [(2, 3)]


@pytest.mark.parametrize("mode", [5, 6])
def test_triangle_strips_and_fans_are_triangulated(tmp_path, mode):
    content = load_gltf(write(tmp_path, quad_doc(indices=(0, 1, 3, 2) if mode == 5 else (0, 1, 2, 3), mode=mode)))
    (mesh,) = content.meshes.values()
    expected = [[0, 1, 3], [3, 1, 2]] if mode == 5 else [[0, 1, 2], [0, 2, 3]]
    assert mesh.indices.tolist() == expected


def test_fan_in_a_glb_is_triangulated(tmp_path):
    doc = quad_doc(indices=(0, 1, 2, 3), mode=6)
    binary = base64.b64decode(doc["buffers"][0].pop("uri").split(",", 1)[1])
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    path = tmp_path / "fan.glb"
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
    (mesh,) = load_gltf(path).meshes.values()
    assert mesh.indices.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_node_cycle_is_refused(tmp_path):
    doc = quad_doc()
    doc["nodes"] = [{"mesh": 0, "children": [1]}, {"children": [0]}]
    refused(write(tmp_path, doc), "is its own ancestor (a cycle)")


def test_node_that_is_its_own_child_is_refused(tmp_path):
    doc = quad_doc()
    doc["nodes"][0]["children"] = [0]
    refused(write(tmp_path, doc), "nodes[0] is its own child")


def test_pure_cycle_without_root_is_refused(tmp_path):
    doc = quad_doc()
    doc["nodes"] = [{"mesh": 0, "children": [1]}, {"children": [2]}, {"children": [0]}]
    refused(write(tmp_path, doc), "cycle")


def test_deep_chain_is_refused_without_recursion_error(tmp_path):
    doc = quad_doc()
    doc["nodes"] = [{"children": [i + 1]} for i in range(2999)] + [{"mesh": 0}]
    refused(write(tmp_path, doc), f"more than {MAX_NODE_DEPTH} levels deep")


def test_chain_within_the_bound_loads(tmp_path):
    doc = quad_doc()
    doc["nodes"] = [{"children": [i + 1]} for i in range(MAX_NODE_DEPTH - 1)] + [{"mesh": 0}]
    assert load_gltf(write(tmp_path, doc)).nodes


@pytest.mark.parametrize(
    ("camera", "fragment"),
    [
        ({"yfov": 0}, "yfov = 0"),
        ({"yfov": math.pi}, "yfov"),
        ({"yfov": -0.5}, "yfov = -0.5"),
        ({"znear": -0.1}, "znear = -0.1"),
        ({"znear": 1e-9, "zfar": 1e9}, "exhausts"),
        ({"zfar": 0.05}, "zfar = 0.05"),
    ],
)
def test_bad_camera_numbers_are_refused(tmp_path, camera, fragment):
    refused(write(tmp_path, with_camera(**camera)), "nodes[1].camera", fragment)


def test_camera_node_with_nan_is_refused(tmp_path):
    path = tmp_path / "m.gltf"
    path.write_text(json.dumps(with_camera(node={"translation": [0, 0, 5]})).replace("[0, 0, 5]", "[0, NaN, 5]"))
    refused(path, "nodes[1].translation")


def test_camera_node_scaled_to_zero_warns(tmp_path):
    with pytest.warns(UserWarning, match="scaled to zero"):
        content = load_gltf(write(tmp_path, with_camera(node={"scale": [0, 0, 0]})))
    assert content.camera is None


def test_mesh_node_scaled_to_zero_warns_and_renders(tmp_path):
    doc = quad_doc()
    doc["nodes"][0]["scale"] = [0, 0, 0]
    path = write(tmp_path, doc)
    with pytest.warns(UserWarning, match=r"nodes\[0\] is scaled to zero"):
        rc = main(["render", str(path), "--width", "32", "--height", "32", "--out", str(tmp_path / "o.png")])
    assert rc == 0


def test_unknown_required_extension_is_refused(tmp_path):
    doc = quad_doc()
    doc["extensionsUsed"] = doc["extensionsRequired"] = ["EXT_made_up"]
    refused(write(tmp_path, doc), "EXT_made_up")


QUAD = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]


def sparse_doc(moved: dict[int, list], base: bool = True, index_type: int = 5121) -> dict:
    """quad_doc whose positions accessor is sparse: vertex k of `moved` is substituted by moved[k].

    The substitution's indices and values lie in a second buffer, each in a buffer view; without
    `base` the accessor has no bufferView of its own and starts from zeros.
    """
    doc = quad_doc()
    keys = sorted(moved)
    idx = np.array(keys, {5121: np.uint8, 5123: np.uint16, 5125: np.uint32}[index_type]).tobytes()
    idx += b"\0" * (-len(idx) % 4)
    vals = np.array([moved[k] for k in keys], np.float32).tobytes()
    doc["buffers"].append({"byteLength": len(idx + vals), "uri": _data_uri(idx + vals)})
    doc["bufferViews"] += [
        {"buffer": 1, "byteOffset": 0, "byteLength": len(idx)},
        {"buffer": 1, "byteOffset": len(idx), "byteLength": len(vals)},
    ]
    acc = doc["accessors"][0]
    acc["sparse"] = {
        "count": len(keys),
        "indices": {"bufferView": 2, "componentType": index_type},
        "values": {"bufferView": 3},
    }
    acc.pop("min"), acc.pop("max")
    if not base:
        del acc["bufferView"]
    return doc


def loaded_positions(path) -> list:
    (mesh,) = load_gltf(path).meshes.values()
    return mesh.positions[mesh.indices.reshape(-1)].tolist()  # by corner: independent of vertex order


@pytest.mark.parametrize("index_type", [5121, 5123, 5125])
def test_sparse_accessor_substitutes_its_values(tmp_path, index_type):
    """A sparse POSITION accessor moves vertex 2 from (1, 1, 0) to (2, 3, 0); the others stay."""
    got = loaded_positions(write(tmp_path, sparse_doc({2: [2, 3, 0]}, index_type=index_type)))
    moved = [[2, 3, 0] if k == 2 else QUAD[k] for k in (0, 1, 2, 0, 2, 3)]
    assert got == moved


def test_sparse_accessor_without_a_buffer_view_starts_from_zeros(tmp_path):
    got = loaded_positions(write(tmp_path, sparse_doc({1: [1, -1, 0], 2: [1, 1, 0]}, base=False)))
    assert got == [[0, 0, 0], [1, -1, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0], [0, 0, 0]]


def test_sparse_accessor_in_a_glb_and_as_indices(tmp_path):
    """The substitution works on a GLB's binary chunk and on an index accessor (triangle 2 turned round)."""
    doc = quad_doc()
    doc["buffers"].append({"byteLength": 4, "uri": _data_uri(np.array([4, 5, 3, 2], np.uint8).tobytes())})
    doc["bufferViews"] += [
        {"buffer": 1, "byteOffset": 0, "byteLength": 2},
        {"buffer": 1, "byteOffset": 2, "byteLength": 2},
    ]
    doc["accessors"][1]["sparse"] = {
        "count": 2,
        "indices": {"bufferView": 2, "componentType": 5121},
        "values": {"bufferView": 3},
    }  # indices[4] = 3 and [5] = 2: the second triangle (0, 2, 3) becomes (0, 3, 2)
    doc["accessors"][1]["componentType"] = 5121
    doc["bufferViews"][1]["byteLength"] = 6
    pos = base64.b64decode(doc["buffers"][0]["uri"].split(",", 1)[1])[:48]
    doc["buffers"][0] = {"byteLength": 56}
    binary = pos + np.array([0, 1, 2, 0, 2, 3, 0, 0], np.uint8).tobytes()
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    path = tmp_path / "sparse.glb"
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
    assert loaded_positions(path) == [QUAD[k] for k in (0, 1, 2, 0, 3, 2)]


def test_each_buffer_file_is_read_once_per_load(tmp_path, monkeypatch):
    """A strip over a sparse accessor, both buffers in files: checking, densifying and triangulating
    read each file once (trimesh's own read of the file it is handed is not counted: it uses open())."""
    import pathlib

    doc = sparse_doc({2: [2, 3, 0]})
    doc["meshes"][0]["primitives"][0]["mode"] = 5
    for i, buf in enumerate(doc["buffers"]):
        (tmp_path / f"b{i}.bin").write_bytes(base64.b64decode(buf["uri"].split(",", 1)[1]))
        buf["uri"] = f"b{i}.bin"
    reads: dict[str, int] = {}
    read_bytes = pathlib.Path.read_bytes

    def counted(self):
        reads[self.name] = reads.get(self.name, 0) + 1
        return read_bytes(self)

    monkeypatch.setattr(pathlib.Path, "read_bytes", counted)
    path = write(tmp_path, doc)
    load_gltf(path)
    assert reads == {"m.gltf": 1, "b0.bin": 1, "b1.bin": 1}
    load_gltf(path)  # a second load reads again: nothing is kept between loads
    assert reads == {"m.gltf": 2, "b0.bin": 2, "b1.bin": 2}


@pytest.mark.parametrize(
    "change, fragment",
    [
        (lambda s: s.update(count=5), "accessors[0].sparse.count 5 exceeds the accessor's count 4"),
        (lambda s: s.update(count=0), "accessors[0].sparse needs a count of at least 1"),
        (lambda s: s["indices"].update(componentType=5126), "accessors[0].sparse.indices.componentType = 5126"),
        (lambda s: s["indices"].update(bufferView=9), "accessors[0].sparse.indices.bufferView = 9 is not an index"),
        (lambda s: s["values"].update(byteOffset=8), "accessors[0].sparse.values (1 x 12 bytes from byteOffset 8)"),
        (lambda s: s.pop("values"), "needs a count of at least 1, indices and values"),
    ],
    ids=["count", "zero", "index-type", "view", "values-past-view", "no-values"],
)
def test_malformed_sparse_accessor_is_refused_naming_it(tmp_path, change, fragment):
    doc = sparse_doc({2: [2, 3, 0]})
    change(doc["accessors"][0]["sparse"])
    refused(write(tmp_path, doc), fragment)


@pytest.mark.parametrize("stride", [0, 8])
def test_byte_stride_shorter_than_an_element_is_refused(tmp_path, stride):
    doc = quad_doc()
    doc["bufferViews"][0]["byteStride"] = stride
    doc["bufferViews"][0]["byteLength"] = 48
    refused(write(tmp_path, doc), f"bufferViews[0].byteStride {stride} is less than an element of accessors[0] (12")


def test_interleaved_positions_with_a_stride_load(tmp_path):
    """Positions 24 bytes apart (interleaved with something else) read as the packed ones do."""
    doc = quad_doc()
    pos = np.zeros((4, 6), np.float32)
    pos[:, :3] = QUAD
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint16).tobytes()
    data = pos.tobytes() + idx
    doc["buffers"][0] = {"byteLength": len(data), "uri": _data_uri(data)}
    doc["bufferViews"][0] = {"buffer": 0, "byteOffset": 0, "byteLength": 96, "byteStride": 24}
    doc["bufferViews"][1] = {"buffer": 0, "byteOffset": 96, "byteLength": len(idx)}
    assert loaded_positions(write(tmp_path, doc)) == [QUAD[k] for k in (0, 1, 2, 0, 2, 3)]


def test_sparse_index_past_the_accessor_count_is_refused(tmp_path):
    refused(write(tmp_path, sparse_doc({7: [2, 3, 0]})), "accessors[0].sparse.indices holds 7, not below")


def test_sparse_accessor_renders_the_moved_quad(tmp_path, renderer_factory):
    """The quad moved wholly left of the centre by its sparse accessor: the left is red, the centre background."""
    from guaca_py import load

    left = {k: [x - 2.5, y * 0.5, 0] for k, (x, y, _) in enumerate(QUAD)}
    write(tmp_path, sparse_doc(left))
    (tmp_path / "s.yaml").write_text(
        "camera: {position: [0, 0, 5], target: [0, 0, 0], fov_y: 60}\nbackground: [0, 0, 0]\n"
        "nodes: [{mesh: {file: m.gltf}, material: {description: unlit, uniforms: {color: [1, 0, 0]}}}]\n"
    )
    image = renderer_factory("default").render(load(tmp_path / "s.yaml"), 64, 64).image
    assert image[32, 32].tolist() == [0, 0, 0] and image[32, 10, 0] > 200 and image[32, 10, 1] < 20


@pytest.mark.parametrize("component, scale", [(5121, 255), (5123, 65535)])
def test_normalized_integer_texcoords_are_read_as_fractions(tmp_path, component, scale):
    """TEXCOORD_0 as normalized unsigned bytes or shorts (core glTF 2.0) reads as the float version does."""
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 0.5]])
    docs = []
    for ints in (False, True):
        doc = quad_doc()
        data = (
            np.round(uv * scale).astype({5121: np.uint8, 5123: np.uint16}[component]) if ints else uv.astype(np.float32)
        ).tobytes()
        doc["buffers"].append({"byteLength": len(data), "uri": _data_uri(data)})
        doc["bufferViews"].append({"buffer": 1, "byteLength": len(data)})
        doc["accessors"].append(
            {
                "bufferView": 2,
                "componentType": component if ints else 5126,
                "count": 4,
                "type": "VEC2",
                "normalized": ints,
            }
        )
        doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 2
        doc["meshes"][0]["primitives"][0]["material"] = 0
        doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}}]
        docs.append(load_gltf(write(tmp_path, doc, f"uv{ints}.gltf")))
    (floats,), (ints,) = (list(d.meshes.values()) for d in docs)
    assert np.allclose(ints.texcoords, floats.texcoords, atol=1.0 / scale) and floats.texcoords.max() > 0.9


@pytest.mark.parametrize("factor", ["[1, 1, 1, NaN]", "[NaN, 0, 0, 1]", "[1, 1, 1, 2]"])
def test_nan_or_out_of_range_base_colour_is_refused(tmp_path, factor):
    doc = quad_doc()
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": "FACTOR"}}]
    doc["meshes"][0]["primitives"][0]["material"] = 0
    path = tmp_path / "m.gltf"
    path.write_text(json.dumps(doc).replace('"FACTOR"', factor))
    refused(path, "materials[0].pbrMetallicRoughness.baseColorFactor")


def test_glb_whose_json_chunk_claims_too_much_names_the_file(tmp_path):
    path = tmp_path / "big.glb"
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 40) + struct.pack("<II", 10**9, 0x4E4F534A) + b"{}" * 10)
    refused(path, "claims")


def test_buffer_uri_naming_a_fifo_is_refused_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "pipe.bin")
    doc = quad_doc()
    doc["buffers"][0]["uri"] = "pipe.bin"
    refused(write(tmp_path, doc), "buffers[0].uri", "FIFO")


@pytest.mark.parametrize(("uri", "fragment"), [("a\0b.bin", "NUL"), ("loop.bin", "symbolic links"), (".", "directory")])
def test_buffer_uri_that_is_no_regular_file_is_refused(tmp_path, uri, fragment):
    (tmp_path / "loop.bin").symlink_to(tmp_path / "loop.bin")
    doc = quad_doc()
    doc["buffers"][0]["uri"] = uri
    refused(write(tmp_path, doc), "buffers[0].uri", fragment)


def _textured(tmp_path, image_bytes: bytes | None, uri: str | None = None) -> dict:
    doc = quad_doc()
    doc["images"] = [{"uri": uri} if uri else {"uri": _data_uri(b"")}]
    if image_bytes is not None:
        (tmp_path / "t.png").write_bytes(image_bytes)
        doc["images"] = [{"uri": "t.png"}]
    doc["textures"] = [{"source": 0}]
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    doc["meshes"][0]["primitives"][0]["material"] = 0
    return doc


def _png(mode: str, size=(4, 4), value=0) -> bytes:
    out = io.BytesIO()
    Image.new(mode, size, value).save(out, "PNG")
    return out.getvalue()


@pytest.mark.parametrize(
    ("data", "fragment"),
    [
        (b"this is text", "not a readable image"),
        (b"", "is empty"),
        (_png("RGB")[:40], "not a readable image"),
    ],
)
def test_bad_texture_is_a_located_error(tmp_path, data, fragment):
    refused(write(tmp_path, _textured(tmp_path, data)), "images[0]", fragment)


def test_texture_with_corrupt_zlib_data_is_a_located_error(tmp_path):
    png = bytearray(_png("RGB", (64, 64), (200, 10, 10)))
    at = png.index(b"IDAT") + 4
    png[at + 2 : at + 12] = b"\xff" * 10
    refused(write(tmp_path, _textured(tmp_path, bytes(png))), "images[0]")


def _bomb_png(side: int) -> bytes:
    """A PNG header claiming side x side greyscale pixels with one tiny IDAT: the size is in the header."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def test_texture_past_the_size_bound_is_refused_before_decoding(tmp_path):
    refused(write(tmp_path, _textured(tmp_path, _bomb_png(MAX_TEXTURE_SIDE + 1))), "images[0]", f"{MAX_TEXTURE_SIDE}")
    with pytest.raises(ValueError, match="too many pixels"):
        decode_image(_bomb_png(60000), "bomb")
    wide = io.BytesIO()
    Image.new("L", (MAX_TEXTURE_SIDE + 1, 1)).save(wide, "PNG")
    with pytest.raises(ValueError, match=f"is {MAX_TEXTURE_SIDE + 1}x1; the largest read is {MAX_TEXTURE_SIDE}x"):
        decode_image(wide.getvalue(), "wide")


def test_image_in_a_data_uri_is_bounded_too(tmp_path):
    doc = _textured(tmp_path, None)
    doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(_bomb_png(60000)).decode()}]
    refused(write(tmp_path, doc), "images[0]", "too many pixels")


def test_image_in_a_buffer_view_is_checked(tmp_path):
    doc = _textured(tmp_path, None)
    junk = b"not an image at all"
    doc["buffers"].append({"byteLength": len(junk), "uri": _data_uri(junk)})
    doc["bufferViews"].append({"buffer": 1, "byteLength": len(junk)})
    doc["images"] = [{"bufferView": 2, "mimeType": "image/png", "name": "albedo"}]
    refused(write(tmp_path, doc), "images[0] (albedo)", "not a readable image")


def test_gltf_path_with_nul_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="NUL"):
        load_gltf(str(tmp_path / "a\0b.gltf"))


def test_sixteen_bit_grey_png_reads_scaled_not_white():
    out = io.BytesIO()
    Image.fromarray(np.full((2, 2), 32896, np.uint16)).save(out, "PNG")  # 0x8080: half grey
    px = decode_image(out.getvalue(), "grey16")
    assert px.shape == (2, 2, 4)
    assert px[0, 0].tolist() == [128, 128, 128, 255]


def test_grey_alpha_png_keeps_its_alpha():
    px = decode_image(_png("LA", (2, 2), (100, 50)), "la")
    assert px[0, 0].tolist() == [100, 100, 100, 50]


def test_cli_exits_2_naming_the_file_and_object(tmp_path, capsys):
    path = write(tmp_path, with_camera(yfov=0))
    rc = main(["render", str(path), "--width", "32", "--height", "32", "--out", str(tmp_path / "o.png")])
    err = capsys.readouterr().err
    assert rc == 2
    assert "m.gltf" in err and "nodes[1].camera" in err and "Traceback" not in err
    assert not (tmp_path / "o.png").exists()


def load_mesh(path):
    from guaca_py import load

    return load(path)


def mesh_refused(path, *fragments: str) -> None:
    with pytest.raises(ConfigError) as info:
        load_mesh(path)
    text = str(info.value)
    assert path.name in text, text
    for fragment in fragments:
        assert fragment in text, text


TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


def test_obj_with_one_nan_vertex_is_refused(tmp_path):
    path = tmp_path / "n.obj"
    path.write_text(TRI + "v nan 0 0\nv 1 1 0\nf 1 2 3\nf 2 4 5\n")
    mesh_refused(path, "1 non-finite vertex position (NaN or inf)")


def test_obj_with_only_nan_vertices_says_so(tmp_path):
    path = tmp_path / "n.obj"
    path.write_text("v nan 0 0\nv 0 nan 0\nv 0 0 nan\nf 1 2 3\n")
    mesh_refused(path, "non-finite vertex")


def test_obj_face_index_zero_is_refused(tmp_path):
    path = tmp_path / "z.obj"
    path.write_text(TRI + "f 0 1 2\n")
    mesh_refused(path, "z.obj:4", "face index 0")


def test_obj_mtllib_naming_a_fifo_is_refused_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "pipe.mtl")
    path = tmp_path / "m.obj"
    path.write_text("mtllib pipe.mtl\n" + TRI + "f 1 2 3\n")
    mesh_refused(path, "mtllib", "FIFO")


def test_mtl_texture_naming_a_fifo_is_refused(tmp_path):
    os.mkfifo(tmp_path / "pipe.png")
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 1 1 1\nmap_Kd pipe.png\n")
    path = tmp_path / "m.obj"
    path.write_text("mtllib m.mtl\n" + TRI + "usemtl a\nf 1 2 3\n")
    mesh_refused(path, "map_kd", "FIFO")


def test_obj_with_missing_mtllib_still_loads(tmp_path):
    path = tmp_path / "m.obj"
    path.write_text("mtllib gone.mtl\n" + TRI + "f 1 2 3\n")
    assert load_mesh(path).nodes


def test_mesh_file_that_is_a_fifo_is_refused(tmp_path):
    from guaca_py.scene.files import load_model
    from guaca_py.scene.mesh_io import load_mesh_file

    os.mkfifo(tmp_path / "pipe.obj")
    for reader in (load_model, load_mesh_file):
        with pytest.raises(ConfigError, match="mesh file is a FIFO, not a regular file"):
            reader(tmp_path / "pipe.obj")


def test_stl_header_claiming_two_billion_triangles_names_the_file(tmp_path):
    path = tmp_path / "big.stl"
    path.write_bytes(b"\0" * 80 + struct.pack("<I", 2**31) + b"\0" * 100)
    mesh_refused(path, "claims 2147483648 triangles")


def test_valid_binary_stl_loads(tmp_path):
    tri = struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0)
    path = tmp_path / "ok.stl"
    path.write_bytes(b"\0" * 80 + struct.pack("<I", 1) + tri)
    assert load_mesh(path).nodes


def test_file_problem_names_fifos_nul_and_devices(tmp_path):
    from guaca_py.yaml_source import file_problem

    os.mkfifo(tmp_path / "pipe.png")
    assert file_problem(tmp_path / "pipe.png") == "is a FIFO, not a regular file"
    assert file_problem(str(tmp_path / "a\0b")) == "contains a NUL character"
    assert file_problem("/dev/null") == "is a device, not a regular file"


def _textured_scene(tmp_path, texture: str):
    quad = "{primitive: quad, size: [10, 10]}"
    material = f"{{description: pbr_textured, uniforms: {{albedo_map: {texture}}}}}"
    path = tmp_path / "s.yaml"
    path.write_text(
        f"camera: {{position: [0, 0, 3], target: [0, 0, 0]}}\nbackground: [0, 0, 0]\n"
        f"nodes:\n  - {{mesh: {quad}, material: {material}}}\n"
    )
    return path


def _render(tmp_path, scene, capsys) -> tuple[int, str]:
    rc = main(["render", str(scene), "--width", "32", "--height", "32", "--out", str(tmp_path / "o.png")])
    return rc, capsys.readouterr().err


@pytest.mark.parametrize(("make", "fragment"), [("fifo", "t.png"), ("empty", "is empty"), ("zlib", "t.png")])
def test_scene_texture_that_is_no_readable_image_exits_2(tmp_path, capsys, make, fragment):
    target = tmp_path / "t.png"
    if make == "fifo":
        os.mkfifo(target)
    elif make == "empty":
        target.write_bytes(b"")
    else:
        png = bytearray(_png("RGB", (64, 64), (200, 10, 10)))
        at = png.index(b"IDAT") + 4
        png[at + 2 : at + 12] = b"\xff" * 10
        target.write_bytes(bytes(png))
    rc, err = _render(tmp_path, _textured_scene(tmp_path, "t.png"), capsys)
    assert rc == 2, err
    assert err.startswith("error: ") and "Traceback" not in err and fragment in err, err


def test_scene_texture_16_bit_grey_renders_like_8_bit(tmp_path, capsys):
    Image.fromarray(np.full((4, 4), 32896, np.uint16)).save(tmp_path / "g16.png")
    Image.new("L", (4, 4), 128).save(tmp_path / "g8.png")
    images = []
    for name in ("g16.png", "g8.png"):
        rc, err = _render(tmp_path, _textured_scene(tmp_path, name), capsys)
        assert rc == 0, err
        images.append(np.asarray(Image.open(tmp_path / "o.png")))
    assert np.array_equal(images[0], images[1])
    assert images[0][16, 16, :3].max() < 250  # not white


def test_gltf_named_by_a_scene_is_cited_at_the_scene_line_and_names_the_gltf(tmp_path, capsys):
    write(tmp_path, with_camera(yfov=0), "cam.gltf")
    scene = tmp_path / "s.yaml"
    scene.write_text(
        "camera: {position: [0, 0, 3], target: [0, 0, 0]}\nnodes:\n  - {mesh: {file: cam.gltf}, material: {description: unlit}}\n"
    )
    rc, err = _render(tmp_path, scene, capsys)
    assert rc == 2, err
    assert "s.yaml:3" in err and "cam.gltf" in err and "yfov" in err and "Traceback" not in err, err


def test_gltf_json_nested_100k_deep_is_refused_without_recursion_error(tmp_path):
    path = tmp_path / "deep.gltf"
    path.write_text('{"asset": ' + "[" * 100_000 + "]" * 100_000 + "}")
    refused(path, "cannot read glTF file")


def test_camera_matrix_with_nan_is_refused(tmp_path):
    doc = with_camera()
    doc["nodes"][1] = {"camera": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, "NAN"]}
    path = tmp_path / "m.gltf"
    path.write_text(json.dumps(doc).replace('"NAN"', "NaN"))
    refused(path, "nodes[1].matrix must be 16 finite numbers")


@pytest.mark.parametrize(("image", "expected"), [("I;16", [128, 128, 128, 255]), ("LA", [100, 100, 100, 50])])
def test_gltf_grey_textures_read_as_written(tmp_path, image, expected):
    out = io.BytesIO()
    if image == "I;16":
        Image.fromarray(np.full((2, 2), 32896, np.uint16)).save(out, "PNG")  # 0x8080: half grey, not white
    else:
        Image.new("LA", (2, 2), (100, 50)).save(out, "PNG")
    doc = _textured(tmp_path, out.getvalue())
    doc["accessors"].append({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC2"})
    doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 2
    (root,) = load_gltf(write(tmp_path, doc)).nodes
    maps = [n.material.uniforms["base_color_map"] for n, _ in root.walk() if n.material is not None]
    assert [m.pixels[0, 0].tolist() for m in maps] == [expected]


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        (
            lambda d: d["accessors"][0].update(count=10**9),
            "accessors[0] (1000000000 x VEC3) reaches past bufferViews[0]",
        ),
        (lambda d: d["bufferViews"][0].update(byteLength=10**12), "bufferViews[0] (byteOffset 0"),
        (lambda d: d["buffers"][0].update(byteLength=10**6), "buffers[0] holds 60 bytes"),
        (lambda d: d["nodes"][0].update(mesh=7), "nodes[0].mesh = 7"),
        (lambda d: d.update(scene=5), "scene = 5"),
        (lambda d: d["nodes"][0].update(rotation=[0, 0, 0, 0]), "nodes[0].rotation is a zero quaternion"),
        (lambda d: d["accessors"][1].update(componentType=1), "accessors[1] needs"),
    ],
)
def test_inconsistent_gltf_objects_are_refused_by_path(tmp_path, change, fragment):
    doc = quad_doc()
    change(doc)
    refused(write(tmp_path, doc), fragment)


def test_fan_without_indices_is_triangulated(tmp_path):
    doc = quad_doc(mode=6)
    del doc["meshes"][0]["primitives"][0]["indices"]
    (mesh,) = load_gltf(write(tmp_path, doc)).meshes.values()
    assert mesh.indices.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_texture_image_scales_16_bit_and_zeroes_nan():
    from guaca_py.scene.texture import TextureImage

    assert TextureImage(np.full((1, 1), 32896, np.uint16)).pixels[0, 0].tolist() == [128, 128, 128, 255]
    assert TextureImage(np.array([[[np.nan, 0.5, 2.0]]])).pixels[0, 0].tolist() == [0, 128, 255, 255]


@pytest.mark.parametrize(("data", "fragment"), [(b"not a png", "not a readable image"), (None, "too many pixels")])
def test_mtl_colour_map_that_does_not_decode_is_refused(tmp_path, data, fragment):
    (tmp_path / "t.png").write_bytes(_bomb_png(60000) if data is None else data)
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 1 1 1\nmap_Kd t.png\n")
    path = tmp_path / "m.obj"
    path.write_text("mtllib m.mtl\nvt 0 0\n" + TRI + "usemtl a\nf 1/1 2/1 3/1\n")
    mesh_refused(path, "m.mtl:3", fragment)


def test_image_named_only_by_an_extension_is_not_decoded(tmp_path):
    doc = _textured(tmp_path, _png("RGB"))
    doc["images"].append({"uri": _data_uri(b"KTX2 data Pillow cannot read"), "mimeType": "image/ktx2"})
    doc["textures"][0]["extensions"] = {"KHR_texture_basisu": {"source": 1}}
    doc["extensionsUsed"] = ["KHR_texture_basisu"]
    assert load_gltf(write(tmp_path, doc)).nodes


_HOSTILE_VALUES = [float("nan"), float("inf"), -1, 0, 1e9, 2**40, "x", [], {}, None, True, [1, 2], -0.5, 3.5]


def _json_paths(value, prefix=()):
    yield prefix
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in items:
        yield from _json_paths(child, (*prefix, key))


@pytest.mark.parametrize("seed", range(3))
def test_mutated_gltf_is_loaded_or_refused_never_a_traceback(tmp_path, seed, request):
    """Mutation fuzzing: 1-3 fields of a valid glTF set to hostile values; only ConfigError may come out.

    `pytest --fuzz-cases N` raises the number of documents per seed (default 150) for a longer run.
    """
    import copy
    import random
    import warnings

    base = with_camera()
    base["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}, "alphaMode": "BLEND"}]
    base["meshes"][0]["primitives"][0]["material"] = 0
    fields = [p for p in _json_paths(base) if p and p[0] != "buffers"]
    rng = random.Random(seed)
    path = tmp_path / "fuzz.gltf"
    for _ in range(request.config.getoption("--fuzz-cases")):
        doc = copy.deepcopy(base)
        for field in rng.sample(fields, rng.randint(1, 3)):
            holder = doc  # an earlier mutation may have replaced a container on this field's path
            for key in field[:-1]:
                fits = isinstance(holder, dict) and key in holder
                fits = fits or (isinstance(holder, list) and isinstance(key, int) and key < len(holder))
                holder = holder[key] if fits else None
            key = field[-1]
            if isinstance(holder, dict) or (isinstance(holder, list) and isinstance(key, int) and key < len(holder)):
                holder[key] = rng.choice(_HOSTILE_VALUES)
        path.write_text(json.dumps(doc))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                load_gltf(path)
            except ConfigError as exc:
                assert "fuzz.gltf" in str(exc)


@pytest.mark.parametrize("seed", range(2))
def test_byte_mutated_mesh_files_are_loaded_or_refused_never_a_traceback(tmp_path, seed, request):
    """Byte-level fuzzing of OBJ, STL, PLY, OFF and GLB files (truncations and overwritten bytes).

    `pytest --fuzz-cases N` raises the number of files per seed (default 150) for a longer run.
    """
    import random
    import warnings

    import trimesh

    from guaca_py import load

    box = trimesh.creation.box()
    sources = {}
    for ext in ("obj", "stl", "ply", "off", "glb"):
        data = box.export(file_type=ext)
        sources[ext] = data.encode() if isinstance(data, str) else data
    rng = random.Random(seed)
    hostile = [0, 255, ord("-"), ord("n"), ord("9"), ord(" "), ord("\n")]
    for _ in range(request.config.getoption("--fuzz-cases")):
        ext = rng.choice(sorted(sources))
        data = bytearray(sources[ext])
        if rng.random() < 0.3:
            data = data[: rng.randrange(len(data))]
        else:
            for _ in range(rng.randint(1, 8)):
                data[rng.randrange(len(data))] = rng.choice([*hostile, rng.randrange(256)])
        path = tmp_path / f"fuzz.{ext}"
        path.write_bytes(bytes(data))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                load(path)
            except ConfigError as exc:
                assert "fuzz." in str(exc)


def test_out_of_range_ply_face_and_odd_obj_digits_are_refused(tmp_path):
    path = tmp_path / "o.obj"
    path.write_text(TRI + "f 1 2 7\u00b36\n")
    with pytest.raises(ConfigError):
        load_mesh(path)
    ply = tmp_path / "o.ply"
    ply.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 90\n"
    )
    mesh_refused(ply, "face indices outside its vertex list")


def test_obj_vertex_beyond_float32_is_refused_without_warnings(tmp_path, recwarn):
    path = tmp_path / "far.obj"
    path.write_text("v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    mesh_refused(path, "vertex coordinates up to 1e+39, beyond float32's range")
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_obj_with_huge_coordinates_keeps_its_distinct_vertices(tmp_path, recwarn):
    """trimesh's merge hashes coordinates x 1e8 as int64: at 1e12 it joined 300 vertices into 60; not merged now."""
    from guaca_py.scene.mesh_io import load_mesh_file

    rng = np.random.default_rng(0)
    v = rng.random((300, 3)) * 1e12
    faces = np.arange(300).reshape(100, 3) + 1
    path = tmp_path / "huge.obj"
    path.write_text(
        "".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in v) + "".join(f"f {a} {b} {c}\n" for a, b, c in faces)
    )
    mesh = load_mesh_file(path)
    assert len(mesh.positions) == 300 and np.allclose(mesh.positions[mesh.indices.reshape(-1)], v, rtol=1e-6)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def textured_quad(index: int) -> dict:
    doc = quad_doc()
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": index}}}]
    doc["meshes"][0]["primitives"][0]["material"] = 0
    return doc


@pytest.mark.parametrize(
    "change, fragment",
    [
        (lambda d: None, "materials[0].pbrMetallicRoughness.baseColorTexture.index = 0 is not an index below 0"),
        (lambda d: d.update(textures=[{"source": 3}]), "textures[0].source = 3 is not an index below 0"),
        (lambda d: d.update(textures=[{"sampler": 1}]), "textures[0].sampler = 1 is not an index below 0"),
        (
            lambda d: (d.update(textures=[{}]), d["materials"][0].update(normalTexture=5)),
            "materials[0].normalTexture must be an object",
        ),
    ],
    ids=["texture", "image", "sampler", "not-an-object"],
)
def test_dangling_texture_references_are_refused(tmp_path, change, fragment):
    """trimesh drops a texture that is not there and draws the model untextured: refused by its path instead."""
    doc = textured_quad(0)
    change(doc)
    refused(write(tmp_path, doc), fragment)


@pytest.mark.parametrize("binary_as", ["m.gltf", "m.glb"])
def test_the_container_is_read_by_its_content_not_its_name(tmp_path, binary_as):
    """JSON named .glb and a binary glTF named .gltf both load."""
    doc = quad_doc()
    if binary_as == "m.gltf":
        data = base64.b64decode(doc["buffers"][0].pop("uri").split(",", 1)[1])
        text = json.dumps(doc).encode()
        text += b" " * (-len(text) % 4)
        body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
        (tmp_path / binary_as).write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
    else:
        write(tmp_path, doc, binary_as)
    assert loaded_positions(tmp_path / binary_as) == [QUAD[k] for k in (0, 1, 2, 0, 2, 3)]


def test_a_file_without_scenes_draws_its_root_nodes(tmp_path):
    """glTF leaves a file without `scenes` to the reader: its root nodes are drawn (trimesh read nothing)."""
    doc = quad_doc()
    del doc["scenes"], doc["scene"]
    assert loaded_positions(write(tmp_path, doc)) == [QUAD[k] for k in (0, 1, 2, 0, 2, 3)]
