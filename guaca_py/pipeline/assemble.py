"""Builds a config's passes: checks what each reads against what earlier passes write, then fuses per-pixel passes."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..errors import ConfigError
from ..registry import PASSES
from .config import PipelineConfig
from .device import Device
from .resources import RESOURCE_TYPES

if TYPE_CHECKING:
    from ..passes.base import Pass

FRAME_INPUTS = ("draw_list", "lights", "host_layer")  # resources the frame itself provides before the first pass


def readers_of(config: PipelineConfig) -> dict[str, tuple[str, ...]]:
    """Resource -> the passes of `config` that declare reading it, in order."""
    out: dict[str, tuple[str, ...]] = {}
    for pc in config.passes:
        for res in PASSES.get(pc.name).reads:
            out[res] = (*out.get(res, ()), pc.name)
    return out


def assemble(config: PipelineConfig, device: Device, fuse: bool = True) -> list[Pass]:
    """The passes of `config`, declarations checked (file and line of a bad pass), fused where allowed."""
    readers = readers_of(config)
    passes = [PASSES.get(pc.name)(device, pc.settings, readers) for pc in config.passes]
    available = set(FRAME_INPUTS)
    for p, pc in zip(passes, config.passes):
        unknown = [r for r in (*p.reads, *p.writes) if r not in RESOURCE_TYPES]
        if unknown:  # a pass class declaring a resource nobody defines is a programming error: say which
            raise ConfigError(
                f"pass '{p.name}' declares unknown resources {', '.join(unknown)}", config.source, pc.line
            )
        missing = [r for r in p.reads if r not in available]
        if missing:
            raise ConfigError(
                f"pass '{p.name}' reads {', '.join(missing)} which no earlier pass writes",
                config.source,
                pc.line,
                "passes",
            )
        available |= set(p.writes)
    if fuse:
        fuse_per_pixel(passes)
    return passes


def fuse_per_pixel(passes: list[Pass]) -> None:
    """Let a pass apply the per-pixel pass right after it to its own output (one full-screen write and read fewer).

    Fused when the later pass is per-pixel, reads only what the earlier one writes, and no pass
    after them reads that intermediate resource (it is then never made). The default
    pipeline's composite thus writes the tone-mapped image itself.
    """
    for i in range(len(passes) - 1):
        first, second = passes[i], passes[i + 1]
        if not (first.accepts_epilogue and first.epilogue is None and first.fused_into is None):
            continue
        if not second.per_pixel or len(second.reads) != 1 or second.reads[0] not in first.writes:
            continue
        if any(second.reads[0] in later.reads for later in passes[i + 2 :]):
            continue
        first.set_epilogue(second)
        second.fused_into = first.name
