"""Batch job files: what they mean (cameras, keyframes, animation, variants) and how bad ones are refused."""

from __future__ import annotations

import pytest
from batch_jobs import SCENE, orbit_cameras, write_job

from guaca_py.batch import load_job
from guaca_py.batch.plan import interpolate, plan, scene_payload
from guaca_py.cli import main
from guaca_py.errors import ConfigError
from guaca_py.pipeline.config import load_pipeline


def _job(folder, text: str):
    (folder / "scene.yaml").write_text(SCENE)
    p = folder / "job.yaml"
    p.write_text(text)
    return p


def _tasks(path):
    job = load_job(path)
    return job, plan(job, [scene_payload(p, n) for p, n in zip(job.scenes, job.scene_names)])


def test_orbit_follows_the_formula_and_keeps_the_scene_camera(tmp_path):
    job, tasks = _tasks(write_job(tmp_path, frames=8))
    assert [t.file for t in tasks] == [f"exact/{i:05d}.png" for i in range(8)]
    for t, cam in zip(tasks, orbit_cameras(8)):
        assert t.camera["position"] == cam.position and t.camera["target"] == cam.target
        assert (t.camera["fov_y"], t.camera["near"], t.camera["far"], t.camera["up"]) == (
            50.0,
            0.1,
            100.0,
            (0.0, 1.0, 0.0),
        )
    assert tasks[2].camera["position"][0] == pytest.approx(5.0) and tasks[2].camera["position"][2] == pytest.approx(0.0)
    assert len({t.key for t in tasks}) == 8


def test_orbit_defaults_come_from_the_scene_camera(tmp_path):
    # the scene camera sits at (0, 0.5, 5) looking at the origin: radius 5, height 0.5, starting where it is
    _, tasks = _tasks(_job(tmp_path, "scene: scene.yaml\nframes: 4\ncamera: {orbit: {}}\n"))
    assert tasks[0].camera["position"] == pytest.approx((0.0, 0.5, 5.0))
    assert tasks[1].camera["position"] == pytest.approx((5.0, 0.5, 0.0))
    assert tasks[0].size == load_pipeline("default").resolution  # no resolution given: the pipeline's


def test_keyframes_interpolate_and_hold(tmp_path):
    text = """\
scene: scene.yaml
frames: 6
camera:
  keyframes:
    - {frame: 1, position: [0, 0, 4]}
    - {frame: 3, position: [2, 0, 4], fov_y: 30}
"""
    _, tasks = _tasks(_job(tmp_path, text))
    xs = [t.camera["position"][0] for t in tasks]
    assert xs == [0.0, 0.0, 1.0, 2.0, 2.0, 2.0]
    assert [t.camera["fov_y"] for t in tasks] == [50.0, 50.0, 40.0, 30.0, 30.0, 30.0]  # 50: the scene camera's
    assert tasks[0].camera["target"] == (0.0, 0.0, 0.0)


def test_camera_list_sets_the_frame_count(tmp_path):
    text = "scene: scene.yaml\ncamera:\n  list:\n    - {position: [0, 0, 3]}\n    - {position: [1, 0, 3], target: [1, 0, 0]}\n"
    job, tasks = _tasks(_job(tmp_path, text))
    assert job.frames == 2 and tasks[1].camera["target"] == (1.0, 0.0, 0.0)


def test_node_animation_moves_the_named_node(tmp_path):
    text = """\
scene: scene.yaml
frames: 3
animate:
  - node: box
    keyframes:
      - {frame: 0, rotation_deg: [0, 0, 0]}
      - {frame: 2, rotation_deg: [0, 90, 0], scale: 2}
"""
    _, tasks = _tasks(_job(tmp_path, text))
    index = 2  # the box, third in walk order
    assert [t.nodes[index]["rotation_deg"][1] for t in tasks] == [0.0, 45.0, 90.0]
    assert tasks[1].nodes[index]["scale"] == (1.5, 1.5, 1.5)
    assert tasks[0].nodes[index]["translation"] == (0.3, 0.2, 0.5)  # not keyed: the node's own
    assert tasks[0].camera == tasks[2].camera  # no camera path: the scene's


def test_interpolate_without_base_keys():
    from guaca_py.batch.job import Keyframe

    keys = [Keyframe(0, {"a": 0.0}, None), Keyframe(4, {"a": 8.0}, None)]
    assert [interpolate(keys, {}, i)["a"] for i in range(5)] == [0.0, 2.0, 4.0, 6.0, 8.0]


def test_variants_apply_set_like_the_command_line(tmp_path):
    variants = """\
  - {name: exact, pipeline: exact}
  - {name: fast, set: {threshold: 0.95, transparency.budget_mb: 64}}
  - {name: aa, method: presort_lf, set: {antialiasing.samples: 4}, resolution: [32, 24]}"""
    job, tasks = _tasks(write_job(tmp_path, frames=2, variants=variants))
    exact, fast, aa = job.variants
    assert exact.pipeline.name != fast.pipeline.name
    assert fast.overrides == {"threshold": 0.95, "budget_mb": 64}
    assert aa.pipeline.antialiasing["samples"] == 4 and aa.method == "presort_lf" and aa.overrides == {}
    assert [t.file for t in tasks][2:4] == ["fast/00000.png", "fast/00001.png"]
    assert tasks[4].size == (32, 24) and tasks[0].size == (64, 48)
    assert tasks[0].key != tasks[2].key  # same camera, another variant: another key


def test_several_scenes_get_a_folder_each(tmp_path):
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "other.yaml").write_text(SCENE)
    job, tasks = _tasks(_job(tmp_path, "scene: [scene.yaml, b/other.yaml]\nframes: 2\nresolution: [8, 8]\n"))
    assert [t.file for t in tasks] == [
        "scene/default/00000.png",
        "scene/default/00001.png",
        "other/default/00000.png",
        "other/default/00001.png",
    ]


BAD = [
    ("scene: scene.yaml\nframes: 4\ncolour: red\n", 3, "colour", "unknown key 'colour'"),
    ("scene: nope.yaml\nframes: 4\n", 1, "scene", "scene file not found"),
    ("scene: scene.yaml\nframes: 0\n", 2, "frames", "must be in [1,"),
    ("scene: scene.yaml\nframes: 4\ncamera: {orbit: {radius: -1}}\n", 3, "camera.orbit.radius", "must be > 0"),
    ("scene: scene.yaml\nframes: 4\ncamera: {orbit: {}, list: []}\n", 3, "camera", "exactly one of"),
    ("scene: scene.yaml\ncamera:\n  keyframes: [{frame: 0}]\n", 3, "camera.keyframes", "needs 'frames'"),
    ("scene: scene.yaml\n", 1, "frames", "missing"),
    (
        "scene: scene.yaml\nframes: 4\ncamera:\n  keyframes:\n    - {frame: 2}\n    - {frame: 1}\n",
        6,
        "camera.keyframes[1].frame",
        "does not follow frame 2",
    ),
    (
        "scene: scene.yaml\nframes: 3\ncamera:\n  list:\n    - {position: [0, 0, 1]}\n",
        2,
        "frames",
        "the camera list has 1",
    ),
    (
        "scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a}\n  - {name: b, set: {threshold: 5}}\n",
        5,
        "variants[1].set.threshold",
        "must be in (0, 1]",
    ),
    (
        "scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a, set: {antialiasing.samples: 3}}\n",
        4,
        "variants[0].set.antialiasing.samples",
        "must be one of",
    ),
    (
        "scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a, set: {bogus: 1}}\n",
        4,
        "variants[0].set.bogus",
        "unknown setting 'bogus'",
    ),
    ("scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a, method: nope}\n", 4, "variants[0].method", "nope"),
    (
        "scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a, pipeline: fastest}\n",
        4,
        "variants[0].pipeline",
        "no built-in pipeline 'fastest'",
    ),
    ("scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a/b}\n", 4, "variants[0].name", "folder-safe"),
    ("scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a}\n  - {name: a}\n", 5, "variants[1].name", "two variants"),
    (
        "scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a, method: dfb, set: {antialiasing.samples: 4}}\n",
        4,
        "variants[0]",
        "does not support antialiasing.samples 4",
    ),
    ("scene: scene.yaml\nframes: 4\nresolution: [64]\n", 3, "resolution", "[width, height]"),
    ("scene: scene.yaml\nframes: 4\nvideo: yes\n", 3, "video", "true or false"),
    ("scene: scene.yaml\nframes: 4\npng_level: 12\n", 3, "png_level", "must be in [0, 9]"),
]


@pytest.mark.parametrize("text, line, key, reason", BAD, ids=[b[2] + ":" + b[3][:20] for b in BAD])
def test_bad_jobs_name_file_line_and_key(tmp_path, text, line, key, reason):
    path = _job(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        load_job(path)
    e = err.value
    assert (str(e.file), e.line, e.key) == (str(path), line, key), str(e)
    assert reason in e.reason, str(e)


def test_problems_found_with_the_scene_name_the_job_line(tmp_path):
    path = _job(tmp_path, "scene: scene.yaml\nframes: 2\nanimate:\n  - node: ghost\n    keyframes: [{frame: 0}]\n")
    with pytest.raises(ConfigError, match=r"job.yaml:4: 'animate\[0\].node': no node named 'ghost'"):
        _tasks(path)
    path = _job(tmp_path, "scene: scene.yaml\nframes: 2\ncamera: {orbit: {radius: 1, height: 0, target: [0, 0, 0]}}\n")
    _tasks(path)  # fine; a camera on its target is not
    path.write_text("scene: scene.yaml\ncamera:\n  list:\n    - {position: [0, 0, 0], target: [0, 0, 0]}\n")
    with pytest.raises(ConfigError, match=r"'camera.list\[0\]': frame 0: the camera's position is its target"):
        _tasks(path)


def test_video_needs_even_sizes(tmp_path):
    path = _job(tmp_path, "scene: scene.yaml\nframes: 2\nresolution: [63, 48]\nvideo: true\n")
    with pytest.raises(ConfigError) as err:
        load_job(path)
    assert err.value.key in ("resolution", "video")  # odd size, or imageio-ffmpeg missing: both at their key


def test_cli_refuses_a_bad_job_with_status_2(tmp_path, capsys):
    path = _job(tmp_path, "scene: scene.yaml\nframes: 4\nvariants:\n  - {name: a, set: {threshold: 5}}\n")
    assert main(["batch", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"error: {path}:4: 'variants[0].set.threshold': must be in (0, 1]" in err
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_dict_jobs_read_like_files(tmp_path):
    (tmp_path / "scene.yaml").write_text(SCENE)
    job = load_job({"scene": "scene.yaml", "frames": 3, "camera": {"orbit": {"degrees": 90}}}, base=tmp_path)
    assert job.frames == 3 and job.camera[1]["degrees"] == 90.0
    with pytest.raises(ConfigError, match="^<job>: 'frames': expected a whole number, got 2.5$"):
        load_job({"scene": "scene.yaml", "frames": 2.5}, base=tmp_path)


def test_a_job_scene_texture_is_decoded_as_renders_decode_it(tmp_path):
    """The driver reads textures for the workers with the renderer's bounded decoder: a bad file is named."""
    from PIL import Image

    from guaca_py.batch.plan import self_contained
    from guaca_py.scene.loader import load_scene_text

    Image.new("I;16", (2, 2), 32768).save(tmp_path / "grey.png")
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20)
    text = "nodes: [{{material: {{description: pbr_textured, uniforms: {{albedo_map: {}}}}}}}]"
    grey = self_contained(load_scene_text(text.format("grey.png"), "s.yaml", tmp_path)).nodes[0].material
    assert grey.uniforms["albedo_map"].pixels[0, 0].tolist() == [128, 128, 128, 255]  # 16-bit scaled, not clipped
    with pytest.raises(ConfigError, match="bad.png.*not a readable image"):
        self_contained(load_scene_text(text.format("bad.png"), "s.yaml", tmp_path))
