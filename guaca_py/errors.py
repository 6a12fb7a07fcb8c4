"""Error types of guaca_py: every failure names where it came from and what to do."""

from __future__ import annotations

from pathlib import Path


class GuacaError(Exception):
    """Base class of all errors raised by guaca_py."""


class ConfigError(GuacaError):
    """A file (scene, pipeline, material) is malformed; names file, line, key and reason."""

    def __init__(
        self,
        reason: str,
        file: str | Path | None = None,
        line: int | None = None,
        key: str | None = None,
        hint: str | None = None,
    ):
        self.reason, self.file, self.line, self.key, self.hint = reason, file, line, key, hint
        if file is None:  # an argument or command-line option: the key is the location
            msg = "" if not key else f"{key}: " if key.startswith("-") else f"'{key}': "
        else:
            msg = f"{file}{'' if line is None else f':{line}'}: " + (f"'{key}': " if key else "")
        msg += reason
        if hint:
            msg += f" ({hint})"
        super().__init__(msg)


class ArgumentError(ConfigError, TypeError):
    """An argument of the wrong kind (still a TypeError, as Python's own checks raise)."""


class LimitError(ConfigError):
    """A request exceeds a device or format limit; names the option or key, the limit and what to do."""


class ShaderCompileError(GuacaError):
    """GLSL failed to compile; the message maps compiler lines back to material/template files."""


class DeviceError(GuacaError):
    """No usable OpenGL 4.5 device, or a feature the request needs is missing on this device."""


class UnsupportedMethodError(DeviceError):
    """A transparency method cannot run on the current device; the message says why."""
