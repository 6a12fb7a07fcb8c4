"""Fuzzing every file format guaca_py reads: the README's promises on inputs nobody listed.

Hypothesis mutates the project's own valid files (pipelines/*.yaml, materials/*.json, the demo
scene, a small generated glTF and its GLB form): byte flips, deleted and duplicated keys and
lines, swapped types, huge, NaN and infinite numbers, deep nesting, aliases, paths to FIFOs and
devices. Each case runs the loader and, when the input loads, a 16x16 render, and must end in
success or in one of the library's own errors (GuacaError): no other exception, no hang (a
per-case time bound), no changed input file.

In CI each target runs a fixed number of examples from a fixed seed (the whole file in well
under two minutes). Longer on demand, with pytest options registered in tests/conftest.py::

    python -m pytest tests/test_fuzz.py --fuzz-examples=2000            # examples per target
    python -m pytest tests/test_fuzz.py --fuzz-examples=500 --fuzz-seed=7  # another sequence

A failure prints the shrunk input (`data.draw` lines) that reproduces it.
"""

from __future__ import annotations

import base64
import contextlib
import copy
import hashlib
import io
import json
import math
import os
import signal
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, Phase, given, seed, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from guaca_py import GuacaError, Renderer  # noqa: E402
from guaca_py.materials import load_material  # noqa: E402
from guaca_py.pipeline.config import load_pipeline  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PIPELINES = sorted((ROOT / "pipelines").glob("*.yaml"))
MATERIALS = sorted((ROOT / "materials").glob("*.json"))
GLSL = sorted((ROOT / "materials").glob("*.glsl"))
DEMO = ROOT / "guaca_py" / "data" / "demo_scene.yaml"
SEEDS = [*PIPELINES, *MATERIALS, *GLSL, DEMO]
CASE_SECONDS = 30  # one load and render; far beyond any honest case, short of a hang
SIZE = 16


class Hang(Exception):
    """A case ran past CASE_SECONDS (not a GuacaError: the test fails)."""


@contextlib.contextmanager
def time_bound(seconds: float):
    """Raise Hang in this thread when the block runs longer than `seconds` (blocking system calls included)."""

    def expire(signum, frame):
        raise Hang(f"no result after {seconds} s")

    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def digest(paths) -> dict[Path, str]:
    """SHA-256 of each file (its content only)."""
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in paths}


def promise(call, inputs):
    """`call()`'s result, or None for a GuacaError; no other exception, no hang, the input files unchanged.

    numpy's overflow and invalid-value warnings count as failures: a number that overflowed on its way
    to the GPU is a silently wrong image.
    """
    before = digest(inputs)
    try:
        with time_bound(CASE_SECONDS), warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            return call()
    except GuacaError:
        return None
    finally:
        assert digest(inputs) == before, "an input file changed"


# ---------------------------------------------------------------------------- mutations
DEEP_LIST: list = []
for _ in range(150):  # deeper ones come as text ("nest"): dumping and copying this one recurses per level
    DEEP_LIST = [DEEP_LIST]
NASTY = [
    0, -1, 1.5, 1e20, -1e20, 1e300, math.inf, -math.inf, math.nan, -0.0, 2**31, 2**63, 10**30, 1e-320,
    "", "abc", "1e30", "auto", "off", "pbr", True, None, [], {}, [1, 2], [0, 0, 0], [1e38, 1e38, 1e38],
    [1e300, -1e300, 0], [math.nan, 1, 1], [[1]], {"a": 1}, "a\0b", "../../x.obj", "/dev/null",
    "x" * 10_000, [1] * 1000, DEEP_LIST, "pipe.obj", "pipe.png", "pipe.glsl", "pipe.gltf", "pipe.bin", "pipe.json",
]  # fmt: skip
FIFO_NAMES = ("pipe.obj", "pipe.png", "pipe.glsl", "pipe.gltf", "pipe.bin", "pipe.json")  # in every case's folder


def paths_in(tree, prefix: tuple = ()) -> list[tuple]:
    """Key paths of every value in a parsed document (the root first), at most a few thousand."""
    out = [prefix]
    if len(prefix) < 12:
        items = tree.items() if isinstance(tree, dict) else enumerate(tree) if isinstance(tree, list) else ()
        for k, v in items:
            out += paths_in(v, prefix + (k,))
            if len(out) > 4000:
                break
    return out


def at(tree, path: tuple):
    for k in path:
        tree = tree[k]
    return tree


def mutate_tree(data, tree):
    """One structural mutation of a parsed YAML/JSON document, drawn by Hypothesis."""
    paths = paths_in(tree)
    path = data.draw(st.sampled_from(paths), label="path")
    op = data.draw(st.sampled_from(["replace", "delete", "wrap", "share", "swap", "rename"]), label="op")
    if not path:
        return copy.deepcopy(data.draw(st.sampled_from(NASTY), label="root"))  # NASTY itself stays as it is
    parent, key = at(tree, path[:-1]), path[-1]
    value = parent[key]
    if op == "replace":
        parent[key] = copy.deepcopy(data.draw(st.sampled_from(NASTY), label="value"))
    elif op == "delete":
        del parent[key]
    elif op == "wrap":
        parent[key] = data.draw(st.sampled_from([[value], {"x": value}, [value, value]]), label="wrap")
    elif op == "share":  # the same object twice: yaml.safe_dump writes an anchor and an alias
        other = data.draw(st.sampled_from(paths), label="to")
        if other and other[: len(path)] != path:  # not into its own subtree (JSON has no cycles)
            with contextlib.suppress(KeyError, IndexError, TypeError):
                at(tree, other[:-1])[other[-1]] = value
    elif op == "swap":  # the same value as another type
        swapped = {int: str, float: str, str: float, list: dict, dict: list, bool: int, type(None): str}
        to = swapped.get(type(value), str)
        with contextlib.suppress(ValueError, TypeError, OverflowError):
            parent[key] = dict(enumerate(value)) if to is dict else list(value.values()) if to is list else to(value)
    elif op == "rename" and isinstance(parent, dict):
        parent[data.draw(st.sampled_from(["x", "name", "type", "file", "children", "uniforms", "<<"]))] = value
    return tree


def mutate_text(data, text: str) -> str:
    """One textual mutation: flipped or deleted characters, a duplicated line, deep nesting, an alias bomb."""
    op = data.draw(st.sampled_from(["flip", "cut", "dup_line", "nest", "bomb", "tab"]), label="text_op")
    n = len(text)
    i = data.draw(st.integers(0, max(n - 1, 0)), label="at")
    if op == "flip":
        return text[:i] + chr(data.draw(st.integers(1, 255), label="char")) + text[i + 1 :]
    if op == "cut":
        return text[:i] + text[i + data.draw(st.integers(1, 40), label="len") :]
    if op == "dup_line":
        lines = text.splitlines(keepends=True) or [""]
        j = data.draw(st.integers(0, len(lines) - 1), label="line")
        return "".join(lines[: j + 1] + lines[j:])
    if op == "nest":
        depth = data.draw(st.sampled_from([70, 300, 3000]), label="depth")
        return text[:i] + "[" * depth + "]" * depth + text[i:]
    if op == "bomb":
        levels = "".join(f"b{k}: &b{k} [{', '.join([f'*b{k - 1}'] * 9)}]\n" for k in range(1, 9))
        return "b0: &b0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + levels + text
    return text.replace("  ", "\t", 1)


def mutated_yaml(data, text: str) -> str:
    """A YAML document mutated in its structure (then dumped again) and/or its text."""
    if data.draw(st.booleans(), label="structural"):
        tree = yaml.safe_load(text)
        for _ in range(data.draw(st.integers(1, 3), label="n")):
            tree = mutate_tree(data, tree)
        text = yaml.safe_dump(tree, sort_keys=False)
    if data.draw(st.booleans(), label="textual"):
        text = mutate_text(data, text)
    return text


def mutated_json(data, text: str) -> str:
    """A JSON document mutated in its structure and/or its text."""
    if data.draw(st.booleans(), label="structural"):
        tree = json.loads(text)
        for _ in range(data.draw(st.integers(1, 3), label="n")):
            tree = mutate_tree(data, tree)
        text = json.dumps(tree, indent=2)
    if data.draw(st.booleans(), label="textual"):
        text = mutate_text(data, text)
    return text


# ---------------------------------------------------------------------------- a small glTF of every part
def _png() -> str:
    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(np.uint8([[[255, 0, 0, 255], [0, 255, 0, 128]], [[0, 0, 255, 255], [255, 255, 255, 0]]])).save(
        out, "PNG"
    )
    return base64.b64encode(out.getvalue()).decode()


def gltf_document() -> tuple[dict, bytes]:
    """A glTF (dict) with a textured, blended triangle under a transformed parent, a camera; and its buffer."""
    pos = np.float32([[-1, -1, 0], [1, -1, 0], [0, 1, 0]])
    nrm = np.float32([[0, 0, 1]] * 3)
    uv = np.float32([[0, 0], [1, 0], [0.5, 1]])
    idx = np.uint16([0, 1, 2, 0])  # padded to 4 bytes
    parts = [pos.tobytes(), nrm.tobytes(), uv.tobytes(), idx.tobytes()]
    views, offset = [], 0
    for p in parts:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(p)})
        offset += len(p)
    views[3]["byteLength"] = 6
    blob = b"".join(parts)
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 2]}],
        "nodes": [
            {"name": "root", "children": [1], "translation": [0, 0, -1], "rotation": [0, 0, 0, 1], "scale": [1, 1, 1]},
            {"name": "tri", "mesh": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]},
            {"name": "cam", "camera": 0, "translation": [0, 0, 3]},
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 100, "aspectRatio": 1}}],
        "meshes": [
            {
                "primitives": [
                    {
                        "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                        "indices": 3,
                        "material": 0,
                        "mode": 4,
                    }
                ]
            }
        ],
        "materials": [
            {
                "name": "glass",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [1, 0.5, 0.2, 0.6],
                    "metallicFactor": 0.1,
                    "roughnessFactor": 0.5,
                    "baseColorTexture": {"index": 0},
                },
                "alphaMode": "BLEND",
                "doubleSided": True,
            }
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{}],
        "images": [{"uri": "data:image/png;base64," + _png()}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 3, "type": "SCALAR"},
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    return doc, blob


def glb(doc: dict, blob: bytes) -> bytes:
    """The binary glTF of `doc` with `blob` as its BIN chunk."""
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    blob += b"\0" * (-len(blob) % 4)
    chunks = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(blob), b"BIN\0") + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


SCENE_WITH = "camera: {{position: [0, 0, 3], target: [0, 0, 0]}}\nnodes:\n  - {{mesh: {{file: {name}}}}}\n"


# ---------------------------------------------------------------------------- the run
@pytest.fixture(scope="module")
def fuzz(request, gl_context, tmp_path_factory):
    """Per-run settings, a folder for the cases, and the promise that the project's own files stay as they were."""
    before = digest(SEEDS)
    examples = request.config.getoption("--fuzz-examples")
    chosen = request.config.getoption("--fuzz-seed")
    root = tmp_path_factory.mktemp("fuzz")
    from hypothesis.configuration import set_hypothesis_home_dir

    set_hypothesis_home_dir(root / ".hypothesis")  # its caches go with the cases, not into the tree
    for name in FIFO_NAMES:  # paths a mutation may name: opening them must not block
        os.mkfifo(root / name)
    cases = iter(range(10**9))
    renderer = Renderer("default", ctx=gl_context)

    def run(body, share: int = 1):
        """Run `body(data, folder)` as a Hypothesis test over its share of the examples."""

        def case(data):
            folder = root / f"case{next(cases)}"
            folder.mkdir()
            for name in FIFO_NAMES:
                os.symlink(root / name, folder / name)
            body(data, folder)

        test = given(st.data())(case)
        test = settings(
            max_examples=max(1, examples * share),
            deadline=None,
            database=None,  # nothing written into the tree
            derandomize=chosen is None,
            phases=[Phase.generate, Phase.shrink],
            suppress_health_check=list(HealthCheck),
        )(test)
        if chosen is not None:
            test = seed(chosen)(test)
        test()

    run.ctx, run.renderer = gl_context, renderer
    yield run
    renderer.release()
    assert digest(SEEDS) == before, "a project file changed while fuzzing"


def render(renderer, scene) -> None:
    """A tiny frame of `scene`; its image must be what was asked for."""
    frame = renderer.render(scene, SIZE, SIZE)
    assert frame.image.shape[:2] == (SIZE, SIZE)


def test_fuzz_scene_yaml(fuzz):
    def body(data, folder: Path):
        text = mutated_yaml(data, DEMO.read_text())
        scene_file = folder / "scene.yaml"
        scene_file.write_text(text)
        scene = promise(lambda: load_scene(scene_file), [scene_file])
        if scene is not None:
            promise(lambda: render(fuzz.renderer, scene), [scene_file])

    fuzz(body, share=2)


def test_fuzz_pipeline_yaml(fuzz):
    def body(data, folder: Path):
        seed_file = data.draw(st.sampled_from(PIPELINES), label="pipeline")
        p = folder / seed_file.name
        p.write_text(mutated_yaml(data, seed_file.read_text()))
        config = promise(lambda: load_pipeline(p), [p])
        if config is None:
            return

        def draw():
            r = Renderer(config, ctx=fuzz.ctx)
            try:
                from guaca_py.scene.loader import demo_scene

                render(r, demo_scene())
            finally:
                r.release()

        promise(draw, [p])

    fuzz(body)


def test_fuzz_material_json(fuzz):
    from conftest import quad_node, simple_scene

    def body(data, folder: Path):
        seed_file = data.draw(st.sampled_from(MATERIALS), label="material")
        for glsl in GLSL:
            (folder / glsl.name).write_bytes(glsl.read_bytes())
        p = folder / seed_file.name
        text = seed_file.read_text()
        if data.draw(st.booleans(), label="mutate_glsl") and "file" in text:
            g = folder / data.draw(st.sampled_from([g.name for g in GLSL]), label="glsl")
            g.write_text(mutate_text(data, g.read_text()))
        p.write_text(mutated_json(data, text))
        inputs = [p, *(folder / g.name for g in GLSL)]
        mat = promise(lambda: load_material(p), inputs)
        if mat is None:
            return
        node = quad_node("q", 0, (1, 0, 0), 0.5, material=mat.name)
        node.material.uniforms = {}

        def draw():
            r = Renderer("exact", ctx=fuzz.ctx, material_paths=[folder])
            try:
                render(r, simple_scene([node]))
            finally:
                r.release()

        promise(draw, inputs)

    fuzz(body)


def test_fuzz_gltf(fuzz):
    doc, blob = gltf_document()

    def body(data, folder: Path):
        if data.draw(st.booleans(), label="binary"):
            raw = bytearray(glb(doc, blob))
            if data.draw(st.booleans(), label="structural"):
                raw = bytearray(glb(mutate_tree(data, copy.deepcopy(doc)), blob))
            for _ in range(data.draw(st.integers(0, 4), label="flips")):
                i = data.draw(st.integers(0, len(raw) - 1), label="byte")
                raw[i] = data.draw(st.integers(0, 255), label="to")
            model = folder / "m.glb"
            model.write_bytes(bytes(raw))
        else:
            d = copy.deepcopy(doc)
            d["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
            model = folder / "m.gltf"
            model.write_text(mutated_json(data, json.dumps(d, indent=2)))
        scene_file = folder / "scene.yaml"
        scene_file.write_text(SCENE_WITH.format(name=model.name))
        scene = promise(lambda: load_scene(scene_file), [scene_file, model])
        if scene is not None:
            promise(lambda: render(fuzz.renderer, scene), [scene_file, model])

    fuzz(body)


def test_fuzz_seeds_are_valid(fuzz, tmp_path):
    """Unmutated, every seed loads and renders: the mutations start from valid files."""
    from guaca_py.scene.loader import demo_scene

    for p in PIPELINES:
        assert load_pipeline(p).passes
    for p in MATERIALS:
        assert load_material(p).name
    render(fuzz.renderer, demo_scene())
    doc, blob = gltf_document()
    (tmp_path / "m.glb").write_bytes(glb(doc, blob))
    (tmp_path / "scene.yaml").write_text(SCENE_WITH.format(name="m.glb"))
    scene = load_scene(tmp_path / "scene.yaml")
    assert scene.nodes[0].children
    render(fuzz.renderer, scene)
