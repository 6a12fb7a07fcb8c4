"""Hybrid and coherent layer peeling (Carr, Mech & Miller 2008): peeling that exploits sorted input.

Both composite whole runs of correctly ordered fragments in one geometry pass: such a pass shades
the fragments of a per-pixel key range in place and lets the hardware blend them under the front
accumulation in submission order, which is depth order inside the range. Peeling proper is only
needed where the input is out of order.

Hybrid layer peeling (paper §3, Algorithm 1): draws are split into a sorted set (planar draws whose
view-depth intervals follow each other front to back in submission order: the longest such chain)
and the rest. Each iteration peels the nearest layer of the unsorted draws, composites the sorted
draws between the previous and this layer, then the peeled layer. A fully sorted scene takes one
geometry pass.

Coherent layer peeling (paper §5): per iteration four counting passes find, per pixel, the nearest
remaining surface s_n, the nearest earlier-submitted surface behind it (z_min_prev, passes 1-2:
count z-buffer updates in the stencil, count them back down) and the nearest surface after the
in-order run that starts at s_n (z_min_post, passes 3-4: count the run, skip it); pass 5
composites [D(s_n), min(z_min_prev, z_min_post)) in submission order and a step shades the surface
at the upper bound (the paper's pass 6). Depth and stencil are emulated per pixel in primitive
order on exact (depth, tie) keys; the stencil is 8 bits like the paper's. More than 255 z-buffer
updates in pass 1 (255 surfaces submitted in reverse order in front of s_n) saturate it: such
pixels peel just s_n that iteration (exact, slower) and are counted in stats and warnings.
"""

from __future__ import annotations

import numpy as np

from ..pipeline.settings import Setting
from ..registry import register
from .base import MethodSpec
from .peeling import EMPTY_NEAR, EMPTY_NEAR_TIE, NEAREST_PAYLOAD, PEEL_SETTINGS, ZERO, Peeling, PeelKind

# Emulated GL state of the counting passes (peeling/stencil8.glsl.j2 and coherent_stencil.glsl.j2).
DEPTH_LESS, DEPTH_GREATER = 1, 2
ST_ALWAYS, ST_LESS, ST_GREATER, ST_EQUAL = 0, 1, 2, 3
OP_KEEP, OP_ZERO, OP_INCR, OP_DECR, OP_INVERT = 0, 1, 2, 3, 4
# pass: (depth func, stencil func, stencil ref, (sfail, zfail, zpass), store payload on zpass)
COUNTING_PASSES = {
    1: (DEPTH_LESS, ST_ALWAYS, 0, (OP_KEEP, OP_KEEP, OP_INCR), True),  # count z-buffer updates
    2: (DEPTH_LESS, ST_LESS, 1, (OP_KEEP, OP_KEEP, OP_DECR), True),  # count back down: z_min_prev
    3: (DEPTH_GREATER, ST_GREATER, 128, (OP_KEEP, OP_INVERT, OP_INCR), False),  # length of the in-order run
    4: (DEPTH_LESS, ST_EQUAL, 255, (OP_INCR, OP_KEEP, OP_KEEP), True),  # skip the run: z_min_post
}
PASSES_PER_ITERATION = 5


def view_depth_interval(draw, view: np.ndarray) -> tuple[float, float]:
    """Distance range along the view direction of a draw's transformed vertices."""
    p = np.asarray(draw.mesh.positions, dtype=np.float64)
    world = p @ np.asarray(draw.world, dtype=np.float64)[:3, :3].T + np.asarray(draw.world)[:3, 3]
    z = -(world @ view[:3, :3].T + view[:3, 3])[:, 2]
    return float(z.min()), float(z.max())


def is_planar(draw, rel_eps: float = 1e-6) -> bool:
    """All vertices on one plane: the draw covers a pixel centre at most once (up to coplanar overlap)."""
    p = np.asarray(draw.mesh.positions, dtype=np.float64)
    if len(p) <= 3:
        return True
    c = p - p.mean(axis=0)
    _, sv, _ = np.linalg.svd(c, full_matrices=False)
    return sv[-1] <= rel_eps * max(sv[0], 1e-30)


def sorted_chain(intervals: list[tuple[float, float] | None]) -> list[int]:
    """Indices of the longest subsequence whose intervals follow each other front to back.

    Interval i may follow j when far(j) <= near(i); None marks draws that cannot be in the chain.
    Patience-style: tails[k] is the smallest far end of a chain of length k + 1.
    """
    import bisect

    tails: list[float] = []
    tail_idx: list[int] = []
    parent: dict[int, int] = {}
    for i, iv in enumerate(intervals):
        if iv is None:
            continue
        near, far = iv
        k = bisect.bisect_right(tails, near)  # chains whose last far end <= near
        if k > 0:
            parent[i] = tail_idx[k - 1]
        if k == len(tails):
            tails.append(far)
            tail_idx.append(i)
        elif far < tails[k]:
            tails[k] = far
            tail_idx[k] = i
    if not tails:
        return []
    out = [tail_idx[-1]]
    while out[-1] in parent:
        out.append(parent[out[-1]])
    return out[::-1]


def split_sorted(m: Peeling, frame) -> tuple[list, list]:
    """(sorted draws, unsorted draws) in submission order, by the method's `sorted_set` setting."""
    draws = frame.transparent_draws
    if m.settings["sorted_set"] == "none":
        return [], draws
    # vertex displacement moves geometry on the GPU: the CPU interval would not bound it
    ivs = [
        view_depth_interval(d, frame.view) if is_planar(d) and not d.material.methods.get("displacement") else None
        for d in draws
    ]
    chain = set(sorted_chain(ivs))
    return [d for i, d in enumerate(draws) if i in chain], [d for i, d in enumerate(draws) if i not in chain]


def peel_hybrid(m: Peeling, frame) -> None:
    """Algorithm 1 of the paper, on exact keys: peel the unsorted draws, composite the sorted ones
    between peeled layers; stops once an iteration peels no unsorted layer."""
    s = m.stats
    sorted_draws, unsorted = split_sorted(m, frame)
    s.update(sorted_draws=len(sorted_draws), unsorted_draws=len(unsorted))
    peel = bool(unsorted)
    left = 0
    while True:
        need = int(peel) + int(bool(sorted_draws))
        if m.cap_reached(need):
            m.truncate(left)
            m.warn(f"{m.id}: sorted fragments behind the last peeled layer were not composited")
            break
        m.reset_counters()
        if peel:
            m.geometry_pass(frame, "nearest", draws=unsorted)
        m.step(frame, "hybrid_range")
        if sorted_draws:
            m.composite_range_pass(frame, draws=sorted_draws)
        m.step(frame, "nearest")
        c = m.read_counters()
        s["iterations"] += 1
        s["peeled"] += c["peeled"]
        s["composited"] += c["composited"]
        s["saturated_pixels"] += c["saturated"]
        left = c["in_range"] - c["peeled"]
        if c["peeled"] == 0:
            break  # no unsorted layer: the sorted draws were composited up to the opaque surface
        peel = peel and left > 0  # no unsorted fragment left: one more compositing pass finishes


def _counting_pass(m: Peeling, frame, n: int) -> None:
    """Counting pass n (1-4) with the paper's depth/stencil state, then its step."""
    depth, sfunc, ref, (sfail, zfail, zpass), capture = COUNTING_PASSES[n]
    m.geometry_pass(
        frame,
        "stencil",
        uniforms={
            "gua_cl_pass": n,
            "gua_cl_depth_func": depth,
            "gua_cl_stencil_func": sfunc,
            "gua_cl_stencil_ref": ref,
            "gua_cl_op_sfail": sfail,
            "gua_cl_op_zfail": zfail,
            "gua_cl_op_zpass": zpass,
            "gua_cl_capture": capture,
        },
    )
    m.step(frame, f"coherent_after_{n}")


def peel_coherent(m: Peeling, frame) -> None:
    """Iterations of passes 1-5 until nothing is left in front of the opaque surfaces."""
    s = m.stats
    s.update(stencil_overflow_pixels=0)
    left = 0
    while True:
        if m.cap_reached(1):
            m.truncate(left)
            break
        m.reset_counters()
        _counting_pass(m, frame, 1)
        c = m.read_counters()
        if c["in_range"] == 0:
            break  # nothing left to peel anywhere
        if m.cap_reached(PASSES_PER_ITERATION - 1):
            m.truncate(c["in_range"])
            break
        for n in (2, 3, 4):
            _counting_pass(m, frame, n)
        m.composite_range_pass(frame)
        m.step(frame, "coherent_after_5")
        c = m.read_counters()
        s["iterations"] += 1
        s["peeled"] += c["peeled"]
        s["composited"] += c["composited"]
        s["saturated_pixels"] += c["saturated"]
        s["stencil_overflow_pixels"] += c["overflow"]
        left = c["in_range"] - c["composited"] - c["peeled"]
        if left == 0:
            break
    if s["stencil_overflow_pixels"]:
        m.warn(
            f"{m.id}: 8-bit stencil overflow: more than 255 out-of-order surfaces in front of the "
            f"nearest one ({s['stencil_overflow_pixels']} pixel-iterations); those pixels peeled one "
            "layer per iteration instead (exact, more passes)"
        )


register("method")(
    MethodSpec(
        "hybrid_layer_peeling",
        "hybrid layer peeling: depth-peel unsorted draws, composite sorted draws between layers",
        Peeling,
        PeelKind("nearest", peel_hybrid, NEAREST_PAYLOAD, has_range=True),
        {
            **PEEL_SETTINGS,
            "sorted_set": Setting(
                (str,),
                "auto",
                "which draws are composited as sorted geometry: 'auto' (the "
                "longest front-to-back chain of planar draws) or 'none' (plain depth peeling)",
                choices=("auto", "none"),
            ),
        },
        geometry_passes=None,
        geometry_passes_rule="2(unsorted+1)",
    )
)
register("method")(
    MethodSpec(
        "coherent_layer_peeling",
        "coherent layer peeling: stencil-counted in-order runs composited per pass (8-bit stencil)",
        Peeling,
        PeelKind(
            "coherent",
            peel_coherent,
            # the emulated depth (key, cleared to far) and 8-bit stencil (0) the counting passes read
            # and write in primitive order, and the upper surface's payload (none)
            (
                ("depth", 4, "uvec4(GUA_INF, GUA_TIE_MAX, 0u, 0u)"),
                ("stencil", 1, ZERO),
                ("payload0", 4, EMPTY_NEAR),
                ("payload1", 4, EMPTY_NEAR_TIE),
            ),
            has_range=True,
        ),
        PEEL_SETTINGS,
        geometry_passes=None,
        geometry_passes_rule="5/iteration",
    )
)
