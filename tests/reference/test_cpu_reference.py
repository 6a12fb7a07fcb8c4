"""Self-checks of the float64 CPU reference compositor against hand-computed answers."""

from __future__ import annotations

import numpy as np
import pytest

from guaca_py.reference import (
    camera_rays,
    compare,
    edge_mask,
    interpenetrating_scene,
    layered_quads_scene,
    quad_mesh,
    ray_hits,
    render_reference,
    scene_triangles,
    triangle_mesh,
    unlit,
)
from guaca_py.scene.graph import Camera, MaterialInstance, Node, Scene, Transform

BG = (0.1, 0.2, 0.3)


def _cam(fov_y: float = 90.0) -> Camera:
    """Camera at +5 Z looking at the origin; fov 90 makes ndc = view x / depth."""
    return Camera(position=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), fov_y=fov_y, near=0.1, far=100.0)


def _quad(name: str, center: tuple[float, float, float], half: float, color, alpha: float) -> Node:
    """An untilted square quad node facing the camera."""
    return Node(
        name=name,
        transform=Transform(translation=center),
        mesh=quad_mesh(half, half, name),
        material=unlit(color, alpha),
    )


def _render(scene: Scene, w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Reference image and layer counts of a scene."""
    tris, rgb, alpha = scene_triangles(scene)
    return render_reference(tris, rgb, alpha, scene.camera, w, h, scene.background)


def test_camera_rays_match_pinhole() -> None:
    """Top-left ray points up-left, and rays span tan(fov/2)*aspect horizontally."""
    eye, dirs, f = camera_rays(_cam(), 4, 2)
    assert np.allclose(eye, (0, 0, 5)) and np.allclose(f, (0, 0, -1))
    assert np.allclose(dirs @ f, 1.0)
    # W=4,H=2, tan=1, aspect 2: col 0 centre ndc_x=-0.75 -> x=-1.5; row 0 ndc_y=+0.5.
    assert np.allclose(dirs[0, 0], (-1.5, 0.5, -1.0))
    assert np.allclose(dirs[1, 3], (1.5, -0.5, -1.0))


def test_full_screen_opaque_quad_gives_its_color() -> None:
    """Every pixel of a screen-filling opaque quad is exactly its color."""
    color = (0.8, 0.4, 0.2)
    scene = Scene(camera=_cam(), background=BG, nodes=[_quad("q", (0, 0, 0), 20.0, color, 1.0)])
    img, layers = _render(scene, 16, 16)
    assert np.allclose(img, color, atol=1e-12)
    tris, _, _ = scene_triangles(scene)
    inner = ~edge_mask(tris, scene.camera, 16, 16)
    assert inner.sum() > 200  # only the quad diagonal is excluded
    assert np.all(layers[inner] == 1)


@pytest.mark.parametrize("reverse", [False, True])
def test_two_transparent_quads_over_composite(reverse: bool) -> None:
    """Overlap pixel equals the analytic over-composite regardless of submission order."""
    c1, a1 = np.array([1.0, 0.2, 0.1]), 0.4  # near
    c2, a2 = np.array([0.1, 0.9, 0.3]), 0.6  # far
    nodes = [_quad("near", (0.3, 0.1, 1.0), 1.5, c1, a1), _quad("far", (-0.2, 0.0, -1.0), 2.0, c2, a2)]
    scene = Scene(camera=_cam(), background=BG, nodes=nodes[::-1] if reverse else nodes)
    img, layers = _render(scene, 32, 32)
    bg = np.array(BG)
    # Pixel (12, 16): ndc (0.03125, 0.21875) -> inside both quads, off both diagonals.
    expected = a1 * c1 + (1 - a1) * a2 * c2 + (1 - a1) * (1 - a2) * bg
    assert layers[12, 16] == 2
    assert np.allclose(img[12, 16], expected, atol=1e-12)
    # Pixel (16, 1): ndc (-0.9375, -0.03125) -> depth 6 point x=-5.6, outside both: background.
    assert layers[16, 1] == 0
    assert np.allclose(img[16, 1], bg, atol=1e-15)


def test_missing_pixel_is_background_and_near_far_respected() -> None:
    """Geometry behind the camera or past the far plane leaves the background."""
    behind = _quad("behind", (0, 0, 7.0), 5.0, (1, 0, 0), 1.0)
    too_far = _quad("far", (0, 0, -200.0), 500.0, (0, 1, 0), 1.0)
    scene = Scene(camera=_cam(), background=BG, nodes=[behind, too_far])
    img, layers = _render(scene, 8, 8)
    assert np.all(layers == 0)
    assert np.allclose(img, BG, atol=0)


def test_opaque_pixels_ignore_background() -> None:
    """Behind-opaque pixels of the layered scene do not depend on the background."""
    scene = layered_quads_scene()
    tris, rgb, alpha = scene_triangles(scene)
    img_a, _ = render_reference(tris, rgb, alpha, scene.camera, 48, 48, (0.0, 0.0, 0.0))
    img_b, _ = render_reference(tris, rgb, alpha, scene.camera, 48, 48, (1.0, 1.0, 1.0))
    # Only the opaque quad has alpha 1, so pixels that ignore the background are the ones it covers.
    covered = np.all(np.abs(img_a - img_b) < 1e-12, axis=2)
    assert 50 < covered.sum() < 48 * 48 // 2


def test_edge_mask_marks_projected_edge_only() -> None:
    """A vertical triangle edge through column 20's centres is marked; nearby off-edge pixels are not."""
    # fov 90 at depth 5: ndc_x = x / 5; column 20 of 32 has ndc (20.5/16 - 1) = 9/32.
    x0 = 5.0 * 9.0 / 32.0
    tris = np.array([[[x0, -1.0, 0.0], [3.0, 0.0, 0.0], [x0, 1.0, 0.0]]])
    mask = edge_mask(tris, _cam(), 32, 32)
    assert mask[16, 20] and mask[14, 20]
    assert not mask[16, 21] and not mask[16, 19]  # exactly 1 px away, radius 0.5
    assert not mask[2, 2] and not mask[16, 22]


def test_edge_mask_clips_edges_at_near_plane() -> None:
    """An edge running behind the camera is clipped, not projected through the image centre."""
    # Row 23 of 32 has ndc_y = 1 - 23.5/16 = -0.46875; at depth 1 that is view y -0.46875.
    y = -0.46875
    tris = np.array([[[0.5, y, 4.0], [0.5, y, 6.0], [-0.5, y, 4.0]]])  # middle vertex behind the eye
    mask = edge_mask(tris, _cam(), 32, 32)
    assert mask[23, 16]  # on the in-front horizontal edge
    # A naive divide by negative depth would send two edges through the image centre.
    assert not mask[15, 15] and not mask[16, 16]


def _local_quad_hits(scene: Scene, w: int, h: int, row: int, col: int) -> int:
    """Independent layer count: intersect the pixel ray with each quad in its local frame."""
    eye, dirs, _ = camera_rays(scene.camera, w, h)
    d = dirs[row, col]
    count = 0
    for node, world in scene.walk():
        inv = np.linalg.inv(world)
        o = inv[:3, :3] @ eye + inv[:3, 3]
        dl = inv[:3, :3] @ d
        t = -o[2] / dl[2]  # local plane z = 0; world t == local t (affine)
        p = o + t * dl
        half = node.mesh.positions.max(axis=0)
        if scene.camera.near <= t <= scene.camera.far and abs(p[0]) <= half[0] and abs(p[1]) <= half[1]:
            count += 1
    return count


def test_layer_counts_match_local_quad_intersection() -> None:
    """Layer counts at non-edge pixels equal an independent per-quad plane test."""
    scene = layered_quads_scene()
    w = h = 40
    tris, rgb, alpha = scene_triangles(scene)
    _, layers = render_reference(tris, rgb, alpha, scene.camera, w, h, scene.background)
    ok = ~edge_mask(tris, scene.camera, w, h)
    rng = np.random.default_rng(3)
    rows, cols = np.nonzero(ok)
    pick = rng.choice(len(rows), size=60, replace=False)
    for r, c in zip(rows[pick], cols[pick]):
        assert layers[r, c] == _local_quad_hits(scene, w, h, r, c), (r, c)
    assert layers.max() >= 8 and len(np.unique(layers)) >= 6  # counts really vary


@pytest.mark.parametrize("order", ["back_to_front", "shuffled"])
def test_layered_scene_is_order_independent(order: str) -> None:
    """Every submission order of the layered scene composites to the same image."""
    ref_img, ref_layers = _render(layered_quads_scene(order="front_to_back"), 48, 48)
    img, layers = _render(layered_quads_scene(order=order, seed=5), 48, 48)
    assert np.array_equal(layers, ref_layers)
    assert np.allclose(img, ref_img, atol=1e-12)


def test_interpenetrating_scene_crosses_in_depth() -> None:
    """Each pair of transparent triangles swaps depth order somewhere on screen."""
    scene = interpenetrating_scene()
    tris, _, alpha = scene_triangles(scene)
    eye, dirs, _ = camera_rays(scene.camera, 64, 64)
    hit, t = ray_hits(eye, dirs.reshape(-1, 3), tris, scene.camera.near, scene.camera.far)
    transparent = np.nonzero(alpha < 1.0)[0]
    assert len(transparent) == 3
    for i in transparent:
        for j in transparent:
            if i < j:
                both = hit[:, i] & hit[:, j]
                assert np.any(t[both, i] < t[both, j]) and np.any(t[both, i] > t[both, j])


def test_scene_triangles_applies_parent_transform_and_rejects_lit() -> None:
    """World positions compose parent transforms; non-unlit materials raise."""
    child = Node(
        name="t",
        transform=Transform(translation=(1.0, 0.0, 0.0)),
        mesh=triangle_mesh((0, 0, 0), (1, 0, 0), (0, 1, 0)),
        material=unlit((1, 1, 1), 0.5),
    )
    parent = Node(name="p", transform=Transform(translation=(0.0, 2.0, 0.0), rotation_deg=(0, 0, 90)), children=[child])
    tris, rgb, alpha = scene_triangles(Scene(nodes=[parent]))
    # Rz(90) maps local (1,0,0)+(1,0,0) -> (0,2,0); plus parent translation (0,2,0).
    assert np.allclose(tris[0], [[0, 3, 0], [0, 4, 0], [-1, 3, 0]], atol=1e-12)
    assert alpha[0] == 0.5 and np.allclose(rgb[0], 1.0)
    child.material = MaterialInstance(description="pbr", uniforms={})
    with pytest.raises(ValueError):
        scene_triangles(Scene(nodes=[parent]))


def test_compare_reports_error_in_255_units() -> None:
    """compare() ignores excluded pixels and reports the worst compared one."""
    ref = np.full((4, 4, 3), 0.5)
    gpu = np.full((4, 4, 3), 128, dtype=np.uint8)
    gpu[0, 0] = 0  # excluded
    gpu[2, 3, 1] = 131  # 3.5 off
    mask = np.zeros((4, 4), dtype=bool)
    mask[0, 0] = True
    res = compare(gpu, ref, mask)
    assert res["n_compared"] == 15
    assert res["worst_pixel"] == (2, 3)
    assert res["max_abs_255"] == pytest.approx(3.5)
    assert res["rmse_255"] == pytest.approx(np.sqrt((44 * 0.25 + 3.5**2) / 45))
