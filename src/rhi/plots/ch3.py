"""Figures of chapter 3 (Figs 3.6–3.8) from `rhi.experiments.ch3` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from rhi.experiments.result import Result
from rhi.plots.draw import chain, ellipse


def workspaces(result: Result) -> Figure:
    """Fig. 3.6: the workspaces of the RHI, PHANToM and Rehab and the experiment's start point."""
    fig, ax = plt.subplots(figsize=(5.5, 6))
    handles = []
    for pts, label, color in zip(result.arrays["workspaces"], ("RHI", "PHANToM", "Rehab"), ("C0", "C1", "C2")):
        ax.plot(pts[:, 0], pts[:, 1], ".", ms=1, alpha=0.3, color=color)
        handles.append(Line2D([], [], ls="", marker="o", ms=6, color=color, label=label))
    ax.plot([0.49], [-0.22], "k*", ms=10)
    handles.append(Line2D([], [], ls="", marker="*", ms=10, color="k", label="start (0.49, −0.22) m"))
    ax.set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title="Fig. 3.6 workspaces")
    # legend below the axes: own-size proxy markers (markerscale would blow up the star) over no data
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, frameon=False)
    fig.tight_layout()
    return fig


def _map(result: Result, key: str, title: str, label: str) -> Figure:
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    x, y, Z = result.arrays["x"], result.arrays["y"], result.arrays[key]
    Zm = np.ma.masked_invalid(Z)
    lo, hi = float(Zm.min()), float(Zm.max())
    norm = TwoSlopeNorm(1.0, min(lo, 0.999), max(hi, 1.001))  # ratio 1 (no advantage) is white
    pc = ax.pcolormesh(x, y, Zm, shading="nearest", cmap="RdBu_r" if key == "lambda_ratio" else "RdBu", norm=norm)
    fig.colorbar(pc, ax=ax, label=label)
    ax.plot([0.49, 0.49], [-0.22, -0.14], "r-", lw=2, label="experiment segment")
    ax.set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title=title)
    ax.legend(loc="upper left")
    return fig


def lambda_ratio(result: Result) -> Figure:
    """Fig. 3.7: Λ_RHI / Λ_PHANToM along u = [0, 1]."""
    return _map(result, "lambda_ratio", "Fig. 3.7 effective apparent inertia ratio", "Λ_RHI / Λ_PHANToM [1]")


def rho_ratio(result: Result) -> Figure:
    """Fig. 3.8: ρ_RHI / ρ_PHANToM along u = [0, 1]."""
    return _map(result, "rho_ratio", "Fig. 3.8 effective manipulability ratio", "ρ_RHI / ρ_PHANToM [1]")


def configurations(result: Result) -> Figure:
    """Table 3.1 set-up: the three interfaces at the two points with their velocity ellipses (scaled ×0.3)."""
    from rhi.experiments.ch3.measures import POINTS, devices  # data access only

    devs = devices()
    fig, axes = plt.subplots(1, 2, figsize=(10, 5), sharey=True)
    for i, ax in enumerate(axes):
        for (nm, dev), color in zip(devs.items(), ("C0", "C1", "C2")):
            q = result.arrays[f"q_opt_{i}"] if nm == "RHI" else result.arrays[f"q_{nm}_{i}"]
            chain(ax, dev.skeleton(q)[:, :2], color=color, label=nm)
            J = dev.jacobian(q)
            ellipse(ax, POINTS[i], J @ J.T, scale=0.3, color=color, lw=1)
        ax.set(xlabel="x [m]", aspect="equal", title=f"point {POINTS[i]}")
    axes[0].set_ylabel("y [m]")
    axes[0].legend()
    return fig


def apparent_inertia(result: Result) -> Figure:
    """Figs 3.2–3.3: |A1(jω)| (eq. 3.17) and |A2(jω)| (eq. 3.19) of the drawn case, with MuJoCo's measured points."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(a["omega"], a["a1"], label="1-DoF, eq. 3.17")
    ax.loglog(a["omega"], a["a2"], label="redundant 2-DoF, eq. 3.19")
    ax.loglog(a["sim_omega"], a["sim_a1"], "o", color="C0", label="1-DoF, MuJoCo")
    ax.loglog(a["sim_omega"], a["sim_a2"], "s", color="C1", label="2-DoF, MuJoCo")
    ax.set_xlabel("ω [rad/s]")
    ax.set_ylabel("|F_h / (s² X1)| [kg]")
    ax.legend()
    ax.set_title("Apparent inertia, eqs. 3.17 and 3.19")
    return fig
