"""Figures of the passivity experiments (`rhi.experiments.beyond.passivity`, `.zwidth`): energy, force, chatter, Z-width."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.beyond.passivity import CASES
from rhi.experiments.result import Result

_NAMES = {
    "objectives": "objectives, no PC",
    "objectives_pc": "objectives, PC: damper + bounding (motors)",
    "objectives_damper": "objectives, damper only (motors)",
    "objectives_bounding": "objectives, bounding only (motors)",
    "objectives_tank": "objectives on the null-space tank, no PC",
    "objectives_tank_damper": "objectives on the null-space tank, damper (motors)",
    "bare": "no objectives, no PC",
    "bare_pc": "no objectives, PC (motors)",
    "objectives_pc_handle": "objectives, PC (handle port)",
    "scaling": "objectives, force scaling, no PC",
    "passive": "passive null space, tank full at start, no PC",
    "passive_empty": "passive null space, tank empty at start, no PC",
}


def _cases(result: Result, prefix: str = "") -> list[str]:
    return [c for c in CASES if f"{prefix}{c}_t" in result.arrays]


def energy(result: Result) -> Figure:
    """The hand's work W(t) = ∫F_hᵀẋ dt per case (below zero: energy the device gave the hand) and E_obs."""
    a = result.arrays
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    for k, c in enumerate(_cases(result)):
        ax.plot(a[f"{c}_t"], a[f"{c}_W"], color=f"C{k}", lw=1.1, label=_NAMES[c])
        if np.isfinite(a[f"{c}_E_obs"]).any():
            ax2.plot(a[f"{c}_t"], 1e3 * a[f"{c}_E_obs"], color=f"C{k}", lw=1.0, label=_NAMES[c])
    ax.axhline(-1e-3, color="k", ls=":", lw=0.8, label="−1 mJ")
    ax.set(xlabel="t [s]", ylabel="W [J]", title=f"Hand's work palpating {float(a['stiffness']):g} N/m")
    ax.legend(fontsize=7)
    ax2.axhline(0.0, color="k", ls=":", lw=0.8)
    ax2.set(xlabel="t [s]", ylabel="E_obs [mJ]", title="Passivity observer (motor port: ≥ 0 passive)")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    return fig


def force(result: Result) -> Figure:
    """Rendered force along u against the wall K_e δX, without and with the passivity controller (its methods)."""
    a = result.arrays
    cases = [c for c in ("objectives", "objectives_pc", "objectives_damper", "passive", "bare", "bare_pc")
             if f"{c}_t" in a]
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for k, c in enumerate(cases):
        ax.plot(1e3 * a[f"{c}_pen"], a[f"{c}_F"], ".", ms=1.5, color=f"C{k}", label=_NAMES[c])
    p = np.linspace(0.0, 1e3 * max(float(np.max(a[f"{c}_pen"])) for c in cases), 50)
    ax.plot(p, float(a["stiffness"]) * p / 1e3, "k--", lw=1, label="K_e δX")
    ax.set(xlabel="penetration δX [mm]", ylabel="force along u [N]", title="What passivity costs in force")
    ax.legend(fontsize=7, markerscale=6)
    fig.tight_layout()
    return fig


def chatter(result: Result) -> Figure:
    """Handle velocity along u at the stiff wall without and with the passivity controller."""
    a = result.arrays
    cases = _cases(result, "stiff_")
    fig, axes = plt.subplots(len(cases), 1, figsize=(8, 2.4 * max(len(cases), 1)), sharex=True, squeeze=False)
    for ax, c in zip(axes[:, 0], cases):
        ax.plot(a[f"stiff_{c}_t"], 1e3 * a[f"stiff_{c}_xdot"], lw=0.7)
        ax.set(ylabel="ẋ·u [mm/s]", title=f"{float(a.get('stiff', np.nan)):g} N/m, {_NAMES[c]}")
    axes[-1, 0].set_xlabel("t [s]")
    fig.tight_layout()
    return fig


def z_width(result: Result) -> Figure:
    """Colgate and Brown's Z-width per passivity method: walls (K, B) rendered passively at 1 kHz, and the peak force."""
    a = result.arrays
    K, B = a["stiffness"], a["damping"]
    methods = [m for m in ("none", "damper_bounding", "damper", "bounding") if f"{m}_W_min" in a]
    fig, axes = plt.subplots(1, len(methods), figsize=(3.4 * len(methods), 3.6), sharey=True, squeeze=False)
    kk, bb = np.meshgrid(np.arange(len(K)), np.arange(len(B)), indexing="ij")
    for ax, m in zip(axes[0], methods):
        passive = a[f"{m}_W_min"] >= -1e-3
        ax.scatter(kk[passive], bb[passive], s=160, marker="o", color="tab:green", label="passive")
        ax.scatter(kk[~passive], bb[~passive], s=160, marker="x", color="tab:red", label="active")
        for i in range(len(K)):
            for j in range(len(B)):
                ax.annotate(f"{a[f'{m}_peak'][i, j]:.1f}", (i, j), textcoords="offset points", xytext=(0, 9),
                            ha="center", fontsize=6)
        ax.set_xticks(range(len(K)), [f"{k / 1e3:g}" for k in K], fontsize=7)
        ax.set_yticks(range(len(B)), [f"{b:g}" for b in B], fontsize=7)
        ax.set(xlabel="K [kN/m]", title=_ZW_NAMES[m])
        ax.set_xlim(-0.5, len(K) - 0.5)
        ax.set_ylim(-0.5, len(B) - 0.3)
    axes[0, 0].set_ylabel("B [N s/m]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="upper right", ncol=2, markerscale=0.6)
    fig.suptitle("Z-width of rhi4 at 1 kHz (numbers: peak force [N])", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    return fig


_ZW_NAMES = {"none": "no PC", "damper_bounding": "damper + energy bounding", "damper": "series damper only",
             "bounding": "energy bounding only"}
