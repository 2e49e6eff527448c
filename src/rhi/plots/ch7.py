"""Figures of chapter 7 (Figs 7.1, 7.5) from `rhi.experiments.ch7` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result
from rhi.plots.draw import force_torque_panels

_TITLES = {"none": "(a) no compensation", "scaling": "(b) simple scaling", "ascm": "(c) ASCM", "lp": "(d) LP optimum"}


def example_3dof(result: Result) -> Figure:
    """Fig. 7.1: joint torques (dotted), desired F_e (black) and output force (red) per method."""
    return force_torque_panels(result.arrays, _TITLES, "Fig. 7.1 3-DoF RHI with saturating joints", fe_y=True)


def deficiency_map(result: Result) -> Figure:
    """Fig. 7.5: percent deficiency of the force capability without ASCM (eq. 7.19)."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    pc = ax.pcolormesh(a["x"], a["y"], np.ma.masked_invalid(a["pd"]), shading="nearest", cmap="viridis")
    fig.colorbar(pc, ax=ax, label="PD [%]")
    ax.set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title="Fig. 7.5 percent deficiency, u = [0, 1]")
    return fig
