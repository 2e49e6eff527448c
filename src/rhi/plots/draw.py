"""Drawing primitives: planar arms and ellipses."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure


def ellipse(ax: Axes, center, A: np.ndarray, *, scale: float = 1.0, **style) -> None:
    """Draw the 2-D ellipse {center + scale·v : vᵀ A⁻¹ v = 1} of an SPD matrix A: (2, 2)."""
    w, V = np.linalg.eigh(A)
    t = np.linspace(0, 2 * np.pi, 100)
    pts = (V * np.sqrt(np.maximum(w, 0))) @ np.stack([np.cos(t), np.sin(t)]) * scale
    ax.plot(center[0] + pts[0], center[1] + pts[1], **style)


def chain(ax: Axes, points: np.ndarray, **style) -> None:
    """Draw a planar serial chain through joint positions points: (k, 2) [m]."""
    ax.plot(points[:, 0], points[:, 1], "-o", ms=3, **style)


def force_torque_panels(arrays: dict, titles: dict[str, str], suptitle: str, *, fe_y: bool = False) -> Figure:
    """One panel per case: joint torques (dotted), desired F_e (black) and output force (red) over time.

    `arrays` holds "t" (T,), "Fe" (T, 2) and, per case key of `titles`, "tau_<key>" (T, n) and
    "force_<key>" (T, 2); `fe_y` also draws F_e,y.
    """
    t, Fe = arrays["t"], arrays["Fe"]
    # at most two panels a row, so the figure keeps readable text when the report scales it to the page width
    ncols = min(2, len(titles))
    nrows = -(-len(titles) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5.2 * ncols, 3.4 * nrows + 0.9), sharey=True, squeeze=False)
    axes = axes.ravel()
    for ax in axes[len(titles):]:
        fig.delaxes(ax)
    for ax, (key, title) in zip(axes, titles.items()):
        tau, F = arrays[f"tau_{key}"], arrays[f"force_{key}"]
        for i in range(tau.shape[1]):
            ax.plot(t, tau[:, i], ":", label=f"τ{i + 1} [N m]")
        ax.plot(t, Fe[:, 0], "k-", label="F_e,x")
        if fe_y:
            ax.plot(t, Fe[:, 1], "k--", label="F_e,y")
        ax.plot(t, F[:, 0], "r-", label="F_out,x")
        ax.plot(t, F[:, 1], "r--", label="F_out,y")
        ax.set(title=title, xlabel="t [s]", ylabel="force [N] / torque [N m]")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 7), fontsize=10, frameon=False)
    fig.suptitle(suptitle)
    fig.tight_layout(rect=(0, 0.55 / (3.4 * nrows + 0.9), 1, 1))
    return fig
