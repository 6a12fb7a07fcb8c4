"""Raw OpenGL through ctypes: the one module that loads the GL, EGL and GLX libraries and GL entry points.

moderngl has no API for some of what guaca needs: capabilities such as NV conservative
rasterization (passes/light_culling.py), the host's context state that host_state.py saves and
restores, depth blits between a host's framebuffer and guaca's (present.py), deletable queries (gpu_timer.py), persistently mapped read-back (gpu_counters.py) and
NVX memory info (limits.py). Those call GL directly through `raw_gl()`, whose functions dispatch
to whatever context is current; host_state.py makes contexts current with the EGL/GLX libraries
`load_library` opens.
"""

from __future__ import annotations

import ctypes
from functools import cache, lru_cache

GL_CONSERVATIVE_RASTERIZATION_NV = 0x9346
INT, FLOAT, BOOL = "i", "f", "b"  # value kinds of RawGL.get
GL_LIBRARIES = ("libOpenGL.so.0", "libGL.so.1", "libGL.so")

_u, _i, _f, _d, _p = ctypes.c_uint, ctypes.c_int, ctypes.c_float, ctypes.c_double, ctypes.c_void_p
_ub = ctypes.c_ubyte
_SIGNATURES = {
    # timer queries (guaca_py/gpu_timer.py: moderngl's Query cannot be deleted)
    "glGenQueries": (None, [_u, _p]),
    "glDeleteQueries": (None, [_u, _p]),
    "glBeginQuery": (None, [_u, _u]),
    "glEndQuery": (None, [_u]),
    "glGetQueryObjectui64v": (None, [_u, _u, _p]),
    "glQueryCounter": (None, [_u, _u]),
    # fenced read-back through a persistently mapped buffer (guaca_py/gpu_counters.py)
    "glCreateBuffers": (None, [_i, _p]),
    "glDeleteBuffers": (None, [_i, _p]),
    "glNamedBufferStorage": (None, [_u, ctypes.c_ssize_t, _p, _u]),
    "glMapNamedBufferRange": (_p, [_u, ctypes.c_ssize_t, ctypes.c_ssize_t, _u]),
    "glCopyNamedBufferSubData": (None, [_u, _u, ctypes.c_ssize_t, ctypes.c_ssize_t, ctypes.c_ssize_t]),
    "glFenceSync": (_p, [_u, _u]),
    "glClientWaitSync": (_u, [_p, _u, ctypes.c_uint64]),
    "glDeleteSync": (None, [_p]),
    "glGetIntegerv": (None, [_u, _p]),
    "glGetIntegeri_v": (None, [_u, _u, _p]),
    "glGetInteger64i_v": (None, [_u, _u, _p]),
    "glGetFloatv": (None, [_u, _p]),
    "glGetBooleanv": (None, [_u, _p]),
    "glGetBooleani_v": (None, [_u, _u, _p]),
    "glIsEnabled": (_ub, [_u]),
    "glIsEnabledi": (_ub, [_u, _u]),
    "glEnable": (None, [_u]),
    "glDisable": (None, [_u]),
    "glEnablei": (None, [_u, _u]),
    "glDisablei": (None, [_u, _u]),
    "glGetError": (_u, []),
    "glClear": (None, [_u]),
    "glBindFramebuffer": (None, [_u, _u]),
    # depth copies between a host's framebuffer and guaca's (guaca_py/present.py: moderngl blits colour only)
    "glBlitNamedFramebuffer": (None, [_u, _u, _i, _i, _i, _i, _i, _i, _i, _i, _u, _u]),
    "glBindRenderbuffer": (None, [_u, _u]),
    "glViewport": (None, [_i, _i, _i, _i]),
    "glScissor": (None, [_i, _i, _i, _i]),
    "glDepthFunc": (None, [_u]),
    "glDepthMask": (None, [_ub]),
    "glDepthRange": (None, [_d, _d]),
    "glClearColor": (None, [_f, _f, _f, _f]),
    "glClearDepth": (None, [_d]),
    "glClearStencil": (None, [_i]),
    "glBlendColor": (None, [_f, _f, _f, _f]),
    "glBlendFuncSeparatei": (None, [_u, _u, _u, _u, _u]),
    "glBlendEquationSeparatei": (None, [_u, _u, _u]),
    "glColorMaski": (None, [_u, _ub, _ub, _ub, _ub]),
    "glCullFace": (None, [_u]),
    "glFrontFace": (None, [_u]),
    "glPolygonMode": (None, [_u, _u]),
    "glPolygonOffset": (None, [_f, _f]),
    "glProvokingVertex": (None, [_u]),
    "glClipControl": (None, [_u, _u]),
    "glActiveTexture": (None, [_u]),
    "glBindTexture": (None, [_u, _u]),
    "glBindBuffer": (None, [_u, _u]),
    "glBindBufferBase": (None, [_u, _u, _u]),
    "glBindBufferRange": (None, [_u, _u, _u, ctypes.c_ssize_t, ctypes.c_ssize_t]),
    "glBindImageTexture": (None, [_u, _u, _i, _ub, _i, _u, _u]),
    "glUseProgram": (None, [_u]),
    "glBindVertexArray": (None, [_u]),
    "glPixelStorei": (None, [_u, _i]),
    "glIsBuffer": (_ub, [_u]),
    "glIsTexture": (_ub, [_u]),
    "glIsVertexArray": (_ub, [_u]),
    "glIsProgram": (_ub, [_u]),
    "glIsFramebuffer": (_ub, [_u]),
    "glIsQuery": (_ub, [_u]),
}


@cache
def load_library(name: str) -> ctypes.CDLL | None:
    """The shared library `name` (opened once per process), or None where it does not load."""
    try:
        return ctypes.CDLL(name)
    except OSError:
        return None


class RawGL:
    """The GL entry points above as ctypes functions (dispatching to the current context), with small helpers."""

    def __init__(self):
        lib = None
        self.source = "eglGetProcAddress"  # where the entry points come from (the library when it has them)
        for name in GL_LIBRARIES:
            lib = load_library(name)
            if lib is not None:
                self.source = name
                break
        get_proc = getattr(load_library("libEGL.so.1"), "eglGetProcAddress", None)
        if get_proc is not None:
            get_proc.restype, get_proc.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
        for fname, (res, args) in _SIGNATURES.items():
            addr = None
            if lib is not None:
                try:
                    addr = ctypes.cast(getattr(lib, fname), ctypes.c_void_p).value
                except AttributeError:
                    addr = None
            if not addr and get_proc is not None:
                addr = get_proc(fname.encode())
            if not addr:
                raise OSError(f"OpenGL entry point {fname} not found")
            setattr(self, fname, ctypes.CFUNCTYPE(res, *args)(addr))

    def get(self, enum: int, kind: str = INT, count: int = 1) -> tuple:
        """glGet{Integer,Float,Boolean}v as a tuple."""
        ctype, fn = {INT: (ctypes.c_int, self.glGetIntegerv), FLOAT: (ctypes.c_float, self.glGetFloatv)}.get(
            kind, (ctypes.c_ubyte, self.glGetBooleanv)
        )
        buf = (ctype * max(count, 4))()  # GL may write more than asked for odd enums; never overflow
        fn(enum, buf)
        return tuple(buf[:count])

    def get_i(self, enum: int, index: int) -> int:
        """glGetIntegeri_v(enum, index)."""
        buf = (ctypes.c_int * 4)()
        self.glGetIntegeri_v(enum, index, buf)
        return buf[0]

    def get_booleans_i(self, enum: int, index: int, count: int) -> tuple[int, ...]:
        """glGetBooleani_v(enum, index) as `count` values (0 or 1)."""
        buf = (ctypes.c_ubyte * max(count, 4))()
        self.glGetBooleani_v(enum, index, buf)
        return tuple(buf[:count])

    def get_i64(self, enum: int, index: int) -> int:
        """glGetInteger64i_v(enum, index)."""
        buf = (ctypes.c_int64 * 2)()
        self.glGetInteger64i_v(enum, index, buf)
        return buf[0]

    def drain_errors(self) -> list[int]:
        """Pending glGetError codes (at most 16)."""
        out = []
        for _ in range(16):
            e = self.glGetError()
            if not e:
                break
            out.append(int(e))
        return out

    def enable(self, cap: int) -> None:
        """glEnable(cap)."""
        self.glEnable(cap)

    def disable(self, cap: int) -> None:
        """glDisable(cap)."""
        self.glDisable(cap)

    def is_enabled(self, cap: int) -> bool:
        """glIsEnabled(cap)."""
        return bool(self.glIsEnabled(cap))

    def try_enable(self, cap: int) -> bool:
        """Enable `cap` and confirm the context took it (False, state unchanged, when it did not)."""
        self.drain_errors()
        self.enable(cap)
        ok = not self.drain_errors() and self.is_enabled(cap)
        if not ok:
            self.disable(cap)
            self.drain_errors()
        return ok


@lru_cache(maxsize=1)
def raw_gl() -> RawGL | None:
    """The process-wide raw entry points (loaded once), or None where no GL library exposes them all."""
    try:
        return RawGL()
    except OSError:
        return None


__all__ = ["BOOL", "FLOAT", "GL_CONSERVATIVE_RASTERIZATION_NV", "INT", "RawGL", "load_library", "raw_gl"]
