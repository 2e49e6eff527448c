"""Figures of the simulated §7.5 palpation (`rhi.experiments.ch7.contact`): Fig. 7.6, force vs penetration."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result

_NAMES = {"none": "no compensation", "scaling": "simple scaling", "ascm": "ASCM", "lp": "LP optimum"}


def _cases(result: Result) -> list[str]:
    """Case keys ``{saturation}_{projector}`` in the order they were simulated (dynamic first)."""
    keys = [k[: -len("_events")] for k in result.arrays if k.endswith("_events")]
    return sorted(keys, key=lambda k: (k.split("_")[1] != "dynamic", list(_NAMES).index(k.split("_")[0])))


def _title(key: str) -> str:
    sat, proj = key.split("_")
    return f"{_NAMES[sat]} ({'J#' if proj == 'dynamic' else 'J⁺'})"


def fig7_6(result: Result) -> Figure:
    """Fig. 7.6: desired force K_e δX (dashed), measured F/T force (solid) and joint torques τ_i (dotted) per case."""
    a = result.arrays
    cases = _cases(result)
    ncol = min(3, len(cases))
    nrow = -(-len(cases) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.6 * nrow), squeeze=False, sharey=True)
    for ax in axes.flat[len(cases):]:
        ax.set_visible(False)
    tmax = a["torque_max"]
    for ax, key in zip(axes.flat, cases):
        t = a[f"{key}_t"]
        ax.plot(t, a[f"{key}_F_des"], "k--", lw=1, label="K_e δX")
        ax.plot(t, a[f"{key}_F"], "k-", lw=1.2, label="F_f/t")
        tw = ax.twinx()
        for i in range(a[f"{key}_tau"].shape[1]):
            tw.plot(t, a[f"{key}_tau"][:, i], ":", color=f"C{i}", label=f"τ{i + 1}")
        tw.set_ylim(-1.1 * tmax.max(), 1.1 * tmax.max())
        t_sat, t_full, t_lim = a[f"{key}_events"]
        for tv, st, lab in ((t_full, "-", "force no longer full"), (t_lim, "-.", "joint at a range limit")):
            if np.isfinite(tv):
                ax.axvline(tv, color="0.5", ls=st, lw=0.8, label=lab)
        ax.set(title=_title(key), xlabel="t [s]")
        if key == cases[-1]:
            tw.set_ylabel("τ [N m]")
            tw.legend(fontsize=6, loc="lower right")
    axes[0, 0].set_ylabel("force along u [N]")
    axes[0, 0].legend(fontsize=6, loc="upper left")
    fig.suptitle("Fig. 7.6 palpating K_e = 1000 N/m on the simulated rhi4")
    fig.tight_layout()
    return fig


def force_penetration(result: Result) -> Figure:
    """Measured force vs penetration per case, the wall K_e δX and the contact configuration's static capabilities."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    pmax = 0.0
    for k, key in enumerate(_cases(result)):
        pen = 1e3 * a[f"{key}_pen"]
        ax.plot(pen, a[f"{key}_F"], color=f"C{k}", lw=1, label=_title(key))
        pmax = max(pmax, float(np.max(pen)))
    p = np.linspace(0.0, pmax, 50)
    K = float(a["stiffness"])
    ax.plot(p, K * p / 1e3, "k--", lw=1, label=f"K_e δX ({K:g} N/m)")
    for name, style in (("scaling", ":"), ("ascm_dynamic", "-."), ("ascm_pseudoinverse", "--")):
        key = f"capability_{name}"
        if key in a:
            ax.axhline(float(a[key]), color="0.4", ls=style, lw=0.9,
                       label=f"static capability, {name.replace('_', ' ')}")
    ax.set(xlabel="penetration δX [mm]", ylabel="measured force along u [N]",
           title="Force vs penetration (static capabilities of the contact configuration)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def settling(result: Result) -> Figure:
    """Before contact: the tertiary objective ν (eq. 7.18) and the handle drift while the hand holds X₀."""
    a = result.arrays
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.2))
    ax1.plot(a["settle_t"], a["settle_nu"])
    ax1.set(xlabel="t [s]", ylabel="ν (eq. 7.18) [1]", title="tertiary objective while holding X₀")
    ax2.plot(a["settle_t"], 1e3 * a["settle_drift"])
    ax2.axhline(0.5, color="k", ls=":", lw=0.8)
    ax2.set(xlabel="t [s]", ylabel="handle drift [mm]")
    fig.tight_layout()
    return fig
