"""Test helpers: frames of the reference scenes checked against the CPU reference, references cached per module."""

from __future__ import annotations

import numpy as np

from guaca_py.reference import compare, interpenetrating_scene, layered_quads_scene, reference_of
from guaca_py.scene.graph import Scene


class ReferenceCache(dict):
    """reference_of() results by a caller's key: several methods are compared on one scene."""

    def of(self, key, scene: Scene, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The cached reference for (key, size), computed on first use."""
        if (key, width, height) not in self:
            self[key, width, height] = reference_of(scene, width, height)
        return self[key, width, height]


def render_layered_exactly(refs: ReferenceCache, renderer, order: str, size: int):
    """18 tilted layers and an opaque quad between them in one submission order: the frame, checked within 2/255."""
    scene = layered_quads_scene(n_layers=18, order=order, seed=3)
    ref, mask, layers = refs.of(("layered", order), scene, size, size)
    assert layers.max() >= 16
    frame = renderer.render(scene, size, size)
    err = compare(frame.image, ref, mask)
    assert err["max_abs_255"] <= 2.0, err
    return frame


def render_interpenetrating_exactly(refs: ReferenceCache, renderer, order: str, size: int):
    """Mutually intersecting triangles (no per-object order exists), an opaque one in front: the frame, within 2/255."""
    scene = interpenetrating_scene(order=order, seed=1)
    ref, mask, _ = refs.of(("interpenetrating", order), scene, size, size)
    frame = renderer.render(scene, size, size)
    err = compare(frame.image, ref, mask)
    assert err["max_abs_255"] <= 2.0, err
    return frame
