"""The programs in examples/ run, and show what they claim."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _example(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_embed_host_app_composes_with_the_host_frame(tmp_path):
    out = tmp_path / "host.png"
    example = _example("embed_host_app")
    img = example.main(["--frames", "3", "--width", "96", "--height", "80", "--out", str(out)])
    assert out.is_file() and img.shape == (80, 96, 3)
    scene = img[: 80 - 10].astype(float)
    assert scene.std() > 10  # guaca's frame is there
    # the host's gradient stays where nothing of guaca is in front of it (its top row: the top colour)
    assert np.abs(img[0, :8] - np.array(example.GRADIENT[1]) * 255).max() <= 3
    # the host's opaque marker is there (guaca's frame was composed over it, not drawn instead of it),
    # and so is the pin the host drew after guaca's frame with its depth test
    marker = (img[..., 0] > 200) & (img[..., 1] > 90) & (img[..., 1] < 170) & (img[..., 2] < 60)
    pin = (img[..., 0] > 200) & (img[..., 1] > 200) & (img[..., 2] < 120)
    assert marker.sum() > 100 and pin.sum() > 10
    # the UI bar is blended (alpha 0.8) over the host's frame: the host's blend state survived guaca's frame;
    # drawn opaque it would be exactly its own colour (26, 26, 51) everywhere
    bar = img[-7:].astype(float)  # the host's UI bar: bottom 10% of the rows
    assert np.abs(bar - np.array([26.0, 26.0, 51.0])).max(axis=2).mean() > 8
    assert (bar[:, :, 2] >= bar[:, :, 0]).all() and bar.max() < 0.8 * 0.4 * 255 + 0.2 * 255 + 2


def test_animate_scene_uploads_each_mesh_content_once(tmp_path):
    out = tmp_path / "anim.png"
    fig = _example("animate_scene").main(["--frames", "45", "--width", "64", "--height", "48", "--out", str(out)])
    assert out.is_file()
    # 45 frames, one upload per content each time it comes back after KEEP_FRAMES unused frames:
    # plane 1, sphere 1 (five balls share it), box at frames 0/20/40, cylinder 10/30, added box 10/30
    assert fig["mesh_uploads"] == 1 + 1 + 3 + 2 + 2
    assert fig["meshes_on_gpu"] == 3  # plane, sphere, box: the others were freed


@pytest.mark.parametrize("right,differs", [("unsorted_blend", True), ("presort_lf_et", False)])
def test_compare_methods_side_by_side(tmp_path, right, differs):
    out = tmp_path / "cmp.png"
    fig = _example("compare_methods").main(["--right", right, "--width", "80", "--height", "60", "--out", str(out)])
    assert out.is_file()
    if differs:
        assert fig["rmse"] > 0.5 and fig["max"] > 20
    else:
        assert fig["max"] == 0  # the same method in both halves: identical images
