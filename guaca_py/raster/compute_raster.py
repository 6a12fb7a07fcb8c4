"""A rasterizer for transparent draws written in compute shaders, feeding the method's A-buffer insertion.

After Laine & Karras, "High-Performance Software Rasterization on GPUs" (HPG 2011), reduced to
what transparent fragments need (no depth buffer, no ordering: the A-buffer sorts). Per draw:

1. vertex   one thread per vertex: the vertex stage with the material's displacement methods;
1b. order   a bucket sort of the triangles in the frustum by view depth: front to back for
            methods with early termination, back to front for the others (order.comp.j2);
2. setup    one thread per triangle, in that order: setup; a triangle whose candidate box holds at most
            SMALL_AREA pixels is rasterized by that thread, a larger one is queued;
3. bin      one workgroup per queued triangle: rasterizes it when its box holds at most
            MEDIUM_AREA pixels, else makes a (triangle, tile) job per TILE² tile it may cover;
4. fine     one workgroup per job, one thread per pixel.

Every covered pixel runs the material's visibility methods and the method's gua_submit_at()
(raster/fragment_host.glsl.j2): one material source, two hosts. Stages 3 and 4 are dispatched
indirectly from counts the GPU writes (raster/args.comp.j2, order.comp.j2); the CPU reads the frame's totals
once, after the pass, through a copy. The queue and the job list are sized to the frame, grow
to the measured need on overflow (the frame is rendered again, at most MAX_REGROW times) and
report what they hold and drop.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import NamedTuple

import moderngl
import numpy as np

from .. import env
from ..errors import ConfigError
from ..frozen import freeze
from ..gpu_counters import CounterBlock, UploadBuffer
from ..gpu_timer import Timestamps
from ..growth import with_margin
from ..limits import require_bytes
from ..pipeline.device import Device
from ..pipeline.draw_cache import TwoGenerations
from ..shaders import set_uniform, set_uniforms
from ..shaders.slots import Buffer, Texture
from .choice import large_tile_frame
from .draw_record import RecordLayout, head_bytes, material_bytes, record_layout
from .material_program import apply_material, material_program
from .material_support import ComputeMaterial, compute_material

# state words of raster/state.glsl.j2, in order
STATE_WORDS = (
    "large",
    "jobs",
    "large_n",
    "jobs_n",
    "bin_x",
    "bin_y",
    "bin_z",
    "fine_x",
    "fine_y",
    "fine_z",
    "large_total",
    "large_peak",
    "large_dropped",
    "jobs_total",
    "jobs_peak",
    "jobs_dropped",
    "tiled",
    "tiled_total",
    "visible",
    "visible_total",
    "setup_x",
    "setup_y",
    "setup_z",
)
# byte offsets of the indirect dispatch arguments in the state block (glDispatchComputeIndirect)
_DISPATCH_OFFSET = {w: 4 * STATE_WORDS.index(w) for w in ("setup_x", "bin_x", "fine_x")}
TILE = 8  # tile edge in pixels of the large-triangle path (one 64-thread workgroup per job, as L&K's fine raster)
SMALL_AREA = 128  # candidate boxes up to this many pixels may be rasterized by one thread
# A triangle covering more than SMALL_FRAGMENTS px² goes to a workgroup (bin stage) even in a small
# box: one thread would shade its many fragments one after another and hold its SIMD group back,
# a workgroup shades them side by side. The box alone is no measure: a sliver's box is large and its fragments few (hairball_v1: boxes of
# ~18 px, 5 px² on average, fastest on one thread), a close-up strand's box and area both large
# (hairball_v2: 72 px, 41 px²). On the H100 (docs/decisions.md, 2026-11-25 "one-thread bounds") 16 px² took
# hairball_v2 from 15.8 to 12.4 ms and Sponza v1 from 1.58 to 1.25 ms and left the dragons and
# hairball_v1 as they were; 8 px² gained more on those two but sent a third of hairball_v1's
# strands out of their depth order (early termination then culled less: 4.6 -> 6.0 ms).
SMALL_FRAGMENTS = 16.0
MEDIUM_AREA = 1024  # larger boxes up to this many pixels by one 64-thread workgroup, without tiles
VERTEX_RECORD_BYTES = 48  # clip position, world position + u, normal + v
MAX_REGROW = 2  # re-renders one frame may take to grow the queue or the job list
MAX_REMEMBERED_KERNELS = 256  # (material, method state) pairs whose kernels draw() keeps at hand
BUCKETS = 16384  # buckets of the triangle order (a multiple of SCAN_LANES: order_scan.comp.j2)
# Tile order in frames past raster/choice.py's LARGE_FRAME_PIXELS: 256 depth buckets in each of the
# 16 x 16 tiles instead of 64, so early termination still meets a tile's triangles nearly front to
# back (H100, 4096², tile order: the dragons 15.1 -> 12.5 ms). Smaller frames keep BUCKETS: the
# one-workgroup prefix sum of 65536 buckets costs ~0.08 ms more per draw (the dragons' 7 draws at
# 1024²: order stage 0.6 -> 1.2 ms).
LARGE_TILE_BUCKETS = 65536
SCAN_LANES = 1024  # invocations of the one-workgroup prefix sum over the buckets (the GL minimum limit)
ORDER_TILE_BITS = 4  # tile order: 16 x 16 screen tiles of 64 depth buckets each
# Between the stages of a draw, what one kernel writes and the next reads: storage buffers, the
# saturation-depth image and indirect dispatch arguments; draw() ends with a full barrier for whatever
# reads the method's storage next.
_STAGE_BARRIER = (
    moderngl.SHADER_STORAGE_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT | moderngl.COMMAND_BARRIER_BIT
)
_GROUP = 64  # threads per workgroup of the vertex and setup stages
_MAX_GROUPS_X = 65535  # the GL minimum of GL_MAX_COMPUTE_WORK_GROUP_COUNT; grids wrap into y


_TOO_BIG = "draw this mesh with transparency.raster: hardware, or split it (GUACA_MAX_BUFFER_MB sets the rule)"


def _bound_corners(mesh) -> np.ndarray:
    """The 8 corners of the mesh's object-space bounds as homogeneous points (8, 4), kept with its arrays."""
    return mesh.derived("bound_corners", _corners)


def _corners(mesh) -> np.ndarray:
    lo, hi = (np.asarray(b, dtype=np.float64) for b in mesh.bounds())
    return np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


@functools.lru_cache(maxsize=8)
def sample_uniforms(positions: tuple[tuple[float, float], ...]) -> Mapping[str, object]:
    """The rasterizer's uniforms derived from the device's sample points, computed once per set of points.

    gua_sample_pos: the points in the pixel (the homogeneous path's); gua_sample_offset: each one's
    offset from the pixel centre in 1/256 pixel (the fixed-point path's); gua_sample_span: their
    bounds (x0, y0, x1, y1) in 1/256 pixel, the pixel centre (128) with one sample.
    """
    offsets = tuple((round(x * 256) - 128, round(y * 256) - 128) for x, y in positions)
    xs, ys = [128 + o[0] for o in offsets] or [128], [128 + o[1] for o in offsets] or [128]
    return MappingProxyType(  # read-only: the cache hands the same mapping to every call
        {
            "gua_sample_pos": positions,
            "gua_sample_offset": offsets,
            "gua_sample_span": (min(xs), min(ys), max(xs), max(ys)),
        }
    )


def _grid(items: int, group: int = _GROUP) -> tuple[int, int, int]:
    groups = max(1, math.ceil(items / group))
    return min(groups, _MAX_GROUPS_X), math.ceil(groups / _MAX_GROUPS_X), 1


class _Material(NamedTuple):
    """What the rasterizer derives from a material description."""

    compute: ComputeMaterial  # its visibility code for the compute host, or why it cannot run there
    record: RecordLayout  # where its values lie in a draw's record
    samplers: bool  # it has textures to bind per draw


class ComputeRasterizer:
    """Draws transparent draws through compute kernels into the current method's insertion code."""

    def __init__(self, device: Device):
        self.device = device
        self.ctx = device.ctx
        self._state: CounterBlock | None = None  # queue cursors, indirect dispatch arguments, frame totals
        self._verts = self._large = self._jobs = None
        self._buckets = self._order = self._keys = None
        self.vertex_capacity = 0
        self.order_capacity = 0  # triangles of the largest draw (the order list and the bucket keys)
        self.large_capacity = 0  # queued large triangles per draw
        self.job_capacity = 0  # (triangle, tile) jobs per draw
        self._want: dict[str, int] = {}
        self._fresh = True  # the next draw starts a geometry pass: reset the state
        self._frame = None  # the frame being drawn (a new one always starts afresh)
        self._triangles = 0
        self.tile = TILE  # tunable per renderer (raster_sweep.py --tile, --small-area; aa_cost.py --small-fragments)
        self.small_area = SMALL_AREA
        self.small_fragments = SMALL_FRAGMENTS
        self.medium_area = MEDIUM_AREA
        self._materials: dict[int, tuple] = {}  # id(material) -> (material, _Material)
        # the draws' records of a call (raster/draw_record.py): sent through a staging copy, and only where
        # they changed, as every buffer the CPU fills for shaders to read
        self._records = UploadBuffer(self.ctx)
        self._material_bytes = TwoGenerations()  # id(values) -> (values, their bytes in a record)
        self._kernels: dict[tuple, tuple] = {}  # (id(material), _method_key) -> (material, its four kernels)
        # GUACA_RASTER_STAGES=1: GPU time per stage in stats (reading it waits for the GPU: profiling only)
        self._stages: Timestamps | None = None
        self.profile_stages(env.raster_stages())

    def profile_stages(self, on: bool) -> None:
        """Record the GPU time of each stage into stats (reading it waits for the GPU: profiling only)."""
        if on and self._stages is None:
            self._stages = Timestamps()
        elif not on and self._stages is not None:
            self._stages.release()
            self._stages = None

    # ------------------------------------------------------------------ programs
    def _raster_vars(self) -> dict:
        return {
            "raster_state_words": STATE_WORDS,
            "raster_tile": self.tile,
            "raster_small_area": self.small_area,
            "raster_small_fragments": float(self.small_fragments),
            "raster_medium_area": self.medium_area,
            "raster_buckets": BUCKETS,
            "raster_order_tile_bits": ORDER_TILE_BITS,
            "raster_scan_lanes": SCAN_LANES,
        }

    def _material(self, mat) -> _Material:
        """What the rasterizer derives from a material description, once per description."""
        hit = self._materials.get(id(mat))
        if hit is None or hit[0] is not mat:
            samplers = any(u.type == "sampler2D" for u in mat.uniforms.values())
            hit = self._materials[id(mat)] = (mat, _Material(compute_material(mat), record_layout(mat), samplers))
        return hit[1]

    def material_problem(self, draw) -> str | None:
        """Why `draw`'s material cannot run in the compute host (None: it can)."""
        return self._material(draw.material).compute.problem

    @staticmethod
    def _method_key(method, tuning: tuple) -> tuple:
        """What the kernels take from `method` and the tuning (the frozen _raster_vars): equal keys, equal
        kernels (draw() derives it once a call)."""
        return freeze(method.template_vars()), method.extensions(), method.fragment_template(), tuning

    def _call_kernels(self, buckets: int, tuning: tuple) -> tuple[dict, tuple]:
        """The material-independent kernels of a call: the queue bookkeeping after the setup (1) and bin (2)
        stages; the order stage's bucket clear (0), count (1) and scatter (3), then its prefix sum.
        Remembered per bucket count and tuning, as _programs remembers a material's."""
        hit = self._kernels.get(("call", buckets, tuning))
        if hit is None:
            args = {m: self._kernel("raster/args.comp.j2", args_mode=m) for m in (1, 2)}
            order_kernels = (
                *(self._kernel("raster/order.comp.j2", order_mode=m, raster_buckets=buckets) for m in (0, 1, 3)),
                self._kernel("raster/order_scan.comp.j2", raster_buckets=buckets),
            )
            hit = self._kernels[("call", buckets, tuning)] = (args, order_kernels)
        return hit

    def _programs(self, method, draw, method_key: tuple):
        """(vertex, setup, bin, fine) kernels for the draw's material and `method`, remembered per material
        and `method_key` (_method_key): the program cache's key of each kernel freezes every template
        variable, some hundred calls a material and frame otherwise."""
        mat = draw.material
        hit = self._kernels.get((id(mat), method_key))
        if hit is not None and hit[0] is mat:
            return hit[1]
        if len(self._kernels) >= MAX_REMEMBERED_KERNELS:  # materials or methods replaced over and over
            self._kernels.clear()
        kernels = self._build_programs(method, draw)
        self._kernels[(id(mat), method_key)] = (mat, kernels)
        return kernels

    def _build_programs(self, method, draw) -> tuple:
        """(vertex, setup, bin, fine) kernels for the draw's material and `method`, from the program cache."""
        mat = draw.material
        cm = self._material(mat).compute
        if cm.problem:
            raise ConfigError(cm.problem, mat.path, None, "transparency.raster")
        fragment = dict(
            self._raster_vars(),
            **method.template_vars(),
            compute_raster=True,
            frag_xy="gua_frag_xy",
            tc_derivatives=cm.tc_derivatives,
            method_extensions=method.extensions(),
            method_fragment_template=method.fragment_template(),
        )
        kernels = [
            material_program(
                self.device.programs,
                mat,
                {"compute_shader": ("raster/vertex.comp.j2", "displacement", {})},
                ", compute raster vertex",
                record=True,
            )
        ]
        for stage in ("setup", "bin", "fine"):  # the triangle record's layout is chosen per kernel
            skeleton = {
                "compute_shader": (f"raster/{stage}.comp.j2", "visibility", {**fragment, "raster_stage": stage})
            }
            kernels.append(
                material_program(
                    self.device.programs, mat, skeleton, f", compute raster {stage}", cm.sources, record=True
                )
            )
        return tuple(kernels)

    def _kernel(self, template: str, **variables):
        """A material-independent kernel of the rasterizer, compiled once per template, variables and tuning."""
        return self.device.programs.compute(template, **{**self._raster_vars(), **variables})

    # ------------------------------------------------------------------ storage
    def _begin(self, frame, draws) -> None:
        """First draw of a geometry pass: size the buffers to the frame, reset the state on the GPU."""
        ctx = self.ctx
        tiles = math.ceil(frame.width / self.tile) * math.ceil(frame.height / self.tile)
        triangles = max(d.mesh.triangle_count for d in draws)
        large = self._want.pop("large", 0) or max(self.large_capacity, 1024, triangles // 8)
        jobs = self._want.pop("jobs", 0) or max(self.job_capacity, 4096, 4 * tiles)
        limits = self.device.caps.limits
        if limits is not None:  # the storage rule: queues past it drop (counted, warned), never overflow memory
            large = max(1, min(large, limits.elements(4)))
            jobs = max(1, min(jobs, limits.elements(8)))
        if self._state is None:
            self._state = CounterBlock(ctx, STATE_WORDS)
            self._buckets = ctx.buffer(reserve=max(BUCKETS, LARGE_TILE_BUCKETS) * 4)
        if large != self.large_capacity:
            self._release(self._large)
            self.large_capacity, self._large = large, ctx.buffer(reserve=large * 4)
        if jobs != self.job_capacity:
            self._release(self._jobs)
            self.job_capacity, self._jobs = jobs, ctx.buffer(reserve=jobs * 8)
        # a GPU copy, not a loop in the args kernel: NVIDIA's compiler refused that loop's store
        # ("lvalue in array access too complex")
        self._state.reset()
        ctx.memory_barrier()
        self._triangles = 0
        self._mark("begin")  # stage profiling: what follows until the first draw's vertex stage is its set-up

    def _fit_vertices(self, vertices: int) -> None:
        """Room for draws of up to `vertices` transformed vertices (no overflow path: within the storage rule)."""
        require_bytes(self.device.caps.limits, vertices * VERTEX_RECORD_BYTES, "transparency.raster", _TOO_BIG)
        if vertices > self.vertex_capacity:
            self._release(self._verts)
            self.vertex_capacity = vertices
            self._verts = self.ctx.buffer(reserve=vertices * VERTEX_RECORD_BYTES)

    def _fit_order(self, triangles: int) -> None:
        """An order list for draws of up to `triangles` triangles."""
        require_bytes(self.device.caps.limits, triangles * 4, "transparency.raster", _TOO_BIG)  # each of the two
        if triangles > self.order_capacity:
            self._release(self._order)
            self._release(self._keys)
            self.order_capacity = triangles
            self._order = self.ctx.buffer(reserve=max(1, triangles) * 4)
            self._keys = self.ctx.buffer(reserve=max(1, triangles) * 4)

    @staticmethod
    def _depth_ranges(clip_w, draws) -> dict[int, tuple[float, float]]:
        """Per draw index, the nearest and farthest view depth (clip w) of its bounding box corners, for
        the order; `clip_w`: the last row of the frame's projection times view. One array product for
        all the draws (a field of 64 draws spent ~0.1 ms a frame on one small product per draw)."""
        rows = np.einsum("j,njk->nk", clip_w, np.array([d.world for d in draws]))  # clip_w @ world, per draw
        corners = np.array([_bound_corners(d.mesh) for d in draws])  # (n, 8, 4)
        w = np.maximum(np.einsum("nck,nk->nc", corners, rows), 0.0)
        return dict(zip((d.index for d in draws), zip(w.min(axis=1).tolist(), w.max(axis=1).tolist())))

    @staticmethod
    def _front_to_back(method) -> bool:
        """Whether depth runs nearest first: with early termination, whose saturation depth then culls.

        (Back to front with early termination, measured on the dragons, saved 0.2 ms at 1 sample and
        1.6 ms at 4, but it then culls nothing while the composite still stops at the threshold: what
        the threshold hides would go uncounted. docs/decisions.md, 2026-11-25 "the dragons' 4-sample time".)
        """
        return bool(getattr(method, "early_termination", False))

    def _order_constants(self, frame, order_kernels, span) -> None:
        """The order kernels' uniforms that hold for every draw of a call."""
        order = frame.method.raster_order(frame.width * frame.height)
        values = (
            ("gua_back_to_front", not self._front_to_back(frame.method)),
            ("gua_mesh_order", order == "mesh"),
            ("gua_tile_order", order == "tile"),
            ("gua_resolution", (frame.width, frame.height)),
            ("gua_sample_span", span),
        )
        for kernel in order_kernels[:3]:
            set_uniforms(kernel, values)

    def _buckets_of(self, frame) -> int:
        """Buckets of the frame's triangle order: LARGE_TILE_BUCKETS for tile order in large frames."""
        return LARGE_TILE_BUCKETS if large_tile_frame(frame.method, frame.width * frame.height) else BUCKETS

    def _order_pass(self, order_kernels, grids) -> None:
        """Bucket-sort the draw's triangles in the frustum by view depth, index or screen tile (order.comp.j2).

        draw() binds the buckets, the keys, the order list and the draw's record (its triangle count
        and depth range); `grids`: the dispatch grids of the bucket clear and of the draw's triangles.
        """
        ctx, (clear, count, scatter, scan) = self.ctx, order_kernels
        clear_grid, triangle_grid = grids
        # clear the bucket counts, count (a clear folded into the one-workgroup prefix sum made the order
        # stage slower: docs/decisions.md, 2026-11-28 "the order stage's clear")
        for kernel, grid in ((clear, clear_grid), (count, triangle_grid)):
            kernel.run(*grid)
            ctx.memory_barrier(_STAGE_BARRIER)
        scan.run(1)  # prefix sum, and the setup stage's dispatch
        ctx.memory_barrier(_STAGE_BARRIER)
        scatter.run(*triangle_grid)
        ctx.memory_barrier(_STAGE_BARRIER)

    def _write_records(self, draws, ranges: dict[int, tuple[float, float]]) -> int:
        """Every draw's record (raster/draw_record.py) into the records buffer, in `draws`' order; the stride.

        UploadBuffer sends none of it where the buffer holds these bytes already (a still scene's).
        """
        layouts = [self._material(d.material).record for d in draws]
        stride = max(layout.stride for layout in layouts)
        data = bytearray(stride * len(draws))
        cache = self._material_bytes
        for k, (d, layout) in enumerate(zip(draws, layouts)):
            hit = cache.get(id(d.values))
            if hit is None or hit[0] is not d.values:
                hit = cache.put(id(d.values), (d.values, material_bytes(layout, d.values)))
            head = head_bytes(
                d.model_gl(), d.normal_gl(), ranges[d.index], len(d.mesh.positions), d.mesh.triangle_count, d.index
            )
            at = k * stride
            data[at : at + len(head)] = head
            data[at + len(head) : at + len(head) + len(hit[1])] = hit[1]
        cache.end_frame()
        self._records.upload(bytes(data))  # grows to the largest call, never shrinks: 256 B a draw
        return stride

    @staticmethod
    def _release(buf) -> None:
        if buf is not None:
            buf.release()

    # ------------------------------------------------------------------ drawing
    def draw(self, frame, draws, uniforms: dict, per_program=None) -> None:
        """Rasterize `draws` into the method's storage (bound by the method, as for hardware draws)."""
        if not draws:
            return
        if self._fresh or self._frame is not frame:
            self._begin(frame, draws)
            self._fresh, self._frame = False, frame
        ctx, device = self.ctx, self.device
        gbuffer = frame.resources["gbuffer"]
        gbuffer.depth.use(location=Texture.RASTER_DEPTH)
        samples = sample_uniforms(device.antialiasing.positions)
        buckets = self._buckets_of(frame)
        tuning = freeze(self._raster_vars())
        args, order_kernels = self._call_kernels(buckets, tuning)
        self._order_constants(frame, order_kernels, samples["gua_sample_span"])
        set_uniform(args[1], "gua_capacity", self.large_capacity)
        set_uniform(args[2], "gua_capacity", self.job_capacity)
        # what every draw of this call shares, written once per kernel below (a kernel serves all the
        # draws of its material, so only the per-draw values change between them)
        call_values = {
            **uniforms,
            "gua_any_opaque": gbuffer.has_opaque,  # the geometry pass's own answer
            **samples,  # coverage at the hardware's sample points
            "gua_large_capacity": self.large_capacity,
            "gua_job_capacity": self.job_capacity,
        }
        programs: dict[int, tuple] = {}
        method_key = self._method_key(frame.method, tuning)
        ready: set[int] = set()  # kernels given call_values in this call
        last = None  # (kernels, material instance) whose uniforms and textures the draw before set
        # draws run one after the other: take them in depth order too (see _order_pass)
        ranges = self._depth_ranges((frame.projection @ frame.view)[3], draws)
        if self._front_to_back(frame.method):
            draws = sorted(draws, key=lambda d: ranges[d.index][0])
        else:
            draws = sorted(draws, key=lambda d: -ranges[d.index][1])
        # sized for this call's largest mesh, here rather than in _begin: a later call of the pass may bring one larger
        self._fit_vertices(max(len(d.mesh.positions) for d in draws))
        self._fit_order(max(d.mesh.triangle_count for d in draws))
        # the buffers every draw of the call shares
        self._verts.bind_to_storage_buffer(Buffer.RASTER_VERTICES)
        self._state.bind(Buffer.RASTER_STATE)
        self._large.bind_to_storage_buffer(Buffer.RASTER_LARGE)
        self._jobs.bind_to_storage_buffer(Buffer.RASTER_JOBS)
        self._buckets.bind_to_storage_buffer(Buffer.RASTER_BUCKETS)
        self._order.bind_to_storage_buffer(Buffer.RASTER_ORDER)
        self._keys.bind_to_storage_buffer(Buffer.RASTER_ORDER_KEYS)
        stride = self._write_records(draws, ranges)
        clear_grid = _grid(buckets)
        last_mesh = None
        for k, d in enumerate(draws):
            new_mesh = d.mesh is not last_mesh
            if new_mesh:  # what follows from the mesh alone, looked up once for a run of draws of one mesh
                last_mesh = d.mesh
                vertices, triangles = len(d.mesh.positions), d.mesh.triangle_count
                vertex_grid, order_grids = _grid(vertices), (clear_grid, _grid(triangles))
                vbo, ibo = device.meshes.buffers(d.mesh)
                vbo.bind_to_storage_buffer(Buffer.RASTER_MESH_VERTICES)
                ibo.bind_to_storage_buffer(Buffer.RASTER_INDICES)
            kernels = programs.get(id(d.material))
            if kernels is None:  # once a material a call: _programs' key (a nested tuple) is hashed anew each look-up
                kernels = programs[id(d.material)] = self._programs(frame.method, d, method_key)
            vert, setup, binner, fine = kernels
            for prog in kernels:
                if prog.glo in ready:
                    continue
                ready.add(prog.glo)
                frame.set_frame_uniforms(prog)
                if prog is not vert:
                    set_uniforms(prog, call_values.items())
                    if per_program is not None:
                        per_program(prog)
            self._records.buffer.bind_to_storage_buffer(Buffer.RASTER_DRAW, offset=k * stride, size=stride)
            if self._material(d.material).samplers and (
                last is None or last[0] is not kernels or last[1] is not d.values
            ):
                # the material's textures (its other values are in the record), unless the draw before's
                apply_material(device.textures, d, kernels, samplers_only=True)
                last = kernels, d.values
            self._mark("between_draws")  # from the last stage (or the set-up) to this draw's start
            vert.run(*vertex_grid)
            ctx.memory_barrier(_STAGE_BARRIER)
            self._mark("vertex")
            self._order_pass(order_kernels, order_grids)
            self._mark("order")
            setup.run_indirect(self._state.buffer, _DISPATCH_OFFSET["setup_x"])
            ctx.memory_barrier(_STAGE_BARRIER)
            self._mark("setup")
            self._queued_stage(args[1], binner, "bin_x")
            self._mark("bin")
            self._queued_stage(args[2], fine, "fine_x")
            self._mark("fine")
            self._triangles += triangles
        ctx.memory_barrier()

    def _mark(self, stage: str) -> None:
        """A GPU timestamp at the end of `stage` when stage profiling is on."""
        if self._stages is not None:
            self._stages.mark(stage)

    def _queued_stage(self, args, prog, dispatch_word: str) -> None:
        """Clamp the queue the last stage filled to its capacity (an args kernel), then run `prog` over it."""
        args.run(1)
        self.ctx.memory_barrier(_STAGE_BARRIER)
        prog.run_indirect(self._state.buffer, _DISPATCH_OFFSET[dispatch_word])
        self.ctx.memory_barrier(_STAGE_BARRIER)

    def finish(self, frame) -> bool:
        """Totals into frame.stats; after an overflow, grow and ask for the frame again (MAX_REGROW times)."""
        if self._fresh or self._frame is not frame:  # nothing drawn through compute in this pass
            return False
        self._fresh, self._frame = True, None
        # a frame loop without read-back reads the previous frame's totals (finished by now) and sets
        # this frame's aside for the next, so the CPU never waits for this frame here
        c, _, late = self._state.latest(frame.late_counters, frame.view_index)
        if frame.late_counters:
            self._state.stage(view=frame.view_index)
        frame.stats.setdefault("raster", {})["compute"] = {
            "order": frame.method.raster_order(frame.width * frame.height),
            "triangles": self._triangles,
            "large_triangles": c["large_total"],
            "visible_triangles": c["visible_total"],
            "tiled_triangles": c["tiled_total"],
            "tile_jobs": c["jobs_total"],
            "large_dropped": c["large_dropped"],
            "tile_jobs_dropped": c["jobs_dropped"],
        }
        if self._stages is not None:  # stage profiling: this frame's spans (waits for the GPU)
            spans = self._stages.spans_ms()
            frame.stats["raster"]["compute"]["stage_ms"] = {k: round(v, 4) for k, v in spans.items()}
        frame.stats.section("memory").update(self.memory(c["large_peak"], c["jobs_peak"]))
        dropped = c["large_dropped"] or c["jobs_dropped"]
        if dropped and late:  # grow for the next frame; this one is not rendered again
            self._grow(c)
            frame.stats.warn(
                f"compute raster: {c['large_dropped']} large triangles and {c['jobs_dropped']} tile jobs dropped "
                "in the previous frame; the queues grow for the next"
            )
            return False
        redraws = frame.stats.get("regrown", 0)  # re-draws of this frame so far (pipeline/retry.py)
        if dropped and redraws < MAX_REGROW:
            self._grow(c)
            return True
        if dropped:
            frame.stats.warn(
                f"compute raster: {c['large_dropped']} large triangles and {c['jobs_dropped']} tile jobs dropped "
                f"(queue {self.large_capacity}, jobs {self.job_capacity} per draw) after {redraws} re-draws"
            )
        return False

    def _grow(self, c: dict) -> None:
        """Ask the next frame's buffers for room for what the counts `c` show was dropped."""
        if c["large_dropped"]:
            self._want["large"] = with_margin(c["large_peak"])
        if c["jobs_dropped"]:
            # a larger queue lets more triangles through to binning: leave room for their jobs too
            scale = 1.0 if not c["large_dropped"] else c["large_peak"] / max(1, self.large_capacity)
            self._want["jobs"] = with_margin(c["jobs_peak"] * scale, slack=4096)

    def memory(self, large_peak: int = 0, jobs_peak: int = 0) -> dict:
        """Bytes of the rasterizer's buffers, allocated and used by the busiest draw."""
        return {
            "raster_vertices": self.vertex_capacity * VERTEX_RECORD_BYTES,
            "raster_order": 2 * self.order_capacity * 4 + max(BUCKETS, LARGE_TILE_BUCKETS) * 4,
            "raster_large_queue": self.large_capacity * 4,
            "raster_large_queue_used": min(large_peak, self.large_capacity) * 4,
            "raster_tile_jobs": self.job_capacity * 8,
            "raster_tile_jobs_used": min(jobs_peak, self.job_capacity) * 8,
            "raster_draw_records": self._records.buffer.size if self._records.buffer is not None else 0,
        }

    def release(self) -> None:
        """Free all buffers."""
        if self._stages is not None:
            self._stages.release()
        if self._state is not None:
            self._state.release()
        for b in (
            self._verts,
            self._large,
            self._jobs,
            self._buckets,
            self._order,
            self._keys,
        ):
            self._release(b)
        self._records.release()
        self._state = self._verts = self._large = self._jobs = None
        self._buckets = self._order = self._keys = None
        self._kernels.clear()  # the programs are the library's; the renderer releases them with it
        self.vertex_capacity = self.large_capacity = self.job_capacity = self.order_capacity = 0
        self._fresh, self._frame = True, None
