"""Independent float64 CPU reference renderer for checking order-independent transparency.

Deliberately shares no math with the renderer: the camera basis, ray generation, projection
and compositing are all derived here from the Camera's raw fields.
"""

from __future__ import annotations

import math

import numpy as np

from ..scene.graph import Camera, Scene

_UNLIT_UNIFORMS = frozenset({"color", "alpha"})
_PIXEL_CHUNK = 4096  # pixels per ray batch: bounds the (pixels x triangles) temporaries


# ----------------------------------------------------------------------------- scene input


def scene_triangles(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World-space triangles (N,3,3), colors (N,3) and alphas (N,) of all mesh nodes, in walk order."""
    tris: list[np.ndarray] = []
    rgb: list[np.ndarray] = []
    alpha: list[np.ndarray] = []
    for node, world in scene.walk():
        if node.mesh is None:
            continue
        mat = node.material
        if mat is None or mat.description != "unlit":
            raise ValueError(f"node {node.name!r}: reference only models 'unlit' materials, got {mat!r}")
        unknown = set(mat.uniforms) - _UNLIT_UNIFORMS
        if unknown:
            # An uniform we cannot model would make the reference silently wrong.
            raise ValueError(f"node {node.name!r}: unsupported unlit uniforms {sorted(unknown)}")
        color = np.asarray(mat.uniforms.get("color", (1.0, 1.0, 1.0)), dtype=np.float64)
        if color.shape != (3,):
            raise ValueError(f"node {node.name!r}: color must have 3 components, got {color.shape}")
        a = float(mat.uniforms.get("alpha", 1.0))
        pos = np.asarray(node.mesh.positions, dtype=np.float64)
        world_pos = pos @ world[:3, :3].T + world[:3, 3]
        idx = np.asarray(node.mesh.indices, dtype=np.int64).reshape(-1, 3)
        tris.append(world_pos[idx])
        rgb.append(np.broadcast_to(color, (len(idx), 3)))
        alpha.append(np.full(len(idx), a))
    if not tris:
        return np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0)
    return np.concatenate(tris), np.concatenate(rgb).astype(np.float64), np.concatenate(alpha)


# ----------------------------------------------------------------------------- camera model


def camera_basis(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Eye, right s, up u, forward f (orthonormal, right-handed look-at) and tan(fov_y/2)."""
    eye = np.asarray(camera.position, dtype=np.float64)
    f = np.asarray(camera.target, dtype=np.float64) - eye
    f = f / np.linalg.norm(f)
    s = np.cross(f, np.asarray(camera.up, dtype=np.float64))
    s = s / np.linalg.norm(s)
    u = np.cross(s, f)
    return eye, s, u, f, math.tan(math.radians(camera.fov_y) / 2.0)


def camera_rays(camera: Camera, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eye (3,), pixel-centre ray directions (H,W,3) with row 0 at the top, and forward f (3,).

    Directions are not normalised: dot(dir, f) == 1, so a ray parameter t is the view depth.
    """
    eye, s, u, f, tan_half = camera_basis(camera)
    aspect = width / height
    ndc_x = (np.arange(width) + 0.5) / width * 2.0 - 1.0
    ndc_y = 1.0 - (np.arange(height) + 0.5) / height * 2.0
    dirs = f[None, None, :] + (ndc_x * tan_half * aspect)[None, :, None] * s + (ndc_y * tan_half)[:, None, None] * u
    return eye, dirs, f


# ----------------------------------------------------------------------------- ray casting


def ray_hits(
    eye: np.ndarray, dirs: np.ndarray, tris: np.ndarray, near: float, far: float
) -> tuple[np.ndarray, np.ndarray]:
    """Double-sided Möller–Trumbore of rays (P,3) from eye against tris (N,3,3): hit mask and t, both (P,N)."""
    v0 = tris[:, 0]
    e1 = tris[:, 1] - v0
    e2 = tris[:, 2] - v0
    tvec = eye[None, :] - v0
    # All rays share one origin, so every cross product is ray independent; via the scalar
    # triple product, det, u and v each become one (P,3)x(3,N) matrix product.
    n_swapped = np.cross(e2, e1)  # d . (e2 x e1) == e1 . (d x e2) == det
    u_axis = np.cross(e2, tvec)  # d . (e2 x tvec) == tvec . (d x e2)
    qvec = np.cross(tvec, e1)
    det = dirs @ n_swapped.T
    # Grazing rays on (near) edge-on triangles have no stable hit; GPUs draw nothing there either.
    scale = np.linalg.norm(dirs, axis=1)[:, None] * np.linalg.norm(n_swapped, axis=1)[None, :]
    valid = np.abs(det) > 1e-12 * scale
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(valid, 1.0 / np.where(valid, det, 1.0), 0.0)
        u = (dirs @ u_axis.T) * inv
        v = (dirs @ qvec.T) * inv
        t = np.einsum("ij,ij->i", e2, qvec)[None, :] * inv
    hit = valid & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t >= near) & (t <= far)
    return hit, t


def render_reference(
    tris: np.ndarray,
    rgb: np.ndarray,
    alpha: np.ndarray,
    camera: Camera,
    width: int,
    height: int,
    background: tuple[float, float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """Exact per-pixel sorted front-to-back "under" composite: image (H,W,3) float64, layers (H,W) int."""
    eye, dirs, _ = camera_rays(camera, width, height)
    dirs = dirs.reshape(-1, 3)
    n_pix = dirs.shape[0]
    bg = np.asarray(background, dtype=np.float64).reshape(3)
    image = np.empty((n_pix, 3))
    layers = np.zeros(n_pix, dtype=np.int64)
    tris = np.asarray(tris, dtype=np.float64).reshape(-1, 3, 3)
    rgb = np.asarray(rgb, dtype=np.float64).reshape(-1, 3)
    alpha = np.asarray(alpha, dtype=np.float64).reshape(-1)
    for start in range(0, n_pix, _PIXEL_CHUNK):
        d = dirs[start : start + _PIXEL_CHUNK]
        color = np.zeros((len(d), 3))
        acc = np.zeros(len(d))
        if len(tris):
            hit, t = ray_hits(eye, d, tris, camera.near, camera.far)
            depth = np.where(hit, t, np.inf)
            # Stable sort: equal depths keep triangle (submission) order; misses sort last.
            order = np.argsort(depth, axis=1, kind="stable")
            count = hit.sum(axis=1)
            for k in range(int(count.max(initial=0))):
                tri = order[:, k]
                a = np.where(k < count, alpha[tri], 0.0)
                color += ((1.0 - acc) * a)[:, None] * rgb[tri]
                acc += (1.0 - acc) * a
            layers[start : start + len(d)] = count
        image[start : start + len(d)] = color + (1.0 - acc)[:, None] * bg
    return image.reshape(height, width, 3), layers.reshape(height, width)


# ----------------------------------------------------------------------------- edge mask


def _clip_polygon(poly: list[np.ndarray], keep_sign: float, plane_z: float) -> list[np.ndarray]:
    """Sutherland–Hodgman clip of a view-space polygon to keep_sign*(z - plane_z) >= 0."""
    out: list[np.ndarray] = []
    for i, cur in enumerate(poly):
        prev = poly[i - 1]
        dc = keep_sign * (cur[2] - plane_z)
        dp = keep_sign * (prev[2] - plane_z)
        if (dc >= 0.0) != (dp >= 0.0):
            out.append(prev + (cur - prev) * (dp / (dp - dc)))
        if dc >= 0.0:
            out.append(cur)
    return out


def projected_edges(tris: np.ndarray, camera: Camera, width: int, height: int) -> np.ndarray:
    """Screen-space segments (E,2,2) as (col,row) pixel coordinates of each triangle clipped to [near,far].

    Pixel (r,c) has its centre at (c, r). Clipping adds the near/far cut lines as edges, since
    the GPU's clipped polygon has those boundaries too.
    """
    eye, s, u, f, tan_half = camera_basis(camera)
    aspect = width / height
    basis = np.stack([s, u, f])  # rows: view x, view y, depth
    view = (np.asarray(tris, dtype=np.float64).reshape(-1, 3, 3) - eye) @ basis.T
    segs: list[np.ndarray] = []
    for tri in view:
        poly = _clip_polygon(list(tri), 1.0, camera.near)
        poly = _clip_polygon(poly, -1.0, camera.far) if poly else poly
        if len(poly) < 2:
            continue
        p = np.array(poly)
        col = (p[:, 0] / (p[:, 2] * tan_half * aspect) + 1.0) * 0.5 * width - 0.5
        row = (1.0 - p[:, 1] / (p[:, 2] * tan_half)) * 0.5 * height - 0.5
        pts = np.stack([col, row], axis=1)
        segs.append(np.stack([pts, np.roll(pts, -1, axis=0)], axis=1))
    return np.concatenate(segs) if segs else np.zeros((0, 2, 2))


def edge_mask(tris: np.ndarray, camera: Camera, width: int, height: int, radius: float = 0.5) -> np.ndarray:
    """(H,W) bool: pixel centres within `radius` pixels of any projected (near/far clipped) triangle edge."""
    mask = np.zeros((height, width), dtype=bool)
    reach = radius + 1e-9  # slack so pixels exactly at `radius` are excluded despite rounding
    for a, b in projected_edges(tris, camera, width, height):
        c0 = max(int(math.floor(min(a[0], b[0]) - reach)), 0)
        c1 = min(int(math.ceil(max(a[0], b[0]) + reach)), width - 1)
        r0 = max(int(math.floor(min(a[1], b[1]) - reach)), 0)
        r1 = min(int(math.ceil(max(a[1], b[1]) + reach)), height - 1)
        if c0 > c1 or r0 > r1:
            continue
        rr, cc = np.mgrid[r0 : r1 + 1, c0 : c1 + 1]
        px = np.stack([cc, rr], axis=-1).astype(np.float64)
        ab = b - a
        len2 = float(ab @ ab)
        w = np.clip(((px - a) @ ab) / len2, 0.0, 1.0) if len2 > 0.0 else np.zeros(rr.shape)
        dist2 = np.sum((px - (a + w[..., None] * ab)) ** 2, axis=-1)
        mask[r0 : r1 + 1, c0 : c1 + 1] |= dist2 <= reach * reach
    return mask


# ----------------------------------------------------------------------------- comparison


def compare(gpu_rgb_uint8: np.ndarray, ref_float: np.ndarray, mask_exclude: np.ndarray) -> dict:
    """Error in 1/255 units over non-excluded pixels: max_abs_255, rmse_255, n_compared, worst_pixel (row,col)."""
    gpu = np.asarray(gpu_rgb_uint8)
    ref = np.asarray(ref_float, dtype=np.float64)
    mask = np.asarray(mask_exclude, dtype=bool)
    if gpu.dtype != np.uint8 or gpu.shape != ref.shape or gpu.shape[:2] != mask.shape or gpu.shape[2] != 3:
        raise ValueError(f"shape/dtype mismatch: gpu {gpu.shape} {gpu.dtype}, ref {ref.shape}, mask {mask.shape}")
    keep = ~mask
    n = int(keep.sum())
    if n == 0:
        raise ValueError("every pixel is excluded; nothing to compare")
    # The GPU stores into a clamped unorm target, so compare against the clamped reference.
    err = np.abs(gpu.astype(np.float64) - np.clip(ref, 0.0, 1.0) * 255.0)
    per_pixel = np.where(keep, err.max(axis=2), -1.0)
    worst = np.unravel_index(int(np.argmax(per_pixel)), per_pixel.shape)
    return {
        "max_abs_255": float(per_pixel[worst]),
        "rmse_255": float(np.sqrt(np.mean(err[keep] ** 2))),
        "n_compared": n,
        "worst_pixel": (int(worst[0]), int(worst[1])),
    }


def reference_of(scene: Scene, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference image, the exclusion mask of edge pixels and per-pixel layer counts of a scene."""
    tris, rgb, alpha = scene_triangles(scene)
    img, layers = render_reference(tris, rgb, alpha, scene.camera, width, height, scene.background)
    return img, edge_mask(tris, scene.camera, width, height), layers
