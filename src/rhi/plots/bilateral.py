"""Figures of delayed bilateral teleoperation (`rhi.experiments.beyond.bilateral`): energy, forces, drift."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result


def _keys(result: Result) -> list[str]:
    return [k[:-2] for k in result.arrays if k.endswith("_t")]


def drift(result: Result) -> Figure:
    """The slave set-point's drift from the master's position vs time, per delay, with the TDPA."""
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for key in _keys(result):
        d, k, pc = key.split("_")
        if pc == "tdpa" and f"{key}_drift" in result.arrays:
            ax.plot(result.arrays[f"{key}_t"], 1e3 * np.linalg.norm(result.arrays[f"{key}_drift"], axis=1), lw=1.2,
                    label=f"{d}, {k} N/m")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("set-point drift [mm]")
    ax.set_title("TDPA drift, compensated once the hand leaves the tissue", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return fig


def energy(result: Result) -> Figure:
    """Energy the teleoperator handed the hand and the tissue (measured) vs time, without (dashed) and with the TDPA."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for key in _keys(result):
        d, k, pc = key.split("_")
        ax.plot(result.arrays[f"{key}_t"], 1e3 * result.arrays[f"{key}_generated"], "-" if pc == "tdpa" else "--",
                lw=1.2, label=f"{d}, {k} N/m, {'TDPA' if pc == 'tdpa' else 'none'}")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("energy handed out, −(W_hand + W_env) [mJ]")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return fig


def forces(result: Result) -> Figure:
    """Contact force at the slave and force rendered on the hand at the longest delay, without and with the TDPA."""
    cases = [k.split("_") for k in _keys(result)]  # [delay "50ms", stiffness "1000", "none" | "tdpa"]
    delay = max((c[0] for c in cases), key=lambda d: int(d[:-2]))
    stiffness = min((c[1] for c in cases if c[0] == delay), key=lambda k: abs(int(k) - 1000))
    keys = ["_".join(c) for c in cases if c[0] == delay and c[1] == stiffness]
    fig, axes = plt.subplots(len(keys), 1, figsize=(6.4, 2.6 * len(keys)), sharex=True, squeeze=False)
    for ax, key in zip(axes[:, 0], keys, strict=True):
        a = result.arrays
        ax.plot(a[f"{key}_t"], np.linalg.norm(a[f"{key}_F_e"], axis=1), "k-", lw=1, label="|F_e| at the slave")
        ax.plot(a[f"{key}_t"], np.linalg.norm(a[f"{key}_F_m"], axis=1), "r-", lw=0.8, label="|F_m| on the hand")
        ax.set_ylabel("force [N]")
        ax.set_title(key.replace("_", ", ").replace("tdpa", "TDPA").replace("none", "no passivity control"), fontsize=9)
        ax.legend(fontsize=8)
    axes[-1, 0].set_xlabel("time [s]")
    fig.tight_layout()
    return fig
