"""MuJoCo's OpenGL backend on a machine without a display.

MuJoCo chooses its backend from ``MUJOCO_GL`` when it is imported and defaults to glfw, which
aborts the process on a headless machine. `headless_default` runs before rhi imports MuJoCo: where
``MUJOCO_GL`` is unset, there is no display and MuJoCo is not imported yet, it selects a software
or EGL backend whose library is installed (osmesa, else egl). It never overrides a choice made.
"""

from __future__ import annotations

import ctypes.util
import os
import sys


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or sys.platform != "linux"


def headless_default() -> None:
    if "MUJOCO_GL" in os.environ or has_display() or "mujoco" in sys.modules:
        return
    for backend, lib in (("osmesa", "OSMesa"), ("egl", "EGL")):
        if ctypes.util.find_library(lib):
            os.environ["MUJOCO_GL"] = backend
            return
