"""Seeing the device: MuJoCo offscreen renders (`render`) and the live browser view on viser (`View`).

Nothing in the control loop imports this package; the view reads the loop's published
telemetry (`rhi.runtime.Telemetry`) or a saved log. Its names load lazily, so that
`MUJOCO_GL` may still be chosen after `import rhi.viz` and viser (the `view` extra) is only
needed by `View`.
"""

import importlib

_WHERE = {"Posed": "posed", "RenderUnavailable": "render", "render": "render", "save_png": "render",
          "LogPlayer": "replay", "View": "view", "live": "live"}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(f"rhi.viz.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'rhi.viz' has no attribute {name!r}")
