"""Interactive viewer (`guaca view`): an orbit/fly camera, method and debug-view keys, a status line.

`app.Viewer` is the part that talks to guaca_py and is independent of the window toolkit (it
is the embedding example: give it any moderngl context and framebuffer); `window.run_viewer`
drives it from a moderngl-window window, or a headless one for scripts and CI.
"""

from .app import Viewer
from .camera import CameraController

__all__ = ["CameraController", "Viewer"]
