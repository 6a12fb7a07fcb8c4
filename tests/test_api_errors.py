"""The Python API refuses wrong arguments, released objects, wrong threads and unusable data with its own errors."""

from __future__ import annotations

import gc
import math
import threading

import moderngl
import numpy as np
import pytest
from conftest import quad_node, simple_scene, unit_quad

from guaca_py import Renderer
from guaca_py.errors import ConfigError, GuacaError
from guaca_py.host_state import count_gl_objects
from guaca_py.renderer import release_dropped
from guaca_py.scene.graph import Camera, Light, MaterialInstance, MeshData, Node, Scene, Transform

SIZE = 16


@pytest.fixture(autouse=True)
def _shared_context_current_after(gl_context):
    """Renderers of their own contexts make those current: later modules' fixtures expect the shared one."""
    yield
    gc.collect()
    release_dropped()
    gl_context.__enter__()


@pytest.fixture(scope="module")
def own(gl_context):
    """A renderer with a context of its own (the thread and release checks apply to it)."""
    r = Renderer("default")
    yield r
    r.release()
    gl_context.__enter__()


def scene() -> Scene:
    """One opaque quad in front of the default camera."""
    return simple_scene([quad_node("q", 0.0, (1.0, 0.5, 0.2), 1.0)])


# ------------------------------------------------------------------ renderer arguments and lifetime
def test_render_after_release_raises_guaca_error():
    r = Renderer("default")
    r.render(scene(), SIZE, SIZE)
    r.release()
    with pytest.raises(GuacaError, match="released; make a new Renderer"):
        r.render(scene(), SIZE, SIZE)
    r.release()  # a second release does nothing


@pytest.mark.parametrize(
    "value, match",
    [(None, "NoneType"), (np.zeros((4, 4, 3)), "ndarray"), ("scene.yaml", r"guaca_py\.load\(path\)")],
)
def test_render_refuses_what_is_not_a_scene(own, value, match):
    with pytest.raises(ConfigError, match=match) as info:
        own.render(value, SIZE, SIZE)
    assert isinstance(info.value, TypeError)  # still what Python's own argument checks raise


def test_released_or_foreign_context_is_refused():
    ctx = moderngl.create_context(standalone=True, backend="egl", require=450)
    ctx.release()
    with pytest.raises(ConfigError, match="'ctx': the moderngl context was released"):
        Renderer("default", ctx)
    with pytest.raises(ConfigError, match="'ctx': must be a moderngl.Context, got str"):
        Renderer("default", "ctx")


def test_render_after_the_host_released_its_context():
    ctx = moderngl.create_context(standalone=True, backend="egl", require=450)
    r = Renderer("default", ctx)
    ctx.release()
    with pytest.raises(GuacaError, match="context this Renderer draws in was released"):
        r.render(scene(), SIZE, SIZE)
    r.release()  # nothing left to free: no error


def test_numpy_integers_are_a_size(own):
    frame = own.render(scene(), np.int64(SIZE), np.uint16(SIZE // 2))
    assert frame.image.shape == (SIZE // 2, SIZE, 3)


def test_render_from_another_thread_names_the_contexts_thread(own):
    caught = []

    def worker():
        try:
            own.render(scene(), SIZE, SIZE)
        except Exception as exc:  # noqa: BLE001 - the test inspects what was raised
            caught.append(exc)

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert len(caught) == 1 and isinstance(caught[0], GuacaError)
    assert "GL calls belong to the context's thread" in str(caught[0])
    assert own.render(scene(), SIZE, SIZE).image.shape == (SIZE, SIZE, 3)  # its own thread still renders


# ------------------------------------------------------------------ camera
@pytest.mark.parametrize(
    "field, value, key",
    [
        ("fov_y", 0.0, "fov_y"),
        ("fov_y", -10.0, "fov_y"),
        ("fov_y", 180.0, "fov_y"),
        ("fov_y", math.nan, "fov_y"),
        ("near", math.nan, "near"),
        ("far", math.nan, "far"),
        ("near", 0.0, "near"),
        ("far", 0.05, "far"),  # below near (0.1)
        ("up", (0.0, 0.0, -1.0), "up"),  # parallel to the view direction, (0, 0, -1)
        ("up", (0.0, 0.0, 0.0), "up"),
        ("target", (0.0, 1.0, 5.0), "target"),  # the camera position
        ("position", (math.inf, 0.0, 0.0), "position"),
    ],
)
def test_camera_values_no_frame_can_use_are_refused(own, field, value, key):
    s = scene()
    s.camera = Camera(position=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0))
    if field == "target":
        value = s.camera.position
    setattr(s.camera, field, value)
    with pytest.raises(ConfigError, match=rf"'camera\.{key}'"):
        own.render(s, SIZE, SIZE)


def test_huge_up_vector_renders_like_a_unit_one(own):
    s = scene()
    s.camera = Camera(position=(0.0, 1.0, 5.0), target=(0.0, 0.0, 0.0), up=(1.0e300, 1.0e300, 0.0))
    big = own.render(s, SIZE, SIZE).image
    s.camera.up = (1.0, 1.0, 0.0)
    assert np.array_equal(big, own.render(s, SIZE, SIZE).image)


# ------------------------------------------------------------------ meshes
def quad(**change) -> MeshData:
    m = unit_quad()
    fields = dict(positions=m.positions, normals=m.normals, texcoords=m.texcoords, indices=m.indices, name="bad")
    fields.update(change)
    return MeshData(**fields)


@pytest.mark.parametrize(
    "change, match",
    [
        (dict(indices=np.array([[0, 1, 2_000_000_000]], dtype=np.uint32)), r"indices must lie in \[0, 4\)"),
        (dict(indices=np.array([[0, 1, -1]])), "indices must lie"),
        (dict(positions=np.zeros((4, 2), np.float32)), r"positions must have shape \(n, 3\)"),
        (dict(positions=np.full((4, 3), np.nan, np.float32)), "positions must be finite"),
        (dict(normals=np.zeros((3, 3), np.float32)), "normals has 3 rows for 4 positions"),
        (dict(texcoords=np.zeros((5, 2), np.float32)), "texcoords has 5 rows for 4 positions"),
        (dict(indices=np.zeros((1, 3), np.float32)), "indices must be integers"),
        (dict(indices=np.zeros(4, np.uint32)), r"indices must have shape \(n, 3\)"),
    ],
)
def test_meshdata_refuses_inconsistent_arrays_naming_the_mesh(change, match):
    with pytest.raises(ConfigError, match=match) as info:
        quad(**change)
    assert "mesh 'bad'" in str(info.value)


def test_meshdata_takes_a_flat_index_list():
    assert quad(indices=np.array([0, 1, 2, 0, 2, 3], dtype=np.uint32)).indices.shape == (6,)


CHANGED_MESHES = [
    ("positions", np.full((4, 3), np.nan, np.float32), "positions must be finite"),
    ("positions", np.zeros((4, 2), np.float32), r"positions must have shape \(n, 3\)"),
    ("positions", np.zeros((4, 3)).astype(str), "positions must hold real numbers, got <U"),
    ("normals", np.full((4, 3), 1e39), "normals hold values beyond float32's range"),
    ("indices", np.array([[0, 1, 2_000_000_000]], dtype=np.int64), r"indices must lie in \[0, 4\)"),
    ("indices", np.array([[0, 1, 2]], dtype=np.float32), "indices must be integers"),
    ("texcoords", None, r"texcoords must have shape \(n, 2\), got NoneType"),
]


@pytest.mark.parametrize("field, value, match", CHANGED_MESHES, ids=lambda v: str(v)[:24] if isinstance(v, str) else "")
def test_a_mesh_changed_after_it_was_drawn_is_checked_again(own, field, value, match):
    """Replacing an array of a drawn mesh: the next render raises ConfigError naming the mesh, never draws it."""
    mesh = quad()
    s = simple_scene([Node("q", Transform(), mesh, MaterialInstance("unlit"))])
    own.render(s, SIZE, SIZE)
    setattr(mesh, field, value)
    for _ in range(2):  # and again: the refusal is not memoised away
        with pytest.raises(ConfigError, match=match) as info:
            own.render(s, SIZE, SIZE)
        assert "mesh 'bad'" in str(info.value)


def test_a_mesh_is_checked_and_hashed_once_per_change(own, monkeypatch):
    """Frames that draw an unchanged mesh neither check nor hash it again; replacing an array does, once."""
    mesh = quad()
    s = simple_scene([Node("q", Transform(), mesh, MaterialInstance("unlit"))])
    own.render(s, SIZE, SIZE)
    checks = []
    monkeypatch.setattr(MeshData, "check", lambda self: checks.append(self.name))
    for _ in range(3):
        own.render(s, SIZE, SIZE)
    assert checks == []
    uploads = own.meshes.uploads
    mesh.positions = mesh.positions * 0.5
    for _ in range(3):
        own.render(s, SIZE, SIZE)
    assert checks == ["bad"] and own.meshes.uploads == uploads + 1


def test_a_flat_index_list_counts_its_triangles():
    assert quad(indices=np.array([0, 1, 2, 0, 2, 3], dtype=np.uint32)).triangle_count == 2


# ------------------------------------------------------------------ lights and background
@pytest.mark.parametrize(
    "fields, key",
    [
        (dict(intensity=math.nan), "intensity"),
        (dict(color=(1.0, math.nan, 1.0)), "color"),
        (dict(intensity=1.0e38), "intensity"),
        (dict(color=(1.0e38, 1.0, 1.0)), "intensity"),
        (dict(type="directional", direction=(0.0, 0.0, 0.0)), "direction"),
        (dict(type="spot", direction=(math.nan, -1.0, 0.0)), "direction"),
        (dict(type="laser"), "type"),
        (dict(intensity=-1.0), "intensity"),
        (dict(color=(1.0, -0.5, 0.0)), "color"),
        (dict(type="point", radius=0.0), "radius"),
        (dict(type="spot", radius=-1.0), "radius"),
        (dict(type="spot", inner_angle_deg=80.0, outer_angle_deg=10.0), "inner_angle_deg"),
        (dict(type="spot", inner_angle_deg=-1.0), "inner_angle_deg"),
        (dict(type="spot", outer_angle_deg=95.0), "outer_angle_deg"),
    ],
)
def test_light_refuses_unusable_values_at_construction(fields, key):
    with pytest.raises(ConfigError, match=rf"'light\.{key}'"):
        Light(**fields)


def test_unused_light_fields_are_not_held_to_ranges():
    """A directional light has no radius or cone: values there are not refused (they draw nothing)."""
    assert Light(type="directional", radius=-1.0, outer_angle_deg=120.0).radius == -1.0


@pytest.mark.parametrize("field, value", [("radius", 0.0), ("outer_angle_deg", 90.0), ("intensity", -2.0)])
def test_light_range_changed_after_construction_is_refused_at_render(own, field, value):
    s = scene()
    s.lights = [Light(type="spot", position=(0.0, 0.0, 3.0), direction=(0.0, 0.0, -1.0))]
    setattr(s.lights[0], field, value)
    with pytest.raises(ConfigError, match=rf"'lights\[0\]\.{field}'"):
        own.render(s, SIZE, SIZE)


def test_light_changed_after_construction_is_refused_at_render(own):
    s = scene()
    s.lights = [Light(type="directional")]
    s.lights[0].intensity = math.inf
    with pytest.raises(ConfigError, match=r"'lights\[0\]\.intensity'"):
        own.render(s, SIZE, SIZE)


def test_scene_check_names_the_scene_file(tmp_path):
    s = Scene(source=tmp_path / "lit.yaml", lights=[Light(type="point")])
    s.lights[0].color = (1.0e38, 1.0, 1.0)
    with pytest.raises(ConfigError, match=r"lit\.yaml: 'lights\[0\]\.intensity': color .* exceeds 1e\+06"):
        s.check()
    s.lights[0].color = (1.0, 1.0, 1.0)
    s.lights.append(Light(type="spot"))
    s.lights[1].direction = (0.0, 0.0, 0.0)
    with pytest.raises(ConfigError, match=r"'lights\[1\]\.direction'"):
        s.check()
    s.lights[1].direction = (0.0, -1.0, 0.0)
    s.check()


def test_huge_light_direction_is_normalised_without_overflow(own):
    s = scene()
    s.lights = [Light(type="directional", direction=(1.0e300, -1.0e300, 0.0))]
    big = own.render(s, SIZE, SIZE).image
    s.lights = [Light(type="directional", direction=(1.0, -1.0, 0.0))]
    assert np.array_equal(big, own.render(s, SIZE, SIZE).image)
    from guaca_py.passes.lights import light_table

    row = light_table([Light(type="directional", direction=(1.0e300, -1.0e300, 0.0))])[0]
    assert np.allclose(row[8:11], [math.sqrt(0.5), -math.sqrt(0.5), 0.0])


@pytest.mark.parametrize("background", [(1.0e20, 0.0, 0.0), (math.nan, 0.0, 0.0), (math.inf,) * 3, (1.0, 2.0)])
def test_background_must_be_finite_and_bounded(own, background):
    with pytest.raises(ConfigError, match="'background'"):
        Scene(background=background)
    s = scene()
    s.background = background
    with pytest.raises(ConfigError, match="'background'"):
        own.render(s, SIZE, SIZE)


# ------------------------------------------------------------------ lifetime of dropped renderers
def test_dropped_renderers_free_their_gpu_objects(gl_context):
    """Renderers on a shared context, dropped without release(), leave no GL objects behind once collected."""
    gl_context.__enter__()
    warm = Renderer("default", gl_context)
    warm.render(scene(), SIZE, SIZE)  # what a context keeps across renderers (a shared program) now exists
    warm.release()
    gc.collect()
    before = count_gl_objects()
    for _ in range(5):
        r = Renderer("default", gl_context)
        r.render(scene(), SIZE, SIZE)
        del r
        gc.collect()
    release_dropped()  # what the next Renderer would do first
    gl_context.__enter__()
    assert count_gl_objects() == before


def test_dropped_renderers_with_own_contexts_do_not_grow_memory():
    """20 renderers with contexts of their own, dropped without release(): resident memory stays flat."""

    def rss_mb() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * 4096 / 2**20

    def one():
        Renderer("default").render(scene(), SIZE, SIZE)

    for _ in range(3):  # warm-up: caches, the driver's compiled shaders
        one()
    gc.collect()
    start = rss_mb()
    for _ in range(20):
        one()
        gc.collect()
    assert rss_mb() - start < 40.0  # ~6.5 MB each (130 MB) when they leaked


# ------------------------------------------------------------------ wrong kinds of arguments and parts
def test_renderer_arguments_of_the_wrong_kind(own, tmp_path):
    with pytest.raises(ConfigError, match="'pipeline': must be a pipeline name"):
        Renderer(5)
    with pytest.raises(ConfigError, match="'method_overrides': must be a dict"):
        own.set_method("presort_lf_et", [1])
    with pytest.raises(ConfigError, match=r"missing: 'material_paths': material directory not found"):
        Renderer(material_paths=str(tmp_path / "missing"))  # one folder as a string, not a list of letters
    own.ctx.__enter__()  # moderngl creates objects in the current context: make it the renderer's
    target = own.ctx.texture((SIZE, SIZE), 4)
    for viewport in [(0, 0, -1, 5), "abcd", (0, 0, 4.5, 4)]:
        with pytest.raises(ConfigError, match="'viewport': must be"):
            own.render(scene(), SIZE, SIZE, target=target, viewport=viewport)
    frame = own.render(scene(), SIZE // 2, SIZE // 2, target=target, viewport=(0.0, 0, np.int32(SIZE // 2), SIZE / 2))
    assert frame.image.shape == (SIZE // 2, SIZE // 2, 3)  # whole numbers of any type are a viewport
    target.release()


@pytest.mark.parametrize(
    "make, key",
    [
        (lambda s: setattr(s, "camera", None), "'camera': must be a Camera"),
        (lambda s: setattr(s, "lights", Light()), "'lights': must be a list"),
        (lambda s: s.lights.append(None), r"'lights\[0\]': must be a Light"),
        (lambda s: s.nodes.append(None), r"'nodes\[1\]': must be a Node"),
        (lambda s: setattr(s.nodes[0], "transform", None), r"'nodes\[0\]\.transform': must be a Transform"),
        (lambda s: setattr(s.nodes[0], "material", "unlit"), r"'nodes\[0\]\.material': must be a MaterialInstance"),
        (lambda s: s.nodes[0].children.append("x"), r"'nodes\[0\]\.children\[0\]': must be a Node"),
        (lambda s: setattr(s.nodes[0].material, "description", 5), r"'nodes\[0\]\.material\.description': must be"),
        (lambda s: setattr(s.nodes[0].material, "uniforms", [1]), r"'nodes\[0\]\.material\.uniforms': must be a dict"),
        (lambda s: s.nodes[0].children.append(s.nodes[0]), r"'nodes\[0\]\.children\[0\]': is a node that contains it"),
    ],
)
def test_scene_parts_of_the_wrong_type_are_named(own, make, key):
    s = scene()
    make(s)
    with pytest.raises(ConfigError, match=key):
        own.render(s, SIZE, SIZE)


def test_transform_values_must_be_finite():
    with pytest.raises(ConfigError, match="'Transform.translation': must be 3 finite numbers") as info:
        Transform(translation=(math.nan, 0.0, 0.0))
    assert isinstance(info.value, ValueError)
    with pytest.raises(ConfigError, match="'Transform.scale'"):
        Transform(scale=(1.0, 1.0))
    assert Node(transform=Transform(translation=np.float32([1, 2, 3])), material=MaterialInstance()).mesh is None


@pytest.mark.parametrize(
    "field, value",
    [("translation", "abc"), ("rotation_deg", (1.0, "x", 0.0)), ("scale", (math.nan, 1.0, 1.0)), ("scale", 3)],
)
def test_transform_values_changed_after_construction_are_named_with_the_node(own, field, value):
    s = scene()
    setattr(s.nodes[0].transform, field, value)
    with pytest.raises(ConfigError, match=rf"'q\.transform\.{field}': must be 3 finite numbers"):
        own.render(s, SIZE, SIZE)


def test_meshes_without_triangles_draw_nothing(own):
    """An empty MeshData, or vertices without triangles, is drawn as nothing (it was an empty GPU buffer)."""
    empty = MeshData(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 3), np.uint32), "empty")
    points = MeshData(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 2)), np.zeros((0, 3), np.uint32), "points")
    reference = own.render(scene(), SIZE, SIZE).image
    s = scene()
    s.nodes += [Node("e", Transform(), empty, MaterialInstance("unlit")), Node("p", Transform(), points)]
    frame = own.render(s, SIZE, SIZE)
    assert np.array_equal(frame.image, reference) and frame.stats["draws"] == 1


@pytest.mark.parametrize("path", [123, None, b"/tmp/scene.yaml", ["a.yaml"]])
def test_load_names_an_argument_that_is_not_a_path(path):
    from guaca_py import load
    from guaca_py.errors import ArgumentError

    with pytest.raises(ArgumentError, match="'path': load takes a file path") as info:
        load(path)
    assert isinstance(info.value, TypeError)


@pytest.mark.parametrize(
    "pixels, match",
    [
        (np.zeros((2, 2, 2, 2)), r"must be \(H, W\[, 1-4\]\) pixels"),
        (np.zeros((1, 16385), np.uint8), "is 16385x1; the largest texture is 16384x16384"),
        (np.array([["a"]]), "must hold numbers"),
    ],
    ids=["4d", "too-wide", "text"],
)
def test_texture_image_refuses_what_is_no_image(pixels, match):
    from guaca_py.scene.texture import TextureImage

    with pytest.raises(ConfigError, match=match) as info:
        TextureImage(pixels, "img")
    assert isinstance(info.value, ValueError) and "'TextureImage 'img''" in str(info.value)


def test_an_image_wider_than_the_device_takes_is_refused_before_upload():
    """The driver would make an incomplete texture (llvmpipe: without an error) that samples as black."""
    from types import SimpleNamespace

    from guaca_py.errors import LimitError
    from guaca_py.gpu_resources import TextureCache
    from guaca_py.scene.texture import TextureImage

    small_device = SimpleNamespace(info={"GL_MAX_TEXTURE_SIZE": 8})  # no texture is made: the check comes first
    with pytest.raises(LimitError, match="is 16x4; the device's largest texture is 8x8"):
        TextureCache(small_device).get(TextureImage(np.zeros((4, 16, 4), np.uint8), "wide"))


def test_a_cycle_below_the_roots_is_named():
    a, b = Node("a"), Node("b")
    a.children.append(b)
    b.children.append(a)
    s = scene()
    s.nodes[0].children.append(a)
    with pytest.raises(ConfigError, match=r"'nodes\[0\]\.children\[0\]\.children\[0\]\.children\[0\]': is a node that"):
        s.check_structure()


def test_a_node_tree_too_deep_to_walk_is_refused_and_a_shared_node_drawn_twice(own):
    from guaca_py.scene.graph import MAX_TREE_DEPTH

    s = scene()
    s.nodes.append(s.nodes[0])  # the same node twice: two draws, no cycle
    assert own.render(s, SIZE, SIZE).stats["draws"] == 2
    node = s.nodes[0]
    for i in range(MAX_TREE_DEPTH):
        child = Node(f"n{i}")
        node.children.append(child)
        node = child
    with pytest.raises(
        ConfigError,
        match=rf"nodes\[0\]\.\(\.\.\.{MAX_TREE_DEPTH - 1} levels\.\.\.\)\.children\[0\]': nodes nested deeper than {MAX_TREE_DEPTH}",
    ):
        own.render(s, SIZE, SIZE)
