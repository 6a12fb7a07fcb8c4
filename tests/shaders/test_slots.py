"""The binding slot table (guaca_py/shaders/slots.py): templates and Python bind by its names, its
numbers never meet twice in one program, and docs/slots.md shows it."""

from __future__ import annotations

import re
import types
from itertools import combinations
from pathlib import Path

import moderngl
import pytest
from conftest import unit_quad

from guaca_py import antialiasing
from guaca_py.antialiasing import with_samples
from guaca_py.methods import method_ids
from guaca_py.pipeline.config import load_pipeline, pipeline_from_text
from guaca_py.resources import builtin_dir
from guaca_py.scene.graph import MaterialInstance, Node, Transform
from guaca_py.scene.loader import demo_scene
from guaca_py.shaders import ShaderLibrary, slots
from guaca_py.shaders.slots import KINDS, Texture

ROOT = Path(__file__).resolve().parents[2]
TEMPLATES = sorted(builtin_dir("shader_templates").rglob("*.j2"))
KIND = {k.__name__: k for k in KINDS}
NAME_USE = re.compile(r"\b(Buffer|Image|Texture)\.([A-Za-z_]\w*)")
# Python binding calls with a number where a slot name belongs
PY_LITERAL = re.compile(r"bind_to_storage_buffer\(\s*\d|bind_to_image\(\s*\d|\.use\(\s*location\s*=\s*\d|\.bind\(\s*\d")


# ----------------------------------------------------------------------------- the sources
def test_no_template_binds_by_number():
    bad = []
    for path in TEMPLATES:
        for i, line in enumerate(path.read_text().splitlines(), 1):
            # a literal, or an expression that does not start from a slot (`{{ loop.index0 }}`)
            if re.search(r"binding\s*=\s*(\d|\{\{(?!\s*(Buffer|Image|Texture)\.))", line):
                bad.append(f"{path.name}:{i}: {line.strip()}")
    assert not bad, "bind by a slot name of guaca_py/shaders/slots.py:\n" + "\n".join(bad)


def test_every_slot_name_in_a_template_is_in_the_table():
    used = {(m[1], m[2]) for path in TEMPLATES for m in NAME_USE.finditer(path.read_text())}
    assert len(used) > 40  # the templates do name their slots
    unknown = sorted(f"{k}.{n}" for k, n in used if n not in KIND[k].TABLE)
    assert not unknown, unknown


def test_python_binds_by_name():
    bad = []
    for path in sorted((ROOT / "guaca_py").rglob("*.py")):
        for i, line in enumerate(path.read_text().splitlines(), 1):
            if PY_LITERAL.search(line):
                bad.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not bad, "bind by a slot name of guaca_py/shaders/slots.py:\n" + "\n".join(bad)


def test_every_slot_is_used():
    text = "\n".join(p.read_text() for p in TEMPLATES) + "\n".join(
        p.read_text() for p in (ROOT / "guaca_py").rglob("*.py") if p.name != "slots.py"
    )
    used = {(m[1], m[2]) for m in NAME_USE.finditer(text)}
    unused = [f"{k.__name__}.{n}" for k in KINDS for n in k.TABLE if (k.__name__, n) not in used]
    assert not unused, unused


# ----------------------------------------------------------------------------- the table
def test_slots_are_ints_of_their_rows():
    for kind in KINDS:
        for name, row in kind.TABLE.items():
            assert getattr(kind, name) == row.number and type(getattr(kind, name)) is int
            assert row.kind == kind.__name__ and row.name == name and row.number >= 0 and row.count >= 1


def test_groups_that_meet_use_different_numbers():
    """Two slots of one kind may share a number only where the table says no program binds both."""
    for kind in KINDS:
        for name, group in kind.GROUPS.items():
            for other in group.meets:
                assert other in kind.GROUPS and name in kind.GROUPS[other].meets, (kind.__name__, name, other)
        assert {row.group for row in kind.TABLE.values()} <= set(kind.GROUPS)
        for a, b in combinations(kind.TABLE.values(), 2):
            if b.group in kind.GROUPS[a.group].meets:
                assert not set(a.numbers()) & set(b.numbers()), (
                    f"{a.kind}.{a.name} and {b.kind}.{b.name} meet in a program"
                )


def test_host_state_saves_every_slot():
    """An embedding host gets back every binding guaca may change (host_state.py)."""
    from guaca_py import host_state

    limits = {
        "Buffer": host_state._INDEXED_BUFFERS[0x90D2][-1],
        "Image": host_state._IMAGE_UNITS,
        "Texture": host_state._TEXTURE_UNITS,
    }
    for kind in KINDS:
        top = max(row.number + row.count for row in kind.TABLE.values())
        assert top <= limits[kind.__name__], kind.__name__


def test_docs_show_the_table():
    text = (ROOT / "docs" / "slots.md").read_text()
    assert slots.markdown_table() in text, (
        "docs/slots.md: paste the output of "
        "`python -c \"from guaca_py.shaders.slots import markdown_table; print(markdown_table(), end='')\"`"
    )


# ----------------------------------------------------------------------------- the programs
MARK = re.compile(r"(\d+) /\*@slot (\w+)\.(\w+)\+(\d+)\*/")
SAMPLER = re.compile(r"uniform\s+[iu]?sampler\w*\s+(\w+)\s*;")


class _Marked(int):
    """A slot number that renders with its name, so a program's source tells which slot each binding is."""

    def __new__(cls, row, offset: int = 0):
        obj = super().__new__(cls, row.number + offset)
        obj.row, obj.offset = row, offset
        return obj

    def __str__(self) -> str:
        return f"{int(self)} /*@slot {self.row.kind}.{self.row.name}+{self.offset}*/"

    def __add__(self, other):
        return _Marked(self.row, self.offset + int(other))

    __radd__ = __add__


def _marked_globals() -> dict:
    return {k.__name__: types.SimpleNamespace(**{n: _Marked(r) for n, r in k.TABLE.items()}) for k in KINDS}


def slot_clashes(source: str) -> list[str]:
    """Numbers of one kind that two different slots take in one program's source (marked globals)."""
    taken: dict[tuple[str, int], set[str]] = {}
    problems = []
    for number, kind, name, offset in MARK.findall(source):
        if int(offset) >= KIND[kind].TABLE[name].count:
            problems.append(f"{kind}.{name}+{offset} lies past the slot's {KIND[kind].TABLE[name].count} numbers")
        taken.setdefault((kind, int(number)), set()).add(name)
    problems += [f"{k} {n}: {sorted(names)}" for (k, n), names in sorted(taken.items()) if len(names) > 1]
    return problems


def test_clash_check_finds_a_clash():
    lib_globals = _marked_globals()
    ok = f"binding = {lib_globals['Buffer'].ABUFFER_LINKS} ... binding = {lib_globals['Buffer'].LIGHTS}"
    assert slot_clashes(ok) == []
    clash = f"binding = {lib_globals['Buffer'].ABUFFER_LINKS} ... binding = {lib_globals['Buffer'].KBUFFER_HEADS}"
    assert slot_clashes(clash) == ["Buffer 0: ['ABUFFER_LINKS', 'KBUFFER_HEADS']"]
    past = f"binding = {lib_globals['Image'].PEEL_STEP_SLOTS + 4}"
    assert "past" in slot_clashes(past)[0]


def _scene():
    """The demo scene's camera and lights over an opaque and a transparent textured quad (programs are
    compiled per material: two materials keep them few), with textures on material units."""
    scene = demo_scene()
    scene.nodes = [
        Node(name, Transform((0.0, 0.9, z)), unit_quad(size, size), MaterialInstance(material, values))
        for name, z, size, material, values in (
            ("opaque", -0.8, 2.0, "gltf_opaque", {}),
            ("transparent", -0.3, 1.5, "pbr_textured", {"alpha": 0.6}),
        )
    ]
    return scene


def _configs():
    """(label, pipeline, method, overrides): every method with light culling, tone mapping and FXAA;
    multisampling and the compute rasterizer (also multisampled) on two A-buffer methods each (their
    programs are alike across the family; all of them would triple the first run's compiling, about
    14 s on llvmpipe with an empty shader cache); the light grid built the other way; the debug views."""
    default, exact = load_pipeline("default"), load_pipeline("exact")
    text = Path(default.source).read_text()
    views = text.replace("  - fxaa: {}\n", "  - debug_light_count: {}\n  - debug_depth_complexity: {}\n")
    out = [(mid, default, mid, {}) for mid in method_ids()]
    out += [(f"{m} 4x", with_samples(exact, 4), m, {}) for m in ("presort_lf", "post_merge16")]
    out += [("presort_cs compute", exact, "presort_cs", {"raster": "compute"})]
    out += [("presort_lf_merge2_et compute 4x", with_samples(exact, 4), "presort_lf_merge2_et", {"raster": "compute"})]
    out.append(("debug views", pipeline_from_text(views, default.source), "presort_lf", {}))
    # composed over a host's framebuffer (render(..., over_target=True)): the host's depth in and out
    out += [("over target", default, "presort_lf_et", {}), ("over target 4x", with_samples(exact, 4), "presort_lf", {})]
    out.append(
        ("light grid fallback", pipeline_from_text(text.replace("mode: auto", "mode: fallback")), "presort_lf", {})
    )
    return out


@pytest.fixture(scope="module")
def programs(gl_context, renderer_factory):
    """(label, sources, program) of every program these renders compile, with slots marked by name."""
    compiled = []
    current = {"label": ""}  # the configuration being rendered
    mp = pytest.MonkeyPatch()
    program, compute_shader = moderngl.Context.program, moderngl.Context.compute_shader

    def record_program(self, *args, **kwargs):
        prog = program(self, *args, **kwargs)
        stages = {**dict(zip(("vertex_shader", "fragment_shader", "geometry_shader"), args)), **kwargs}
        compiled.append((current["label"], {k: v for k, v in stages.items() if isinstance(v, str)}, prog))
        return prog

    def record_compute(self, source, *args, **kwargs):
        prog = compute_shader(self, source, *args, **kwargs)
        compiled.append((current["label"], {"compute_shader": source}, prog))
        return prog

    mp.setattr(slots, "template_globals", _marked_globals)
    mp.setattr(antialiasing, "_positions", {})  # read once per context: earlier tests may have read them
    mp.setattr(moderngl.Context, "program", record_program)
    mp.setattr(moderngl.Context, "compute_shader", record_compute)
    try:
        scene = _scene()
        for current["label"], pipeline, method, overrides in _configs():
            r = renderer_factory(pipeline, method=method, method_overrides=overrides or None)
            if current["label"].startswith("over target"):
                target = gl_context.framebuffer([gl_context.texture((40, 30), 4)], gl_context.depth_texture((40, 30)))
                r.render(scene, 40, 30, target=target, over_target=True)
                for o in (*target.color_attachments, target.depth_attachment, target):
                    o.release()
                continue
            target = gl_context.texture((40, 30), 4)
            r.render(scene, 40, 30, target=target)  # drawn into a host texture: the present program too
            target.release()
        current["label"] = "brdf check"
        ShaderLibrary(gl_context).compute("shading/brdf_eval.comp.j2")
    finally:
        mp.undo()
    return compiled


def test_no_program_binds_two_slots_at_one_number(programs):
    seen = set()
    problems = []
    for label, sources, _ in programs:
        text = "\n".join(sources.values())
        seen |= {(k, n) for _, k, n, _ in MARK.findall(text)}
        problems += [f"{label}: {p}" for p in slot_clashes(text)]
    assert not problems, "\n".join(problems)
    named = {(m[1], m[2]) for p in TEMPLATES for m in NAME_USE.finditer(p.read_text())}
    # all were checked but peeling's ordered images, which need fragment shader interlock where
    # there is no framebuffer fetch (NVIDIA), and llvmpipe has framebuffer fetch
    assert named - seen <= {("Image", "PEEL_ORDERED_SLOTS")}, named - seen


def test_no_program_samples_two_textures_at_one_unit(programs):
    """Sampler uniforms set from Python (table names, material units) never share a unit in a program."""
    problems = []
    materials = set(Texture.TABLE["MATERIALS"].numbers())
    material_units = set()
    for label, sources, prog in programs:
        units: dict[int, list[str]] = {}
        for name in {m for src in sources.values() for m in SAMPLER.findall(src)}:
            try:
                units.setdefault(prog[name].value, []).append(name)
            except KeyError:  # declared but unused: the compiler dropped it
                continue
        problems += [f"{label}: unit {u}: {sorted(n)}" for u, n in sorted(units.items()) if len(n) > 1]
        material_units |= set(units) & materials
    assert not problems, "\n".join(problems)
    assert material_units == {8, 9, 10, 11}, material_units  # gltf_opaque's four maps, pbr_textured's three
