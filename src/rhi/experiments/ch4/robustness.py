"""§4.4 set-up sensitivity: how the optima move with the sampling density, K2 and the other choices."""

from __future__ import annotations

import numpy as np

from rhi.design import evaluate, optimize
from rhi.design.executors import using
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.ch4.setup import K2_MIN_TABLE_4_1, THESIS_TABLE, THESIS_THETA, mirror, problem
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress

#: One-at-a-time changes of the set-up re-optimised by `sensitivity` (keyword arguments of `problem`).
VARIANTS: dict[str, dict] = {
    "baseline": {},
    "k_q = 0.5": {"k_q": 0.5},
    "k_q = 4": {"k_q": 4.0},
    "no joint-limit penalty": {"k_q": None},
    "K2 = 1": {"K2": 1.0},
    "K2 = 10": {"K2": 10.0},
    "K2 = 100": {"K2": 100.0},
    "W = 0.1 m × 0.2 m (x ∈ [0.374, 0.474])": {"xlim": (0.374, 0.474)},
    "W = 0.3 m square": {"xlim": (0.274, 0.574), "ylim": (-0.15, 0.15)},
    "r0 = 0.20 m fixed": {"r0": 0.20},
    "r0 = 0.22 m fixed": {"r0": 0.22},
    "r0 = 0.24 m fixed": {"r0": 0.24},
    "r0 = 0.25 m fixed": {"r0": 0.25},
    "Sobol' sampling": {"kind": "sobol"},
}


@checked
def sensitivity(*, density: float = 100.0, densities=(25.0, 50.0, 100.0, 200.0), maxiter: int = 40,
                k2_values=(10.0, 11.0, 20.0, 30.0), variants=None, executor=None,
                progress: Progress | None = None) -> Result:
    """Convergence of the indices with the sampling density, and how the optima move with each open choice.

    Args:
        density: workspace samples per metre of the re-optimised variants.
        densities: sampling densities of the convergence check [1/m].
        maxiter: differential-evolution generations of each re-optimisation.
        k2_values: K2/K1 ratios at which the full design (Table 4.1) is re-optimised.
        variants: names of the set-up variants to re-optimise (keys of `VARIANTS`); None: all.
        executor: an executor or a name (`rhi.design.executors.using`; default: local pool).
        progress: ``progress(done, total)``.
    """
    with using(executor) as ex:
        return _sensitivity(ex, density, densities, maxiter, k2_values, variants, progress)


def _sensitivity(ex, density, densities, maxiter, k2_values, names, progress) -> Result:
    rows_conv = []
    arrays: dict[str, np.ndarray] = {"densities": np.array(densities, dtype=float)}
    x2 = [np.deg2rad(2.0)]
    vals: dict[str, list[float]] = {k: [] for k in ("GM_T", "GM_M", "GC_M")}
    for dens in densities:
        at = evaluate(problem("theta_z", density=dens), x2)
        for k in vals:
            vals[k].append(at[k])
    for k, vs in vals.items():
        arrays[f"conv_{k}"] = np.array(vs)
        for i in range(1, len(densities)):
            rel = abs(vs[i] / vs[i - 1] - 1)
            rows_conv.append(Row(f"{k} at θz = 2°: relative change {densities[i - 1]:g} → {densities[i]:g} /m",
                                 None, rel, "", "< 0.01 required" if densities[i] <= 2 * density else ""))
    if names is None:
        names = list(VARIANTS)
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        raise InvalidInput(f"variants: unknown {unknown}; available: {list(VARIANTS)}")
    variants = {n: VARIANTS[n] for n in names}
    n_steps = len(variants) + len(k2_values)
    rows_sens = []
    for i, (name, kw) in enumerate(variants.items()):
        p = problem("theta_z", density=density, **kw)
        for which in ("C1", "C2"):
            o = optimize(p, which, executor=ex, seed=0, maxiter=maxiter)
            rows_sens.append(Row(f"θz* of {which}, {name}", THESIS_THETA[which], float(np.rad2deg(o.x[0])), "deg",
                                 f"GM_T {o.values['GM_T']:.4f}, GM_M {o.values['GM_M']:.4f}"))
        if progress:
            progress(i + 1, n_steps)
    rows_k2 = []
    k2_arr: dict[str, list[float]] = {k: [] for k in ("l2_C1", "l2_C2", "GM_T_C1", "GM_T_C1_mirror", "GM_T_C2",
                                                      "GC_M_C1", "GC_M_C2", "GM_M_C1", "GM_M_C2")}
    for j, k2 in enumerate(k2_values):
        p = problem("full", density=density, K2=k2)
        o1 = optimize(p, "C1", executor=ex, seed=0, maxiter=maxiter)
        o2 = optimize(p, "C2", executor=ex, seed=0, maxiter=maxiter)
        m = evaluate(p, mirror(p, o1.x))
        for k, v in (("l2_C1", o1.params["l2"]), ("l2_C2", o2.params["l2"]), ("GM_T_C1", o1.values["GM_T"]),
                     ("GM_T_C1_mirror", m["GM_T"]), ("GM_T_C2", o2.values["GM_T"]), ("GC_M_C1", o1.values["GC_M"]),
                     ("GC_M_C2", o2.values["GC_M"]), ("GM_M_C1", o1.values["GM_M"]), ("GM_M_C2", o2.values["GM_M"])):
            k2_arr[k].append(float(v))
        where = (f"C2 optimum θz = {np.rad2deg(o2.params['theta_z']):.1f}°, Z_PH = {o2.params['z_ph']:.3f} m; "
                 f"GC_M {o1.values['GC_M']:.4f} (C1) vs {o2.values['GC_M']:.4f} (C2); GM_T of C1 and its mirror "
                 f"{o1.values['GM_T']:.4f} / {m['GM_T']:.4f}")
        rows_k2.append(Row(f"K2/K1 = {k2:g}: l2 of the C2 optimum", THESIS_TABLE["C2"]["l2"], o2.params["l2"], "m",
                           where))
        rows_k2.append(Row(f"K2/K1 = {k2:g}: GM_T of the C2 optimum", THESIS_TABLE["C2"]["GM_T"],
                           o2.values["GM_T"], ""))
        if progress:
            progress(len(variants) + j + 1, n_steps)
    arrays["k2_values"] = np.array(k2_values, dtype=float)
    for k, series in k2_arr.items():
        arrays[f"k2_{k}"] = np.array(series)
    return Result("ch4.sensitivity", "§4.4 set-up sensitivity and sampling convergence",
                  [Table("Convergence with sampling density (grid)", rows_conv),
                   Table("θz optimum vs the unstated set-up", rows_sens),
                   Table("Table 4.1 optimum vs K2/K1", rows_k2)], arrays,
                  ["Each variant changes one choice of rhi.experiments.ch4's docstring and re-optimises D = {θz}.",
                   f"Table 4.1 requires K2/K1 ≥ {K2_MIN_TABLE_4_1:.1f}; the K2/K1 scan re-optimises D = "
                   "{l2, θz, Z_PH} for C1 and C2 at each ratio."])
