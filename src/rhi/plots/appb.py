"""Figures of Appendix B (Figs. B.7–B.11) from `rhi.experiments.appb` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result


def singularity(result: Result) -> Figure:
    """Fig. B.7: σ_min(J_m) with and without singularity avoidance; end-effector position without it."""
    a = result.arrays
    t = a["t"]
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    ax0.plot(t, a["without_sigma"], "r-", label="AMD")
    ax0.plot(t, a["with_sigma"], "b-", label="AMD + singularity avoidance")
    ax0.axhline(0.15, color="k", ls=":", lw=0.8, label="σ_m,min")
    act = np.nan_to_num(a["with_base_active"]) > 0
    ax0.fill_between(t, 0, 1, where=act, color="b", alpha=0.08, transform=ax0.get_xaxis_transform(),
                     label="base enabled")
    ax0.set(xlabel="t [s]", ylabel="σ_min(J_m) [m/rad]", title="(a) singularity criterion")
    ax0.legend(fontsize=8)
    xd, x = a["x_des"], a["without_x"]
    for i, (ax_, c) in enumerate(zip("xyz", ("tab:blue", "tab:orange", "tab:green"))):
        ax1.plot(t, xd[:, i], "--", color=c, lw=0.8)
        ax1.plot(t, x[:, i], "-", color=c, label=ax_)
    ax1.set(xlabel="t [s]", ylabel="[m]", title="(b) end-effector without avoidance (dashed: desired)")
    ax1.legend(fontsize=8)
    fig.suptitle("Fig. B.7 AMD with and without singularity avoidance")
    fig.tight_layout()
    return fig


def _tracking(result: Result, where: str, title: str) -> Figure:
    a = result.arrays
    t = a["t"]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    xd = a[f"{where}_proposed_x_des"]
    axes[0].plot(xd[:, 0], xd[:, 1], "k--", label="desired")
    for method, color in (("traditional", "tab:red"), ("proposed", "tab:blue")):
        x = a[f"{where}_{method}_x"]
        axes[0].plot(x[:, 0], x[:, 1], color=color, label=method)
        e = (x - xd) * 100
        axes[1].plot(t, e[:, 0], color=color, label=f"{method}, x")
        axes[1].plot(t, e[:, 1], color=color, ls=":", label=f"{method}, y")
        dq = a[f"{where}_{method}_dq"]
        axes[2].plot(t, dq[:, 0] * 100, color=color, label=f"{method}, v_x_b")
        axes[2].plot(t, dq[:, 1] * 100, color=color, ls=":", label=f"{method}, v_y_b")
    axes[0].set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title="end-effector (true)")
    axes[1].set(xlabel="t [s]", ylabel="error [cm]", title="tracking errors")
    axes[2].set(xlabel="t [s]", ylabel="[cm/s]", title="commanded base velocity")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def within(result: Result) -> Figure:
    """Figs. B.8–B.9: the circle within the arm's workspace."""
    return _tracking(result, "within", "Figs. B.8–B.9 within the arm's workspace")


def beyond(result: Result) -> Figure:
    """Figs. B.10–B.11: the circle beyond the arm's workspace."""
    return _tracking(result, "beyond", "Figs. B.10–B.11 beyond the arm's workspace")


def base_paths(result: Result) -> Figure:
    """Fig. B.11(b, d): base paths in the x–y plane, odometry (desired) and true."""
    a = result.arrays
    # one scale for both panels (the proposed base moves little: a panel of its own would be squashed flat)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.8), sharex=True, sharey=True)
    paths = [a[f"beyond_{m}_{k}"][:, :2] for m in ("traditional", "proposed") for k in ("q", "q_true")]
    lo, hi = np.min([p.min(axis=0) for p in paths], axis=0), np.max([p.max(axis=0) for p in paths], axis=0)
    pad = 0.08 * float(np.max(hi - lo)) + 1e-3
    for ax, method in zip(axes, ("traditional", "proposed")):
        q, qt = a[f"beyond_{method}_q"], a[f"beyond_{method}_q_true"]
        ax.plot(q[:, 0], q[:, 1], "k--", label="commanded (odometry)")
        ax.plot(qt[:, 0], qt[:, 1], "b-", label="true")
        ax.set(xlabel="x_b [m]", ylabel="y_b [m]", title=method, xlim=(lo[0] - pad, hi[0] + pad),
               ylim=(lo[1] - pad, hi[1] + pad))
        ax.set_aspect("equal", adjustable="box")
        ax.legend(fontsize=9, loc="best")
    fig.suptitle("Fig. B.11 base paths beyond the workspace")
    fig.tight_layout()
    return fig
