"""Device set-ups drawn with MuJoCo's offscreen renderer (`rhi.viz.render`) where they read better than lines.

Without an OpenGL backend (no MUJOCO_GL=egl/osmesa) the figures fall back to the line drawings
of the same configurations, titled so.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.devices.model import Device, device
from rhi.experiments.result import Result
from rhi.viz.posed import Posed
from rhi.viz.render import RenderUnavailable, render


def _grid(panels: list[tuple[str, Device, np.ndarray]], title: str, *, elevation: float | None = None,
          azimuth: float | None = None) -> Figure:
    """One rendered picture per (label, device, q); the line drawing of each when rendering is unavailable."""
    fig, axes = plt.subplots(1, len(panels), figsize=(4 * len(panels), 3.4))
    axes = np.atleast_1d(axes)
    posed: dict[int, Posed] = {}
    try:
        for ax, (label, dev, q) in zip(axes, panels):
            p = posed.setdefault(id(dev), Posed(dev))
            ax.imshow(render(p, q, width=560, height=420, elevation=elevation, azimuth=azimuth))
            ax.set_title(label, fontsize=10)
            ax.axis("off")
    except RenderUnavailable as exc:
        for ax, (label, dev, q) in zip(axes, panels):
            ax.clear()
            s = dev.skeleton(q)
            ax.plot(s[:, 0], s[:, 1], "-o", ms=3)
            ax.set(aspect="equal", title=label, xlabel="x [m]", ylabel="y [m]")
        title += f" (line drawing: {str(exc).split(';')[0]})"
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def ch3_configurations(result: Result) -> Figure:
    """Table 3.1 set-up (Fig. 3.5-style), rendered: the RHI, the PHANToM and the rehabilitation robot.

    The RHI at its optimised configuration, all three at the first of the two points of §3.5.
    """
    from rhi.experiments.ch3.measures import POINTS, devices  # data access only

    devs = devices()
    a = result.arrays
    panels = [(f"{nm} at {POINTS[0]}", dev, a["q_opt_0"] if nm == "RHI" else a[f"q_{nm}_0"]) for nm, dev in devs.items()]
    return _grid(panels, "§3.5 set-up: the three interfaces at the same handle point", elevation=-70.0)


def wmm_configurations(result: Result) -> Figure:
    """Fig. A.7: the mobile manipulator at its start and after DM enhancement along z and along x, rendered."""
    from rhi.experiments.appa import Q0

    dev = device("wmm")
    a = result.arrays
    panels = [("start q0", dev, Q0)] + [(f"after DM enhancement, u = {k}", dev, a[f"{k}_q"][-1])
                                        for k in ("z", "x") if f"{k}_q" in a]
    return _grid(panels, "§A.4.3 configurations (Fig. A.7)", elevation=-15.0, azimuth=-120.0)
