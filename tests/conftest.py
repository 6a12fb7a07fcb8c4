"""Shared fixtures: one headless GL context per session, small scenes built in code."""

from __future__ import annotations

import numpy as np
import pytest

from guaca_py.reference import origin_camera, quad_mesh, unlit
from guaca_py.scene.graph import Camera, MaterialInstance, MeshData, Node, Scene, Transform


def pytest_addoption(parser):
    """Options of tests/test_fuzz.py: how many examples each fuzzed format gets, and from which seed."""
    group = parser.getgroup("fuzz", "fuzzing the file formats (tests/test_fuzz.py)")
    group.addoption("--fuzz-examples", type=int, default=40, help="examples per fuzzed format (CI: 40)")
    group.addoption("--fuzz-seed", type=int, default=None, help="random seed (default: a fixed sequence)")
    group.addoption(
        "--fuzz-cases", type=int, default=150, help="mutated model files per seed (tests/scene/test_hostile_models.py)"
    )


@pytest.fixture(scope="session")
def gl_context():
    """One standalone EGL context shared by all tests (contexts are slow to create on llvmpipe)."""
    from guaca_py.context import create_context

    ctx, _ = create_context()
    return ctx


@pytest.fixture(autouse=True)
def _shared_context_current(request):
    """Make the shared context current before each test that uses it.

    Renderers make their own context current for each call and then restore whatever was
    current before; tests that read a renderer's buffers or textures directly rely on the
    shared context being current, which a test that created another context (a benchmark
    run, a host application) would otherwise change for every later test.
    """
    if "gl_context" in request.fixturenames or "renderer_factory" in request.fixturenames:
        request.getfixturevalue("gl_context").__enter__()  # moderngl: make current (no __exit__: keep it so)
    yield


@pytest.fixture(scope="session")
def renderer_factory(gl_context):
    """Build Renderers on the shared context."""
    from guaca_py import Renderer

    made = []

    def make(pipeline="exact", **kw):
        r = Renderer(pipeline, ctx=gl_context, **kw)
        made.append(r)
        return r

    yield make
    for r in made:
        r.release()


@pytest.fixture(scope="session")
def lit_demo_presort(renderer_factory):
    """The demo scene and its lit, tone-mapped presort_lf frame (96x72): what other methods must shade like."""
    from guaca_py.scene.loader import demo_scene

    return demo_scene(), renderer_factory("default", method="presort_lf").render(demo_scene(), 96, 72).image


def lit_demo_difference(renderer_factory, lit_demo_presort, method: str) -> int:
    """Largest channel difference (0-255) between `method`'s lit demo frame and presort_lf's."""
    scene, expected = lit_demo_presort
    frame = renderer_factory("default", method=method).render(scene, 96, 72)
    assert frame.stats["fragments"]["stored"] > 0
    return int(np.abs(frame.image.astype(int) - expected.astype(int)).max())


@pytest.fixture(scope="module")
def renderers(renderer_factory):
    """One exact-pipeline renderer per (method, settings) in a module: programs compile once."""
    made: dict = {}

    def get(method, **overrides):
        key = (method, tuple(sorted(overrides.items())))
        if key not in made:
            made[key] = renderer_factory("exact", method=method, method_overrides=overrides or None)
        return made[key]

    return get


def unit_quad(w: float = 2.0, h: float = 2.0) -> MeshData:
    """Quad in the XY plane facing +Z."""
    p = np.array([[-w / 2, -h / 2, 0], [w / 2, -h / 2, 0], [w / 2, h / 2, 0], [-w / 2, h / 2, 0]], np.float32)
    return MeshData(
        p,
        np.tile(np.float32([0, 0, 1]), (4, 1)),
        np.float32([[0, 0], [1, 0], [1, 1], [0, 1]]),
        np.uint32([[0, 1, 2], [0, 2, 3]]),
        "quad",
    )


def quad_node(name, z, color, alpha, size=2.0, xy=(0.0, 0.0), material="unlit", rot=(0.0, 0.0, 0.0)) -> Node:
    """An unlit quad at depth z."""
    return Node(
        name,
        Transform((xy[0], xy[1], z), rot),
        unit_quad(size, size),
        MaterialInstance(material, {"color": list(color), "alpha": alpha}),
    )


def simple_scene(nodes, background=(0.1, 0.1, 0.1)) -> Scene:
    """Camera at z=5 looking at the origin."""
    return Scene(
        camera=Camera(position=(0, 0, 5), target=(0, 0, 0), fov_y=50, near=0.1, far=100),
        background=background,
        nodes=list(nodes),
    )


def random_quads(seed: int, n: int = 10) -> Scene:
    """Randomly placed, rotated (so interpenetrating) transparent quads and one opaque quad."""
    rng = np.random.default_rng(seed)
    nodes = [
        Node(
            f"q{i}",
            Transform(tuple(rng.uniform(-1, 1, 3) * [1.2, 1.2, 1.0]), tuple(rng.uniform(-60, 60, 3))),
            quad_mesh(*rng.uniform(0.5, 1.3, 2)),
            unlit(tuple(rng.uniform(0.1, 1, 3)), float(rng.uniform(0.3, 0.8))),
        )
        for i in range(n)
    ]
    nodes.append(Node("opaque", Transform((0.3, -0.2, -1.5), (10, 20, 5)), quad_mesh(0.9, 0.7), unlit((0.9, 0.9, 0.8))))
    return Scene(camera=origin_camera(), background=(0.05, 0.08, 0.12), nodes=nodes)
