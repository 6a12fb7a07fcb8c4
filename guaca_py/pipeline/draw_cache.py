"""Per-renderer memo of what draws derive from values: matrices and resolved material instances.

A frame loop rebuilds the draw list every frame; with this cache a node whose transform and
material values did not change costs a few dictionary lookups instead of matrix products,
inverses and uniform validation. Keys are the values themselves (never object identity), so
editing a transform or a uniform in place is seen. Entries unused for two frames are dropped,
which keeps the cache bounded however the scene changes.
"""

from __future__ import annotations

import numpy as np
from pyglm import glm

from ..frozen import freeze


class TwoGenerations:
    """A dict whose entries survive while used in this frame or the previous one."""

    def __init__(self):
        self.current: dict = {}
        self.previous: dict = {}

    def get(self, key):
        if key in self.current:
            return self.current[key]
        if key in self.previous:
            value = self.current[key] = self.previous.pop(key)
            return value
        return None

    def put(self, key, value):
        self.current[key] = value
        return value

    def end_frame(self) -> None:
        self.previous, self.current = self.current, {}

    def __len__(self) -> int:
        return len(self.current) + len(self.previous)


class DrawCache:
    """World matrices (with their GL bytes and normal matrices) and resolved material instances."""

    def __init__(self):
        self._worlds = TwoGenerations()
        self._materials = TwoGenerations()

    def world(self, parent_key, parent_world: glm.dmat4 | None, transform) -> tuple:
        """(key, PyGLM world matrix, numpy world matrix, model bytes, normal-matrix bytes) of a node under its parent."""
        key = (parent_key, transform.key())
        hit = self._worlds.get(key)
        if hit is not None:
            return hit
        transform.check()  # values changed since construction (a NaN, a string) are named, once per change
        local = transform.glm_matrix()
        world = local if parent_world is None else parent_world * local
        # column-major float32 bytes, as mat_bytes() writes them
        model, normal = glm.mat4(world).to_bytes(), glm.mat4(glm.transpose(glm.inverse(world))).to_bytes()
        return self._worlds.put(key, (key, world, np.array(world), model, normal))

    def material(self, key, resolve):
        """The resolved (description, values, transparent) for a material-instance key, computed once."""
        hit = self._materials.get(key)
        if hit is not None:
            return hit
        return self._materials.put(key, resolve())

    def end_frame(self) -> None:
        """Forget what the last two frames did not use."""
        self._worlds.end_frame()
        self._materials.end_frame()

    def __len__(self) -> int:
        return len(self._worlds) + len(self._materials)


def material_key(inst, scene_source) -> tuple:
    """Hashable key of a MaterialInstance's description and uniform values (and where errors point)."""
    if inst is None:
        return ("pbr", (), (str(scene_source), None))
    where = getattr(inst, "source", (scene_source, None))
    uniforms = tuple(sorted((k, freeze(v)) for k, v in inst.uniforms.items()))
    return (inst.description, uniforms, (str(where[0]), where[1]))
