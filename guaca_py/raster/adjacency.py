"""Edge neighbours of a triangle mesh, for merging the coverage of adjacent triangles (antialiasing.merge).

For triangle t and corner j, `edge_apexes(indices)[t, j]` is the far vertex of the triangle across
the edge opposite corner j: the vertex of the neighbour that the two triangles do not share. Only
edges of a consistently wound manifold surface have one (the edge used once in each direction by
exactly two triangles); a boundary, a non-manifold edge (three or more triangles) or a neighbour
wound the other way gets NO_NEIGHBOUR. The compute rasterizer reads it per triangle
(raster/triangle.glsl.j2, gua_neighbours).
"""

from __future__ import annotations

import numpy as np

NO_NEIGHBOUR = 0xFFFFFFFF


def edge_apexes(indices: np.ndarray) -> np.ndarray:
    """(M, 3) uint32: per triangle and corner j, the apex of the neighbour across the edge opposite j."""
    f = np.asarray(indices, dtype=np.int64).reshape(-1, 3)
    m = len(f)
    out = np.full((m, 3), NO_NEIGHBOUR, dtype=np.uint32)
    if m == 0:
        return out
    n = int(f.max()) + 1
    # directed edge opposite corner j runs from corner j+1 to corner j+2 (the winding's direction);
    # slot j * m + t holds that edge of triangle t
    tail = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    head = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    apex = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    key = tail * n + head
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    first = np.searchsorted(sorted_key, key, side="left")
    count = np.searchsorted(sorted_key, key, side="right") - first
    twin = head * n + tail  # the same edge run the other way: the neighbour's
    t_first = np.searchsorted(sorted_key, twin, side="left")
    t_count = np.searchsorted(sorted_key, twin, side="right") - t_first
    # a manifold, consistently wound edge: this direction once, the other once, not a degenerate loop
    ok = (count == 1) & (t_count == 1) & (tail != head)
    slots = np.nonzero(ok)[0]
    neighbour_slot = order[t_first[slots]]
    out[slots % m, slots // m] = apex[neighbour_slot].astype(np.uint32)
    return out
