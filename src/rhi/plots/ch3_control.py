"""Figures of the simulated chapter-3 null-space controller (`rhi.experiments.ch3.nullspace` results)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.devices.model import device
from rhi.experiments.result import Result
from rhi.plots.draw import chain, ellipse


def _runs(result: Result) -> list[str]:
    """Run keys ``p{i}_{start}_{variant}`` present in the result, in a stable order."""
    return sorted(k[: -len("_nu")] for k in result.arrays if k.endswith("_nu"))


def _points(result: Result) -> list[int]:
    return sorted({int(r.split("_")[0][1:]) for r in _runs(result)})


def _label(run: str) -> str:
    _, start, variant = run.split("_", 2)
    return f"{start} start, " + ("barrier" if variant == "barrier" else "eq. 3.21 alone (stops)")


def convergence(result: Result) -> Figure:
    """JBLD cost ν(t) (eq. 3.22) and handle drift |x − x₀| per run, one column per Table 3.1 point."""
    a = result.arrays
    pts = _points(result)
    fig, axes = plt.subplots(2, len(pts), figsize=(5.5 * len(pts), 6), squeeze=False, sharex=True)
    for c, i in enumerate(pts):
        top, bot = axes[0, c], axes[1, c]
        for run in (r for r in _runs(result) if r.startswith(f"p{i}_")):
            style = "-" if run.endswith("barrier") else "--"
            top.plot(a[f"{run}_t"], a[f"{run}_nu"], style, label=_label(run))
            bot.plot(a[f"{run}_t"], 1e3 * a[f"{run}_drift"], style, label=_label(run))
        x = a[f"{next(r for r in _runs(result) if r.startswith(f'p{i}_'))}_point"]
        top.set(title=f"point ({x[0]:g}, {x[1]:g}) m", ylabel="ν (JBLD, eq. 3.22) [1]")
        bot.axhline(0.5, color="k", lw=0.8, ls=":", label="0.5 mm bound")
        bot.set(xlabel="t [s]", ylabel="handle drift [mm]", yscale="log")
        top.legend(fontsize=7)
        bot.legend(fontsize=7)
    fig.suptitle("Null-space VME matching on the simulated rhi4 (hand holding the handle)")
    fig.tight_layout()
    return fig


def configurations(result: Result) -> Figure:
    """The RHI at its start (thin) and converged (thick) configurations, with the velocity ellipse JJᵀ (×0.3)."""
    dev = device("rhi4")
    a = result.arrays
    pts = _points(result)
    fig, axes = plt.subplots(1, len(pts), figsize=(5.5 * len(pts), 5), squeeze=False, sharey=True)
    for c, i in enumerate(pts):
        ax = axes[0, c]
        runs = [r for r in _runs(result) if r.startswith(f"p{i}_")]
        for k, run in enumerate(runs):
            color = f"C{k}"
            chain(ax, dev.skeleton(a[f"{run}_q_start"])[:, :2], color=color, alpha=0.35, lw=1)
            q = a[f"{run}_q_end"]
            chain(ax, dev.skeleton(q)[:, :2], color=color, lw=2.5, label=_label(run))
            J = dev.jacobian(q)
            ellipse(ax, a[f"{run}_point"], J @ J.T, scale=0.3, color=color, lw=1)
        if f"p{i}_q_slsqp" in a:
            static = dev.skeleton(a[f"p{i}_q_slsqp"])[:, :2]
            ax.plot(static[:, 0], static[:, 1], ":o", ms=2, color="k", lw=1, label="static optimum of eq. 3.22 (SLSQP)")
        x = a[f"{runs[0]}_point"]
        ax.set(xlabel="x [m]", aspect="equal", title=f"point ({x[0]:g}, {x[1]:g}) m")
        ax.legend(fontsize=7, loc="upper left")
    axes[0, 0].set_ylabel("y [m]")
    fig.tight_layout()
    return fig


def drift_hist(result: Result) -> Figure:
    """Largest handle drift per run beside the 0.5 mm bound (bar chart)."""
    a = result.arrays
    runs = _runs(result)
    vals = [1e3 * float(np.max(a[f"{r}_drift"])) for r in runs]
    fig, ax = plt.subplots(figsize=(max(4, 1.2 * len(runs)), 3.5))
    ax.bar(range(len(runs)), vals, color=["C0" if r.endswith("barrier") else "C3" for r in runs])
    ax.axhline(0.5, color="k", ls=":", lw=1)
    ax.set_xticks(range(len(runs)), runs, rotation=30, ha="right", fontsize=7)
    ax.set(ylabel="max drift [mm] (sampled every 10 ms)")
    fig.tight_layout()
    return fig
