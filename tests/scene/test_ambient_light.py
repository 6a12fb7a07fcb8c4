"""The ambient light: light from every direction, reflected as albedo times its colour, in every tile."""

from __future__ import annotations

import numpy as np
import pytest

import guaca_py
from guaca_py import pipeline_from_text
from guaca_py.scene import load_scene_text

SIZE = 64
#: light culling on (tiles of 8 pixels), linear output: the ambient light must reach every tile
TILED = """
passes:
  - geometry: {}
  - light_culling: {mode: fallback, tile_size: 8}
  - composite: {}
"""


def test_ambient_light_reaches_every_tile_and_reflects_the_albedo(renderer_factory):
    text = """
camera: {position: [0, 0, 60], target: [0, 0, 50], fov_y: 60}
background: [0, 0, 0]
lights: [{type: ambient, color: [0.5, 1.0, 1.0], intensity: 0.8}]
nodes:
  - mesh: {primitive: quad, size: [20, 20]}
    transform: {translation: [0, 0, 50]}
    material: {description: pbr, uniforms: {albedo: [0.5, 0.25, 1.0]}}
"""
    # far from the origin, where a light's unused position and radius (0 and 10) would put a
    # culled light's volume: only a light given every tile shades the whole quad
    scene = load_scene_text(text)
    assert scene.lights[0].type == "ambient"
    for pipeline in ("exact", pipeline_from_text(TILED)):
        frame = renderer_factory(pipeline).render(scene, SIZE, SIZE)
        expected = np.array([0.5 * 0.5, 1.0 * 0.25, 1.0 * 1.0]) * 0.8 * 255
        assert np.abs(frame.image[..., :3].astype(float) - expected).max() <= 1.0
    with pytest.raises(guaca_py.ConfigError, match="'direction' does not apply to ambient lights"):
        load_scene_text("lights: [{type: ambient, direction: [0, -1, 0]}]")


def test_ambient_lights_reach_every_tile_of_the_exact_grid():
    from guaca_py.passes.light_grid_cpu import exact_tile_lights
    from guaca_py.passes.lights import light_table, visible_mask
    from guaca_py.scene import Camera, Light

    cam = Camera(position=(0, 0, 3), target=(0, 0, 0))
    view, proj = cam.view_matrix(), cam.projection_matrix(1.0)
    lights = [Light(type="ambient"), Light(type="point", position=(0, 0, 50), radius=1.0)]
    grid = exact_tile_lights(lights, view, proj, 32, 32, 8)
    assert grid[0].all() and not grid[1].any()
    # far from the frustum, an ambient light (its position unused) is still visible
    far_away = Light(type="ambient", position=(1e6, 0, 0), radius=1e-3)
    assert visible_mask(light_table([far_away]), proj @ view).tolist() == [True]
