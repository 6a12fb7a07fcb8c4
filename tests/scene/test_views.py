"""Camera sets: stereo pairs and rows look in parallel from evenly spaced eyes; cube-map faces follow GL's layout."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import quad_node

from guaca_py.errors import ArgumentError, ConfigError
from guaca_py.scene import Camera, Scene, camera_row, cube_map, stereo_pair
from guaca_py.scene.views import CUBE_FACES


def forward(cam: Camera) -> np.ndarray:
    d = np.subtract(cam.target, cam.position)
    return d / np.linalg.norm(d)


def test_stereo_pair_moves_the_eyes_apart_along_the_right_axis():
    cam = Camera(position=(1, 2, 5), target=(0, 0, 0), up=(0, 1, 0), fov_y=40, near=0.2, far=30)
    left, right = stereo_pair(cam, 0.064)
    gap = np.subtract(right.position, left.position)
    assert np.linalg.norm(gap) == pytest.approx(0.064)
    assert np.allclose((np.add(left.position, right.position)) / 2, cam.position)
    assert abs(gap @ forward(cam)) < 1e-12 and abs(gap @ np.array(cam.up)) < 1e-12  # sideways only
    assert gap @ np.cross(forward(cam), cam.up) > 0  # the left eye first
    for eye in (left, right):
        assert np.allclose(forward(eye), forward(cam))  # parallel, not toed in
        assert (eye.up, eye.fov_y, eye.near, eye.far) == (cam.up, cam.fov_y, cam.near, cam.far)


def test_camera_row_is_centred_and_evenly_spaced_left_to_right():
    cam = Camera(position=(0, 1, 5), target=(0, 1, 0))
    row = camera_row(cam, 5, 0.25)
    xs = [c.position[0] for c in row]
    assert np.allclose(xs, [-0.5, -0.25, 0.0, 0.25, 0.5])  # looking down -Z, right is +X
    assert all(c.position[1:] == (1.0, 5.0) and c.target[0] == c.position[0] for c in row)
    assert camera_row(cam, 1, 0.25) == [cam]


def gl_cube_face(d: np.ndarray) -> tuple[int, float, float]:
    """(face index, s, t) where GL samples a cube map in direction `d` (OpenGL 4.5, table 8.19)."""
    rx, ry, rz = d
    axis = int(np.argmax(np.abs(d)))
    if axis == 0:
        face, sc, tc, ma = (0, -rz, -ry, rx) if rx > 0 else (1, rz, -ry, rx)
    elif axis == 1:
        face, sc, tc, ma = (2, rx, rz, ry) if ry > 0 else (3, rx, -rz, ry)
    else:
        face, sc, tc, ma = (4, rx, -ry, rz) if rz > 0 else (5, -rx, -ry, rz)
    return face, (sc / abs(ma) + 1) / 2, (tc / abs(ma) + 1) / 2


def test_cube_map_faces_project_directions_where_gl_samples_them():
    # a face's frame (row 0 at the bottom, as GL holds it) is texel (s, t) of GL's cube-map face
    position = np.array([1.0, -2.0, 0.5])
    faces = cube_map(tuple(position), near=0.05, far=10)
    assert [f.fov_y for f in faces] == [90.0] * 6 and len(CUBE_FACES) == 6
    rng = np.random.default_rng(3)
    for d in rng.normal(size=(200, 3)):
        face, s, t = gl_cube_face(d)
        cam = faces[face]
        clip = cam.projection_matrix(1.0) @ cam.view_matrix() @ np.append(position + d, 1.0)
        ndc = clip[:3] / clip[3]
        assert ndc[:2] == pytest.approx([2 * s - 1, 2 * t - 1], abs=1e-5)
        assert -1 < ndc[2] < 1


def test_cube_map_views_see_what_lies_in_their_direction(renderer_factory):
    # six coloured walls around the origin: each face's centre shows the wall it looks at
    colours = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (0, 1, 1)]
    walls = []
    for i, (_, look, _) in enumerate(CUBE_FACES):
        look = np.array(look, float)
        # a quad faces +Z: turned to face the origin from 2 units along `look`
        yaw = math.degrees(math.atan2(-look[0], -look[2])) if look[1] == 0 else 0.0
        pitch = 90.0 * look[1]
        walls.append(quad_node(f"w{i}", 0.0, colours[i], 1.0, size=3.0, rot=(pitch, yaw, 0.0)))
        walls[-1].transform.translation = tuple(2 * look)
    scene = Scene(nodes=walls, background=(0, 0, 0))
    views = renderer_factory("exact", method="presort_lf").render_views(scene, cube_map((0, 0, 0)), 16, 16)
    for colour, view in zip(colours, views):
        assert np.allclose(view.image[8, 8] / 255.0, colour, atol=0.02)


@pytest.mark.parametrize(
    "call, error, match",
    [
        (lambda: stereo_pair("camera", 0.06), ArgumentError, r"'camera': must be a Camera, got str"),
        (lambda: stereo_pair(Camera(), 0), ConfigError, r"'eye_separation': must be a finite number > 0"),
        (lambda: stereo_pair(Camera(), math.nan), ConfigError, r"'eye_separation'"),
        (lambda: stereo_pair(Camera(fov_y=200), 0.06), ConfigError, r"'camera\.fov_y'"),
        (lambda: camera_row(Camera(), 0, 0.1), ArgumentError, r"'count': must be a whole number >= 1"),
        (lambda: camera_row(Camera(), 2.5, 0.1), ArgumentError, r"'count'"),
        (lambda: camera_row(Camera(), True, 0.1), ArgumentError, r"'count'"),
        (lambda: camera_row(Camera(), 3, -1), ConfigError, r"'spacing'"),
        (lambda: cube_map((0, math.inf, 0)), ConfigError, r"'position': must be 3 finite numbers"),
        (lambda: cube_map((0, 0)), ConfigError, r"'position'"),
        (lambda: cube_map((0, 0, 0), near=0), ConfigError, r"'near'"),
        (lambda: cube_map((0, 0, 0), near=1, far=1), ConfigError, r"'far': must be a finite number greater"),
    ],
)
def test_camera_sets_refuse_bad_arguments_by_name(call, error, match):
    with pytest.raises(error, match=match):
        call()
