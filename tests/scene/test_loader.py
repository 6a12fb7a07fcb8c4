"""Tests for primitives, mesh file loading, YAML scene loading and the built-in demo scene."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh

from guaca_py.errors import ConfigError
from guaca_py.scene import PRIMITIVE_KINDS, demo_scene, load_mesh_file, load_scene, load_scene_text, make_primitive
from guaca_py.scene.graph import Transform


def _yaml(text: str) -> str:
    """Dedent a YAML snippet so line numbers in tests match what is written."""
    return textwrap.dedent(text).lstrip("\n")


def _scene_file(tmp_path: Path, text: str) -> Path:
    """Write a scene file and return its path."""
    p = tmp_path / "scene.yaml"
    p.write_text(_yaml(text), encoding="utf-8")
    return p


def _face_normals(mesh) -> np.ndarray:
    """Unnormalised normals from triangle winding (CCW = front)."""
    p = mesh.positions.astype(np.float64)[mesh.indices.astype(np.int64)]
    return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def _signed_volume(mesh) -> float:
    """Divergence-theorem volume: positive only when all faces wind outward."""
    p = mesh.positions.astype(np.float64)[mesh.indices.astype(np.int64)]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def _check_mesh_invariants(mesh) -> None:
    """Dtypes, shapes, unit normals, valid indices and winding agreeing with normals."""
    n = mesh.positions.shape[0]
    assert mesh.positions.dtype == np.float32 and mesh.positions.shape == (n, 3)
    assert mesh.normals.dtype == np.float32 and mesh.normals.shape == (n, 3)
    assert mesh.texcoords.dtype == np.float32 and mesh.texcoords.shape == (n, 2)
    assert mesh.indices.dtype == np.uint32 and mesh.indices.ndim == 2 and mesh.indices.shape[1] == 3
    assert mesh.indices.max() < n
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-5)
    fn = _face_normals(mesh)
    assert np.all(np.linalg.norm(fn, axis=1) > 1e-9), "degenerate triangles"
    vn = mesh.normals[mesh.indices.astype(np.int64)].sum(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, vn) > 0), "winding disagrees with vertex normals"


# ---- primitives -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kind, params, verts, tris",
    [
        ("quad", {"size": [2, 3]}, 4, 2),
        ("plane", {"size": [4, 2]}, 4, 2),
        ("plane", {"size": [4, 2], "subdivisions": 5}, 36, 50),
        ("box", {"size": [1, 2, 3]}, 24, 12),
        ("sphere", {"radius": 2, "segments": 12, "rings": 6}, 7 * 13, 2 * 12 * 5),
        ("cylinder", {"radius": 1, "height": 2, "segments": 10}, 22 + 22, 40),
        ("cylinder", {"radius": 1, "height": 2, "segments": 10, "capped": False}, 22, 20),
    ],
)
def test_primitive_counts_and_invariants(kind, params, verts, tris):
    mesh = make_primitive(kind, **params)
    assert mesh.positions.shape[0] == verts
    assert mesh.triangle_count == tris
    _check_mesh_invariants(mesh)
    assert np.all((mesh.texcoords >= 0) & (mesh.texcoords <= 1))


def test_flat_primitives_face_the_documented_axis():
    quad = make_primitive("quad", size=[2, 4])
    np.testing.assert_allclose(quad.normals, [[0, 0, 1]] * 4)
    assert np.all(_face_normals(quad)[:, 2] > 0)
    lo, hi = quad.bounds()
    np.testing.assert_allclose(lo, [-1, -2, 0])
    np.testing.assert_allclose(hi, [1, 2, 0])

    plane = make_primitive("plane", size=[6, 2], subdivisions=3)
    np.testing.assert_allclose(plane.normals, np.tile([0, 1, 0], (16, 1)))
    assert np.all(_face_normals(plane)[:, 1] > 0)
    lo, hi = plane.bounds()
    np.testing.assert_allclose(lo, [-3, 0, -1])
    np.testing.assert_allclose(hi, [3, 0, 1])


@pytest.mark.parametrize(
    "kind, params, volume, tol",
    [
        ("box", {"size": [1, 2, 3]}, 6.0, 1e-5),
        ("sphere", {"radius": 1.5, "segments": 64, "rings": 32}, 4 / 3 * math.pi * 1.5**3, 0.02),
        ("cylinder", {"radius": 0.5, "height": 3, "segments": 64}, math.pi * 0.25 * 3, 0.02),
    ],
)
def test_closed_primitives_wind_outward(kind, params, volume, tol):
    mesh = make_primitive(kind, **params)
    assert _signed_volume(mesh) == pytest.approx(volume, rel=tol)
    # Every face normal points away from the centre (all these shapes are convex and centred).
    centroids = mesh.positions[mesh.indices.astype(np.int64)].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", _face_normals(mesh), centroids) > 0)


def test_box_normals_are_flat_per_face_and_sphere_normals_radial():
    box = make_primitive("box", size=[2, 2, 2])
    for face in range(6):
        n = box.normals[4 * face : 4 * face + 4]
        assert np.all(n == n[0]) and sorted(np.abs(n[0])) == [0, 0, 1]
        # The face's vertices lie on the side its normal points to.
        np.testing.assert_allclose(box.positions[4 * face : 4 * face + 4] @ n[0], 1.0)
    assert {tuple(box.normals[4 * f]) for f in range(6)} == {
        (1, 0, 0),
        (-1, 0, 0),
        (0, 1, 0),
        (0, -1, 0),
        (0, 0, 1),
        (0, 0, -1),
    }

    sphere = make_primitive("sphere", radius=3, segments=16, rings=8)
    np.testing.assert_allclose(sphere.normals, sphere.positions / 3.0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(sphere.positions, axis=1), 3.0, atol=1e-5)


def test_unknown_primitive_lists_valid_kinds():
    with pytest.raises(ConfigError) as err:
        make_primitive("teapot")
    for kind in PRIMITIVE_KINDS:
        assert kind in err.value.hint


@pytest.mark.parametrize(
    "kind, params, key",
    [
        ("box", {"radius": 1}, "radius"),
        ("sphere", {"radius": -1}, "radius"),
        ("sphere", {"segments": 2}, "segments"),
        ("sphere", {"rings": 4.5}, "rings"),
        ("quad", {"size": [1, 2, 3]}, "size"),
        ("box", {"size": [1, 0, 1]}, "size"),
        ("cylinder", {"capped": 1}, "capped"),
        ("plane", {"subdivisions": True}, "subdivisions"),
    ],
)
def test_bad_primitive_params(kind, params, key):
    with pytest.raises(ConfigError) as err:
        make_primitive(kind, **params)
    assert err.value.key == key


def test_unknown_param_hint_lists_valid_params():
    with pytest.raises(ConfigError) as err:
        make_primitive("cylinder", radious=1)
    assert all(p in err.value.hint for p in ("radius", "height", "segments", "capped"))


# ---- transforms and the node tree ---------------------------------------------------------


def test_transforms_and_children_give_expected_world_matrices():
    scene = load_scene_text(
        _yaml("""
        nodes:
          - name: parent
            transform: {translation: [1, 0, 0], rotation_deg: [0, 90, 0]}
            children:
              - name: child
                transform: {translation: [0, 0, 1], scale: 2}
                children:
                  - name: grandchild
                    mesh: {primitive: box}
                    transform: {translation: [0, 1, 0], rotation_deg: [90, 0, 0], scale: [1, 2, 3]}
          - name: sibling
            transform: {translation: [0, 5, 0]}
    """),
        "inline.yaml",
    )
    walked = list(scene.walk())
    assert [n.name for n, _ in walked] == ["parent", "child", "grandchild", "sibling"]
    world = {n.name: m for n, m in walked}

    # Ry(90) maps local +Z to world +X, so the child sits at (1,0,0) + (1,0,0).
    np.testing.assert_allclose(world["child"][:3, 3], [2, 0, 0], atol=1e-12)
    np.testing.assert_allclose(world["child"][:3, :3] @ [0, 0, 1], [2, 0, 0], atol=1e-12)
    # The grandchild's +Y offset is scaled by the child's uniform scale of 2.
    np.testing.assert_allclose(world["grandchild"][:3, 3], [2, 2, 0], atol=1e-12)
    expected = (
        Transform((1, 0, 0), (0, 90, 0)).matrix()
        @ Transform((0, 0, 1), scale=(2, 2, 2)).matrix()
        @ Transform((0, 1, 0), (90, 0, 0), (1, 2, 3)).matrix()
    )
    np.testing.assert_allclose(world["grandchild"], expected, atol=1e-12)
    np.testing.assert_allclose(world["sibling"], Transform((0, 5, 0)).matrix())
    assert scene.nodes[0].mesh is None  # a group
    assert scene.nodes[0].children[0].children[0].mesh.triangle_count == 12


def test_defaults_and_unnamed_nodes():
    scene = load_scene_text(
        _yaml("""
        lights: [{position: [1, 2, 3]}]
        nodes:
          - {mesh: {primitive: sphere}}
          - children: [{}]
    """)
    )
    assert scene.background == (0.1, 0.1, 0.1) and scene.camera.fov_y == 60
    light = scene.lights[0]
    assert (light.type, light.intensity, light.radius) == ("point", 1.0, 10.0)
    assert scene.nodes[0].name == "nodes[0]" and scene.nodes[1].children[0].name == "nodes[1].children[0]"
    assert load_scene_text("").nodes == []


def test_lights_and_camera_are_parsed():
    scene = load_scene_text(
        _yaml("""
        camera: {position: [0, 2, 8], target: [0, 1, 0], fov_y: 45, near: 0.5, far: 40}
        background: [0, 0, 0.2]
        lights:
          - {type: point, position: [2, 3, 2], color: [1, 0.5, 0], intensity: 20, radius: 7}
          - {type: spot, position: [0, 4, 0], direction: [0, -2, 0], inner_angle_deg: 10, outer_angle_deg: 20}
          - {type: directional, direction: [0, 0, -3], color: [0.2, 0.2, 0.3], intensity: 0.5}
    """)
    )
    assert scene.camera.position == (0, 2, 8) and scene.camera.near == 0.5 and scene.camera.far == 40
    assert scene.background == (0, 0, 0.2)
    point, spot, sun = scene.lights
    assert (point.type, point.color, point.intensity, point.radius) == ("point", (1, 0.5, 0), 20, 7)
    assert spot.direction == (0, -1, 0) and (spot.inner_angle_deg, spot.outer_angle_deg) == (10, 20)
    assert sun.type == "directional" and sun.direction == (0, 0, -1)


def test_material_keeps_source_line_and_converts_uniforms():
    scene = load_scene_text(
        _yaml("""
        nodes:
          - name: a
            mesh: {primitive: quad}
            material:
              description: pbr
              uniforms: {albedo: [1, 0, 0], alpha: 1, double_sided: true, mode: fancy}
          - name: b
            material: unlit
    """),
        "m.yaml",
    )
    mat = scene.nodes[0].material
    assert mat.description == "pbr"
    assert mat.uniforms == {"albedo": (1.0, 0.0, 0.0), "alpha": 1.0, "double_sided": True, "mode": "fancy"}
    assert isinstance(mat.uniforms["alpha"], float)
    assert mat.source == ("m.yaml", 4)
    assert mat.uniform_lines["alpha"] == 6
    assert scene.nodes[1].material.description == "unlit"
    assert scene.nodes[1].material.source == ("m.yaml", 8)


# ---- paths -----------------------------------------------------------------------------------


def test_relative_mesh_and_texture_paths_resolve_against_scene_dir(tmp_path, monkeypatch):
    (tmp_path / "models").mkdir()
    (tmp_path / "tex").mkdir()
    tri = trimesh.Trimesh(vertices=[[0, 0, 0], [2, 0, 0], [0, 3, 0]], faces=[[0, 1, 2]], process=False)
    tri.export(tmp_path / "models" / "tri.obj")
    (tmp_path / "tex" / "albedo.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    scene_path = _scene_file(
        tmp_path,
        """
        nodes:
          - name: one
            mesh: {file: models/tri.obj}
            material: {description: pbr, uniforms: {albedo_map: tex/albedo.png}}
          - name: two
            mesh: {file: ./models/../models/tri.obj}
    """,
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # resolution must not depend on the cwd
    scene = load_scene(scene_path)
    mesh = scene.nodes[0].mesh
    assert mesh.triangle_count == 1
    np.testing.assert_allclose(mesh.bounds()[1], [2, 3, 0])
    assert scene.nodes[1].mesh is mesh  # same file is loaded once and shared
    tex = scene.nodes[0].material.uniforms["albedo_map"]
    assert Path(tex).is_absolute() and Path(tex) == (tmp_path / "tex" / "albedo.png").resolve()
    assert scene.source == scene_path.resolve()


def test_load_scene_text_uses_base_dir(tmp_path):
    trimesh.creation.box().export(tmp_path / "b.stl")
    scene = load_scene_text("nodes: [{mesh: {file: b.stl}}]", "mem.yaml", tmp_path)
    assert scene.nodes[0].mesh.triangle_count == 12


def test_missing_mesh_file_names_path_file_and_line(tmp_path):
    scene_path = _scene_file(
        tmp_path,
        """
        nodes:
          - name: ok
            mesh: {primitive: box}
          - name: lost
            mesh:
              file: models/nope.obj
    """,
    )
    with pytest.raises(ConfigError) as err:
        load_scene(scene_path)
    e = err.value
    assert "nope.obj" in str(e) and str(tmp_path) in str(e)
    assert Path(e.file) == scene_path and e.line == 6
    assert e.key == "nodes[1].mesh.file"


def test_missing_texture_is_an_error(tmp_path):
    scene_path = _scene_file(
        tmp_path,
        """
        nodes:
          - material: {description: pbr, uniforms: {albedo_map: gone.jpg}}
    """,
    )
    with pytest.raises(ConfigError) as err:
        load_scene(scene_path)
    assert "gone.jpg" in str(err.value) and err.value.line == 2


def test_missing_scene_file():
    with pytest.raises(ConfigError, match="not found"):
        load_scene("/definitely/not/here.yaml")


def _special(tmp_path: Path, kind: str, name: str) -> Path:
    """A FIFO, a folder or a device (a link to /dev/null) under `name`: no regular file, never to be opened."""
    import os

    p = tmp_path / name
    if kind == "device":
        p.symlink_to(os.devnull)
    else:
        os.mkfifo(p) if kind == "fifo" else p.mkdir()
    return p


SPECIAL = {
    "fifo": "is a FIFO, not a regular file",
    "directory": "is a directory",
    "device": "is a device, not a regular file",
}


@pytest.mark.parametrize("kind", SPECIAL)
def test_a_scene_file_that_is_no_regular_file_says_what_it_is(tmp_path, kind):
    """A FIFO given as the scene is refused by what it is (opening it would wait for a writer forever)."""
    p = _special(tmp_path, kind, "scene.yaml")
    with pytest.raises(ConfigError) as err:
        load_scene(p)
    assert f"scene file {SPECIAL[kind]}" in str(err.value) and "not found" not in str(err.value)
    assert Path(err.value.file) == p


@pytest.mark.parametrize("kind", SPECIAL)
def test_a_texture_that_is_no_regular_file_cites_the_scene_line(tmp_path, kind):
    texture = _special(tmp_path, kind, "tex.png")
    scene_path = _scene_file(
        tmp_path,
        f"""
        nodes:
          - mesh: {{primitive: box}}
            material: {{description: pbr_textured, uniforms: {{albedo_map: {texture}}}}}
    """,
    )
    with pytest.raises(ConfigError) as err:
        load_scene(scene_path)
    e = err.value
    assert f"texture file {SPECIAL[kind]}: {texture.resolve()}" in str(e) and "not found" not in str(e)
    assert Path(e.file) == scene_path and e.line == 3 and e.key == "nodes[0].material.uniforms.albedo_map"


@pytest.mark.parametrize("fmt, suffix", [("WEBP", ".webp"), ("BMP", ".bmp"), ("GIF", ".gif"), ("TIFF", ".tif")])
def test_textures_of_every_image_suffix_resolve_against_the_scene(tmp_path, fmt, suffix):
    """Not only .png/.jpg: any image suffix Pillow reads names a texture beside the scene (not beside the material)."""
    from PIL import Image

    Image.new("RGB", (2, 2), (255, 0, 0)).save(tmp_path / f"t{suffix}", fmt)
    scene = load_scene_text(
        f"nodes: [{{material: {{description: pbr_textured, uniforms: {{albedo_map: t{suffix}}}}}}}]", "s.yaml", tmp_path
    )
    assert scene.nodes[0].material.uniforms["albedo_map"] == str(tmp_path / f"t{suffix}")


def test_a_texture_link_loop_is_refused_at_its_line(tmp_path):
    (tmp_path / "loop.png").symlink_to("loop.png")
    with pytest.raises(ConfigError) as err:
        load_scene_text(
            "nodes:\n  - material: {description: pbr_textured, uniforms: {albedo_map: loop.png}}\n", "s.yaml", tmp_path
        )
    assert err.value.line == 2 and "symbolic links" in str(err.value) and "loop.png" in str(err.value)


def test_a_control_character_in_a_scene_is_one_line_at_its_line():
    with pytest.raises(ConfigError) as err:
        load_scene_text("nodes:\n  - name: a\0b\n", "s.yaml")
    assert str(err.value).count("\n") == 0 and err.value.line == 2 and "#x0000 is not allowed" in str(err.value)


@pytest.mark.parametrize("suffix,what", [(".obj", "mesh file"), (".glb", "glTF file")])
@pytest.mark.parametrize("kind", SPECIAL)
def test_a_mesh_that_is_no_regular_file_cites_the_scene_line(tmp_path, kind, suffix, what):
    mesh = _special(tmp_path, kind, "model" + suffix)
    scene_path = _scene_file(tmp_path, f"nodes:\n  - name: a\n    mesh: {{file: '{mesh}'}}\n")
    with pytest.raises(ConfigError) as err:
        load_scene(scene_path)
    e = err.value
    assert f"{what} {SPECIAL[kind]}" in str(e) and str(mesh.resolve()) in str(e)
    assert Path(e.file) == scene_path and e.line == 3 and e.key == "nodes[0].mesh.file"


# ---- mesh files ------------------------------------------------------------------------------


def test_obj_without_normals_or_texcoords(tmp_path):
    # A tetrahedron with outward CCW faces, written by hand: only v and f lines.
    p = tmp_path / "tet.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    mesh = load_mesh_file(p)
    _check_mesh_invariants(mesh)
    assert mesh.triangle_count == 4 and mesh.positions.shape == (4, 3)
    np.testing.assert_array_equal(mesh.texcoords, np.zeros((4, 2), np.float32))
    # Smooth normals point away from the centroid.
    assert np.all(np.einsum("ij,ij->i", mesh.normals, mesh.positions - mesh.positions.mean(0)) > 0)
    assert mesh.name == "tet"


def test_flat_obj_gets_normals_from_winding(tmp_path):
    p = tmp_path / "sq.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    mesh = load_mesh_file(p)
    np.testing.assert_allclose(mesh.normals, [[0, 0, 1]] * 4, atol=1e-6)


def test_obj_with_normals_and_uvs_keeps_them(tmp_path):
    p = tmp_path / "tri.obj"
    p.write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.5\nvt 1 0\nvt 0 1\nvn 0 0 2\nvn 0 0 2\nvn 0 0 2\nf 1/1/1 2/2/2 3/3/3\n"
    )
    mesh = load_mesh_file(p)
    np.testing.assert_allclose(mesh.normals, [[0, 0, 1]] * 3, atol=1e-6)  # normalised
    assert sorted(map(tuple, mesh.texcoords.tolist())) == [(0, 1), (0.25, 0.5), (1, 0)]


def test_gltf_scene_is_flattened_with_transforms(tmp_path):
    sc = trimesh.Scene()
    sc.add_geometry(
        trimesh.creation.box(), node_name="a", transform=trimesh.transformations.translation_matrix([5, 0, 0])
    )
    sc.add_geometry(trimesh.creation.box(), node_name="b")
    sc.export(tmp_path / "two.glb")
    mesh = load_mesh_file(tmp_path / "two.glb")
    assert mesh.triangle_count == 24
    lo, hi = mesh.bounds()
    np.testing.assert_allclose(lo, [-0.5, -0.5, -0.5], atol=1e-6)
    np.testing.assert_allclose(hi, [5.5, 0.5, 0.5], atol=1e-6)
    _check_mesh_invariants(mesh)


def test_point_cloud_and_empty_files_are_rejected(tmp_path):
    trimesh.PointCloud(np.random.default_rng(0).random((20, 3))).export(tmp_path / "pts.ply")
    with pytest.raises(ConfigError, match="not a triangle mesh"):
        load_mesh_file(tmp_path / "pts.ply", "scene.yaml", 7)
    (tmp_path / "empty.obj").write_text("# nothing here\n")
    with pytest.raises(ConfigError) as err:
        load_mesh_file(tmp_path / "empty.obj", "scene.yaml", 9)
    assert (err.value.file, err.value.line) == ("scene.yaml", 9)
    (tmp_path / "verts.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(ConfigError):
        load_mesh_file(tmp_path / "verts.obj")


def test_unsupported_mesh_format(tmp_path):
    (tmp_path / "m.txt").write_text("hello")
    with pytest.raises(ConfigError, match="cannot read"):
        load_mesh_file(tmp_path / "m.txt")


# ---- errors with lines -----------------------------------------------------------------------


def _error(text: str) -> ConfigError:
    with pytest.raises(ConfigError) as err:
        load_scene_text(_yaml(text), "bad.yaml")
    assert err.value.file == "bad.yaml"
    return err.value


def test_broken_yaml_reports_line():
    e = _error("""
        background: [0.1, 0.1, 0.1]
        lights: []
        nodes:
          - name: a
            transform: translation: [1, 2, 3]
    """)
    assert e.line == 5 and "invalid YAML" in e.reason


def test_unclosed_bracket_reports_a_line():
    e = _error("""
        background: [0.1, 0.1, 0.1
        nodes: []
    """)
    assert e.line is not None and e.line >= 1 and "invalid YAML" in e.reason


@pytest.mark.parametrize(
    "text, line, key",
    [
        ("background: [0, 0, 0]\nlightz: []\n", 2, "lightz"),
        ("nodes:\n  - name: a\n    mesh: {primitive: box}\n    materail: {description: pbr}\n", 4, "nodes[0].materail"),
        ("camera:\n  position: [0, 1, 5]\n  fov: 60\n", 3, "camera.fov"),
        ("lights:\n  - type: point\n    colour: [1, 1, 1]\n", 3, "lights[0].colour"),
        ("nodes:\n  - transform: {translation: [0, 0, 0], rotate: [0, 1, 0]}\n", 2, "nodes[0].transform.rotate"),
    ],
)
def test_unknown_key_names_key_and_line(text, line, key):
    e = _error(text)
    assert (e.line, e.key) == (line, key)
    assert key.rsplit(".", 1)[-1] in str(e) and f"bad.yaml:{line}" in str(e)
    assert e.hint and "valid keys" in e.hint


@pytest.mark.parametrize(
    "text, line, key",
    [
        ("nodes:\n  - name: a\n    transform:\n      translation: [1, 2]\n", 4, "nodes[0].transform.translation"),
        ("background: [0, 0, 0, 1]\n", 1, "background"),
        ("lights:\n  - {type: point, color: [1, 1]}\n", 2, "lights[0].color"),
        ("camera: {up: [0, 1, 0, 0]}\n", 1, "camera.up"),
        ("nodes:\n  - transform: {scale: [1, 1]}\n", 2, "nodes[0].transform.scale"),
    ],
)
def test_wrong_vector_length_rejected(text, line, key):
    e = _error(text)
    assert (e.line, e.key) == (line, key)
    assert "expected 3 numbers" in e.reason


@pytest.mark.parametrize(
    "text, line, key, fragment",
    [
        ("lights:\n  - type: laser\n", 2, "lights[0].type", "unknown light type"),
        ("lights:\n  - {type: directional, position: [0, 1, 0]}\n", 2, "lights[0].position", "does not apply"),
        ("lights:\n  - {type: point,\n     intensity: bright}\n", 3, "lights[0].intensity", "expected a number"),
        ("lights:\n  - {type: point, radius: 0}\n", 2, "lights[0].radius", "out of range"),
        (
            "lights:\n  - {type: spot, inner_angle_deg: 40, outer_angle_deg: 30}\n",
            2,
            "lights[0].inner_angle_deg",
            "exceeds",
        ),
        ("lights:\n  - {type: spot, direction: [0, 0, 0]}\n", 2, "lights[0].direction", "zero"),
        ("lights: {type: point}\n", 1, "lights", "expected a list"),
        ("nodes:\n  - name: a\n  - mesh: box\n", 3, "nodes[1].mesh", "expected a mapping"),
        ("nodes:\n  - mesh: {primitive: sphere,\n           radius: -1}\n", 3, "nodes[0].mesh.radius", "radius"),
        ("nodes:\n  - mesh: {primitive: teapot}\n", 2, "nodes[0].mesh.primitive", "unknown primitive"),
        ("nodes:\n  - mesh: {primitive: box, file: a.obj}\n", 2, "nodes[0].mesh", "exactly one"),
        ("nodes:\n  - transform: {scale: 0}\n", 2, "nodes[0].transform.scale", "non-zero"),
        ("nodes:\n  - material: {uniforms: {alpha: 0.5}}\n", 2, "nodes[0].material", "description"),
        ("camera: {fov_y: '60'}\n", 1, "camera.fov_y", "expected a number"),
        ("camera: {near: 10, far: 5}\n", 1, "camera.far", "greater than near"),
        ("camera: {position: [0, 0, 0], target: [0, 0, 0]}\n", 1, "camera.target", "equals"),
        ("nodes: []\nnodes: []\n", 2, "nodes", "duplicate"),
        ("- just\n- a list\n", 1, None, "expected a mapping"),
    ],
)
def test_invalid_values_report_key_and_line(text, line, key, fragment):
    e = _error(text)
    assert (e.line, e.key) == (line, key)
    assert fragment in str(e)


# ---- demo scene ------------------------------------------------------------------------------


def _is_transparent(node) -> bool:
    mat = node.material
    return mat is not None and (mat.description == "fresnel_glass" or mat.uniforms.get("alpha", 1.0) < 1.0)


def _world_corners(mesh, world) -> np.ndarray:
    lo, hi = mesh.bounds()
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return (world @ corners.T).T[:, :3]


def test_demo_scene_contents():
    scene = demo_scene()
    assert scene.source is not None and scene.source.name == "demo_scene.yaml"
    assert len(scene.lights) >= 4
    assert {l.type for l in scene.lights} == {"point", "spot", "directional"}
    assert len({l.color for l in scene.lights}) >= 3  # coloured, not all white
    drawn = [(n, w) for n, w in scene.walk() if n.mesh is not None]
    for node, _ in drawn:
        _check_mesh_invariants(node.mesh)
        assert node.material is not None
        assert node.material.description in {"pbr", "unlit", "fresnel_glass"}
    transparent = [(n, w) for n, w in drawn if _is_transparent(n)]
    opaque = [n for n, _ in drawn if not _is_transparent(n)]
    assert len(transparent) >= 3 and len(opaque) >= 3
    assert {n.material.description for n, _ in transparent} >= {"pbr", "unlit", "fresnel_glass"}
    for n, _ in transparent:
        if "alpha" in n.material.uniforms:
            assert 0.3 <= n.material.uniforms["alpha"] <= 0.6
    ground = next(n for n, _ in drawn if n.name == "ground")
    assert ground.material.uniforms == {"albedo": (0.6, 0.6, 0.6), "roughness": 0.6, "metalness": 0.0}

    # Transparent objects must overlap each other (world AABBs intersect) for the demo to mean anything.
    boxes = [(c.min(0), c.max(0)) for c in (_world_corners(n.mesh, w) for n, w in transparent)]
    overlapping = sum(np.all(a[0] < b[1]) and np.all(b[0] < a[1]) for i, a in enumerate(boxes) for b in boxes[i + 1 :])
    assert overlapping >= 3


def test_demo_camera_frames_every_object():
    scene = demo_scene()
    cam = scene.camera
    vp = cam.projection_matrix(16 / 9) @ cam.view_matrix()
    for node, world in scene.walk():
        if node.mesh is None or node.name == "ground":  # the ground deliberately runs off-screen
            continue
        pts = np.c_[_world_corners(node.mesh, world), np.ones(8)]
        clip = (vp @ pts.T).T
        assert np.all(clip[:, 3] > 0), node.name
        ndc = clip[:, :3] / clip[:, 3:4]
        assert np.all(np.abs(ndc) <= 1.0), node.name


def test_scene_file_not_utf8_names_the_byte_and_its_line(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_bytes(b"camera: {fov_y: 50}\n# caf\xe9\nnodes: []\n")
    with pytest.raises(ConfigError) as err:
        load_scene(p)
    assert (err.value.file, err.value.line) == (p, 2)
    assert "not UTF-8 text (byte 0xe9 on line 2)" in err.value.reason and err.value.hint == "save the file as UTF-8"


def test_huge_light_direction_in_yaml_normalises_without_overflow(tmp_path):
    # scaled by its largest component first: 1e300 squared would overflow to infinity and normalise to zero
    from guaca_py.scene.loader import load_scene_text

    text = (
        "camera: {position: [0, 0, 4], target: [0, 0, 0]}\n"
        "lights: [{type: directional, direction: [1.0e+300, -1.0e+300, 0]}]\n"
        "nodes: []\n"
    )
    d = load_scene_text(text, "s.yaml", tmp_path).lights[0].direction
    assert d == pytest.approx((2**-0.5, -(2**-0.5), 0.0))
