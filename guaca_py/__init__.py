"""guaca_py: deferred shading with exact order-independent transparency (sorted A-buffer) for Python."""

from . import methods, passes  # noqa: F401  (importing them registers every method and pass: registry.py)
from .errors import ConfigError, DeviceError, GuacaError, ShaderCompileError, UnsupportedMethodError
from .pipeline.config import PipelineConfig, load_pipeline, pipeline_from_text
from .pipeline.frame import FrameResult
from .renderer import Renderer
from .scene.graph import Scene
from .scene.loader import load

__version__ = "0.1.0"
__all__ = [
    "Renderer",
    "Scene",
    "load",
    "FrameResult",
    "PipelineConfig",
    "load_pipeline",
    "pipeline_from_text",
    "GuacaError",
    "ConfigError",
    "DeviceError",
    "ShaderCompileError",
    "UnsupportedMethodError",
]
