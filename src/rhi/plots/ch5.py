"""Figures of chapter 5 (Figs 5.3–5.6) from `rhi.experiments.ch5` results."""

from __future__ import annotations

from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result
from rhi.plots.draw import chain, ellipse

SCALE = 0.15  #: ellipse drawing scale [m per (m/s per rad/s)]
_STYLE = {"master": dict(color="C0", lw=1.2), "slave": dict(color="C3", lw=1.2), "tme": dict(color="k", lw=2.0)}
_LABEL = {"master": "HI ME", "slave": "slave ME", "tme": "TME"}
_SCEN: dict[str, tuple[str, dict[str, Any]]] = {"s1": ("scenario 1: RHI + TMI", dict(color="C0", ls="-")),
         "s2": ("scenario 2: RHI + Yoshikawa μ", dict(color="C3", ls="--")),
         "s3": ("scenario 3: 2-DoF Rehab", dict(color="C2", ls=":"))}


def _ellipses(ax, center, mats: dict[str, np.ndarray], scale: float = SCALE, label: bool = True) -> None:
    for key, A in mats.items():
        ellipse(ax, center, A, scale=scale, label=_LABEL[key] if label else None, **_STYLE[key])


def fig5_3(result: Result) -> Figure:
    """Fig. 5.3: HI (blue) and slave (red) with their MEs and the TME, (a) initial, (b) evolution (grey) and final."""
    a = result.arrays
    x0 = a["x0"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.5), sharex=True, sharey=True)
    for ax, when in zip(axes, ("0", "T")):
        if when == "T":
            for sk in a["skel_frames"][1:-1]:
                ax.plot(sk[:, 0], sk[:, 1], "-", color="0.75", lw=1)
        chain(ax, a["skel_slave"], color="C3", label="slave")
        chain(ax, a[f"skel_master_{when}"], color="C0", label="HI")
        _ellipses(ax, x0, {"master": a[f"ell_master_{when}"], "slave": a["ell_slave"], "tme": a[f"tme_{when}"]})
        ax.set(xlabel="x [m]", aspect="equal",
               title="(a) initial configuration" if when == "0" else "(b) evolution (grey) and final configuration")
    axes[0].set_ylabel("y [m]")
    axes[0].legend(loc="upper left", fontsize=8)
    fig.suptitle(f"Fig. 5.3 — TME at (0.48, −0.35) m (ellipses ×{SCALE})")
    fig.tight_layout()
    return fig


def fixed_point_convergence(result: Result) -> Figure:
    """TME area λ and the objective ν of eq. 5.11 against time at the fixed point."""
    a = result.arrays
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6, 5), sharex=True)
    ax1.plot(a["t"], a["tmi"], "k-")
    ax1.set(ylabel="TME area λ = σ₁σ₂ [m²/s² per (rad/s)²]")
    ax2.plot(a["t"], a["nu"], "C0-")
    ax2.set(xlabel="t [s]", ylabel="ν (eq. 5.11) [1]")
    fig.suptitle("Fixed point: convergence of the TMI null-space controller")
    fig.tight_layout()
    return fig


def fig5_4(result: Result) -> Figure:
    """Fig. 5.4: workspaces of the RHI (blue), the 2-DoF Rehab (red), the slave (green) and the W (black)."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(5.5, 7))
    labels, colors = ("RHI", "2-DoF Rehab", "slave"), ("C0", "C3", "C2")
    for i in (2, 0, 1):  # slave below, the Rehab (inside the RHI's) on top
        pts = a["workspaces"][i]
        ax.plot(pts[:, 0], pts[:, 1], ".", ms=1, alpha=0.25, color=colors[i], label=labels[i])
    ax.plot(a["path"][:, 0], a["path"][:, 1], "k-", lw=2, label="reference W")
    ax.set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title="Fig. 5.4 workspaces and the W")
    ax.legend(markerscale=8, loc="upper left", fontsize=8)
    return fig


def fig5_5(result: Result) -> Figure:
    """Fig. 5.5: MEs of the HI, the slave and the TME along the W, per scenario."""
    a = result.arrays
    # scale the ellipses to about half the spacing of the points they sit on
    P = a["path"]
    length = float(np.sum(np.linalg.norm(np.diff(P, axis=0), axis=1)))
    biggest = max(float(np.sqrt(np.linalg.eigvalsh(a[f"{k}_ell_{w}"]).max()))
                  for k in _SCEN for w in ("master", "slave"))
    scale = 0.5 * length / max(1, len(a["s1_ell_points"]) - 1) / biggest
    fig, axes = plt.subplots(1, 3, figsize=(15, 6), sharex=True, sharey=True)
    for ax, (key, (title, _)) in zip(axes, _SCEN.items()):
        ax.plot(a["path"][:, 0], a["path"][:, 1], "k-", lw=1, alpha=0.5)
        ax.plot(a[f"{key}_slave_x"][:, 0], a[f"{key}_slave_x"][:, 1], "-", color="0.6", lw=1)
        for i, p in enumerate(a[f"{key}_ell_points"]):
            _ellipses(ax, p, {"master": a[f"{key}_ell_master"][i], "slave": a[f"{key}_ell_slave"][i],
                              "tme": a[f"{key}_ell_tme"][i]}, scale=scale, label=i == 0)
        ax.set(title=title, xlabel="x [m]", aspect="equal")
    axes[0].set_ylabel("y [m]")
    axes[0].legend(loc="upper left", fontsize=8)
    fig.suptitle(f"Fig. 5.5 — manipulability ellipsoids along the W (×{scale:.3g})")
    fig.tight_layout()
    return fig


def _per_scenario(result: Result, key: str, ylabel: str, title: str) -> Figure:
    """`key` ("work", "area") against time along the W, one line per scenario."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for scen, (label, style) in _SCEN.items():
        t, v = a[f"{scen}_t"], a[f"{scen}_{key}"]
        keep = t >= 0
        ax.plot(t[keep], v[keep], label=label, **style)
    ax.set(xlabel="t [s] (from the start of the W)", ylabel=ylabel, title=title)
    ax.legend()
    fig.tight_layout()
    return fig


def fig5_6(result: Result) -> Figure:
    """Fig. 5.6: the user's work W(t) = ∫F_hᵀẋ dt (eq. 5.15) along the W, per scenario."""
    return _per_scenario(result, "work", "user work W [J]", "Fig. 5.6 user effort")


def tme_along_w(result: Result) -> Figure:
    """TME area λ = σ₁σ₂ against time along the W, per scenario."""
    return _per_scenario(result, "area", "TME area λ = σ₁σ₂", "TME along the W")
