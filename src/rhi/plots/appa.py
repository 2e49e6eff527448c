"""Figures of Appendix A (Figs. A.5–A.9) from `rhi.experiments.appa` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result

_METHODS = (("traditional", "traditional (J⁺)", "tab:red"), ("proposed", "proposed (W_x, γ)", "tab:blue"))


def tracking(result: Result) -> Figure:
    """Fig. A.5: end-effector paths in the x–y plane and tracking errors, traditional vs proposed."""
    a = result.arrays
    t, xd = a["t"], a["x_des"]
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4.2))
    ax0.plot(xd[:, 0], xd[:, 1], "k--", label="desired")
    for key, label, color in _METHODS:
        x = a[f"{key}_x"]
        ax0.plot(x[:, 0], x[:, 1], color=color, label=label)
        e = (x - xd) * 100
        ax1.plot(t, e[:, 0], color=color, label=f"{label}, x")
        ax1.plot(t, e[:, 1], color=color, ls=":", label=f"{label}, y")
    ax0.set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title="(a) end-effector (true)")
    ax0.legend(fontsize=8)
    ax1.set(xlabel="t [s]", ylabel="error [cm]", title="(b) tracking errors")
    ax1.legend(fontsize=7)
    fig.suptitle("Fig. A.5 tracking beyond the arm's workspace")
    fig.tight_layout()
    return fig


def base_motion(result: Result) -> Figure:
    """Fig. A.6: base position (odometry and true) and commanded base velocity with γ."""
    a = result.arrays
    t = a["t"]
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.8))
    for ax, (key, label, _) in zip(axes[:2], _METHODS):
        q, qt = a[f"{key}_q"], a[f"{key}_q_true"]
        ax.plot(t, q[:, 0], "b-", label="x_b odometry")
        ax.plot(t, qt[:, 0], "b:", label="x_b true")
        ax.plot(t, q[:, 1], "g-", label="y_b odometry")
        ax.plot(t, qt[:, 1], "g:", label="y_b true")
        ax.set(xlabel="t [s]", ylabel="[m]", title=label)
    axes[0].legend(fontsize=7)
    ax = axes[2]
    for key, label, color in _METHODS:
        ax.plot(t, np.linalg.norm(a[f"{key}_dq"][:, :2], axis=1) * 100, color=color, label=f"|v_b| {label}")
    ax2 = ax.twinx()
    ax2.plot(t, a["proposed_gamma"], "k:", lw=0.8, label="γ (proposed)")
    ax2.set(ylabel="γ [1]", ylim=(-0.05, 1.05))
    ax.set(xlabel="t [s]", ylabel="base speed [cm/s]", title="commanded base speed")
    ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Fig. A.6 motion of the mobile base")
    fig.tight_layout()
    return fig


def dm_enhancement(result: Result) -> Figure:
    """Figs. A.9(a) and A.7: DM over time (Cartesian then null-space phase) and the final configurations."""
    a = result.arrays
    fig = plt.figure(figsize=(12, 4.2))
    ax = fig.add_subplot(1, 2, 1)
    for key, label, style in (("x", "u = x", "b-"), ("x_weighted", "u = x, A.19 as printed", "b:"),
                              ("z", "u = z", "g-"), ("z_long", "u = z (longer)", "g:")):
        if f"{key}_t" in a:
            ax.plot(a[f"{key}_t"], a[f"{key}_dm"], style, label=label)
    ax.set(xlabel="t [s]", ylabel="DM [N]", title="(a) directional manipulability")
    ax.legend(fontsize=8)
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    for key, color in (("x", "tab:blue"), ("z", "tab:green")):
        s0, s1 = a[f"{key}_skeleton_start"], a[f"{key}_skeleton_end"]
        ax3.plot(s1[:, 0], s1[:, 1], s1[:, 2], "-o", color=color, ms=3, label=f"after, u = {key}")
    s0 = a["x_skeleton_start"]
    ax3.plot(s0[:, 0], s0[:, 1], s0[:, 2], "k--o", ms=3, label="start q0")
    ax3.set(xlabel="x [m]", ylabel="y [m]", zlabel="z [m]", title="(b) configurations (Fig. A.7)")
    ax3.legend(fontsize=7)
    fig.suptitle("§A.4.3 DM enhancement: Cartesian phase, then null space")
    fig.tight_layout()
    return fig


def box_push(result: Result) -> Figure:
    """Fig. A.8: the arm's joint torques in the box push, (a) without and (b) with DM enhancement, joint 4 bold."""
    a = result.arrays
    lim, start = a["limits"], float(a["push_start"])
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), sharey=True)
    for ax, (key, title) in zip(axes, (("without", "(a) without DM enhancement (traditional J⁺)"),
                                       ("with", "(b) with DM enhancement (eq. A.19 as printed)"))):
        t, tau = a[f"{key}_t"], a[f"{key}_tau"]
        for i in range(tau.shape[1]):
            bold = i == 3
            ax.plot(t, tau[:, i], color="k" if bold else plt.get_cmap("tab10")(i), lw=2.0 if bold else 0.9,
                    label=f"joint {i + 1}", zorder=3 if bold else 2)
        for value, style, label in ((lim[0], "r--", "limit, joints 1–4"), (lim[-1], "m--", "limit, joints 5–7"),
                                    (20.0, "g:", "20 N m (thesis, with DM)")):
            ax.axhline(value, color=style[0], ls=style[1:], lw=1, label=label)
            ax.axhline(-value, color=style[0], ls=style[1:], lw=1)
        ax.axvline(start, color="0.5", lw=0.8)
        ax.set(xlabel="t [s]", title=title)
    axes[0].set(ylabel="joint torque, gravity subtracted [N m]")
    axes[1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.suptitle("Fig. A.8 joint torques while pushing the 26 kg box (MuJoCo plant; the push starts at the grey line)")
    fig.tight_layout()
    return fig
