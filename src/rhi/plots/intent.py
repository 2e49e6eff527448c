"""Figures of "Beyond the thesis: intent estimation" from `rhi.experiments.beyond.intent` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
from matplotlib.figure import Figure

from rhi.experiments.result import Result

_STYLE = {"known": "k-", "filtered": "tab:blue", "hmm": "tab:red", "fixed": "tab:gray"}


def strokes(result: Result) -> Figure:
    """Axial error of the two estimators along the first 20 s of the 2-D and 3-D test strokes."""
    a = result.arrays
    fig, axes = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    for ax, m in zip(axes, (2, 3)):
        t = a[f"t_{m}d"]
        sel = t <= 20.0
        for name in ("filtered", "hmm"):
            ax.plot(t[sel], a[f"err_{m}d_{name}"][sel], color=_STYLE[name], lw=0.8, label=name)
        ax.fill_between(t[sel], 0, 90, where=a[f"moving_{m}d"][sel], color="0.9", step="mid", label="moving")
        ax.set(ylabel="axial error [deg]", title=f"{m}-D strokes", ylim=(0, 90))
        ax.legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    return fig


def _panels(result: Result, left: str, left_label: str) -> Figure:
    a = result.arrays
    keys = [k for k in _STYLE if f"{k}_t" in a]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for k in keys:
        axes[0].plot(a[f"{k}_t"], a[f"{k}_{left}"], color=_STYLE[k][:-1] if k == "known" else _STYLE[k], label=k)
        if k != "known":
            axes[1].plot(a[f"{k}_t"], a[f"{k}_err"], color=_STYLE[k], label=k)
    axes[0].set(xlabel="t [s]", ylabel=left_label)
    axes[1].set(xlabel="t [s]", ylabel="axial error of u [deg]", ylim=(0, 92))
    for ax in axes:
        ax.legend(fontsize=8)
    fig.suptitle(result.title)
    fig.tight_layout()
    return fig


def w_trajectory(result: Result) -> Figure:
    """User work (eq. 5.15) and the estimators' axial error along the W."""
    return _panels(result, "work", "user work W(t) [J]")


def palpation(result: Result) -> Figure:
    """Rendered force along u and the estimators' axial error during the palpation."""
    return _panels(result, "force", "force along u [N]")
