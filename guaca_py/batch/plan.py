"""A job's frames as tasks: the scenes loaded once on the driver, each frame's camera and node transforms.

Scenes travel to the workers as loaded, pickled `Scene` objects (meshes, materials, and texture
files read into in-memory `TextureImage`s), not as files: a worker needs no disk holding the
job's scene, meshes or textures, and every worker renders exactly what the driver loaded. A
task names its scene and variant and carries its camera and the transforms of the animated
nodes (by their index in the scene's walk order), so a worker applies it to its own copy of the
scene in any order.
"""

from __future__ import annotations

import hashlib
import json
import math
import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..scene.graph import Camera, Scene, Transform
from ..scene.texture import TEXTURE_SUFFIXES, TextureImage, read_texture_file
from .job import Job, Keyframe

CAMERA_FIELDS = ("position", "target", "up", "fov_y", "near", "far")
TRANSFORM_FIELDS = ("translation", "rotation_deg", "scale")


@dataclass(frozen=True)
class ScenePayload:
    """A loaded scene as the workers receive it: its name, pickled bytes and their digest."""

    name: str
    data: bytes
    digest: str

    def load(self) -> Scene:
        """The Scene (a fresh copy)."""
        return pickle.loads(self.data)


@dataclass(frozen=True)
class Task:
    """One image to render: scene, variant, frame, camera, animated node transforms, size, output file, key."""

    id: int
    scene: str
    variant: str
    frame: int
    camera: dict
    nodes: dict  # walk index -> {translation, rotation_deg, scale}
    size: tuple[int, int]
    file: str  # relative to the output folder
    key: str  # digest of everything that decides the pixels


def apply_task(scene: Scene, task: Task) -> None:
    """Put the task's camera and node transforms into `scene` (the worker's copy)."""
    scene.camera = Camera(**task.camera)
    if task.nodes:
        nodes = [n for n, _ in scene.walk()]
        for index, values in task.nodes.items():
            nodes[index].transform = Transform(**values)


def self_contained(scene: Scene) -> Scene:
    """`scene` with every texture file a material names read into memory, so no worker needs the file."""
    images: dict[str, TextureImage] = {}
    for node, _ in scene.walk():
        mat = node.material
        if mat is None:
            continue
        for name, value in list(mat.uniforms.items()):
            if isinstance(value, str) and value.lower().endswith(TEXTURE_SUFFIXES):
                if value not in images:  # the same decode as TextureCache: RGBA, row 0 at the top, bounded
                    images[value] = TextureImage(read_texture_file(value), Path(value).name)
                mat.uniforms[name] = images[value]
    return scene


def scene_payload(path: Path, name: str) -> ScenePayload:
    """Load a scene file (YAML, glTF or mesh) on the driver and pickle it for the workers."""
    from ..scene.loader import load as load_any

    data = pickle.dumps(self_contained(load_any(path)), protocol=pickle.HIGHEST_PROTOCOL)
    return ScenePayload(name, data, hashlib.sha256(data).hexdigest())


def _camera_dict(cam: Camera) -> dict:
    vectors = ("position", "target", "up")
    return {k: tuple(map(float, getattr(cam, k))) if k in vectors else float(getattr(cam, k)) for k in CAMERA_FIELDS}


def _lerp(a, b, t: float):
    if isinstance(a, tuple):
        return tuple(x + (y - x) * t for x, y in zip(a, b))
    return a + (b - a) * t


def interpolate(keys: list[Keyframe], base: dict, frame: int) -> dict:
    """Values at `frame`: keyframes (each over `base`) linearly interpolated, held outside their range."""
    after = next((k for k in keys if k.frame >= frame), keys[-1])
    before = next((k for k in reversed(keys) if k.frame <= frame), keys[0])
    a, b = {**base, **before.values}, {**base, **after.values}
    if after.frame == before.frame:
        return a
    t = (frame - before.frame) / (after.frame - before.frame)
    return {k: _lerp(a[k], b[k], t) for k in a}


def camera_problem(cam: dict) -> str | None:
    """Why a camera cannot render (near >= far, position on the target, up along the view), or None."""
    if cam["near"] >= cam["far"]:
        return f"near ({cam['near']:g}) must be less than far ({cam['far']:g})"
    f = np.subtract(cam["target"], cam["position"])
    if np.linalg.norm(f) == 0.0:
        return "the camera's position is its target"
    if np.linalg.norm(np.cross(f / np.linalg.norm(f), cam["up"])) < 1e-9:
        return "the camera looks along its up vector"
    return None


def orbit_camera(base: dict, orbit: dict, frame: int, frames: int) -> dict:
    """Frame `frame` of the orbit: θ = degrees·frame/frames, position = target + (r·sin θ, height, r·cos θ)."""
    target = orbit["target"]
    theta = math.radians(orbit["degrees"] * frame / frames)
    r, h = orbit["radius"], orbit["height"]
    position = (target[0] + r * math.sin(theta), target[1] + h, target[2] + r * math.cos(theta))
    return {**base, "position": position, "target": tuple(target)}


def cameras(job: Job, scene: Scene) -> list[dict]:
    """Every frame's camera for `scene` (its own camera where the job gives no path)."""
    base = _camera_dict(scene.camera)
    doc = job.doc
    if job.camera is None:
        return [base] * job.frames
    kind, spec = job.camera
    if kind == "orbit":
        pos, tgt = base["position"], spec.get("target", base["target"])
        orbit = {
            "target": tgt,
            "radius": spec.get("radius", math.hypot(pos[0] - tgt[0], pos[2] - tgt[2])),
            "height": spec.get("height", pos[1] - tgt[1]),
            "degrees": spec["degrees"],
        }
        out = [orbit_camera(base, orbit, i, job.frames) for i in range(job.frames)]
        where = [("camera", "orbit")] * job.frames
    elif kind == "list":
        out = [{**base, **c} for c in spec]
        where = [("camera", "list", i) for i in range(job.frames)]
    else:
        out = [interpolate(spec, base, i) for i in range(job.frames)]
        where = [("camera", "keyframes")] * job.frames
    for i, cam in enumerate(out):
        problem = camera_problem(cam)
        if problem:
            raise doc.error(where[i], f"frame {i}: {problem}", f"scene {scene.source}" if scene.source else None)
    return out


def node_tracks(job: Job, scene: Scene, scene_name: str) -> list[tuple[int, list[Keyframe], dict]]:
    """(walk index, keyframes, the node's own transform) of each animated node this scene holds."""
    tracks = []
    nodes = [n for n, _ in scene.walk()]
    for name, keys, at in job.animate:
        found = [i for i, n in enumerate(nodes) if n.name == name]
        if len(found) > 1:
            raise job.doc.error(at + ("node",), f"{len(found)} nodes are named '{name}' in scene '{scene_name}'")
        if found:
            t = nodes[found[0]].transform
            base = {k: tuple(float(x) for x in getattr(t, k)) for k in TRANSFORM_FIELDS}
            tracks.append((found[0], keys, base))
    return tracks


def plan(job: Job, payloads: list[ScenePayload]) -> list[Task]:
    """Every task of the job, scene by scene, variant by variant, frame by frame."""
    tasks: list[Task] = []
    scenes = {p.name: p.load() for p in payloads}
    for name, _, at in job.animate:
        if not any(n.name == name for s in scenes.values() for n, _ in s.walk()):
            raise job.doc.error(at + ("node",), f"no node named '{name}' in {', '.join(scenes)}", "node names: name:")
    many = len(payloads) > 1
    for payload in payloads:
        scene = scenes[payload.name]
        cams = cameras(job, scene)
        tracks = node_tracks(job, scene, payload.name)
        states = [{index: interpolate(keys, base, i) for index, keys, base in tracks} for i in range(job.frames)]
        for v in job.variants:
            size = v.resolution or job.resolution or v.pipeline.resolution
            folder = f"{payload.name}/{v.name}" if many else v.name
            fingerprint = v.fingerprint()
            for i in range(job.frames):
                key = json.dumps([payload.digest, fingerprint, cams[i], sorted(states[i].items()), list(size)])
                tasks.append(
                    Task(
                        len(tasks),
                        payload.name,
                        v.name,
                        i,
                        cams[i],
                        states[i],
                        tuple(size),
                        f"{folder}/{i:05d}.png",
                        hashlib.sha256(key.encode()).hexdigest(),
                    )
                )
    return tasks


def video_groups(tasks: list[Task]) -> dict[str, list[Task]]:
    """The tasks of each video file (one per scene and variant), in frame order, by the video's relative path."""
    groups: dict[str, list[Task]] = {}
    for t in tasks:
        groups.setdefault(str(Path(t.file).parent) + ".mp4", []).append(t)
    return groups


__all__ = [
    "ScenePayload",
    "Task",
    "apply_task",
    "cameras",
    "interpolate",
    "orbit_camera",
    "plan",
    "scene_payload",
    "self_contained",
    "video_groups",
]
