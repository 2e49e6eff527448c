"""Figures of chapter 6 (Figs 6.3, 6.4, 6.9, 6.10, 6.11) from `rhi.experiments.ch6` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure

from rhi.experiments.result import Result
from rhi.plots.draw import chain, ellipse, force_torque_panels

_LABELS = {"initial": "(a) initial configuration", "free": "(b) matched to M_Free^des",
           "stiff": "(c) matched to M_Stiff^des"}


def example_3dof(result: Result) -> Figure:
    """Fig. 6.3: joint torques (dotted), desired F_e (black) and rendered force (red) at the three configurations."""
    return force_torque_panels(result.arrays, _LABELS, "Fig. 6.3 3-DoF RHI rendering F_e = [3.5 sin(πt/2), 0] N "
                               "(force scaling at saturation)")


def configurations_3dof(result: Result) -> Figure:
    """Fig. 6.4: the initial (blue), M_Free-matched (red) and M_Stiff-matched (magenta) configurations.

    With their FMEs and the desired FMEs (green), all scaled ×0.02 m per √(N²/(N m)²).
    """
    a = result.arrays
    x = a["x"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 5), sharey=True)
    scale = 0.02
    for ax, name, color, des in ((axes[0], "free", "r", "M_free_des"), (axes[1], "stiff", "m", "M_stiff_des")):
        chain(ax, a["skeleton_initial"], color="b", label="initial")
        chain(ax, a[f"skeleton_{name}"], color=color, label=f"matched to M_{name.capitalize()}^des")
        ellipse(ax, x, a["fme_initial"], scale=scale, color="b", lw=1)
        ellipse(ax, x, a[f"fme_{name}"], scale=scale, color=color, lw=1.5)
        ellipse(ax, x, a[des], scale=scale, color="g", lw=1, ls="--")
        ax.set(xlabel="x [m]", aspect="equal", title=f"({'a' if name == 'free' else 'b'}) {name}")
        ax.legend(fontsize=8, loc="lower left")
    axes[0].set_ylabel("y [m]")
    fig.suptitle("Fig. 6.4 configurations and FMEs (desired: green, dashed)")
    fig.tight_layout(rect=(0, 0.02, 1, 0.95))
    return fig


def palpation(result: Result) -> Figure:
    """Fig. 6.9: sensor force, desired force K_e δX and joint torques while palpating, M_Free vs M_Stiff."""
    a = result.arrays
    fig, axes = plt.subplots(1, 2, figsize=(12, 4), sharey=True)
    for ax, case, lab in zip(axes, ("free", "stiff"), ("(a) M_Free^des", "(b) M_Stiff^des")):
        t = a[f"t_{case}"]
        ax.plot(t, a[f"desired_{case}"], "k--", label="desired K_e δX [N]")
        ax.plot(t, a[f"force_{case}"], "r-", label="measured (F/T) [N]")
        tau = a[f"tau_{case}"]
        for i in range(tau.shape[1]):
            ax.plot(t, tau[:, i], ":", label=f"τ{i + 1} [N m]")
        peak = float(np.min(a[f"force_{case}"]))
        ax.axhline(peak, color="r", lw=0.5)
        ax.set(title=f"{lab}: peak {peak:.2f} N", xlabel="t [s]")
        ax.set_ylim(max(-20.0, 1.3 * peak), 4.0)
    axes[0].set_ylabel("force along u [N] / torque [N m]")
    axes[-1].legend(fontsize=7, loc="lower left")
    fig.suptitle("Fig. 6.9 palpation of K_e = 1000 N/m from [0.5, 0.1] m along u = [0, 1] (simulated)")
    fig.tight_layout()
    return fig


def fmax_ratio_map(result: Result) -> Figure:
    """Fig. 6.10: F_max(M_Stiff^des configuration) / F_max(M_Free^des configuration) along u = [0, 1]."""
    a = result.arrays
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    for ax, key, title in ((axes[0], "ratio", "force scaling (ch. 6 controller)"),
                           (axes[1], "ratio_lp", "with null-space torques (LP)")):
        Z = np.ma.masked_invalid(a[key])
        lo, hi = (float(Z.min()), float(Z.max())) if Z.count() else (0.5, 2.0)
        hi = max(hi, 1.001)
        norm = TwoSlopeNorm(1.0, min(lo, 1.0 / hi), hi)  # ratio 1 white, r and 1/r equally saturated
        pc = ax.pcolormesh(a["x"], a["y"], Z, shading="nearest", cmap="RdBu", norm=norm)
        fig.colorbar(pc, ax=ax, label="F_max,Stiff / F_max,Free [1]")
        ax.plot([0.5], [0.1], "k*", ms=10)
        ax.set(xlabel="x [m]", aspect="equal", title=title)
    axes[0].set_ylabel("y [m]")
    fig.suptitle("Fig. 6.10 F_max ratio over rhi4's workspace (★: palpation point)")
    fig.tight_layout()
    return fig


def aso_example(result: Result) -> Figure:
    """Fig. 6.6: the ASO V of eq. 6.14 over the two-DoF example's torque box (S = 50)."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    cs = ax.contourf(a["tau1"], a["tau2"], a["V"], levels=np.linspace(0, 1, 11), cmap="viridis")
    ax.contour(a["tau1"], a["tau2"], a["V"], levels=[0.7], colors="w", linestyles="--")
    fig.colorbar(cs, ax=ax, label="V")
    ax.set_xlabel("τ1 [N m]")
    ax.set_ylabel("τ2 [N m]")
    ax.set_title("ASO, eq. 6.14, S = 50 (dashed: V = 0.7)")
    return fig


def transition(result: Result) -> Figure:
    """Fig. 6.11: null-space signal without (a) and with (b) the transition method; (c) V and Ω; (d) M_des."""
    a = result.arrays
    fig, axes = plt.subplots(2, 2, figsize=(13, 7.5))
    for ax, name, lab in ((axes[0, 0], "without", "(a) without"), (axes[0, 1], "with", "(b) with the method")):
        t = a[f"t_{name}"]
        ts, tn = a[f"tau_s_{name}"], a[f"tau_null_{name}"]
        for i in range(ts.shape[1]):
            ax.plot(t, np.clip(ts[:, i], -20, 20), "-", lw=0.8, color=f"C{i}", label=f"τ_S,{i + 1} = −β∂ν/∂q{i + 1}")
            ax.plot(t, tn[:, i], ":", lw=0.8, color=f"C{i}", label=f"τ_N,{i + 1} applied")
        ax.set(title=f"{lab}: null-space signal [N m] (τ_S clipped at ±20)", xlabel="t [s]")
    axes[0, 1].legend(fontsize=6, ncol=2, loc="lower right")
    ax = axes[1, 0]
    for name, style in (("with", "-"), ("without", "--")):
        ax.plot(a[f"t_{name}"], a[f"V_{name}"], "k" + style, lw=1, label=f"V ({name})")
        ax.plot(a[f"t_{name}"], a[f"omega_{name}"], "b" + style, lw=1, label=f"Ω ({name})")
    ax.axhline(0.7, color="gray", lw=0.5)
    ax.axhline(0.95, color="gray", lw=0.5)
    ax.set(title="(c) ASO V and activation Ω (ε₁ = 0.7, ε₂ = 0.95)", xlabel="t [s]", ylim=(-0.05, 1.05))
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    for name, style in (("with", "-"), ("without", "--")):
        t = a[f"t_{name}"]
        M = a[f"M_des_{name}"]
        ax.plot(t, M[:, 0], "C0" + style, label=f"M_des,xx ({name})")
        ax.plot(t, M[:, 2], "C1" + style, label=f"M_des,yy ({name})")
    ax2 = ax.twinx()
    ax2.plot(a["t_with"], a["force_with"], "r-", lw=0.8, label="F/T along u (with)")
    ax2.plot(a["t_without"], a["force_without"], "r--", lw=0.8, label="F/T along u (without)")
    ax2.set_ylabel("force along u [N]")
    ax.set(title="(d) desired FME entries and the sensor force", xlabel="t [s]", ylabel="desired FME entry [N²/(N m)²]")
    ax.legend(fontsize=7, loc="center left")
    ax2.legend(fontsize=7, loc="center right")
    fig.suptitle("Fig. 6.11 transition between M_Free^des and M_Stiff^des while palpating (simulated rhi4)")
    fig.tight_layout()
    return fig
