"""Figures of chapter 4 (Figs 4.4–4.7 and the θz sweep) from `rhi.experiments.ch4` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result
from rhi.plots.draw import ellipse

SCALE = 0.15  # ellipse drawing scale [m per (m/s per rad/s)]


def _ellipses(result: Result, title: str) -> Figure:
    fig, axes = plt.subplots(1, 2, figsize=(10, 5), sharey=True)
    pts = result.arrays["ellipse_points"]
    for ax, which in zip(axes, ("C1", "C2")):
        for k, p in enumerate(pts):
            for key, style in (("master", dict(color="C0", lw=1)), ("slave", dict(color="C1", lw=1)),
                               ("tme", dict(color="k", lw=2))):
                A = result.arrays[f"ell_{which}_{key}"][k]
                ellipse(ax, p, A, scale=SCALE, label=key if k == 0 else None, **style)
        x = np.rad2deg(result.arrays[f"x_{which}"])
        ax.set(title=f"{which} optimum (θz = {x[-1] if x.size == 1 else x[1]:.1f}°)", xlabel="x [m]", aspect="equal")
        ax.legend(["HI ME", "slave ME", "TME"], loc="upper right")
    axes[0].set_ylabel("y [m]")
    fig.suptitle(title)
    return fig


def fig4_4(result: Result) -> Figure:
    """Fig. 4.4: MEs of the HI, the slave and the TME at six points, θz optima of C1 and C2."""
    return _ellipses(result, "Fig. 4.4 — D = {θz} (ellipses ×0.15)")


def theta_sweep(result: Result) -> Figure:
    """C1, C2, GM_T and GM_M against θz (the landscape behind the θz optima)."""
    a = result.arrays
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    ax1.plot(a["theta_deg"], a["sweep_C1"], label="C1")
    ax1.plot(a["theta_deg"], a["sweep_C2"], label="C2")
    ax1.set(ylabel="cost [1]")
    ax1.legend()
    ax2.plot(a["theta_deg"], a["sweep_GM_T"], label="GM_T")
    ax2.plot(a["theta_deg"], a["sweep_GM_M"], label="GM_M")
    ax2.set(xlabel="θz [deg]", ylabel="index [m²/s²·(s/rad)²]")
    ax2.legend()
    return fig


def fig4_5(result: Result) -> Figure:
    """Fig. 4.5: MEs at six points, D = {l2, θz, Z_PH}."""
    return _ellipses(result, "Fig. 4.5 — D = {l2, θz, Z_PH} (ellipses ×0.15)")


def fig4_6(result: Result) -> Figure:
    """Fig. 4.6: the TMI over the slave workspace at the C1 and C2 optima."""
    pts = result.arrays["workspace"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.5), sharey=True)
    vmax = max(result.arrays["tmi_C1"].max(), result.arrays["tmi_C2"].max())
    for ax, which in zip(axes, ("C1", "C2")):
        sc = ax.scatter(pts[:, 0], pts[:, 1], c=result.arrays[f"tmi_{which}"], s=12, marker="s", vmin=0, vmax=vmax)
        ax.set(title=f"Fig. 4.6 TMI λ, {which} optimum", xlabel="x [m]", aspect="equal")
    axes[0].set_ylabel("y [m]")
    fig.colorbar(sc, ax=axes, label="λ = σ₁σ₂ [m²/s² per (rad/s)²]")
    return fig


def fig4_7(result: Result) -> Figure:
    """Fig. 4.7: ‖q̇‖² moving the slave from A to B at 0.01 m/s for each design."""
    fig, ax = plt.subplots(figsize=(6, 4))
    from rhi.experiments.ch4.setup import ENERGY_LABELS

    for i, lab in enumerate(ENERGY_LABELS):
        ax.plot(result.arrays["energy_t"], result.arrays[f"energy_{i}"], label=str(lab))
    ax.set(xlabel="t [s]", ylabel="‖q̇‖² (eq. 4.22) [(rad/s)²]", title="Fig. 4.7 joint energy A → B")
    ax.legend()
    return fig


def convergence(result: Result) -> Figure:
    """Indices at θz = 2° against the sampling density."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(5, 4))
    for k in ("GM_T", "GM_M"):
        ax.plot(a["densities"], a[f"conv_{k}"] / a[f"conv_{k}"][-1], "o-", label=k)
    ax.set(xscale="log", xlabel="sampling density [1/m]", ylabel="index / finest [1]", title="sampling convergence")
    ax.legend()
    return fig


def k2_scan(result: Result) -> Figure:
    """The full design's optima against K2/K1 (from `rhi.experiments.ch4.sensitivity`): l2 and GM_T of C1 and C2.

    The dotted line is the smallest K2/K1 consistent with Table 4.1 (`ch4.K2_MIN_TABLE_4_1`).
    """
    from rhi.experiments.ch4.setup import K2_MIN_TABLE_4_1

    a = result.arrays
    k = a["k2_values"]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    ax1.plot(k, a["k2_l2_C1"], "o-", label="C1")
    ax1.plot(k, a["k2_l2_C2"], "s-", label="C2")
    ax1.set(ylabel="l2 at the optimum [m]")
    ax1.legend()
    ax2.plot(k, a["k2_GM_T_C1"], "o-", label="C1")
    ax2.plot(k, a["k2_GM_T_C1_mirror"], "o:", label="C1, mirror (−θz)")
    ax2.plot(k, a["k2_GM_T_C2"], "s-", label="C2")
    ax2.set(xlabel="K2/K1 [1]", ylabel="GM_T at the optimum [m²/s²·(s/rad)²]")
    ax2.legend()
    for ax in (ax1, ax2):
        ax.axvline(K2_MIN_TABLE_4_1, color="k", ls=":", lw=1)
    fig.suptitle("Table 4.1 optima vs K2/K1 (dotted: Table 4.1's lower bound)")
    return fig


def l2_scan(result: Result) -> Figure:
    """Best GM_T over (θz, Z_PH) against l2 (from `rhi.experiments.ch4.full_design`)."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(a["l2_scan"], a["l2_scan_GM_T"], "o-")
    ax.set(xlabel="l2 [m]", ylabel="max GM_T over (θz, Z_PH) [m²/s²·(s/rad)²]", title="GM_T rises with the HI's last link")
    return fig
