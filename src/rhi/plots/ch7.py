"""Figures of chapter 7 (Figs 7.1, 7.5) from `rhi.experiments.ch7` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result

_TITLES = {"none": "(a) no compensation", "scaling": "(b) simple scaling", "ascm": "(c) ASCM", "lp": "(d) LP optimum"}


def example_3dof(result: Result) -> Figure:
    """Fig. 7.1: joint torques (dotted), desired F_e (black) and output force (red) per method."""
    a = result.arrays
    t, Fe = a["t"], a["Fe"]
    fig, axes = plt.subplots(1, 4, figsize=(15, 3.6), sharey=True)
    for ax, meth in zip(axes, ("none", "scaling", "ascm", "lp")):
        tau, F = a[f"tau_{meth}"], a[f"force_{meth}"]
        for i in range(tau.shape[1]):
            ax.plot(t, tau[:, i], ":", label=f"τ{i + 1} [N m]")
        ax.plot(t, Fe[:, 0], "k-", label="F_e,x")
        ax.plot(t, Fe[:, 1], "k--", label="F_e,y")
        ax.plot(t, F[:, 0], "r-", label="F_out,x")
        ax.plot(t, F[:, 1], "r--", label="F_out,y")
        ax.set(title=_TITLES[meth], xlabel="t [s]")
    axes[0].set_ylabel("force [N] / torque [N m]")
    axes[-1].legend(fontsize=7, loc="upper right")
    fig.suptitle("Fig. 7.1 3-DoF RHI with saturating joints")
    fig.tight_layout()
    return fig


def deficiency_map(result: Result) -> Figure:
    """Fig. 7.5: percent deficiency of the force capability without ASCM (eq. 7.19)."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    pc = ax.pcolormesh(a["x"], a["y"], np.ma.masked_invalid(a["pd"]), shading="nearest", cmap="viridis")
    fig.colorbar(pc, ax=ax, label="PD [%]")
    ax.set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title="Fig. 7.5 percent deficiency, u = [0, 1]")
    return fig
