"""Assets as their authors meant them: glTF camera world transforms, cameras that see nothing, OBJ/MTL
textures and dissolve, trimesh scenes, the default light rig, and `guaca_py.load` on every kind of file."""

from __future__ import annotations

import json
import struct
import warnings

import numpy as np
import pytest

import guaca_py
from guaca_py.reference import compare, reference_of, unlit
from guaca_py.scene import Light, Node, Scene, SceneWarning, Transform, as_scene, load_scene
from guaca_py.scene.framing import camera_sees

SIZE = 64
BACKGROUND = (0.1, 0.1, 0.1)
#: an ambient light of intensity 1 alone: every lit material shows its albedo, as unlit would
AMBIENT_ONLY = [Light(type="ambient", intensity=1.0)]


def srgb_to_linear(c: float) -> float:
    """The sRGB decoding the gltf_* materials apply to colour textures."""
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def edit_glb(data: bytes, edit) -> bytes:
    """A .glb whose JSON chunk `edit(doc)` changed in place (the binary chunk kept as it is)."""
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + n])
    edit(doc)
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)  # chunks are 4-byte aligned; JSON pads with spaces
    body = struct.pack("<I", len(text)) + b"JSON" + text + data[20 + n :]
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def box_glb(camera_parent_scale: float, camera_local: list[float], yaw_deg: float = 0.0) -> bytes:
    """A yellow box of side 100 under a root node scaled by `camera_parent_scale`, its camera a sibling
    of the box under the same root (as in Duck.glb): the camera's world position is scale * local."""
    import trimesh
    from trimesh.visual.material import PBRMaterial

    box = trimesh.creation.box(extents=(100.0, 100.0, 100.0))
    box.visual = trimesh.visual.TextureVisuals(
        material=PBRMaterial(baseColorFactor=[255, 200, 0, 255], metallicFactor=0.0, roughnessFactor=0.6)
    )
    sc = trimesh.Scene()
    sc.add_geometry(box, node_name="model", geom_name="box")

    def edit(doc):
        mesh_nodes = doc["scenes"][0]["nodes"]
        doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.5, "zfar": 100.0}}]
        half = np.radians(yaw_deg) / 2.0
        doc["nodes"].append(
            {
                "name": "camera1",
                "camera": 0,
                "translation": camera_local,
                "rotation": [0, np.sin(half), 0, np.cos(half)],
            }
        )
        camera = len(doc["nodes"]) - 1
        s = camera_parent_scale
        doc["nodes"].append({"name": "root", "scale": [s, s, s], "children": [*mesh_nodes, camera]})
        doc["scenes"][0]["nodes"] = [len(doc["nodes"]) - 1]

    return edit_glb(sc.export(file_type="glb"), edit)


def _covered(image: np.ndarray, background: np.ndarray) -> float:
    """Fraction of pixels that differ from the background colour."""
    return float(np.mean(np.abs(image[..., :3].astype(int) - background.astype(int)).max(axis=2) > 8))


def test_gltf_camera_under_a_scaled_node_takes_its_world_transform(tmp_path, renderer_factory):
    path = tmp_path / "scaled.glb"
    path.write_bytes(box_glb(0.01, [0.0, 150.0, 400.0]))
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)  # the file's camera sees the model: no warning
        scene = guaca_py.load(path)
    cam = scene.camera
    np.testing.assert_allclose(cam.position, (0.0, 1.5, 4.0), atol=1e-9)  # root scale 0.01 times the local 400
    np.testing.assert_allclose(np.subtract(cam.target, cam.position), (0.0, 0.0, -1.0), atol=1e-9)
    assert cam.fov_y == pytest.approx(np.degrees(0.7)) and cam.near == 0.5 and cam.far == 100.0
    frame = renderer_factory("default").render(scene, SIZE, SIZE)
    bg = frame.image[0, 0]
    assert _covered(frame.image, bg) > 0.05  # the box shows (below the image centre: the eye is 1.5 up)
    rows = np.flatnonzero(np.abs(frame.image[..., :3].astype(int) - bg[:3].astype(int)).max(axis=(1, 2)) > 8)
    assert rows.min() > SIZE // 2


def test_gltf_camera_that_sees_nothing_frames_the_model_and_warns(tmp_path, renderer_factory):
    path = tmp_path / "away.glb"
    path.write_bytes(box_glb(0.01, [0.0, 0.0, 400.0], yaw_deg=180.0))  # at (0, 0, 4), looking away along +Z
    with pytest.warns(SceneWarning, match="sees none of the model"):
        scene = guaca_py.load(path)
    lo, hi = np.array([-0.5] * 3), np.array([0.5] * 3)
    assert camera_sees(scene.camera, lo, hi)
    assert np.linalg.norm(scene.camera.target) < 1e-9  # the framing camera aims at the box's centre
    frame = renderer_factory("default").render(scene, SIZE, SIZE)
    assert _covered(frame.image, frame.image[0, 0]) > 0.1


def test_camera_sees_rejects_boxes_behind_beside_and_past_far():
    from guaca_py.scene import Camera

    cam = Camera(position=(0, 0, 5), target=(0, 0, 0), fov_y=40, near=0.1, far=20)
    lo, hi = np.array([-0.5] * 3), np.array([0.5] * 3)
    assert camera_sees(cam, lo, hi)
    assert not camera_sees(cam, lo + [0, 0, 10], hi + [0, 0, 10])  # behind the eye
    assert not camera_sees(cam, lo + [30, 0, 0], hi + [30, 0, 0])  # far to the side
    assert not camera_sees(cam, lo - [0, 0, 40], hi - [0, 0, 40])  # beyond the far plane
    assert camera_sees(cam, lo * 40, hi * 40)  # the eye inside the box: no corner in view, still seen


def write_obj_with_mtl(folder, dissolve: str = "d 0.5") -> tuple:
    """A 2x2 quad facing +Z with an MTL naming a map_Kd texture: left half red, right half sRGB grey 128,
    the image's top quarter blue (OBJ texture coordinates start at the image's bottom left)."""
    from PIL import Image

    px = np.zeros((32, 32, 3), np.uint8)
    px[:, :16] = (255, 0, 0)
    px[:, 16:] = (128, 128, 128)
    px[:8] = (0, 0, 255)
    Image.fromarray(px).save(folder / "tex.png")
    (folder / "quad.mtl").write_text(f"newmtl glass\nKd 1 1 1\nNs 10\n{dissolve}\nmap_Kd tex.png\n")
    (folder / "quad.obj").write_text(
        "mtllib quad.mtl\n"
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
        "usemtl glass\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
    )
    return folder / "quad.obj", srgb_to_linear(128 / 255)


def test_obj_mtl_texture_and_dissolve(tmp_path, renderer_factory):
    path, grey = write_obj_with_mtl(tmp_path)
    scene = guaca_py.load(path)
    ((node, _),) = list(scene.walk())
    assert node.material.description == "gltf_blend"
    assert node.material.uniforms["base_color"] == [1.0, 1.0, 1.0, 0.5]  # Kd, alpha = d
    assert "base_color_map" in node.material.uniforms
    from guaca_py.scene import Camera

    scene.camera = Camera(position=(0, 0, 3), target=(0, 0, 0), fov_y=60, near=0.1, far=10)
    scene.lights, scene.background = list(AMBIENT_ONLY), BACKGROUND
    frame = renderer_factory("exact").render(scene, SIZE, SIZE)
    img = frame.image[..., :3].astype(float) / 255.0
    bg = np.array(BACKGROUND)
    # the quad covers rows and columns 13.5 to 50.5: its top quarter is rows 13.5 to 22.75
    regions = (  # away from the texture's edges
        (img[15:21, 20:44], (0.0, 0.0, 1.0)),  # the image's top quarter: blue
        (img[26:46, 18:28], (1.0, 0.0, 0.0)),  # left half: red
        (img[26:46, 36:46], (grey, grey, grey)),  # right half: sRGB 128, decoded
    )
    for got, colour in regions:
        expected = 0.5 * np.array(colour) + 0.5 * bg  # alpha d = 0.5 over the background
        np.testing.assert_allclose(got.reshape(-1, 3), np.broadcast_to(expected, (got.size // 3, 3)), atol=2 / 255)
    assert frame.stats["transparent_draws"] == 1


@pytest.mark.parametrize(("line", "alpha"), [("Tr 0.25", 0.75), ("d 0.3\nTr 0.9", 0.3), ("", 1.0)])
def test_mtl_tr_is_one_minus_d_and_d_wins(tmp_path, line, alpha):
    path, _ = write_obj_with_mtl(tmp_path, line)
    ((node, _),) = list(guaca_py.load(path).walk())
    assert node.material.uniforms["base_color"][3] == pytest.approx(alpha)
    assert node.material.description == ("gltf_opaque" if alpha == 1.0 else "gltf_blend")


def translucent_box_scene():
    """A trimesh scene: a translucent red box (face colours, alpha 128) under a moved and rotated parent,
    and an opaque blue plate behind it (a PBR material), seen by the scene's camera."""
    import trimesh
    from trimesh.visual.material import PBRMaterial

    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    box.visual.face_colors = [255, 0, 0, 128]
    plate = trimesh.creation.box(extents=(3.0, 3.0, 0.1))
    plate.visual = trimesh.visual.TextureVisuals(
        material=PBRMaterial(baseColorFactor=[0, 0, 255, 255], metallicFactor=0.0)
    )
    t = trimesh.transformations
    sc = trimesh.Scene()
    sc.graph.update(frame_to="group", matrix=t.translation_matrix([0.2, 0.0, 0.0]) @ t.rotation_matrix(0.4, [0, 1, 0]))
    sc.add_geometry(box, node_name="box", geom_name="box", parent_node_name="group")
    sc.add_geometry(plate, node_name="plate", geom_name="plate", transform=t.translation_matrix([0, 0, -1.5]))
    sc.camera = trimesh.scene.Camera(fov=(45, 45), resolution=(SIZE, SIZE), z_near=0.1, z_far=30.0)
    sc.camera_transform = t.translation_matrix([0.0, 0.3, 4.0])
    return sc


def test_from_trimesh_keeps_graph_camera_and_alpha_and_matches_the_reference(renderer_factory):
    sc = translucent_box_scene()
    scene = Scene.from_trimesh(sc)
    worlds = {n.name: (n, w) for n, w in scene.walk()}
    assert [n.name for n in scene.nodes] == ["group", "plate"]
    assert [c.name for c in scene.nodes[0].children] == ["box"]
    np.testing.assert_allclose(worlds["box"][1], sc.graph["box"][0], atol=1e-12)  # parent * child, as trimesh
    assert worlds["group"][0].transform.has_matrix
    assert scene.camera.position == pytest.approx((0.0, 0.3, 4.0)) and scene.camera.fov_y == pytest.approx(45.0)
    box, plate = worlds["box"][0].material, worlds["plate"][0].material
    assert box.description == "pbr" and box.uniforms == {"albedo": [1.0, 0.0, 0.0], "alpha": 128 / 255}
    assert plate.description == "gltf_opaque"
    assert [l.type for l in scene.lights] == ["directional", "directional", "ambient"]

    # lit by an ambient light of 1 only, each material shows its albedo: the unlit reference's case
    scene.lights, scene.background = list(AMBIENT_ONLY), BACKGROUND
    ref_nodes = [
        Node("box", Transform(matrix=worlds["box"][1]), worlds["box"][0].mesh, unlit((1.0, 0.0, 0.0), 128 / 255)),
        Node("plate", Transform(matrix=worlds["plate"][1]), worlds["plate"][0].mesh, unlit((0.0, 0.0, 1.0))),
    ]
    ref, mask, layers = reference_of(Scene(camera=scene.camera, background=BACKGROUND, nodes=ref_nodes), SIZE, SIZE)
    assert layers.max() >= 3  # both faces of the box over the plate
    frame = renderer_factory("exact").render(scene, SIZE, SIZE)
    err = compare(frame.image, ref, mask)
    assert err["max_abs_255"] <= 2.0, err
    assert frame.stats["transparent_draws"] == 1


def test_from_trimesh_takes_a_single_mesh_and_pbr_blend(renderer_factory):
    import trimesh
    from trimesh.visual.material import PBRMaterial

    mesh = trimesh.creation.icosphere(subdivisions=2)
    mesh.visual = trimesh.visual.TextureVisuals(
        material=PBRMaterial(baseColorFactor=[0, 255, 0, 100], alphaMode="BLEND", doubleSided=True)
    )
    scene = Scene.from_trimesh(mesh)
    ((node, _),) = list(scene.walk())
    assert node.material.description == "gltf_blend"
    assert node.material.uniforms["base_color"][3] == pytest.approx(100 / 255)
    frame = renderer_factory("default").render(scene, SIZE, SIZE)
    assert frame.stats["transparent_draws"] == 1 and _covered(frame.image, frame.image[0, 0]) > 0.2


def test_as_scene_converts_trimesh_once_and_names_the_loaders():
    import trimesh

    sc = translucent_box_scene()
    first = as_scene(sc)
    assert isinstance(first, Scene) and as_scene(sc) is first  # one conversion while the content is the same
    assert as_scene(first) is first
    sc.add_geometry(trimesh.creation.box(), node_name="extra")
    assert as_scene(sc) is not first and len(list(as_scene(sc).walk())) == 4
    with pytest.raises(TypeError, match=r"guaca_py\.load"):
        as_scene("model.glb")
    with pytest.raises(TypeError, match=r"Scene\.from_trimesh"):
        as_scene(object())


def test_load_reads_every_kind_and_load_scene_passes_models_on(tmp_path):
    import trimesh

    (tmp_path / "s.yaml").write_text("nodes: [{mesh: {primitive: box, size: [1, 2, 0.5]}, material: pbr}]\n")
    mesh = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
    for suffix in ("obj", "ply", "stl", "glb", "off"):
        mesh.export(tmp_path / f"m.{suffix}")
    files = trimesh.Scene(mesh).export(file_type="gltf", embed_buffers=True)  # {name: bytes}, buffers inline
    (tmp_path / "m.gltf").write_bytes(files["model.gltf"])
    (tmp_path / "binary.model").write_bytes((tmp_path / "m.glb").read_bytes())  # a .glb under another name
    for name in ("s.yaml", "m.obj", "m.ply", "m.stl", "m.glb", "m.gltf", "m.off", "binary.model"):
        scene = guaca_py.load(tmp_path / name)
        meshes = [n for n, _ in scene.walk() if n.mesh is not None]
        assert len(meshes) == 1, name
        lo, hi = meshes[0].mesh.bounds()
        np.testing.assert_allclose(hi - lo, [1.0, 2.0, 0.5], atol=1e-6, err_msg=name)
        if name != "s.yaml":
            assert scene.source == (tmp_path / name).resolve() and len(scene.lights) == 3
    # load_scene on a model file reads it with its own reader instead of failing as non-UTF-8 YAML
    assert len(list(load_scene(tmp_path / "m.glb").walk())) == 1
    with pytest.raises(guaca_py.ConfigError, match="scene file not found"):
        guaca_py.load(tmp_path / "missing.yaml")


def test_vertex_colours_that_vary_warn_and_use_the_main_colour(tmp_path):
    import trimesh

    mesh = trimesh.creation.box()
    colors = np.tile([[0, 255, 0, 255]], (len(mesh.faces), 1))
    colors[0] = [255, 0, 0, 255]
    mesh.visual.face_colors = colors
    mesh.export(tmp_path / "c.ply")
    with pytest.warns(SceneWarning, match="colours vary"):
        scene = guaca_py.load(tmp_path / "c.ply")
    ((node, _),) = list(scene.walk())
    assert node.material.uniforms["albedo"] == [0.0, 1.0, 0.0]


def test_default_rig_leaves_no_face_black(tmp_path, renderer_factory):
    import trimesh

    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(tmp_path / "b.stl")
    scene = guaca_py.load(tmp_path / "b.stl")
    cam = scene.camera
    cam.position = tuple(2.0 * np.asarray(cam.target) - np.asarray(cam.position))  # from behind the lights
    scene.background = (0.0, 0.0, 0.0)
    frame = renderer_factory("default").render(scene, SIZE, SIZE)
    img = frame.image[..., :3].astype(int)
    covered = img.max(axis=2) > 0
    assert covered.mean() > 0.1
    centre = img[SIZE // 2 - 4 : SIZE // 2 + 4, SIZE // 2 - 4 : SIZE // 2 + 4]
    assert centre.min() >= 20  # faces neither directional light reaches still show (the ambient term)
