"""The shared PBR BRDF (shading/brdf.glsl.j2) and light formulas (shading/lighting.glsl.j2) against float64 numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import unit_quad

from guaca_py import pipeline_from_text
from guaca_py.scene.graph import Camera, Light, MaterialInstance, Node, Scene, Transform

ROUGHNESS = (0.25, 0.5, 1.0)
VIEW_COS = (1.0, 0.5, 0.1)


# ----------------------------------------------------------------------------- numpy model (float64)
def schlick(c, f0):
    """Schlick's Fresnel approximation, broadcast over RGB f0."""
    return f0 + (1.0 - f0) * (1.0 - np.clip(c, 0.0, 1.0))[..., None] ** 5


def alpha_of(rough: float) -> float:
    """GGX alpha from perceptual roughness (clamped like the shader)."""
    return max(rough * rough, 2e-3)


def ggx_d(nh, a):
    """GGX normal distribution."""
    return a * a / (math.pi * (nh * nh * (a * a - 1.0) + 1.0) ** 2)


def brdf_cos(n, v, l, albedo, rough, metal, diffuse="transmittance"):
    """f(l, v) (n.l) for directions l (m, 3); `diffuse='v_dot_h'` is the weighting the shader used to have."""
    n, v, l, albedo = (np.asarray(x, np.float64) for x in (n, v, l, albedo))
    nl = l @ n
    nv = np.clip(abs(v @ n), 1e-4, 1.0)
    h = v + l
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    nh, vh = np.clip(h @ n, 0.0, 1.0), np.clip(h @ v, 0.0, 1.0)
    a = alpha_of(rough)
    a2 = a * a
    vis = 0.5 / np.maximum(nl * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nl * nl * (1 - a2) + a2), 1e-7)
    f0 = 0.04 * (1.0 - metal) + albedo * metal
    f = schlick(vh, f0)
    if diffuse == "v_dot_h":
        kd = 1.0 - f
    else:
        kd = (1.0 - schlick(nl, f0)) * (1.0 - schlick(np.full_like(nl, nv), f0))
    out = (kd * (1.0 - metal) * albedo / math.pi + (ggx_d(nh, a) * vis)[:, None] * f) * nl[:, None]
    return np.where((nl > 0)[:, None], out, 0.0)


# ----------------------------------------------------------------------------- GLSL evaluation
@pytest.fixture(scope="module")
def glsl_brdf(gl_context):
    """Evaluate gua_brdf_cos (and Schlick F) on the GPU for a batch of light directions."""
    from guaca_py.shaders import ShaderLibrary
    from guaca_py.shaders.slots import Buffer

    prog = ShaderLibrary(gl_context).compute("shading/brdf_eval.comp.j2")

    def evaluate(n, v, ls, albedo, rough, metal, cosines=None):
        data = np.zeros((len(ls), 4), np.float32)
        data[:, :3] = ls
        if cosines is not None:
            data[:, 3] = cosines
        bi, bo = gl_context.buffer(data.tobytes()), gl_context.buffer(reserve=data.nbytes)
        bi.bind_to_storage_buffer(Buffer.BRDF_EVAL_IN)
        bo.bind_to_storage_buffer(Buffer.BRDF_EVAL_OUT)
        for name, value in (
            ("gua_n", tuple(map(float, n))),
            ("gua_v", tuple(map(float, v))),
            ("gua_albedo", tuple(map(float, albedo))),
            ("gua_roughness", float(rough)),
            ("gua_metalness", float(metal)),
            ("gua_count", len(ls)),
        ):
            prog[name] = value
        prog.run(-(-len(ls) // 64))
        gl_context.memory_barrier()
        out = np.frombuffer(bo.read(), np.float32).reshape(-1, 4).astype(np.float64)
        bi.release()
        bo.release()
        return out

    return evaluate


def _hemisphere(rng, n, count):
    x = rng.normal(size=(count, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return np.where((x @ n)[:, None] < 0, -x, x)


def test_glsl_brdf_matches_numpy_at_sampled_angles(glsl_brdf):
    rng = np.random.default_rng(0)
    worst = 0.0
    for k in range(36):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        v = _hemisphere(rng, n, 1)[0]
        ls = np.concatenate([_hemisphere(rng, n, 250), -_hemisphere(rng, n, 6)])  # a few below the horizon
        rough = (0.1, 0.2, 0.35, 0.5, 0.8, 1.0)[k % 6]
        metal = (0.0, 0.5, 1.0)[k % 3]
        albedo = rng.uniform(0.05, 1.0, 3)
        got = glsl_brdf(n, v, ls, albedo, rough, metal)[:, :3]
        want = brdf_cos(n, v, ls, albedo, rough, metal)
        assert np.all(got[-6:] == 0.0)
        rel = np.abs(got - want) / np.maximum(np.abs(want), 1e-3)
        worst = max(worst, float(rel.max()))
    print(f"GLSL vs float64 BRDF: worst relative error {worst:.2e}")
    assert worst < 2e-3


def test_fresnel_reaches_one_at_grazing(glsl_brdf):
    cos = np.array([1.0, 0.5, 0.1, 1e-2, 1e-3, 0.0])
    f = glsl_brdf((0, 0, 1), (0, 0, 1), np.tile([0.0, 0.0, 1.0], (len(cos), 1)), (1, 1, 1), 0.5, 0.0, cos)[:, 3]
    assert f[0] == pytest.approx(0.04, abs=1e-6)
    assert np.all(np.diff(f) > 0)  # monotone towards grazing
    assert f[-1] == pytest.approx(1.0, abs=1e-6) and f[-2] > 0.995
    # a metal's specular reflection at grazing turns white whatever its color
    n, v = np.array([0, 0, 1.0]), np.array([math.sqrt(1 - 0.02**2), 0, 0.02])
    l = np.array([[-v[0], 0, v[2]]])  # mirror direction
    c = glsl_brdf(n, v, l, (1.0, 0.2, 0.0), 0.3, 1.0)[0, :3]
    assert c.min() / c.max() > 0.85


# ----------------------------------------------------------------------------- white furnace
def _grid(k):
    u = (np.arange(k) + 0.5) / k
    w = (np.arange(2 * k) + 0.5) / (2 * k) * 2 * math.pi
    a, b = np.meshgrid(u, w, indexing="ij")
    return a.ravel(), b.ravel()


def _furnace_samples(nv, rough, k=128):
    """Light directions from two stratified strategies (GGX half vectors, cosine) with balance-heuristic weights."""
    v = np.array([math.sqrt(1 - nv * nv), 0.0, nv])
    a2 = alpha_of(rough) ** 2
    xi, phi = _grid(k)
    c2 = (1 - xi) / (1 + (a2 - 1) * xi)  # GGX: cos^2 of the half-vector angle
    ch, sh = np.sqrt(c2), np.sqrt(1 - c2)
    h = np.stack([sh * np.cos(phi), sh * np.sin(phi), ch], -1)
    l_spec = 2 * (h @ v)[:, None] * h - v
    l_spec[(h @ v) <= 0] = (0.0, 0.0, -1.0)  # wasted sample: below the horizon, f = 0
    s = np.sqrt(xi)
    l_diff = np.stack([s * np.cos(phi), s * np.sin(phi), np.sqrt(1 - xi)], -1)
    ls = np.concatenate([l_spec, l_diff])

    def pdf_spec(l):
        hh = v + l
        hh /= np.maximum(np.linalg.norm(hh, axis=-1, keepdims=True), 1e-300)
        vh = hh @ v
        return np.where(
            (vh > 0) & (l[:, 2] > 0), ggx_d(hh[:, 2], alpha_of(rough)) * hh[:, 2] / (4 * np.maximum(vh, 1e-300)), 0.0
        )

    m = len(xi)
    weight = 1.0 / (m * pdf_spec(ls) + m * np.maximum(ls[:, 2], 0.0) / math.pi + 1e-300)
    return v, ls, weight


@pytest.mark.parametrize("rough", ROUGHNESS)
def test_white_furnace_directional_albedo_at_most_one(glsl_brdf, rough):
    rows = []
    for nv in VIEW_COS:
        v, ls, w = _furnace_samples(nv, rough)
        for metal in (0.0, 1.0):
            e_gpu = float((glsl_brdf((0, 0, 1), v, ls, (1, 1, 1), rough, metal)[:, 0] * w).sum())
            e_np = float((brdf_cos((0, 0, 1), v, ls, (1, 1, 1), rough, metal)[:, 0] * w).sum())
            rows.append((nv, metal, e_gpu))
            assert e_gpu == pytest.approx(e_np, abs=2e-3)
            assert e_gpu <= 1.0 + 2e-3, f"roughness {rough}, n.v {nv}, metal {metal}: albedo {e_gpu:.4f}"
        if nv == 1.0:
            # the quadrature resolves the lobe: a white metal at normal incidence keeps most energy
            assert rows[-1][2] > {0.25: 0.97, 0.5: 0.88, 1.0: 0.28}[rough]
    print(f"roughness {rough}: directional albedo (n.v, metal, E) {[(a, b, round(c, 4)) for a, b, c in rows]}")


def test_white_furnace_catches_energy_gain():
    # The check is able to fail: the diffuse weighting (1 - F(v.h)) gains energy at grazing view.
    v, ls, w = _furnace_samples(0.1, 0.25)
    e = float((brdf_cos((0, 0, 1), v, ls, (1, 1, 1), 0.25, 0.0, diffuse="v_dot_h")[:, 0] * w).sum())
    assert e > 1.1


# ----------------------------------------------------------------------------- light formulas in a frame
LIT = """
passes:
  - geometry: {}
  - light_culling: {mode: fallback, tile_size: 8}
  - composite: {}
"""


def _radiance(light: Light, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-point incident radiance (m, 3) and unit direction to the light (m, 3): docs/lighting.md."""
    color = np.asarray(light.color) * light.intensity
    if light.type == "directional":
        d = -np.asarray(light.direction) / np.linalg.norm(light.direction)
        return np.tile(color, (len(p), 1)), np.tile(d, (len(p), 1))
    d = np.asarray(light.position) - p
    dist2 = (d * d).sum(axis=1)
    l = d / np.sqrt(dist2)[:, None]
    window = np.clip(1 - (dist2 / light.radius**2) ** 2, 0, 1) ** 2
    att = window / np.maximum(dist2, 1e-2)
    if light.type == "spot":
        axis = np.asarray(light.direction) / np.linalg.norm(light.direction)
        cd = -l @ axis
        co, ci = math.cos(math.radians(light.outer_angle_deg)), math.cos(math.radians(light.inner_angle_deg))
        t = np.clip((cd - co) / (ci - co), 0, 1)
        att *= np.where(cd > co, t * t * (3 - 2 * t), 0.0)
    return att[:, None] * color, l


@pytest.mark.parametrize("kind", ["point", "spot", "directional"])
def test_light_formulas_match_numpy(renderer_factory, kind):
    lights = {
        "point": [Light("point", (0.4, 0.3, 0.8), color=(1.0, 0.8, 0.6), intensity=1.5, radius=1.6)],
        "spot": [
            Light(
                "spot",
                (0.2, -0.1, 1.5),
                direction=(-0.1, 0.1, -1.0),
                color=(0.6, 0.9, 1.0),
                intensity=3.0,
                radius=3.0,
                inner_angle_deg=12,
                outer_angle_deg=25,
            )
        ],
        "directional": [Light("directional", direction=(-0.3, -0.2, -1.0), intensity=0.7)],
    }[kind]
    size, w = 10.0, 48
    cam = Camera(position=(0, 0, 3), target=(0, 0, 0), fov_y=50, near=0.1, far=100)
    plane = Node(
        "plane",
        Transform(),
        unit_quad(size, size),
        MaterialInstance("pbr", {"albedo": [0.5, 0.75, 0.25], "roughness": 0.5, "metalness": 0.0}),
    )
    scene = Scene(camera=cam, background=(0, 0, 0), nodes=[plane], lights=lights)
    frame = renderer_factory(pipeline_from_text(LIT)).render(scene, w, w)
    # pixel centres -> points on the z = 0 plane (rows top to bottom like the image)
    t = math.tan(math.radians(25))
    px = (np.arange(w) + 0.5) / w * 2 - 1
    x, y = np.meshgrid(px * t, -px * t)
    dirs = np.stack([x, y, -np.ones_like(x)], -1).reshape(-1, 3)
    p = np.array(cam.position) + dirs * (cam.position[2] / -dirs[:, 2])[:, None]
    v = np.array(cam.position) - p
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    want = np.zeros_like(p)
    for light in lights:
        rad, l = _radiance(light, p)
        for i in range(len(p)):  # per pixel: the view direction varies
            want[i] += rad[i] * brdf_cos((0, 0, 1), v[i], l[i : i + 1], (0.5, 0.75, 0.25), 0.5, 0.0)[0]
    got = frame.linear.reshape(-1, 3).astype(np.float64)
    err = np.abs(got - want)
    print(f"{kind}: max error {err.max():.2e} of peak {want.max():.3f}")
    assert want.max() > 0.05 and (want == 0).any() == (kind == "spot" or kind == "point")
    assert err.max() <= 1e-4 + 1e-3 * want.max(), f"max error {err.max():.4g} of peak {want.max():.4g}"
