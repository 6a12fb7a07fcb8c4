"""raster/choice.py's screen-space estimates from a fixed sample of each mesh's triangles."""

from __future__ import annotations

import numpy as np
import pytest

from guaca_py.raster.choice import mean_projected_area, projected_shape
from guaca_py.scene.graph import MeshData


def one_triangle(normals: np.ndarray) -> MeshData:
    """A right triangle with legs of 0.2 along x and y (10 px at 100² under the identity projection)."""
    pos = np.float32([[0, 0, 0], [0.2, 0, 0], [0, 0.2, 0]])
    return MeshData(
        positions=pos,
        normals=normals.astype(np.float32),
        texcoords=np.zeros((3, 2), np.float32),
        indices=np.uint32([0, 1, 2]),
        name="one",
    )


def tilted(angle: float) -> list[float]:
    """The +z normal turned by `angle` radians about y."""
    return [np.sin(angle), 0.0, np.cos(angle)]


def test_normal_turn_is_the_fastest_edge_turn_per_pixel():
    # corner 1's normal turns 0.5 rad from the others: 0.5 rad over the 10 px leg is the fastest turn
    # (the hypotenuse turns it over 14.1 px; the other leg not at all)
    mesh = one_triangle(np.array([[0, 0, 1], tilted(0.5), [0, 0, 1]]))
    eye = np.eye(4)
    assert mean_projected_area(mesh, eye, eye, 100, 100) == pytest.approx(50.0)
    assert projected_shape(mesh, eye, eye, 100, 100)[1] == pytest.approx(0.05, rel=1e-5)
    # twice the frame size: the same turn over twice the pixels
    assert projected_shape(mesh, eye, eye, 200, 200)[1] == pytest.approx(0.025, rel=1e-5)
    # a scaled world turns normals through the normal matrix: stretching x by 4 flattens the tilt
    # about y (the normal's x shrinks 4x) while the leg grows to 40 px
    world = np.diag([4.0, 1.0, 1.0, 1.0])
    expected = np.arctan2(np.sin(0.5) / 4, np.cos(0.5)) / 40.0
    assert projected_shape(mesh, world, eye, 100, 100)[1] == pytest.approx(expected, rel=1e-5)


def test_flat_and_off_screen_triangles_turn_nothing():
    flat = one_triangle(np.tile([0.0, 0.0, 1.0], (3, 1)))
    eye = np.eye(4)
    assert projected_shape(flat, eye, eye, 100, 100)[1] == 0.0
    away = np.eye(4)
    away[:3, 3] = (5.0, 0.0, 0.0)  # beyond the right edge of the frame
    turned = one_triangle(np.array([[0, 0, 1], tilted(0.5), [0, 0, 1]]))
    assert projected_shape(turned, away, eye, 100, 100)[1] == 0.0
    assert mean_projected_area(turned, away, eye, 100, 100) == 0.0
