"""glTF 2.0 scenes: hierarchy, camera, OPAQUE / MASK / BLEND materials against the reference, CLI and YAML use."""

from __future__ import annotations

import numpy as np
import pytest

from guaca_py import load
from guaca_py.cli import main
from guaca_py.reference import compare, quad_mesh, reference_of, unlit
from guaca_py.scene.gltf import load_gltf
from guaca_py.scene.graph import Node, Scene, Transform
from guaca_py.scene.loader import load_scene_text

SIZE = 64
GREY_SRGB = 128  # sRGB 128 decodes to linear 0.2158605
GREY_LINEAR = ((128 / 255 + 0.055) / 1.055) ** 2.4


def _trimesh_quad(half: float, material, normal_z: float = 1.0):
    import trimesh

    v = np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]]) if normal_z > 0 else np.array([[0, 2, 1], [0, 3, 2]])
    m = trimesh.Trimesh(v, f, process=False)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    m.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    return m


def write_test_glb(path):
    """Four quads in a parent/child chain with a camera: OPAQUE (alpha ignored, sRGB emissive texture),
    MASK (left half of the texture below the cutoff), BLEND, and a back-facing single-sided OPAQUE quad."""
    import trimesh
    from PIL import Image
    from trimesh.visual.material import PBRMaterial

    mask_px = np.full((64, 64, 4), 255, np.uint8)
    mask_px[:, :32, 3] = 40  # u < 0.5: alpha 0.16 < cutoff 0.5 -> discarded
    grey = np.full((8, 8, 3), GREY_SRGB, np.uint8)
    black = [0.0, 0.0, 0.0]
    mats = {
        "opaque": PBRMaterial(
            name="opaque",
            baseColorFactor=black + [0.3],
            emissiveFactor=[1.0, 0.0, 0.0],
            emissiveTexture=Image.fromarray(grey),
            alphaMode="OPAQUE",
            doubleSided=True,
        ),
        "mask": PBRMaterial(
            name="mask",
            baseColorFactor=black + [1.0],
            baseColorTexture=Image.fromarray(mask_px),
            emissiveFactor=[0.0, 0.8, 0.1],
            alphaMode="MASK",
            alphaCutoff=0.5,
            doubleSided=True,
        ),
        "blend": PBRMaterial(
            name="blend", baseColorFactor=black + [0.5], emissiveFactor=[0.1, 0.2, 0.9], alphaMode="BLEND"
        ),
        "hidden": PBRMaterial(name="hidden", emissiveFactor=[1.0, 1.0, 0.0], alphaMode="OPAQUE", doubleSided=False),
    }
    t = trimesh.transformations.translation_matrix
    sc = trimesh.Scene()
    sc.add_geometry(_trimesh_quad(1.0, mats["opaque"]), node_name="root", geom_name="q_opaque")
    sc.add_geometry(
        _trimesh_quad(0.6, mats["mask"]),
        node_name="mask",
        geom_name="q_mask",
        parent_node_name="root",
        transform=t([0, 0, 0.5]),
    )
    sc.add_geometry(
        _trimesh_quad(0.4, mats["blend"]),
        node_name="blend",
        geom_name="q_blend",
        parent_node_name="mask",
        transform=t([0.25, -0.2, 0.5]),
    )
    sc.add_geometry(
        _trimesh_quad(0.3, mats["hidden"], normal_z=-1.0),
        node_name="hidden",
        geom_name="q_hidden",
        parent_node_name="root",
        transform=t([-0.5, 0.5, 1.5]),
    )
    sc.camera = trimesh.scene.Camera(fov=(40, 40), resolution=(SIZE, SIZE), z_near=0.1, z_far=50.0)
    sc.camera_transform = t([0.0, 0.0, 5.0])
    path.write_bytes(sc.export(file_type="glb"))
    return path


@pytest.fixture(scope="module")
def glb(tmp_path_factory):
    return write_test_glb(tmp_path_factory.mktemp("gltf") / "modes.glb")


def test_hierarchy_materials_and_camera(glb):
    content = load_gltf(glb)
    assert [n.name for n in content.nodes] == ["root"]
    root = content.nodes[0]
    assert sorted(c.name for c in root.children) == ["hidden", "mask"]
    by_name = {n.name: (n, w) for n, w in root.walk()}
    assert by_name["blend"][0].material.description == "gltf_blend"
    assert by_name["mask"][0].material.description == "gltf_mask"
    assert by_name["mask"][0].material.uniforms["alpha_cutoff"] == 0.5
    assert by_name["root"][0].material.description == "gltf_opaque"
    assert by_name["hidden"][0].material.uniforms["double_sided"] == 0
    np.testing.assert_allclose(by_name["blend"][1][:3, 3], [0.25, -0.2, 1.0])  # parent chain kept
    assert by_name["blend"][0].material.uniforms["base_color"][3] == pytest.approx(0.5, abs=1 / 255)
    cam = content.camera
    assert cam.fov_y == pytest.approx(40.0) and cam.position == pytest.approx((0, 0, 5))
    assert np.subtract(cam.target, cam.position) == pytest.approx((0, 0, -1))


def _reference_scene(content) -> Scene:
    """The same quads with unlit materials: what each alpha mode must produce (lights off, emissive only)."""
    by_name = {n.name: (n, w) for root in content.nodes for n, w in root.walk()}
    nodes = []
    for name, (node, world) in by_name.items():
        u = node.material.uniforms
        color = list(u["emissive"])
        if name == "root":
            color = [c * GREY_LINEAR for c in color]  # emissive factor times the sRGB-decoded texture
        if name == "hidden":
            continue  # back-facing and single-sided: culled
        mesh, alpha = node.mesh, 1.0
        if name == "mask":  # only the texture's right half (alpha above the cutoff) remains, opaque
            mesh = quad_mesh(0.3, 0.6)
            world = world @ np.array([[1, 0, 0, 0.3], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        if name == "blend":
            alpha = u["base_color"][3]
        nodes.append(Node(name, Transform(matrix=world), mesh, unlit(color, alpha)))
    return Scene(camera=content.camera, background=(0.1, 0.1, 0.1), nodes=nodes)


@pytest.mark.parametrize("method", ["presort_lf_et", "dfb"])
def test_alpha_modes_match_reference(renderer_factory, glb, method):
    content = load_gltf(glb)
    scene = Scene(camera=content.camera, background=(0.1, 0.1, 0.1), nodes=content.nodes)
    ref, mask, layers = reference_of(_reference_scene(content), SIZE, SIZE)
    frame = renderer_factory("exact", method=method).render(scene, SIZE, SIZE)
    err = compare(frame.image, ref, mask)
    assert err["max_abs_255"] <= 2.0, err
    assert layers.max() >= 3  # opaque, masked and blended surfaces overlap somewhere
    # the blend quad is the only transparent draw: OPAQUE ignores alpha 0.3, MASK compiles opaque
    assert frame.stats["transparent_draws"] == 1
    # pixels where the mask quad was discarded show the opaque quad's sRGB-decoded emissive red
    row = SIZE // 2 - 2
    assert abs(int(frame.image[row, SIZE // 2 - 4, 0]) - round(GREY_LINEAR * 255)) <= 1


def test_yaml_node_with_gltf_file_keeps_hierarchy(glb, renderer_factory):
    text = f"""
camera: {{position: [0, 0, 5], target: [0, 0, 0], fov_y: 40}}
nodes:
  - name: model
    mesh: {{file: {glb}}}
    transform: {{translation: [0.5, 0, 0]}}
    children:
      - {{name: extra, mesh: {{primitive: quad, size: [0.2, 0.2]}}, material: unlit}}
"""
    scene = load_scene_text(text)
    model = scene.nodes[0]
    assert model.mesh is None and [c.name for c in model.children] == ["root", "extra"]
    worlds = {n.name: w for n, w in scene.walk()}
    np.testing.assert_allclose(worlds["blend"][:3, 3], [0.75, -0.2, 1.0])
    frame = renderer_factory("exact").render(scene, SIZE, SIZE)
    assert frame.stats["draws"] == 5 and frame.stats["transparent_draws"] == 1


def test_blend_with_alpha_one_compiles_opaque(tmp_path):
    import trimesh
    from trimesh.visual.material import PBRMaterial

    sc = trimesh.Scene()
    sc.add_geometry(_trimesh_quad(1.0, PBRMaterial(name="b", baseColorFactor=[1, 1, 1, 1.0], alphaMode="BLEND")))
    path = tmp_path / "b.glb"
    path.write_bytes(sc.export(file_type="glb"))
    content = load_gltf(path)
    (node,) = content.nodes
    assert node.material.description == "gltf_opaque"
    assert content.camera is None  # no camera in the file: given as SCENE, it gets a framing one
    cam = load(path).camera
    dist = float(np.linalg.norm(np.subtract(cam.position, cam.target)))
    assert np.linalg.norm(cam.target) < 1e-9  # aimed at the quad's centre
    assert cam.near < dist - 1.42 and dist + 1.42 < cam.far  # the whole quad (radius sqrt(2)) within near..far


def test_cli_renders_glb_and_mesh_files_with_default_camera_and_lights(glb, tmp_path):
    import trimesh

    scene = load(glb)
    assert scene.camera.fov_y == pytest.approx(40.0)
    assert [l.type for l in scene.lights] == ["directional", "directional", "ambient"]  # the default rig
    out = tmp_path / "glb.png"
    assert main(["render", str(glb), "--width", "64", "--height", "64", "--out", str(out)]) == 0
    assert out.is_file()
    obj = tmp_path / "box.obj"
    trimesh.creation.box(extents=(1.0, 2.0, 0.5)).export(obj)
    s = load(obj)
    # the default camera frames the model: every corner of its box projects inside the image
    lo, hi = s.nodes[0].mesh.bounds()
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    clip = corners @ (s.camera.projection_matrix(1.0) @ s.camera.view_matrix()).T
    ndc = clip[:, :3] / clip[:, 3:]
    assert np.abs(ndc).max() < 1.0
    out2 = tmp_path / "obj.png"
    assert main(["render", str(obj), "--width", "64", "--height", "64", "--out", str(out2)]) == 0
    from PIL import Image

    img = np.asarray(Image.open(out2))
    centre = img[24:40, 24:40, :3].astype(int)
    assert np.abs(centre - img[0, 0, :3].astype(int)).max() > 20  # the lit box shows against the background
