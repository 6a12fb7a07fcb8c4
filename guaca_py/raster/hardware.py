"""The hardware rasterizer: draws a draw list through the GL pipeline, one program per material and method."""

from __future__ import annotations

from collections.abc import Callable

import moderngl

from ..pipeline.device import Device
from ..shaders import set_uniform
from .material_program import apply_material, material_program


class HardwareRasterizer:
    """Draws opaque draws into the G-buffer and transparent ones into the method's storage (fragment shaders)."""

    def __init__(self, device: Device):
        self.device = device

    def program(self, method, draw, transparent: bool):
        """Program for (triangle mesh, material, opaque | transparent variant of `method`), compiled once."""
        frag = {"transparent": transparent, "antialiased": self.device.samples > 1}  # centroid attributes
        if transparent:
            frag.update(
                method.template_vars(),
                method_extensions=method.extensions(),
                method_fragment_template=method.fragment_template(),
            )
        else:
            frag.update(method_extensions="", method_fragment_template="")
        skeleton = {
            "vertex_shader": ("geometry/triangle_mesh.vert.j2", "displacement", {}),
            "fragment_shader": ("geometry/triangle_mesh.frag.j2", "visibility", frag),
        }
        return material_program(self.device.programs, draw.material, skeleton)

    def draw(
        self, frame, draws, transparent: bool, uniforms: dict | None = None, per_program: Callable | None = None
    ) -> None:
        """Draw `draws` with their (opaque or transparent) programs and the given extra uniforms."""
        last = last_values = None
        programs: dict[int, object] = {}  # per material description, for this call (the method's state is fixed)
        meshes = self.device.meshes
        for d in draws:
            prog = programs.get(id(d.material))
            if prog is None:
                prog = programs[id(d.material)] = self.program(frame.method, d, transparent)
            switched = prog is not last
            if switched:
                frame.set_frame_uniforms(prog)
                for k, v in (uniforms or {}).items():
                    set_uniform(prog, k, v)
                if per_program is not None:
                    per_program(prog)
                last = prog
            d.write_transform(prog)
            set_uniform(prog, "gua_draw_index", d.index)
            if switched or d.values is not last_values:  # the same instance as the draw before is all set
                apply_material(self.device.textures, d, (prog,))
                last_values = d.values
            meshes.vao(d.mesh, prog).render(moderngl.TRIANGLES)
