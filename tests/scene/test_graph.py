"""Scene-graph parts: transforms given as Euler TRS or as a 4x4 matrix, and the camera's matrices (PyGLM)."""

from __future__ import annotations

import numpy as np
import pytest

from guaca_py.scene import Camera, Transform


def test_transform_takes_a_matrix_and_keeps_euler_trs():
    m = np.array([[0, -2, 0, 1], [2, 0, 0, 2], [0, 0, 2, 3], [0, 0, 0, 1]], float)
    np.testing.assert_array_equal(Transform(matrix=m).matrix(), m)
    np.testing.assert_array_equal(Transform.from_matrix(m.tolist()).matrix(), m)
    assert Transform(matrix=m) == Transform.from_matrix(m) and Transform(matrix=m) != Transform()
    # Euler TRS: T * Rz * Ry * Rx * S, as written out here
    rx, ry, rz = np.radians([30.0, -45.0, 60.0])
    c, s = np.cos, np.sin
    rot_x = np.array([[1, 0, 0], [0, c(rx), -s(rx)], [0, s(rx), c(rx)]])
    rot_y = np.array([[c(ry), 0, s(ry)], [0, 1, 0], [-s(ry), 0, c(ry)]])
    rot_z = np.array([[c(rz), -s(rz), 0], [s(rz), c(rz), 0], [0, 0, 1]])
    expected = np.eye(4)
    expected[:3, :3] = rot_z @ rot_y @ rot_x @ np.diag([1.0, 2.0, 3.0])
    expected[:3, 3] = (4.0, 5.0, 6.0)
    np.testing.assert_allclose(Transform((4, 5, 6), (30, -45, 60), (1, 2, 3)).matrix(), expected, atol=1e-12)
    with pytest.raises(ValueError, match="4x4"):
        Transform(matrix=np.eye(3))
    with pytest.raises(ValueError, match="finite"):
        Transform(matrix=np.full((4, 4), np.nan))


def test_camera_matrices_through_pyglm_match_the_look_at_and_perspective_formulas():
    cam = Camera(position=(1.0, 2.0, 3.0), target=(-1.0, 0.5, 0.0), up=(0.0, 1.0, 0.0), fov_y=50, near=0.2, far=40)
    v = cam.view_matrix()
    eye = np.array(cam.position)
    f = np.subtract(cam.target, eye) / np.linalg.norm(np.subtract(cam.target, eye))
    s_ = np.cross(f, cam.up) / np.linalg.norm(np.cross(f, cam.up))
    u = np.cross(s_, f)
    np.testing.assert_allclose(v[:3, :3], [s_, u, -f], atol=1e-12)
    np.testing.assert_allclose(v[:3, 3], [-s_ @ eye, -u @ eye, f @ eye], atol=1e-12)
    p = cam.projection_matrix(1.5)
    t = 1.0 / np.tan(np.radians(25.0))
    n, fa = 0.2, 40.0
    expected = [[t / 1.5, 0, 0, 0], [0, t, 0, 0], [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)], [0, 0, -1, 0]]
    np.testing.assert_allclose(p, expected, rtol=1e-6)  # single precision, what GL receives


def test_a_camera_changed_after_a_check_is_checked_and_drawn_with_its_new_values():
    from guaca_py.errors import ConfigError

    cam = Camera(position=(0.0, 1.0, 5.0))
    view = cam.view_matrix()
    view[0, 0] = 99.0  # the caller's copy: the next frame's matrix is not changed by it
    assert cam.view_matrix()[0, 0] != 99.0
    cam.position = (0.0, 1.0, 9.0)
    assert cam.view_matrix()[2, 3] == pytest.approx(-np.linalg.norm((0.0, 1.0, 9.0)))
    cam.fov_y = 90.0
    assert cam.projection_matrix(1.0)[1, 1] == pytest.approx(1.0)
    cam.target = cam.position  # passed before, refused now: the memo holds only values that passed
    with pytest.raises(ConfigError, match="differ from the camera position"):
        cam.view_matrix()
    cam.position = np.array([0.0, 1.0, 5.0])  # arrays: compared by value, so an edit in place is seen
    cam.target = np.array([0.0, 1.0, 9.0])
    cam.check()
    cam.target[2] = 5.0
    with pytest.raises(ConfigError, match="differ from the camera position"):
        cam.check()


@pytest.mark.parametrize("count", [2, 100])  # below and above FEW_LIGHTS: per-light memo and vectorised test
def test_a_light_changed_after_a_scene_check_is_refused_and_named(count):
    from guaca_py.errors import ConfigError
    from guaca_py.scene import Light, Scene

    lights = [Light(position=(float(i), 1.0, 0.0)) for i in range(count)]
    scene = Scene(camera=Camera(), lights=lights, nodes=[])
    scene.check()
    scene.check()
    lights[-1].intensity = float("nan")
    with pytest.raises(ConfigError) as err:
        scene.check()
    assert err.value.key == f"lights[{count - 1}].intensity"
    lights[-1].intensity = 1.0
    scene.check()
    lights[-1].intensity = True  # equal to 1.0, refused where 1.0 passed: values of another type are checked
    with pytest.raises(ConfigError) as err:
        scene.check()
    assert err.value.key == f"lights[{count - 1}].intensity"
