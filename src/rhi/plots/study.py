"""Figures of a study with people (`rhi study analyze`): psychometric curves per participant, measures per condition.

From the `Result` of `rhi.report.study.study_result`: ``curve_grid`` (g,) and, per participant p and condition
c, ``data/p/c`` ((k, 3) psignifit rows: level, stiffer, trials) and ``curve/p/c`` (g,) the fitted function;
``values/<measure>`` (conditions, participants) and ``conditions`` (the condition names, in order).
"""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.errors import InvalidInput
from rhi.experiments.result import Result


def _conditions(result: Result) -> list[str]:
    if "conditions" not in result.arrays:
        raise InvalidInput(f"result: {result.name!r} lacks the array 'conditions' these figures draw")
    return [str(c) for c in np.asarray(result.arrays["conditions"]).tolist()]


def psychometric_curves(result: Result) -> Figure:
    """Positive fraction and the fitted psychometric function of every participant, one panel each."""
    conds = _conditions(result)
    a = result.arrays
    subjects = sorted({k.split("/")[1] for k in a if k.startswith("curve/")})
    if not subjects:
        raise InvalidInput(f"result: {result.name!r} holds no fitted curves")
    cols = min(4, len(subjects))
    rows = math.ceil(len(subjects) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False, sharey=True)
    grid = a["curve_grid"]
    for ax, s in zip(axes.ravel(), subjects):
        for i, c in enumerate(conds):
            if f"curve/{s}/{c}" not in a:
                continue
            d = a[f"data/{s}/{c}"]
            ax.plot(d[:, 0], d[:, 1] / d[:, 2], "o", color=f"C{i}", ms=3)
            ax.plot(grid, a[f"curve/{s}/{c}"], "-", color=f"C{i}", label=c)
        ax.set(title=s, ylim=(-0.03, 1.03))
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[len(subjects):]:
        ax.axis("off")
    axes[0, 0].legend(fontsize=7)
    fig.supxlabel("comparison stimulus")
    fig.supylabel("positive fraction (comparison stiffer)")
    fig.tight_layout()
    return fig


def by_condition(result: Result) -> Figure:
    """Every measure per condition: a box per condition, one line per participant, the mean as a green circle."""
    conds = _conditions(result)
    keys = sorted(k for k in result.arrays if k.startswith("values/"))
    if not keys:
        raise InvalidInput(f"result: {result.name!r} holds no per-condition values")
    fig, axes = plt.subplots(1, len(keys), figsize=(4 * len(keys), 3.8), squeeze=False)
    pos = np.arange(1, len(conds) + 1)
    for ax, k in zip(axes[0], keys):
        v = np.asarray(result.arrays[k], dtype=float)  # (conditions, participants)
        ax.boxplot(list(v), medianprops={"color": "red"})
        ax.plot(pos, v, "-", color="0.75", lw=0.8)
        ax.plot(pos, v.mean(axis=1), "o", color="green", label="mean")
        ax.set_xticks(pos, conds)
        ax.set(title=k.split("/", 1)[1])
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    return fig
