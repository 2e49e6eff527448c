"""Figures of the simulated identification and psychophysics experiments (Tables 3.2, 3.3, 6.1; Figs 3.9–3.10).

From the results of `rhi.experiments.ch3.identification`, `ch3.discrimination` and `ch6.identification`.

- `sysid_fit`: one identification trial per case (position, velocity along u) and the
  identified Λ beside eq. 3.13 and the thesis (Tables 3.2 / 6.1).
- `psychometric_curves`: Fig. 3.9, positive fraction and fitted curves of one subject per
  device, with the ideal observer.
- `wf_jnd_boxes`: Fig. 3.10, WF and JND per device (box: median in red, mean as a green circle).
- `perceived_stiffness`: K̂ of the lookup per device against the rendered stiffness and stroke duration.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.errors import InvalidInput
from rhi.experiments.result import Result

_DEVICES = ("RHI", "PHANToM", "Rehab")
_COLORS = {"RHI": "tab:blue", "PHANToM": "tab:orange", "Rehab": "tab:green"}


def _need(result: Result, *keys: str) -> None:
    missing = [k for k in keys if k not in result.arrays]
    if missing:
        raise InvalidInput(f"result: {result.name!r} lacks the arrays {missing} this figure draws")


def sysid_fit(result: Result) -> Figure:
    """Tables 3.2 / 6.1: identified Λ with 95 % CIs beside eq. 3.13 and the thesis, plus a trial's motion.

    Accepts the results of `sysid_table_3_2` and `sysid_table_6_1`.
    """
    a = result.arrays
    if result.name.endswith("table_3_2"):
        keys = [f"{d}_{i}" for i in range(2) for d in _DEVICES]
        labels = [f"{d}\npoint {i + 1}" for i in range(2) for d in _DEVICES]
        thesis = list(a["lambda_thesis"].reshape(-1)) if "lambda_thesis" in a else [np.nan] * len(keys)
    else:
        keys = ["free", "stiff"]
        labels = ["M_Free^des", "M_Stiff^des"]
        from rhi.experiments.ch6.identification import THESIS_TABLE_6_1

        thesis = [THESIS_TABLE_6_1[k][0] for k in keys]
    _need(result, *(f"{k}_fit" for k in keys))
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12, 4.2))
    pos = np.arange(len(keys))
    ident = np.array([a[f"{k}_fit"][0] for k in keys])
    ci = np.array([a[f"{k}_ci"][0] for k in keys])
    model = np.array([a[f"{k}_model"][0] for k in keys])
    ax0.bar(pos - 0.27, ident, 0.27, yerr=np.abs(ci.T - ident), capsize=3, label="identified (simulated plant)")
    ax0.bar(pos, model, 0.27, label="eq. 3.13 (our model)")
    ax0.bar(pos + 0.27, thesis, 0.27, label="thesis (hardware)")
    ax0.set_xticks(pos, labels, fontsize=8)
    ax0.set(ylabel="Λ along u [kg]", yscale="log", title="Identified apparent inertia")
    ax0.legend(fontsize=8)
    for k, lab in zip(keys, labels):
        t, x = a[f"{k}_t"], a[f"{k}_x"]
        ax1.plot(t, np.gradient(x, t), label=lab.replace("\n", " "))
    ax1.set(xlabel="t [s]", ylabel="ẋ along u [m/s]", title="First trial of each case (FK of the encoders)")
    ax1.legend(fontsize=7)
    fig.suptitle(result.title, fontsize=10)
    fig.tight_layout()
    return fig


def psychometric_curves(result: Result) -> Figure:
    """Fig. 3.9: positive fraction of one subject per device, fitted psychometric functions and the ideal observer."""
    _need(result, "stiffness_grid", "fig39_ideal")
    a = result.arrays
    grid = a["stiffness_grid"]
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for d in _DEVICES:
        if f"fig39_data_{d}" not in a:
            continue
        data = a[f"fig39_data_{d}"]
        ax.plot(data[:, 0], data[:, 1] / data[:, 2], "o", color=_COLORS[d], label=f"{d} data")
        ax.plot(grid, a[f"fig39_curve_{d}"], "-", color=_COLORS[d], label=f"{d} fit")
    ax.plot(grid, a["fig39_ideal"], "k--", label="ideal")
    subj = f"S{int(a['fig39_subject']):02d}" if "fig39_subject" in a else "?"
    ax.set(xlabel="comparison stiffness [N/m]", ylabel="positive fraction (comparison stiffer)",
           title=f"Fig. 3.9 simulated subject {subj}", ylim=(-0.03, 1.03))
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def wf_jnd_boxes(result: Result) -> Figure:
    """Fig. 3.10: WF (a) and JND (b) per device; median red line, mean green circle."""
    _need(result, "wf", "jnd")
    a = result.arrays
    devs = list(_DEVICES)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, key, lab in zip(axes, ("wf", "jnd"), ("(a) WF", "(b) JND [N/m]")):
        vals = np.asarray(a[key], dtype=float)
        ax.boxplot(list(vals), medianprops={"color": "red"})
        ax.set_xticks(np.arange(1, len(devs) + 1), devs)
        ax.plot(np.arange(1, len(devs) + 1), vals.mean(axis=1), "o", color="green", label="mean")
        ax.set(title=lab)
        ax.legend(fontsize=8)
    fig.suptitle("Fig. 3.10 simulated subjects", fontsize=10)
    fig.tight_layout()
    return fig


def perceived_stiffness(result: Result) -> Figure:
    """K̂ (what the observer perceives) against the rendered stiffness, per device and stroke duration."""
    _need(result, "stiffness", "durations")
    a = result.arrays
    K, T = a["stiffness"], a["durations"]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharey=True)
    for ax, d in zip(axes, _DEVICES):
        if f"khat_{d}" not in a:
            continue
        kh = a[f"khat_{d}"]
        for j, dur in enumerate(T):
            ax.plot(K, kh[:, j], "o-", ms=3, label=f"T = {dur:g} s")
        ax.plot(K, K, "k--", lw=0.8, label="transparent")
        ax.set(title=d, xlabel="rendered K [N/m]")
    axes[0].set_ylabel("perceived K̂ [N/m]")
    axes[-1].legend(fontsize=7)
    fig.tight_layout()
    return fig
