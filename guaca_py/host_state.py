"""Living in a host's GL context: make the renderer's context current and give the host its state back.

Two jobs, both around every public Renderer call that touches GL:

* `ContextGuard` makes the renderer's context current when another one is (EGL or GLX) and
  makes the previous one current again afterwards. moderngl's own `with ctx:` releases the
  context on exit instead of restoring the previous one, so the native handles are kept here.
* `HostGLState` snapshots, with raw glGet* calls (gl_state.py's entry points), every piece of context state that guaca's
  passes (or moderngl underneath them) may change, resets what the passes assume (no scissor,
  no stencil, filled polygons, full colour masks, default depth range and clip control...) and
  restores the snapshot afterwards. moderngl has getters for almost none of this, and a host
  may have set state with raw GL, so GL itself is the source of truth.

The state covered is listed in `HostGLState` (docs/embedding.md repeats it); anything else
(transform feedback, stencil functions and masks, queries, debug groups) is neither touched
by guaca nor restored.
"""

from __future__ import annotations

import ctypes
import functools
import threading
from contextlib import contextmanager
from functools import lru_cache

import moderngl

from .errors import GuacaError
from .gl_state import BOOL, FLOAT, INT, RawGL, load_library, raw_gl

# ---- GL enums ---------------------------------------------------------------------------
GL_TEXTURE0 = 0x84C0

# Plain capabilities: saved with glIsEnabled; the second element is what guaca's passes expect.
_CAPS = {
    0x0BE2: False,  # GL_BLEND (indexed state saved separately; this is draw buffer 0)
    0x0B44: False,  # GL_CULL_FACE
    0x0B71: False,  # GL_DEPTH_TEST
    0x0C11: False,  # GL_SCISSOR_TEST
    0x0B90: False,  # GL_STENCIL_TEST
    0x8C89: False,  # GL_RASTERIZER_DISCARD
    0x8DB9: False,  # GL_FRAMEBUFFER_SRGB
    0x8037: False,  # GL_POLYGON_OFFSET_FILL
    0x809E: False,  # GL_SAMPLE_ALPHA_TO_COVERAGE
    0x0BF2: False,  # GL_COLOR_LOGIC_OP
    0x8F9D: False,  # GL_PRIMITIVE_RESTART
    0x8D69: False,  # GL_PRIMITIVE_RESTART_FIXED_INDEX
    0x864F: False,  # GL_DEPTH_CLAMP
    0x8642: None,  # GL_PROGRAM_POINT_SIZE (left as found)
    0x884F: None,  # GL_TEXTURE_CUBE_MAP_SEAMLESS
    0x809D: None,  # GL_MULTISAMPLE
    0x0BD0: None,  # GL_DITHER
    0x9346: None,  # GL_CONSERVATIVE_RASTERIZATION_NV (light culling switches it on and off)
}
_CLIP_DISTANCES = [0x3000 + i for i in range(8)]  # GL_CLIP_DISTANCE0..7, guaca expects them off
_DRAW_BUFFERS = 8  # indexed blend / colour-mask state saved for this many draw buffers

# Scalar state read with glGet*v: enum -> (type, count).
_SCALARS = {
    "draw_fbo": (0x8CA6, INT, 1),  # GL_DRAW_FRAMEBUFFER_BINDING
    "read_fbo": (0x8CAA, INT, 1),  # GL_READ_FRAMEBUFFER_BINDING
    "renderbuffer": (0x8CA7, INT, 1),
    "viewport": (0x0BA2, INT, 4),
    "scissor": (0x0C10, INT, 4),
    "depth_func": (0x0B74, INT, 1),
    "depth_mask": (0x0B72, BOOL, 1),
    "depth_range": (0x0B70, FLOAT, 2),
    "clear_color": (0x0C22, FLOAT, 4),
    "clear_depth": (0x0B73, FLOAT, 1),
    "clear_stencil": (0x0B91, INT, 1),
    "blend_color": (0x8005, FLOAT, 4),
    "cull_face_mode": (0x0B45, INT, 1),
    "front_face": (0x0B46, INT, 1),
    "polygon_mode": (0x0B40, INT, 2),
    "polygon_offset": (0x8038, FLOAT, 1),  # GL_POLYGON_OFFSET_FACTOR
    "polygon_units": (0x2A00, FLOAT, 1),  # GL_POLYGON_OFFSET_UNITS
    "provoking_vertex": (0x8E4F, INT, 1),
    "clip_origin": (0x935C, INT, 1),
    "clip_depth_mode": (0x935D, INT, 1),
    "active_texture": (0x84E0, INT, 1),
    "program": (0x8B8D, INT, 1),
    "vao": (0x85B5, INT, 1),
    "pack_alignment": (0x0D05, INT, 1),
    "unpack_alignment": (0x0CF5, INT, 1),
}
# Non-indexed buffer binding points: (binding query, target).
_BUFFER_TARGETS = {
    0x8894: 0x8892,  # ARRAY_BUFFER
    0x8F36: 0x8F36,  # COPY_READ_BUFFER (binding enum equals target)
    0x8F37: 0x8F37,  # COPY_WRITE_BUFFER
    0x88ED: 0x88EB,  # PIXEL_PACK_BUFFER
    0x88EF: 0x88EC,  # PIXEL_UNPACK_BUFFER
    0x8F43: 0x8F3F,  # DRAW_INDIRECT_BUFFER
    0x90EF: 0x90EE,  # DISPATCH_INDIRECT_BUFFER
    0x9193: 0x9192,  # QUERY_BUFFER
    0x8C2A: 0x8C2A,  # TEXTURE_BUFFER (binding query 0x8C2A is also the target)
    0x90D3: 0x90D2,  # SHADER_STORAGE_BUFFER (generic)
    0x8A28: 0x8A11,  # UNIFORM_BUFFER (generic)
    0x92C1: 0x92C0,  # ATOMIC_COUNTER_BUFFER (generic)
}
# Indexed buffer binding points guaca binds: target -> (binding, start, size, max-count query, slots saved).
# (guaca binds storage buffers below 18 and never binds uniform or atomic-counter buffers by index.)
_INDEXED_BUFFERS = {
    0x90D2: (0x90D3, 0x90D4, 0x90D5, 0x90DD, 18),  # SHADER_STORAGE_BUFFER
}
# Texture targets guaca binds (2D, and 2D arrays for the light grid): (binding query, target).
_TEXTURE_TARGETS = (
    (0x8069, 0x0DE1),  # 2D
    (0x8C1D, 0x8C1A),  # 2D_ARRAY
)
_TEXTURE_UNITS = 32  # units 0..31 (every Texture slot: tests/shaders/test_slots.py) plus moderngl's default unit
_IMAGE_UNITS = 16
_IMAGE = (0x8F3A, 0x8F3B, 0x8F3C, 0x8F3D, 0x8F3E, 0x906E)  # name, level, layered, layer, access, format


# ---- GL state snapshot ------------------------------------------------------------------------
class HostGLState:
    """A snapshot of the context state guaca may change; `restore()` puts it back.

    Covered: draw/read framebuffer and renderbuffer bindings, viewport, scissor box and test,
    blend enable/functions/equations per draw buffer and blend colour, colour write masks per
    draw buffer, depth test/function/write mask/range, clear colour/depth/stencil, cull face
    enable/mode, front face, polygon mode and offset, provoking vertex, clip control and clip
    distances, the capabilities in `_CAPS`, the active texture unit, 2D and 2D-array texture
    bindings on units 0-31 and moderngl's default unit, image units 0-15, storage-buffer
    bindings 0-17 (with their ranges), the non-indexed buffer bindings (array, copy, pixel
    pack/unpack, indirect, query, texture, SSBO/UBO/atomic generic), the current program and
    vertex array, and pack/unpack alignment. That is a superset of what guaca's passes change;
    the rest (sampler objects, 3D/cube textures, indexed UBOs, stencil functions, transform
    feedback) guaca never touches.
    """

    def __init__(self, gl: RawGL, extra_units: tuple[int, ...] = ()):
        self.gl = gl
        self.units = tuple(sorted(set(range(_TEXTURE_UNITS)) | set(extra_units)))
        gl.drain_errors()  # the host's pending errors are not ours to report, nor to confuse us
        self.scalars = {k: gl.get(e, t, n) for k, (e, t, n) in _SCALARS.items()}
        self.caps = {c: bool(gl.glIsEnabled(c)) for c in list(_CAPS) + _CLIP_DISTANCES}
        self.blend_i = [bool(gl.glIsEnabledi(0x0BE2, i)) for i in range(_DRAW_BUFFERS)]
        self.blend_funcs = [
            tuple(gl.get_i(e, i) for e in (0x80C9, 0x80C8, 0x80CB, 0x80CA, 0x8009, 0x883D))
            for i in range(_DRAW_BUFFERS)
        ]
        self.color_masks = [gl.get_booleans_i(0x0C23, i, 4) for i in range(_DRAW_BUFFERS)]  # GL_COLOR_WRITEMASK
        self.buffers = {b: gl.get(b)[0] for b in _BUFFER_TARGETS}
        self.indexed = {}
        for target, (binding, start, size, max_q, cap) in _INDEXED_BUFFERS.items():
            slots = []
            for i in range(min(gl.get(max_q)[0], cap)):
                name = gl.get_i(binding, i)  # a range only matters for a bound buffer
                slots.append((name, gl.get_i64(start, i), gl.get_i64(size, i)) if name else (0, 0, 0))
            self.indexed[target] = slots
        self.images = []
        for i in range(min(gl.get(0x8F38)[0], _IMAGE_UNITS)):  # GL_MAX_IMAGE_UNITS
            name = gl.get_i(_IMAGE[0], i)
            self.images.append(tuple(gl.get_i(e, i) for e in _IMAGE) if name else None)
        self.textures = {}
        for unit in self.units:
            gl.glActiveTexture(GL_TEXTURE0 + unit)
            self.textures[unit] = tuple(gl.get(q)[0] for q, _ in _TEXTURE_TARGETS)
        gl.glActiveTexture(self.scalars["active_texture"][0])
        self.errors = gl.drain_errors()  # an enum the driver lacks (e.g. NV conservative raster)

    def reset_for_guaca(self) -> None:
        """Put the state guaca's passes assume but never set themselves to GL's defaults."""
        gl = self.gl
        for cap, value in _CAPS.items():
            if value is False:
                gl.glDisable(cap)
        for cap in _CLIP_DISTANCES:
            gl.glDisable(cap)
        for i in range(_DRAW_BUFFERS):
            gl.glColorMaski(i, 1, 1, 1, 1)
        gl.glPolygonMode(0x0408, 0x1B02)  # FRONT_AND_BACK, FILL
        gl.glDepthRange(0.0, 1.0)
        gl.glClipControl(0x8CA1, 0x935E)  # LOWER_LEFT, NEGATIVE_ONE_TO_ONE
        gl.glFrontFace(0x0901)  # CCW
        gl.glProvokingVertex(0x8E4E)  # LAST_VERTEX_CONVENTION
        gl.drain_errors()

    def restore(self) -> None:
        """Put every saved value back."""
        gl, s = self.gl, self.scalars
        for cap, on in self.caps.items():
            (gl.glEnable if on else gl.glDisable)(cap)
        for i, on in enumerate(self.blend_i):
            (gl.glEnablei if on else gl.glDisablei)(0x0BE2, i)
        for i, (src, dst, src_a, dst_a, eq, eq_a) in enumerate(self.blend_funcs):
            gl.glBlendFuncSeparatei(i, src, dst, src_a, dst_a)
            gl.glBlendEquationSeparatei(i, eq, eq_a)
        for i, m in enumerate(self.color_masks):
            gl.glColorMaski(i, *m)
        gl.glBlendColor(*s["blend_color"])
        gl.glDepthFunc(s["depth_func"][0])
        gl.glDepthMask(s["depth_mask"][0])
        gl.glDepthRange(*s["depth_range"])
        gl.glClearColor(*s["clear_color"])
        gl.glClearDepth(s["clear_depth"][0])
        gl.glClearStencil(s["clear_stencil"][0])
        gl.glCullFace(s["cull_face_mode"][0])
        gl.glFrontFace(s["front_face"][0])
        gl.glPolygonMode(0x0408, s["polygon_mode"][0])
        gl.glPolygonOffset(s["polygon_offset"][0], s["polygon_units"][0])
        gl.glProvokingVertex(s["provoking_vertex"][0])
        gl.glClipControl(s["clip_origin"][0], s["clip_depth_mode"][0])
        for target, slots in self.indexed.items():
            for i, (name, start, size) in enumerate(slots):
                if name and size > 0:
                    gl.glBindBufferRange(target, i, name, start, size)
                else:
                    gl.glBindBufferBase(target, i, name)
        for binding, target in _BUFFER_TARGETS.items():  # after the indexed ones: those set the generic
            gl.glBindBuffer(target, self.buffers[binding])
        for i, image in enumerate(self.images):
            if image is None:
                gl.glBindImageTexture(i, 0, 0, 0, 0, 0x88B8, 0x8229)  # unbound: READ_ONLY, R8 (GL's defaults)
            else:
                gl.glBindImageTexture(i, *image)
        for unit, bound in self.textures.items():
            gl.glActiveTexture(GL_TEXTURE0 + unit)
            for (_, target), name in zip(_TEXTURE_TARGETS, bound):
                gl.glBindTexture(target, name)
        gl.glActiveTexture(s["active_texture"][0])
        gl.glBindFramebuffer(0x8CA9, s["draw_fbo"][0])  # DRAW_FRAMEBUFFER
        gl.glBindFramebuffer(0x8CA8, s["read_fbo"][0])  # READ_FRAMEBUFFER
        gl.glBindRenderbuffer(0x8D41, s["renderbuffer"][0])
        gl.glViewport(*s["viewport"])
        gl.glScissor(*s["scissor"])
        gl.glUseProgram(s["program"][0])
        gl.glBindVertexArray(s["vao"][0])
        gl.glPixelStorei(0x0D05, s["pack_alignment"][0])
        gl.glPixelStorei(0x0CF5, s["unpack_alignment"][0])
        gl.drain_errors()


# ---- current context (EGL / GLX) ----------------------------------------------------------
class _Native:
    """eglGetCurrent* / glXGetCurrent* and the matching MakeCurrent, whichever libraries exist."""

    def __init__(self):
        self.egl = self._load("libEGL.so.1", "egl")
        self.glx = self._load("libGLX.so.0", "glX") or self._load("libGL.so.1", "glX")

    @staticmethod
    def _load(lib_name: str, prefix: str):
        lib = load_library(lib_name)
        if lib is None:
            return None
        try:
            if prefix == "egl":
                fns = {n: getattr(lib, "egl" + n) for n in ("GetCurrentContext", "GetCurrentDisplay")}
                fns["GetCurrentSurface"] = lib.eglGetCurrentSurface
                fns["MakeCurrent"] = lib.eglMakeCurrent
                fns["GetCurrentSurface"].argtypes = [ctypes.c_int]
                fns["MakeCurrent"].argtypes = [ctypes.c_void_p] * 4
            else:
                fns = {
                    n: getattr(lib, "glX" + n)
                    for n in ("GetCurrentContext", "GetCurrentDisplay", "GetCurrentDrawable", "GetCurrentReadDrawable")
                }
                fns["MakeCurrent"] = lib.glXMakeContextCurrent
                fns["MakeCurrent"].argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_void_p]
                fns["GetCurrentDrawable"].restype = ctypes.c_ulong
                fns["GetCurrentReadDrawable"].restype = ctypes.c_ulong
        except AttributeError:
            return None
        for n in ("GetCurrentContext", "GetCurrentDisplay"):
            fns[n].restype = ctypes.c_void_p
        if prefix == "egl":
            fns["GetCurrentSurface"].restype = ctypes.c_void_p
        return fns

    def current(self) -> tuple | None:
        """(api, handles...) of the context current on this thread, or None."""
        if self.egl is not None:
            c = self.egl["GetCurrentContext"]()
            if c:
                e = self.egl
                return (
                    "egl",
                    e["GetCurrentDisplay"](),
                    e["GetCurrentSurface"](0x3059),
                    e["GetCurrentSurface"](0x305A),
                    c,
                )
        if self.glx is not None:
            c = self.glx["GetCurrentContext"]()
            if c:
                g = self.glx
                return ("glx", g["GetCurrentDisplay"](), g["GetCurrentDrawable"](), g["GetCurrentReadDrawable"](), c)
        return None

    def make_current(self, state: tuple) -> None:
        """Make a context returned by current() current again."""
        api, display, draw, read, ctx = state
        (self.egl if api == "egl" else self.glx)["MakeCurrent"](display, draw, read, ctx)


@lru_cache(maxsize=1)
def native() -> _Native:
    """The process-wide EGL/GLX helpers."""
    return _Native()


def native_handle(state: tuple | None):
    """The context handle of a current() result (what identifies a context)."""
    return None if state is None else (state[0], state[4])


class ContextGuard:
    """Re-entrant: make `ctx` current and, for a host's context, save/reset/restore its state."""

    def __init__(self, ctx, restore_state: bool):
        self.ctx = ctx
        self.restore_state = restore_state
        self._depth = 0
        self.handle = None
        with self._switch():  # identify the context by its native handle once
            self.handle = native_handle(native().current())

    @contextmanager
    def _switch(self):
        prev = native().current()
        if self.handle is not None and native_handle(prev) == self.handle:
            yield
            return
        # moderngl's ctx.__enter__ makes it current; its __exit__ would release it instead of
        # restoring the previous one, so that is done here. With nothing current before, the
        # context stays current: a host that relies on its context being current keeps working.
        self.ctx.__enter__()
        try:
            yield
        finally:
            if prev is not None:
                native().make_current(prev)

    @contextmanager
    def __call__(self):
        """Run the body with the context current and (host contexts) the host's state preserved."""
        if self._depth:
            self._depth += 1
            try:
                yield
            finally:
                self._depth -= 1
            return
        with self._switch():
            self._depth = 1
            saved = mgl = None
            try:
                if self.restore_state and raw_gl() is not None:
                    mgl = (self.ctx.fbo,)
                    saved = HostGLState(raw_gl(), (self.ctx.default_texture_unit,))
                    saved.reset_for_guaca()
                yield
            finally:
                self._depth = 0
                if saved is not None:
                    try:  # moderngl's idea of the bound framebuffer (ctx.fbo, what ctx.clear() clears)
                        mgl[0].use() if mgl[0] is not None else setattr(self.ctx, "fbo", None)
                    except (AttributeError, moderngl.Error):  # the host released it meanwhile
                        self.ctx.fbo = None
                    saved.restore()


def on_context(fn):
    """Decorator for Renderer methods: run with the renderer's context current (`self._gl` guard)."""

    @functools.wraps(fn)
    def wrapper(self, *args, **kwargs):
        if getattr(self, "released", False):
            raise GuacaError(f"{fn.__name__}: this Renderer was released; make a new Renderer to render again")
        ctx = getattr(self, "ctx", None)
        if ctx is not None and isinstance(ctx.mglo, moderngl.InvalidObject):
            raise GuacaError(
                f"{fn.__name__}: the moderngl context this Renderer draws in was released; "
                "release the Renderer before its context, and make a new one to render again"
            )
        owner = getattr(self, "thread", None)
        if owner is not None and owner != threading.get_ident():
            raise GuacaError(
                f"{fn.__name__}: called from another thread than the one that made this Renderer; GL calls belong "
                "to the context's thread: render from that thread, or make a Renderer in this one"
            )
        with self._gl():
            return fn(self, *args, **kwargs)

    return wrapper


def count_gl_objects(limit: int = 4096) -> dict[str, int]:
    """Live buffers, textures, VAOs, programs, framebuffers and queries among names 1..limit (current context)."""
    gl = raw_gl()
    if gl is None:
        raise OSError("no GL library exposes the entry points gl_state.RawGL needs")
    out = {}
    for kind, fn in (
        ("buffers", gl.glIsBuffer),
        ("textures", gl.glIsTexture),
        ("vertex_arrays", gl.glIsVertexArray),
        ("programs", gl.glIsProgram),
        ("framebuffers", gl.glIsFramebuffer),
        ("queries", gl.glIsQuery),
    ):
        out[kind] = sum(1 for name in range(1, limit + 1) if fn(name))
    gl.drain_errors()
    return out
