"""Composition with the host's frame: render(..., target=fbo, over_target=True) over the host's colour and depth."""

from __future__ import annotations

import moderngl
import numpy as np
import pytest
from conftest import quad_node, simple_scene

from guaca_py import Renderer
from guaca_py.antialiasing import with_samples, with_settings
from guaca_py.errors import GuacaError
from guaca_py.gl_state import raw_gl
from guaca_py.host_state import HostGLState
from guaca_py.pipeline.config import load_pipeline
from guaca_py.reference.cpu import edge_mask, reference_of, scene_triangles

W, H = 96, 72
HOST_CLEAR = (0.3, 0.5, 0.7)  # the host's background colour
WALL = (0.8, 0.45, 0.2)  # the host's opaque wall: the left half of the view, at z = WALL_Z
WALL_Z = 0.0

HOST_VS = """#version 450 core
in vec3 in_pos;
uniform mat4 mvp;
void main() { gl_Position = mvp * vec4(in_pos, 1.0); }
"""
HOST_FS = """#version 450 core
uniform vec3 color;
out vec4 frag;
void main() { frag = vec4(color, 1.0); }
"""


@pytest.fixture(scope="module")
def host_ctx():
    ctx = moderngl.create_context(standalone=True, backend="egl", require=450)
    yield ctx
    ctx.release()


def _scene(opaque_behind=True, opaque_front=True):
    """Transparent unlit quads in front of the wall (z=1) and behind it (z=-1), across both halves of the view;
    an opaque quad behind the wall (hidden where the wall is) and one in front of it (written back to the host's depth)."""
    nodes = [
        quad_node("front", 1.0, (0.2, 0.3, 0.9), 0.5, size=1.7, xy=(-0.31, 0.13)),
        quad_node("behind", -1.0, (0.9, 0.9, 0.1), 0.6, size=3.1, xy=(0.23, -0.37)),
        quad_node("behind2", -1.5, (0.1, 0.8, 0.3), 0.4, size=2.3, xy=(-0.53, 0.41)),
    ]
    if opaque_behind:
        nodes.append(quad_node("opaque_behind", -2.0, (0.95, 0.1, 0.6), 1.0, size=2.9, xy=(-0.17, -0.29)))
    if opaque_front:
        nodes.append(quad_node("opaque_front", 0.5, (0.6, 0.6, 0.6), 1.0, size=0.9, xy=(0.15, 0.51)))
    return simple_scene(nodes, background=(0.0, 1.0, 0.0))  # never drawn over the host


def _wall_node():
    """The host's wall as a node of the reference scene: opaque, its colour, x <= 0 at z = WALL_Z."""
    return quad_node("wall", WALL_Z, WALL, 1.0, size=40.0, xy=(-20.0, 0.0))


class HostFrame:
    """The host's framebuffer (RGBA8 colour and a depth texture or renderbuffer) with its opaque layer drawn."""

    def __init__(self, ctx, depth="texture", size=(W, H), viewport=None, dtype="f1"):
        self.ctx = ctx
        make_depth = ctx.depth_texture if depth == "texture" else ctx.depth_renderbuffer
        with ctx:
            self.fbo = ctx.framebuffer([ctx.texture(size, 4, dtype=dtype)], make_depth(size))
            self.prog = ctx.program(vertex_shader=HOST_VS, fragment_shader=HOST_FS)
        self.viewport = viewport or (0, 0, *size)

    def draw(self, scene, wall=True, clear=HOST_CLEAR):
        """Clear to the host's colour, draw the wall with the scene camera's matrices (depth test on)."""
        ctx = self.ctx
        with ctx:
            self.fbo.use()
            self.fbo.clear(*clear, 1.0, depth=1.0)
            if not wall:
                return
            view, proj = Renderer.camera_matrices(scene, *self.viewport[2:])
            quad = np.float32([[-50, -50, WALL_Z], [0, -50, WALL_Z], [0, 50, WALL_Z], [-50, 50, WALL_Z]])
            vbo = ctx.buffer(quad.tobytes())
            ibo = ctx.buffer(np.int32([0, 1, 2, 0, 2, 3]).tobytes())
            vao = ctx.vertex_array(self.prog, [(vbo, "3f", "in_pos")], ibo)
            self.prog["mvp"].write((proj @ view).T.astype("f4").tobytes())
            self.prog["color"] = WALL
            ctx.viewport = self.viewport
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.depth_func = "<"
            vao.render(moderngl.TRIANGLES)
            ctx.disable(moderngl.DEPTH_TEST)
            for o in (vao, vbo, ibo):
                o.release()

    def colour(self) -> np.ndarray:
        """(h, w, 3) uint8, row 0 at the top."""
        with self.ctx:
            w, h = self.fbo.size
            return np.frombuffer(self.fbo.read(components=3), np.uint8).reshape(h, w, 3)[::-1].copy()

    def depth(self) -> np.ndarray:
        """(h, w) float32 depth, row 0 at the top."""
        with self.ctx:
            w, h = self.fbo.size
            return (
                np.frombuffer(self.fbo.read(components=1, attachment=-1, dtype="f4"), np.float32)
                .reshape(h, w)[::-1]
                .copy()
            )

    def release(self):
        """Free the host's objects."""
        with self.ctx:
            for a in (*self.fbo.color_attachments, self.fbo.depth_attachment, self.fbo, self.prog):
                a.release()


def _window_depth(scene, z_world: float) -> float:
    """Depth-buffer value of a plane facing the camera at world z (camera on +Z looking at the origin)."""
    view, proj = Renderer.camera_matrices(scene, W, H)
    clip = proj @ view @ np.array([0.0, 0.0, z_world, 1.0])
    return 0.5 * clip[2] / clip[3] + 0.5


def _expected_depth(scene) -> np.ndarray:
    """The host's wall and guaca's opaque quads, nearest first; 1 where nothing opaque is."""
    ref = simple_scene([_wall_node()] + [n for n in scene.nodes if n.material.uniforms["alpha"] == 1.0])
    out = np.ones((H, W))
    for node in sorted(ref.nodes, key=lambda n: -n.transform.translation[2]):  # nearest last wins
        alone = simple_scene([node])
        _, _, layers = reference_of(alone, W, H)
        out = np.where(layers > 0, np.minimum(out, _window_depth(scene, node.transform.translation[2])), out)
    return out


def _reference(scene):
    """Exact float64 composite of the scene over the host: the wall as an opaque quad, the host's colour as background."""
    ref = simple_scene([_wall_node(), *scene.nodes], background=HOST_CLEAR)
    img, _, _ = reference_of(ref, W, H)
    return img


@pytest.mark.parametrize("depth", ["texture", "renderbuffer"])
def test_exact_composite_over_the_host_colour_and_depth(host_ctx, depth):
    scene = _scene()
    host = HostFrame(host_ctx, depth)
    host.draw(scene)
    r = Renderer("exact", ctx=host_ctx)
    res = r.render(scene, W, H, target=host.fbo, over_target=True)
    got = host.colour().astype(np.float64)
    expected = _reference(scene) * 255.0
    err = np.abs(got - expected).max(axis=2)
    assert err.max() <= 3.0, (err.max(), np.unravel_index(err.argmax(), err.shape))
    # the opaque quad behind the wall is hidden where the wall is: the wall's colour under the front quad there
    left, right = (H // 2, W // 2 - 12), (H // 2 + 12, W // 2 + 16)
    assert np.abs(got[left] - expected[left]).max() <= 3.0 and expected[left][1] < 200
    magenta = np.array([0.95, 0.1, 0.6]) * 255
    assert np.abs(got[right] - magenta).max() > 30  # covered by the transparent quads in front of it
    # the host's depth afterwards: the wall and guaca's opaque surfaces, nearest first
    np.testing.assert_allclose(host.depth(), _expected_depth(scene), atol=2e-6)
    # the frame's image is the composed picture, read from the target
    np.testing.assert_array_equal(res.image, host.colour())
    assert res.linear is None and res.stats["method"] == "presort_lf_et"
    # the next frame without the host's layer leaves nothing of it behind (G-buffer depth and marks)
    alone = simple_scene(scene.nodes, background=HOST_CLEAR)
    fresh = Renderer("exact", ctx=host_ctx)
    np.testing.assert_array_equal(r.render(alone, W, H).image, fresh.render(alone, W, H).image)
    fresh.release()
    r.release()
    host.release()


def test_a_float_target_holds_the_exact_composite_in_float(host_ctx):
    """With the exact pipeline and an RGBA32F target the composite over the host is exact to float precision."""
    scene = _scene()
    host = HostFrame(host_ctx, "renderbuffer", dtype="f4")
    host.draw(scene)
    r = Renderer("exact", ctx=host_ctx)
    res = r.render(scene, W, H, target=host.fbo, over_target=True)
    assert res.linear is not None
    np.testing.assert_allclose(res.linear, _reference(scene), atol=2e-3)
    r.release()
    host.release()


def test_host_pixels_with_nothing_in_front_keep_their_colour_in_the_default_pipeline(host_ctx):
    scene = _scene()
    host = HostFrame(host_ctx, "texture")
    host.draw(scene)
    before = host.colour()
    r = Renderer("default", ctx=host_ctx)
    r.render(scene, W, H, target=host.fbo, over_target=True, read_back=False)
    after = host.colour()
    # pixels no guaca surface reaches (two pixels from any edge: FXAA reads the diagonal neighbours)
    tris, _, _ = scene_triangles(scene)
    _, _, layers = reference_of(scene, W, H)
    free = (layers == 0) & ~edge_mask(tris, scene.camera, W, H, radius=2.5)
    assert free.sum() > W * H // 6
    np.testing.assert_array_equal(after[free], before[free])
    covered = (layers > 0) & ~edge_mask(tris, scene.camera, W, H, radius=2.5)
    assert np.abs(after[covered].astype(int) - before[covered]).max() > 40  # guaca's layer is there
    r.release()
    host.release()


def test_multisampled_frame_over_the_host(host_ctx):
    """antialiasing.samples > 1: the host's depth enters every sample; guaca's depth goes back once per pixel."""
    scene = _scene()
    host = HostFrame(host_ctx, "renderbuffer")
    host.draw(scene)
    r = Renderer(with_samples(load_pipeline("exact"), 4, "test"), ctx=host_ctx)
    r.render(scene, W, H, target=host.fbo, over_target=True)
    ref = simple_scene([_wall_node(), *scene.nodes], background=HOST_CLEAR)
    tris, _, _ = scene_triangles(ref)
    inner = ~edge_mask(tris, ref.camera, W, H, radius=1.0)
    err = np.abs(host.colour().astype(np.float64) - _reference(scene) * 255.0).max(axis=2)
    assert err[inner].max() <= 3.0
    depth_err = np.abs(host.depth() - _expected_depth(scene))
    assert depth_err[inner].max() <= 2e-6
    r.release()
    host.release()


@pytest.mark.parametrize("samples", [1, 4])
def test_supersampled_frame_over_the_host(host_ctx, samples):
    """antialiasing.supersample: the host's depth enters every rendered pixel of its output pixel; the nearest of
    them (and of their samples) goes back; the composed colour is exact off the edges."""
    scene = _scene()
    host = HostFrame(host_ctx, "texture")
    host.draw(scene)
    r = Renderer(with_settings(load_pipeline("exact"), {"samples": samples, "supersample": 2}, "test"), ctx=host_ctx)
    res = r.render(scene, W, H, target=host.fbo, over_target=True)
    assert res.stats["render_resolution"] == [2 * W, 2 * H] and res.image.shape == (H, W, 3)
    ref = simple_scene([_wall_node(), *scene.nodes], background=HOST_CLEAR)
    tris, _, _ = scene_triangles(ref)
    inner = ~edge_mask(tris, ref.camera, W, H, radius=1.0)
    err = np.abs(host.colour().astype(np.float64) - _reference(scene) * 255.0).max(axis=2)
    assert err[inner].max() <= 3.0
    assert np.abs(host.depth() - _expected_depth(scene))[inner].max() <= 2e-6
    r.release()
    host.release()


def test_over_a_viewport_of_the_target_and_host_state_restored(host_ctx):
    """A frame composed into the right half of a wider target: the left half is the host's, untouched."""
    scene = _scene()
    host = HostFrame(host_ctx, "texture", size=(2 * W, H), viewport=(W, 0, W, H))
    host.draw(scene)
    before_colour, before_depth = host.colour(), host.depth()
    with host_ctx:
        host.fbo.use()
        host_ctx.enable(moderngl.BLEND | moderngl.DEPTH_TEST)
        host_ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        host_ctx.depth_func = "<="
        state = HostGLState(raw_gl(), (host_ctx.default_texture_unit,))
    r = Renderer("exact", ctx=host_ctx)
    res = r.render(scene, W, H, target=host.fbo, viewport=(W, 0, W, H), over_target=True, read_back=False)
    with host_ctx:
        after = HostGLState(raw_gl(), (host_ctx.default_texture_unit,))
        for attr in ("scalars", "caps", "blend_i", "blend_funcs", "color_masks", "buffers", "indexed", "images"):
            assert getattr(after, attr) == getattr(state, attr), attr
        assert after.textures == state.textures
    colour, depth = host.colour(), host.depth()
    np.testing.assert_array_equal(res.image, colour[:, W:])  # read when asked: the frame's rectangle of the target
    np.testing.assert_array_equal(colour[:, :W], before_colour[:, :W])
    np.testing.assert_array_equal(depth[:, :W], before_depth[:, :W])
    err = np.abs(colour[:, W:].astype(np.float64) - _reference(scene) * 255.0).max()
    assert err <= 3.0
    np.testing.assert_allclose(depth[:, W:], _expected_depth(scene), atol=2e-6)
    r.release()
    host.release()


def test_targets_that_cannot_hold_the_host_layer_are_refused(host_ctx):
    scene = _scene()
    r = Renderer("exact", ctx=host_ctx)
    with host_ctx:
        colour = host_ctx.texture((W, H), 4)
        depth = host_ctx.depth_texture((W, H))
        no_depth = host_ctx.framebuffer([colour])
        no_colour = host_ctx.framebuffer(depth_attachment=depth)
        small = host_ctx.framebuffer([host_ctx.texture((W // 2, H), 4)], host_ctx.depth_texture((W // 2, H)))
    cases = [
        (colour, "got Texture"),
        (None, "got no target"),
        (no_depth, "no depth attachment"),
        (no_colour, "no colour attachment"),
        (small, r"the frame is 96x72, the target of 48x72"),
    ]
    for target, message in cases:
        with pytest.raises(GuacaError, match=message):
            r.render(scene, W, H, target=target, over_target=True)
    with pytest.raises(GuacaError, match="reaches outside"):
        r.render(scene, W, H, target=small, viewport=(10, 0, W, H), over_target=True)
    r.release()
    with host_ctx:
        for o in (no_depth, no_colour, small, *small.color_attachments, small.depth_attachment, colour, depth):
            o.release()


@pytest.mark.parametrize(
    "method,overrides",
    [("post_sort", {}), ("dfb", {}), ("depth_peeling", {}), ("presort_lf_et", {"raster": "compute"})],
)
def test_every_method_family_culls_behind_the_host_depth(host_ctx, method, overrides):
    """A-buffer, counted storage, peeling (drawn in the composite) and the compute rasterizer read the host's depth."""
    scene = _scene()
    host = HostFrame(host_ctx, "texture")
    host.draw(scene)
    r = Renderer("exact", ctx=host_ctx, method=method, method_overrides=overrides or None)
    r.render(scene, W, H, target=host.fbo, over_target=True)
    err = np.abs(host.colour().astype(np.float64) - _reference(scene) * 255.0).max()
    assert err <= 3.0, err
    r.release()
    host.release()
