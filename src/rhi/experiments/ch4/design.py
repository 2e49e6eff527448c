"""§4.4: the two design rounds, D = {θz} (Fig. 4.4) and D = {l2, θz, Z_PH} (Table 4.1, Figs 4.5–4.7)."""

from __future__ import annotations

import numpy as np

from rhi.design import evaluate, optimize, sweep
from rhi.design.executors import using
from rhi.experiments.arguments import checked
from rhi.experiments.ch4.setup import (
    ELLIPSE_POINTS,
    ENERGY_LABELS,
    K2,
    K2_MIN_TABLE_4_1,
    THESIS_GMM,
    THESIS_GMT,
    THESIS_TABLE,
    THESIS_THETA,
    checkpoint,
    ellipses,
    energy_along_task,
    gmt_vs_l2,
    mirror,
    problem,
    tmi_map,
)
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress


@checked
def theta_z_design(
    *, density: float = 100.0, step_deg: float = 1.0, executor=None, checkpoint_dir=None,
    progress: Progress | None = None, maxiter: int = 60, K2: float = K2,
) -> Result:
    """First round of §4.4: D = {θz}, l2 = 0.165 m, Z_PH = 0.0539 m; the optima of C1 and C2 and Fig. 4.4.

    Args:
        density: workspace samples per metre.
        step_deg: step of the θz sweep behind the optima (the landscape figure) [deg].
        executor: an executor or a name (`rhi.design.executors.using`; default: local pool).
        checkpoint_dir: folder of resumable evaluation caches.
        progress: ``progress(done, total)``.
        maxiter: differential-evolution generations.
        K2: weight of eqs. 4.23–4.24 (K1 = 1).
    """
    with using(executor) as ex:
        return _theta_z_design(ex, density, step_deg, checkpoint_dir, progress, maxiter, K2)


def _theta_z_design(ex, density, step_deg, checkpoint_dir, progress, maxiter, k2) -> Result:
    prob = problem("theta_z", density=density, K2=k2)
    half = np.arange(0.0, 90.0 + 1e-9, step_deg)
    grid = np.deg2rad(np.concatenate([-half[:0:-1], half]))  # symmetric about 0, so C1(θ) and C1(−θ) pair up
    n_sw = len(grid)
    tick = (lambda k, n: progress(k, n_sw + 2)) if progress else None
    sw = sweep(prob, [[t] for t in grid], executor=ex, checkpoint=checkpoint(checkpoint_dir, f"ch4_theta_sweep_K{k2:g}"),
               progress=tick)
    opts = {}
    for i, which in enumerate(("C1", "C2")):
        opts[which] = optimize(prob, which, executor=ex, seed=0, maxiter=maxiter,
                               checkpoint=checkpoint(checkpoint_dir, f"ch4_theta_{which}_K{k2:g}"))
        if progress:
            progress(n_sw + i + 1, n_sw + 2)
    rows = []
    arrays: dict[str, np.ndarray] = {"theta_deg": np.rad2deg(grid)}
    for k in ("C1", "C2", "GM_T", "GM_M", "GC_M", "coverage"):
        arrays[f"sweep_{k}"] = np.array([r[k] for r in sw])
    for which, o in opts.items():
        th = float(np.rad2deg(o.x[0]))
        rows.append(Row(f"θz maximising {which}", THESIS_THETA[which], th, "deg",
                        "C1 is symmetric in θz and flat; C2 is flat near its top: see the rows below and "
                        "ch4.sensitivity"))
    for which, o in opts.items():
        rows.append(Row(f"GM_T at the {which} optimum", THESIS_GMT[which], o.values["GM_T"], "m²/s²·(s/rad)²"))
        rows.append(Row(f"GM_M at the {which} optimum", THESIS_GMM[which], o.values["GM_M"], "m²/s²·(s/rad)²"))
        rows.append(Row(f"GC_M at the {which} optimum", None, o.values["GC_M"], ""))
    for which, th in THESIS_THETA.items():
        v = evaluate(prob, [np.deg2rad(th)])
        rows.append(Row(f"GM_T at the thesis's θz = {th:g}°", THESIS_GMT[which], v["GM_T"], "m²/s²·(s/rad)²",
                        "our set-up evaluated at the thesis's design"))
        rows.append(Row(f"GM_M at the thesis's θz = {th:g}°", THESIS_GMM[which], v["GM_M"], "m²/s²·(s/rad)²"))
        rows.append(Row(f"{which} at θz = {th:g}° / {which} at our optimum", None,
                        v[which] / opts[which].values[which], "", "how flat the landscape is near its top"))
    c1 = arrays["sweep_C1"]
    rows.append(Row("max |C1(θz) − C1(−θz)| over the sweep", None, float(np.max(np.abs(c1 - c1[::-1]))), "",
                    "C1 is exactly symmetric in θz (mirror designs)"))
    for k in ("GM_M", "GC_M", "GM_T"):
        a = arrays[f"sweep_{k}"]
        rows.append(Row(f"{k} max/min over θz ∈ [−90°, 90°]", None, float(a.max() / a.min()), ""))
    for which, o in opts.items():
        e = ellipses(prob, o.x)
        for k in ("master", "slave", "tme", "tmi"):
            arrays[f"ell_{which}_{k}"] = e[k]
        arrays[f"x_{which}"] = o.x
    arrays["ellipse_points"] = ELLIPSE_POINTS
    notes = [
        f"Set-up choices: see rhi.experiments.ch4 (W = 0.2 m square centred at (0.424, 0) m, k_q = 1, K1 = 1, "
        f"K2 = {k2:g}, HI rotated about the workspace centre, l1 = 0.21 m).",
        f"C1(θz) = C1(−θz) to {np.max(np.abs(c1 - c1[::-1])):.1e} and GM_M, GC_M vary by "
        f"{100 * (arrays['sweep_GM_M'].max() / arrays['sweep_GM_M'].min() - 1):.1f} %, "
        f"{100 * (arrays['sweep_GC_M'].max() / arrays['sweep_GC_M'].min() - 1):.1f} % over θz: C1 does not "
        "determine an orientation (its optimum comes as a mirror pair ±θz on a flat landscape).",
        f"GM_T varies by {100 * (arrays['sweep_GM_T'].max() / arrays['sweep_GM_T'].min() - 1):.0f} % and "
        "decides C2, but C2 at the thesis's 2° is within "
        f"{100 * (1 - evaluate(prob, [np.deg2rad(2.0)])['C2'] / opts['C2'].values['C2']):.1f} % of our "
        "optimum; where the top of this plateau lies moves with the unstated set-up (ch4.sensitivity).",
    ]
    return Result("ch4.theta_z_design", "§4.4 first round: D = {θz}", [Table("θz-only design (§4.4)", rows)], arrays,
                  notes)


@checked
def full_design(
    *, density: float = 100.0, executor=None, checkpoint_dir=None, progress: Progress | None = None,
    maxiter: int = 60, popsize: int = 15, K2: float = K2,
) -> Result:
    """Second round of §4.4: D = {l2, θz, Z_PH}; Table 4.1, Figs 4.5–4.6, and the joint energy of Fig. 4.7.

    Args:
        density: workspace samples per metre.
        executor: an executor or a name (`rhi.design.executors.using`; default: local pool).
        checkpoint_dir: folder of resumable evaluation caches.
        progress: ``progress(done, total)``.
        maxiter: differential-evolution generations.
        popsize: differential-evolution population size (per design variable).
        K2: weight of eqs. 4.23–4.24 (K1 = 1).
    """
    with using(executor) as ex:
        return _full_design(ex, density, checkpoint_dir, progress, maxiter, popsize, K2)


def _full_design(ex, density, checkpoint_dir, progress, maxiter, popsize, k2) -> Result:
    prob = problem("full", density=density, K2=k2)
    prob1 = problem("theta_z", density=density, K2=k2)
    opts = {}
    for i, which in enumerate(("C1", "C2")):
        sub = (lambda k, n, i=i: progress(i * 1000 + int(1000 * k / n), 2000)) if progress else None
        opts[which] = optimize(prob, which, executor=ex, seed=0, maxiter=maxiter, popsize=popsize,
                               checkpoint=checkpoint(checkpoint_dir, f"ch4_full_{which}_K{k2:g}"), progress=sub)
    rows = []
    unit = {"l2": "m", "z_ph": "m", "theta_z": "deg", "GM_T": "", "GC_M": "", "GM_M": ""}
    label = {"l2": "l2", "z_ph": "Z_PH", "theta_z": "θz", "GM_T": "GM_T", "GC_M": "GC_M", "GM_M": "GM_M"}
    thesis_vals = {}
    for which, o in opts.items():
        t = THESIS_TABLE[which]
        xt = [t["l2"], np.deg2rad(t["theta_z"]), t["z_ph"]]
        thesis_vals[which] = evaluate(prob, xt)
        for k in ("l2", "z_ph", "theta_z", "GM_T", "GC_M", "GM_M"):
            ours = float(np.rad2deg(o.params[k])) if k == "theta_z" else (o.params[k] if k in o.params
                                                                           else o.values[k])
            rows.append(Row(f"{label[k]}, {which} optimum", t[k], ours, unit[k]))
    c1m = evaluate(prob, mirror(prob, opts["C1"].x))
    rows.append(Row("GM_T, mirror image (−θz) of the C1 optimum", THESIS_TABLE["C1"]["GM_T"], c1m["GM_T"], "",
                    f"same C1 (difference {c1m['C1'] - opts['C1'].values['C1']:.1e}): C1 is symmetric in θz"))
    rows_at = []
    for which, v in thesis_vals.items():
        for k in ("GM_T", "GC_M", "GM_M"):
            rows_at.append(Row(f"{k} at the thesis's {which} design (our set-up)", THESIS_TABLE[which][k], v[k], "",
                               "the thesis's design scored with our W, placement and k_q"))
    lv = gmt_vs_l2(prob, executor=ex)
    rows_l2 = [Row(f"best GM_T over (θz, Z_PH) at l2 = {l2:.3f} m", None, g, "",
                   f"at θz = {np.rad2deg(t):.0f}°, Z_PH = {z:.2f} m (10° × 0.02 m grid)")
               for l2, g, t, z in zip(lv["l2"], lv["GM_T"], lv["theta_z"], lv["z_ph"])]
    arrays: dict[str, np.ndarray] = {"workspace": prob.workspace.points, "ellipse_points": ELLIPSE_POINTS,
                                     "l2_scan": lv["l2"], "l2_scan_GM_T": lv["GM_T"]}
    for which, o in opts.items():
        arrays[f"x_{which}"] = o.x
        arrays[f"history_{which}"] = o.history
        e = ellipses(prob, o.x)
        for k in ("master", "slave", "tme", "tmi"):
            arrays[f"ell_{which}_{k}"] = e[k]
        arrays[f"tmi_{which}"] = tmi_map(prob, o.x)
    arrays["x_C1_mirror"] = mirror(prob, opts["C1"].x)
    # Fig. 4.7: the four designs of §4.4
    designs = {}
    th_opts = {w: optimize(prob1, w, executor=ex, seed=0, maxiter=maxiter,
                           checkpoint=checkpoint(checkpoint_dir, f"ch4_full_theta_{w}_K{k2:g}")) for w in ("C1", "C2")}
    for w, o in th_opts.items():
        designs[f"θz only, {w}"] = (prob1, o.x)
    for w, o in opts.items():
        designs[f"l2, θz, Z_PH, {w}"] = (prob, o.x)
    energy_rows = []
    assert tuple(designs) == ENERGY_LABELS
    for i, (name, (p, x)) in enumerate(designs.items()):
        t_task, en = energy_along_task(p, x)
        arrays["energy_t"] = t_task
        arrays[f"energy_{i}"] = en
        energy_rows.append(Row(f"mean ‖q̇‖² A→B, {name}", None, float(np.nanmean(en)), "(rad/s)²·s/rad"))
        sq = energy_along_task(p, x, axes_squared=True)[1]
        energy_rows.append(Row(f"mean ‖q̇‖² A→B with Λ_T = diag(σ²) (eq. 4.21's (J_T J_Tᵀ)⁻¹), {name}", None,
                               float(np.nanmean(sq)), "(rad/s)²"))
    # Fig. 4.7 at the thesis's own printed designs (§4.4's θz = 89°, 2°; Table 4.1), a reading beside ours
    printed = {f"θz only, {w}": (prob1, [np.deg2rad(THESIS_THETA[w])]) for w in ("C1", "C2")}
    printed |= {f"l2, θz, Z_PH, {w}": (prob, [THESIS_TABLE[w]["l2"], np.deg2rad(THESIS_TABLE[w]["theta_z"]),
                                               THESIS_TABLE[w]["z_ph"]]) for w in ("C1", "C2")}
    for name, (p_printed, x_printed) in printed.items():
        energy_rows.append(Row(f"thesis's design: mean ‖q̇‖² A→B, {name}", None,
                               float(np.nanmean(energy_along_task(p_printed, np.asarray(x_printed))[1])),
                               "(rad/s)²·s/rad",
                               "the design §4.4 prints, scored in our set-up (eq. 4.22 as printed)"))
    if progress:
        progress(2000, 2000)
    o1, o2 = opts["C1"], opts["C2"]
    gmt1 = (o1.values["GM_T"], c1m["GM_T"])
    holds = {
        "C1 has the larger l2 (by > 1 mm, the thesis's rounding)": o1.params["l2"] > o2.params["l2"] + 1e-3,
        "C1 has the larger GM_M": o1.values["GM_M"] > o2.values["GM_M"],
        "C1 has the larger GC_M": o1.values["GC_M"] > o2.values["GC_M"],
        "C2 has the larger GM_T (against both mirror designs of C1)": o2.values["GM_T"] > max(gmt1),
    }
    notes = [
        f"K2/K1 = {k2:g}; Table 4.1 itself requires K2/K1 ≥ {K2_MIN_TABLE_4_1:.1f} (module docstring).",
        "The thesis's qualitative results in our set-up: "
        + "; ".join(f"{k}: {'yes' if v else 'no'}" for k, v in holds.items()) + ".",
        f"GM_T's best value over (θz, Z_PH) rises with l2 ({lv['GM_T'][0]:.4f} at {lv['l2'][0]:.3f} m to "
        f"{lv['GM_T'][-1]:.4f} at {lv['l2'][-1]:.3f} m): the slave's ME is the larger one over W, so only GC_M can "
        "keep C2's l2 below its bound, and it does so only for small K2/K1, below the range Table 4.1 allows "
        "(basin switch: ch4.sensitivity, \"Table 4.1 optimum vs K2/K1\").",
        f"C1's optimum is one of a mirror pair (θz, −θz) with equal C1 and GM_T {gmt1[0]:.4f} / {gmt1[1]:.4f}.",
        f"Scored in our set-up, the thesis's C2 design has GM_T {thesis_vals['C2']['GM_T']:.4f}, GC_M "
        f"{thesis_vals['C2']['GC_M']:.4f}, GM_M {thesis_vals['C2']['GM_M']:.4f} (thesis: 0.0590, 0.7315, 0.0728). "
        + ("Our C2 optimum beats it on both terms of C2, so no K1, K2 > 0 makes the thesis's C2 design optimal "
           "in our set-up." if (o2.values["GM_T"] > thesis_vals["C2"]["GM_T"]
                                and o2.values["GC_M"] > thesis_vals["C2"]["GC_M"]) else
           "Our C2 optimum does not beat it on both terms of C2."),
        f"Evaluations: C1 {o1.evaluations}, C2 {o2.evaluations} designs (DE rand1bin seed 0, popsize "
        f"{popsize}, maxiter {maxiter}, then Nelder–Mead from up to 4 distinct regions).",
        "Joint energy uses eq. 4.22 literally (Λ_T = diag(σ_I)); its unit is therefore (m/s)²/(m/s per rad/s).",
    ]
    return Result("ch4.full_design", "§4.4 second round: D = {l2, θz, Z_PH}",
                  [Table("Table 4.1", rows), Table("Table 4.1 designs scored in our set-up", rows_at),
                   Table("GM_T vs l2 (why C2 keeps l2 at its bound)", rows_l2),
                   Table("Fig. 4.7 joint energy", energy_rows)], arrays, notes)
