"""Binding slots: every storage buffer, image unit and texture unit guaca binds, named once.

Python binds by these names (``lights.bind_to_storage_buffer(Buffer.LIGHTS)``) and the templates
declare by the same names (``layout(std430, binding = {{ Buffer.LIGHTS }})``): ShaderLibrary puts
the three kinds into every template's globals, so no number is written twice.

Each slot belongs to a group of the programs that bind it. Two slots of one kind may share a
number only where no program binds both: the slots of one group belong to programs that never
run as one (one transparency method per frame, one rasterizer kernel at a time), and a group's
`meets` lists the groups whose slots can be bound in one program beside its own (their numbers
must differ: tests/shaders/test_slots.py checks this table and every program the tests compile).
guaca binds no uniform or atomic-counter buffers by index: every buffer slot is a storage buffer.
"""

from __future__ import annotations

from typing import ClassVar, NamedTuple


class Group(NamedTuple):
    """The programs a group of slots is bound in, and the groups they meet in one program."""

    programs: str
    meets: frozenset[str] = frozenset()


class Slot(NamedTuple):
    """One row of the table: a binding number with its group and users (`count` numbers from it)."""

    number: int
    group: str  # a key of its kind's GROUPS
    used_by: str
    count: int = 1  # consecutive numbers from `number` (a pass's inputs, a material's textures)
    kind: str = ""  # filled in by Kind: the class it is declared in
    name: str = ""

    def numbers(self) -> range:
        """The binding numbers this slot takes."""
        return range(self.number, self.number + self.count)


class Kind:
    """A kind of binding point; a subclass's Slot attributes become plain ints, their rows go to TABLE."""

    GROUPS: ClassVar[dict[str, Group]] = {}
    TABLE: ClassVar[dict[str, Slot]] = {}

    def __init_subclass__(cls) -> None:
        cls.TABLE = {}
        for name, value in list(vars(cls).items()):
            if isinstance(value, Slot):
                cls.TABLE[name] = value._replace(kind=cls.__name__, name=name)
                setattr(cls, name, value.number)  # ints: GL calls, uniform values and templates take them as they are


class Buffer(Kind):
    """Shader storage buffers: ``layout(std430, binding = ...)`` and bind_to_storage_buffer()."""

    GROUPS = {
        "lights": Group(
            "every program that shades (composite, peeling steps, shade-in-place geometry)",
            frozenset({"method", "raster"}),
        ),
        "method": Group(
            "the transparency method's geometry, raster and composite programs; one method runs per "
            "frame, so methods reuse each other's numbers",
            frozenset({"lights", "raster", "debug"}),
        ),
        "raster": Group(
            "the compute rasterizer's kernels; the fine kernel hosts the method's fragment code, so "
            "they bind above the method's numbers; per draw only the draw's record is bound (and "
            "the mesh's buffers where the mesh changes)",
            frozenset({"lights", "method"}),
        ),
        "debug": Group(
            "the debug views' own buffers, bound beside the method's (the depth-complexity view walks its lists)",
            frozenset({"method"}),
        ),
        "kernel": Group("stand-alone compute kernels that bind nothing else: each starts at 0"),
    }

    LIGHTS = Slot(3, "lights", "the frame's visible lights: shading/light_buffer.glsl.j2, passes/light_culling.py")
    ABUFFER_LINKS = Slot(0, "method", "A-buffer list heads and links (presort_lf family): abuffer/layout.glsl.j2")
    ABUFFER_NODES = Slot(1, "method", "A-buffer node pool (presort_lf family): abuffer/layout.glsl.j2")
    ABUFFER_COUNTERS = Slot(2, "method", "A-buffer frame counters (presort_lf family): abuffer/layout.glsl.j2")
    COUNTED_PIXELS = Slot(
        0, "method", "per-pixel offsets, ranges or page heads (dfb, sbuffer, paged_ll): counted/layout.glsl.j2"
    )
    COUNTED_NODES = Slot(1, "method", "fragment payload pool (dfb, sbuffer, paged_ll): counted/layout.glsl.j2")
    COUNTED_COUNTS = Slot(2, "method", "per-pixel fragment counts (dfb, sbuffer): counted/layout.glsl.j2")
    COUNTED_LINKS = Slot(2, "method", "page links (paged_ll, whose layout has no counts): counted/layout.glsl.j2")
    COUNTED_COUNTERS = Slot(4, "method", "frame counters (dfb, sbuffer, paged_ll): counted/layout.glsl.j2")
    COUNTED_GROUP_BASE = Slot(5, "method", "sbuffer: start of each counter group's region: counted/layout.glsl.j2")
    COUNTED_GROUPS = Slot(5, "method", "sbuffer: counter group totals: counted/sbuffer_address.comp.j2")
    KBUFFER_HEADS = Slot(0, "method", "k-buffer per-pixel lock and count: approx/kbuffer_layout.glsl.j2")
    KBUFFER_SLOTS = Slot(1, "method", "k-buffer per-pixel fragment slots: approx/kbuffer_layout.glsl.j2")
    KBUFFER_COUNTERS = Slot(2, "method", "k-buffer frame counters: approx/kbuffer_layout.glsl.j2")
    STOCHASTIC_DEPTH = Slot(0, "method", "stochastic transparency's sample depths: approx/stochastic_fragment.glsl.j2")
    PEEL_COUNTERS = Slot(4, "method", "peeling frame counters: peeling/common.glsl.j2, peeling/step.comp.j2")
    MULTILAYER_SLOTS = Slot(0, "method", "multi-layer peeling per-pixel slots: peeling/multilayer_layout.glsl.j2")
    MULTILAYER_NODES = Slot(1, "method", "multi-layer peeling node pool: peeling/multilayer_layout.glsl.j2")
    MULTILAYER_DROPPED = Slot(5, "method", "multi-layer peeling dropped counts: peeling/multilayer_layout.glsl.j2")
    RASTER_VERTICES = Slot(8, "raster", "transformed vertex records: raster/vertex.comp.j2 writes, later stages read")
    RASTER_MESH_VERTICES = Slot(9, "raster", "the mesh's vertex buffer, vertex stage only: raster/vertex.comp.j2")
    RASTER_ORDER_KEYS = Slot(16, "raster", "the order stage's sort keys: raster/order.comp.j2")
    RASTER_DRAW = Slot(
        17, "raster", "the draw's record (matrices, counts, depth range, material values): raster/draw_record.glsl.j2"
    )
    RASTER_INDICES = Slot(10, "raster", "the mesh's index buffer: raster/triangle.glsl.j2, raster/order.comp.j2")
    RASTER_STATE = Slot(11, "raster", "queue counters and indirect dispatch arguments: raster/state.glsl.j2")
    RASTER_LARGE = Slot(12, "raster", "triangles queued for the bin stage: raster/setup.comp.j2, raster/bin.comp.j2")
    RASTER_JOBS = Slot(13, "raster", "tile jobs of large triangles: raster/bin.comp.j2, raster/fine.comp.j2")
    RASTER_BUCKETS = Slot(
        14, "raster", "the order stage's bucket counts: raster/order.comp.j2, raster/order_scan.comp.j2"
    )
    RASTER_ORDER = Slot(15, "raster", "triangle indices in drawing order: raster/order.comp.j2, raster/setup.comp.j2")
    DEBUG_COUNT_MAX = Slot(
        6, "debug", "the depth-complexity view's largest per-pixel count: post/debug_depth_complexity.frag.j2"
    )
    FILL_TARGET = Slot(0, "kernel", "the buffer a fill kernel sets: counted/fill.comp.j2, approx/fill.comp.j2")
    SCAN_IN = Slot(0, "kernel", "prefix sum input: counted/scan_blocks.comp.j2 (prefix_sum.py)")
    SCAN_OUT = Slot(1, "kernel", "prefix sum output: counted/scan_blocks.comp.j2, counted/scan_add.comp.j2")
    SCAN_SUMS = Slot(2, "kernel", "prefix sum block totals: counted/scan_blocks.comp.j2, counted/scan_add.comp.j2")
    LIGHT_GRID_EVERYWHERE = Slot(0, "kernel", "bits of the lights that reach every tile: light_grid/clear.comp.j2")
    SAMPLE_POSITIONS = Slot(0, "kernel", "the device's sample positions read back: antialiasing/read_positions.comp.j2")
    BRDF_EVAL_IN = Slot(0, "kernel", "light directions of the BRDF check: shading/brdf_eval.comp.j2 (tests)")
    BRDF_EVAL_OUT = Slot(1, "kernel", "BRDF values of the BRDF check: shading/brdf_eval.comp.j2 (tests)")


class Image(Kind):
    """Image units: ``layout(binding = ..., format)`` image uniforms and bind_to_image()."""

    GROUPS = {
        "method": Group(
            "the transparency method's geometry, raster and peeling step programs; one method runs per "
            "frame, and no method binds an image in the composite"
        ),
        "pass": Group("the compute full-screen passes (composite, tone mapping, FXAA, debug views)"),
        "kernel": Group("a pass's own programs that bind no other image: each starts at 0"),
    }

    CULL_DEPTH = Slot(
        0, "method", "A-buffer saturation depth (presort_lf family): abuffer/submit.glsl.j2, abuffer/clear.comp.j2"
    )
    PEEL_ORDERED_SLOTS = Slot(
        0, "method", "peeling state read in primitive order (interlock): peeling/ordered.glsl.j2", 5
    )
    PEEL_ACC_FRONT = Slot(0, "method", "peeling front accumulation: peeling/step.comp.j2")
    PEEL_ACC_BACK = Slot(1, "method", "dual peeling back accumulation: peeling/step.comp.j2")
    PEEL_BOUNDS = Slot(2, "method", "peeling per-pixel key bounds: peeling/step.comp.j2")
    PEEL_RANGE = Slot(3, "method", "peeling compositing range (coherent, hybrid): peeling/step.comp.j2")
    PEEL_STEP_SLOTS = Slot(4, "method", "peeling state the geometry passes wrote: peeling/step.comp.j2", 4)
    PASS_OUTPUT = Slot(7, "pass", "the pass's target: post/compute_pass.glsl.j2 (passes/base.py)")
    LIGHT_GRID = Slot(
        0, "kernel", "the light grid while it is built: light_grid/clear.comp.j2, light_grid/mark.frag.j2"
    )


class Texture(Kind):
    """Texture units: sampler uniforms set to a unit (or ``layout(binding = ...)``) and Texture.use()."""

    GROUPS = {
        "pass": Group(
            "the full-screen passes (composite: the G-buffer's albedo, normal, material, depth; tone mapping, FXAA)",
            frozenset({"method", "lights"}),
        ),
        "method": Group(
            "the transparency method's inputs: its composite's, or its peeling geometry passes'; one "
            "method runs per frame, so methods reuse each other's numbers",
            frozenset({"pass", "raster", "material", "lights"}),
        ),
        "raster": Group("the compute rasterizer's kernels", frozenset({"method", "material", "lights"})),
        "material": Group("the draw's material textures", frozenset({"method", "raster", "lights"})),
        "lights": Group(
            "every program that shades (composite, peeling steps, shade-in-place geometry)",
            frozenset({"pass", "method", "raster", "material"}),
        ),
        "kernel": Group("programs of their own that bind no other texture: each starts at 0"),
    }

    PASS_INPUTS = Slot(
        0, "pass", "a full-screen pass's inputs in order (composite: the G-buffer layers): passes/base.py", 4
    )
    PEEL_FRONT = Slot(4, "method", "peeling front accumulation in the composite: peeling/resolve.glsl.j2")
    PEEL_BACK = Slot(5, "method", "dual peeling back accumulation in the composite: peeling/resolve.glsl.j2")
    APPROX_ACCUM = Slot(4, "method", "blended methods' accumulation in the composite: approx/blend_resolve.glsl.j2")
    APPROX_WEIGHT = Slot(5, "method", "blended methods' weights in the composite: approx/blend_resolve.glsl.j2")
    PEEL_BOUNDS = Slot(4, "method", "peeling key bounds in the geometry passes: peeling/common.glsl.j2")
    PEEL_OPAQUE = Slot(5, "method", "G-buffer depth in peeling geometry passes and steps: peeling/common.glsl.j2")
    PEEL_RANGE = Slot(6, "method", "peeling compositing range in the geometry passes: peeling/composite_range.glsl.j2")
    RASTER_DEPTH = Slot(7, "raster", "G-buffer depth for the depth test: raster/fragment_host.glsl.j2")
    MATERIALS = Slot(8, "material", "a material's sampler2D uniforms, in order: renderer.apply_material", 23)
    LIGHT_GRID = Slot(31, "lights", "the light grid: shading/lighting.glsl.j2, post/debug_light_count.frag.j2")
    PRESENT_INPUT = Slot(
        0, "kernel", "the frame (or HUD) drawn to the host: present/copy.frag.j2, present/overlay.frag.j2"
    )
    SAMPLE_PROBE = Slot(0, "kernel", "the multisampled probe read back: antialiasing/read_positions.comp.j2")
    HOST_DEPTH = Slot(
        0,
        "kernel",
        "depth copied between the host's layer and the G-buffer: gbuffer/host_layer.frag.j2, present/depth_out.frag.j2",
    )


KINDS = (Buffer, Image, Texture)


def template_globals() -> dict[str, type[Kind]]:
    """What ShaderLibrary adds to every template's globals: the kinds by name."""
    return {kind.__name__: kind for kind in KINDS}


def markdown_table() -> str:
    """The slot table and its groups as Markdown (docs/slots.md)."""
    rows = ["| kind | name | number | group | used by |", "| --- | --- | --- | --- | --- |"]
    for kind in KINDS:
        for s in kind.TABLE.values():
            number = f"{s.number}-{s.number + s.count - 1}" if s.count > 1 else str(s.number)
            rows.append(f"| {kind.__name__} | `{s.name}` | {number} | {s.group} | {s.used_by} |")
    rows += ["", "| kind | group | bound in | meets in one program |", "| --- | --- | --- | --- |"]
    for kind in KINDS:
        for name, group in kind.GROUPS.items():
            meets = ", ".join(sorted(group.meets)) or "no other group"
            rows.append(f"| {kind.__name__} | {name} | {group.programs} | {meets} |")
    return "\n".join(rows) + "\n"
