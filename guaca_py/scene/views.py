"""Sets of cameras for several views of one scene: a stereo pair, a row of views, the faces of a cube map.

Each is a plain list of Cameras, what `Renderer.render_views` takes (and checks with
`check_cameras`): it draws them with one draw list and one transparent pool, an image and
statistics per view.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import ArgumentError
from .nodes import Camera, ValueConfigError, _number, _scaled_unit, _vector3

# The faces of a GL cube map in the order GL_TEXTURE_CUBE_MAP_POSITIVE_X + i names them: the
# direction each view looks in and its up vector, as the cube-map convention orients them (the
# frame's texture then copies straight into the face; `image`, row 0 at the top, is that upside down)
CUBE_FACES: tuple[tuple[str, tuple[int, int, int], tuple[int, int, int]], ...] = (
    ("+x", (1, 0, 0), (0, -1, 0)),
    ("-x", (-1, 0, 0), (0, -1, 0)),
    ("+y", (0, 1, 0), (0, 0, 1)),
    ("-y", (0, -1, 0), (0, 0, -1)),
    ("+z", (0, 0, 1), (0, -1, 0)),
    ("-z", (0, 0, -1), (0, -1, 0)),
)


def _camera(camera) -> Camera:
    """`camera`, checked: a Camera a frame can be made from (ArgumentError or ConfigError naming `camera`)."""
    if not isinstance(camera, Camera):
        raise ArgumentError(f"must be a Camera, got {type(camera).__name__}", key="camera")
    camera.check()
    return camera


def _positive(value, key: str) -> float:
    """`value` as a finite float > 0 (ValueConfigError naming `key`)."""
    v = _number(value)
    if v is None or v <= 0.0:
        raise ValueConfigError(f"must be a finite number > 0, got {value!r}", key=key, hint="in scene units")
    return v


def check_cameras(cameras) -> list[Camera]:
    """`cameras` as a list of Cameras a frame can be made from; otherwise an error naming `cameras[i]` and its field."""
    if isinstance(cameras, Camera) or isinstance(cameras, (str, bytes)):
        raise ArgumentError(
            f"must be a sequence of Cameras, got {type(cameras).__name__}",
            key="cameras",
            hint="a list, e.g. stereo_pair(camera, 0.064) from guaca_py.scene",
        )
    try:
        cameras = list(cameras)
    except TypeError:
        raise ArgumentError(f"must be a sequence of Cameras, got {type(cameras).__name__}", key="cameras") from None
    if not cameras:
        raise ValueConfigError("must hold at least one Camera, got none", key="cameras", hint="render() draws one view")
    for i, camera in enumerate(cameras):
        if not isinstance(camera, Camera):
            raise ArgumentError(f"must be a Camera, got {type(camera).__name__}", key=f"cameras[{i}]")
        camera.check(f"cameras[{i}]")
    return cameras


def camera_row(camera: Camera, count: int, spacing: float) -> list[Camera]:
    """`count` copies of `camera` along its right axis, `spacing` apart and centred on it, left to right.

    The views look in parallel (each target moves with its position) and share the field of view:
    the views of a horizontal-parallax light-field display, or, two of them, a stereo pair.
    """
    camera = _camera(camera)
    if isinstance(count, (bool, np.bool_)) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ArgumentError(f"must be a whole number >= 1, got {count!r}", key="count")
    step = _positive(spacing, "spacing")
    position, target = np.asarray(camera.position, float), np.asarray(camera.target, float)
    right = _scaled_unit(np.cross(_scaled_unit(target - position), _scaled_unit(_vector3(camera.up))))
    cameras = []
    for i in range(int(count)):
        shift = right * step * (i - (count - 1) / 2)
        cameras.append(
            replace(camera, position=tuple((position + shift).tolist()), target=tuple((target + shift).tolist()))
        )
    return cameras


def stereo_pair(camera: Camera, eye_separation: float) -> list[Camera]:
    """[left eye, right eye]: `camera` moved half of `eye_separation` to either side along its right axis.

    The eyes look in parallel with symmetric frusta (objects at infinity fall on the same pixel of
    both images); a display that wants zero parallax at a screen distance shifts the images apart.
    """
    _positive(eye_separation, "eye_separation")
    return camera_row(camera, 2, eye_separation)


def cube_map(position: tuple[float, float, float], near: float = 0.1, far: float = 100.0) -> list[Camera]:
    """The six 90° views from `position` that make a cube map, in GL's face order (+X, -X, +Y, -Y, +Z, -Z).

    Render them square (width == height). Each face is oriented as GL samples a cube map: the
    frame's texture (`FrameResult.texture`) copies into face i of a cube-map texture as it is;
    `FrameResult.image` holds it with row 0 at the top, so it is uploaded flipped (`image[::-1]`).
    """
    eye = _vector3(position)
    if eye is None:
        raise ValueConfigError(f"must be 3 finite numbers, got {position!r}", key="position", hint="e.g. (0, 1, 0)")
    n = _positive(near, "near")
    f = _number(far)
    if f is None or f <= n:
        raise ValueConfigError(f"must be a finite number greater than near ({near!r}), got {far!r}", key="far")
    return [
        Camera(position=tuple(eye.tolist()), target=tuple((eye + look).tolist()), up=up, fov_y=90.0, near=n, far=f)
        for _, look, up in CUBE_FACES
    ]
