"""Chapter 7: actuator saturation compensation (Fig. 7.1 3-DoF example, Fig. 7.5 percent-deficiency map).

Both are static: the end-effector is held fixed, so no physics engine is needed. The
output force of joint torques τ is ``J⁺ᵀ τ`` (pseudoinverse projector, the default) or
``J#ᵀ τ`` (dynamically consistent, ``projector="dynamic"``). The thesis's 12 % gap of
Fig. 7.1 between simple scaling and ASCM is reproduced with the pseudoinverse projector
(equivalently J# with M = I); with the dynamically consistent J# of our planar3r
inertial model the null space is a different subspace and the numbers change (both
are reported).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np

from rhi import thesis as T
from rhi.control.allocation import allocation_method, force_capability
from rhi.control.controller import output_force
from rhi.control.saturation import null_basis
from rhi.design.executors import parallel_map
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput, Unreachable
from rhi.experiments.arguments import checked
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import capabilities, projector_names
from rhi.metrics import max_force
from rhi.metrics.force import ProjectorKind

Q_3DOF = (np.pi / 4, -np.pi / 3, -np.pi / 6)
METHODS = ("none", "scaling", "ascm", "lp")
U = np.array([0.0, 1.0])


def force_run(dev, q, t, Fe, *, projector: str = "pseudoinverse") -> dict[str, dict[str, np.ndarray]]:
    """Render the force history Fe (T, m) [N] at the fixed configuration q with every method.

    Returns:
        {method: {"force": (T, m) [N], "tau": (T, n) [N m], "alpha": (T,), "saturated": (T, n)}}.
    """
    J = dev.jacobian(q)
    M = dev.mass_matrix(q) if projector == "dynamic" else None
    Z = null_basis(J, M)
    lo, hi = dev.torque_limits
    b = np.zeros(dev.n)
    out = {}
    for meth in METHODS:
        strategy = allocation_method(meth)
        tau = np.empty((len(t), dev.n))
        alpha = np.empty(len(t))
        sat = np.zeros((len(t), dev.n), bool)
        for k, F in enumerate(Fe):
            al = strategy.allocate(J.T @ F, b, Z, torque_min=lo, torque_max=hi)
            tau[k], alpha[k], sat[k] = al.tau, al.alpha, al.saturated
        force = np.array([output_force(J, tk, M) for tk in tau])
        out[meth] = {"force": force, "tau": tau, "alpha": alpha, "saturated": sat}
    return out


@checked
def example_3dof(duration: float = 2.0, steps: int = 201, amplitude: float = 4.0) -> Result:
    """Fig. 7.1: planar 3R at q = [π/4, −π/3, −π/6], F_e = [4 sin(πt/2), 0] N, end-effector held.

    Compares no compensation (clipped torques), simple scaling, ASCM (Algorithm 1) and
    the LP-optimal allocation; reports peak output forces and the thesis's "scaling gives
    12 % less peak force than ASCM".

    Args:
        duration: simulated time [s] (2 s covers the full half sine).
        steps: samples.
        amplitude: peak of F_e [N] (thesis: 4).
    """
    dev = device("planar3r")
    q = np.array(Q_3DOF)
    t = np.linspace(0.0, duration, steps)
    Fe = np.stack([amplitude * np.sin(np.pi * t / 2), np.zeros_like(t)], axis=1)
    runs = {p: force_run(dev, q, t, Fe, projector=p) for p in ("pseudoinverse", "dynamic")}
    arrays: dict[str, np.ndarray] = {"t": t, "Fe": Fe, "q": q}
    rows = []
    peaks = {}
    for proj, run in runs.items():
        for meth, r in run.items():
            peak = float(np.max(np.linalg.norm(r["force"], axis=1)))
            peaks[proj, meth] = peak
            if proj == "pseudoinverse":
                arrays[f"force_{meth}"] = r["force"]
                arrays[f"tau_{meth}"] = r["tau"]
                arrays[f"alpha_{meth}"] = r["alpha"]
                arrays[f"saturated_{meth}"] = r["saturated"].astype(int)
            rows.append(Row(f"peak |F_out|, {meth} ({proj} projector)", None, peak, "N"))
        # angle of the output force from F_e's direction without compensation
        Fn = run["none"]["force"]
        ang = np.degrees(np.arctan2(np.abs(Fn[:, 1]), np.maximum(Fn[:, 0], 1e-12)))
        rows.append(Row(f"max direction error without compensation ({proj})", None, float(ang.max()), "deg"))
    gap = {p: 100.0 * (peaks[p, "ascm"] - peaks[p, "scaling"]) / peaks[p, "ascm"] for p in runs}
    rows.insert(0, Row("peak force deficit of scaling vs ASCM (pseudoinverse projector)", T.SCALING_GAP,
                       gap["pseudoinverse"], "%"))
    rows.insert(1, Row("peak force deficit of scaling vs ASCM (dynamic projector, our inertias)", T.SCALING_GAP,
                       gap["dynamic"], "%", "dynamically consistent null space differs from the thesis's"))
    J = dev.jacobian(q)
    # full force until two joints saturate: first time ASCM scales (α < 1) and how many joints are held then
    r = runs["pseudoinverse"]["ascm"]
    first = int(np.argmax(r["alpha"] < 1 - 1e-12)) if np.any(r["alpha"] < 1 - 1e-12) else -1
    lo, hi = dev.torque_limits
    at_limit = (np.abs(r["tau"] - hi) < 1e-9) | (np.abs(r["tau"] - lo) < 1e-9)
    held = int(at_limit[first].sum()) if first >= 0 else 0
    rows.append(Row("joints at a torque limit when ASCM first scales (α < 1)", T.HELD_AT_SCALING, float(held), ""))
    first_sat = int(np.argmax(runs["pseudoinverse"]["none"]["saturated"].any(axis=1)))
    rows.append(Row("|F_e| when the first joint saturates", None, float(np.linalg.norm(Fe[first_sat])), "N"))
    if first >= 0:
        rows.append(Row("|F_e| when ASCM starts scaling", None, float(np.linalg.norm(Fe[first])), "N"))
    rows.append(Row("LP optimum along x (pseudoinverse)", None,
                    float(max_force(J, [1, 0], torque_min=lo, torque_max=hi, projector="pseudoinverse")), "N"))
    return Result(
        "ch7.example_3dof",
        "Fig. 7.1: 3-DoF planar RHI rendering F_e = [4 sin(πt/2), 0] N with saturating joints",
        [Table("Fig. 7.1 peak output forces", rows)],
        arrays,
        [
            "End-effector held fixed; F_out = J⁺ᵀτ (pseudoinverse projector). The thesis's 12 % "
            "scaling-vs-ASCM gap is reproduced with this projector.",
            "With the dynamically consistent projector (our planar3r inertias) ASCM's greedy order "
            "stops short of the LP optimum here; the LP allocation reaches it.",
            "Without compensation the clipped torques distort the force direction (non-zero F_out,y).",
        ],
    )


@functools.cache
def _rhi4() -> Device:
    """rhi4, built once per process (`deficiency_map`'s rows may run in worker processes)."""
    return device("rhi4")


def _deficiency_row(y: float, xs: np.ndarray, projectors: tuple[ProjectorKind, ...]) -> np.ndarray:
    """(3 P, len(xs)) force capabilities [N] along the grid row at height y [m], NaN where skipped.

    Rows: without compensation, ASCM and LP for each of the P projectors. IK is continued along
    the row from the same start configuration for every row, so a row's values do not depend on
    which process computes it.
    """
    dev = _rhi4()
    lo, hi = dev.torque_limits
    out = np.full((3 * len(projectors), len(xs)), np.nan)
    q_prev = np.array([0.125, 0.022, 0.298, 0.175])
    for i, x in enumerate(xs):
        try:
            q = dev.ik((x, y), q_prev, restarts=2)
        except Unreachable:
            continue
        q_prev = q
        J = dev.jacobian(q)
        if np.linalg.svd(J, compute_uv=False)[-1] < 1e-3:
            continue
        f_wo = force_capability(J, U, torque_min=lo, torque_max=hi, method="scaling")
        for p, projector in enumerate(projectors):
            M = dev.mass_matrix(q) if projector == "dynamic" else None
            out[3 * p, i] = f_wo
            out[3 * p + 1:3 * p + 3, i] = capabilities(J, U, torque_min=lo, torque_max=hi, projector=projector, M=M,
                                                       samples=21)[1:]
    return out


@checked
def deficiency_map(
    resolution: int = 25,
    progress: Callable[[int, int], None] | None = None,
    *,
    projectors: Sequence[ProjectorKind] = ("pseudoinverse", "dynamic"),
    executor=None,
    workers: int | None = None,
) -> Result:
    """Fig. 7.5: percent deficiency PD = (F_ASCM − F_w/o)/F_ASCM × 100 along u = [0, 1] over rhi4's workspace (eq. 7.19).

    At each grid point the configuration comes from IK continued from the neighbouring
    point of the row; F_w/o is simple scaling (τ = Jᵀ f u until the first joint saturates),
    F_ASCM the peak of Algorithm 1 over a force ramp, F_LP the optimum over every
    null-space torque. Rows are evaluated through `rhi.design.executors` (one row per
    task), so the map is identical on every executor.

    Args:
        resolution: grid points per axis.
        progress: optional callback(done, total) in grid points, after each finished row.
        projectors: null-space projectors, each a map: "pseudoinverse" (J⁺) and/or "dynamic" (J#).
            The first gives the arrays ``pd``, ``pd_lp``, ``f_ascm``, ``f_lp``; the others add
            ``pd_{projector}``, ``pd_lp_{projector}``, ``f_ascm_{projector}``, ``f_lp_{projector}``.
        executor: an executor, a name ("serial", "local", "ray") or None (``workers``, else
            the default of `rhi.design.executors.configure`: a local process pool).
        workers: processes of a new local pool (1: in this process).
    """
    if not isinstance(resolution, (int, np.integer)) or resolution < 2:
        raise InvalidInput(f"resolution: expected an integer >= 2, got {resolution!r}")
    kinds = projector_names(projectors)
    xs = np.linspace(0.25, 0.75, resolution)
    ys = np.linspace(-0.5, 0.3, resolution)
    rows = parallel_map(functools.partial(_deficiency_row, xs=xs, projectors=kinds), list(ys),
                        executor=executor, workers=workers, progress=progress, units=[resolution] * resolution)
    maps = np.stack(rows, axis=1)  # (3 P, resolution, resolution), rows = y

    def stat(fn, a):
        return float(fn(a)) if a.size else np.nan

    arrays = {"x": xs, "y": ys}
    table_rows = []
    for p, projector in enumerate(kinds):
        f_wo, f_ascm, f_lp = maps[3 * p: 3 * p + 3]
        pd = 100.0 * (f_ascm - f_wo) / f_ascm
        pd_lp = 100.0 * (f_lp - f_wo) / f_lp
        ok = np.isfinite(pd)
        gap = (f_lp - f_ascm)[ok]
        tag = f" ({'J⁺' if projector == 'pseudoinverse' else 'J#'})"
        table_rows += [
            Row("grid points reached" + tag, None, float(ok.sum())),
            Row("min PD (ASCM ≥ w/o everywhere: PD ≥ 0)" + tag, None, stat(np.min, pd[ok]), "%"),
            Row("median PD" + tag, None, stat(np.median, pd[ok]), "%"),
            Row("max PD" + tag, None, stat(np.max, pd[ok]), "%"),
            Row("median PD against the LP optimum" + tag, None, stat(np.median, pd_lp[ok]), "%"),
            Row("fraction of points where ASCM reaches the LP optimum (1e-6 rel.)" + tag, None,
                stat(np.mean, gap <= 1e-6 * f_lp[ok]) if ok.any() else np.nan),
            Row("worst ASCM shortfall from the LP optimum" + tag, None, stat(np.max, gap) if ok.any() else np.nan, "N"),
        ]
        sfx = "" if p == 0 else f"_{projector}"
        arrays.update({f"pd{sfx}": pd, f"pd_lp{sfx}": pd_lp, f"f_ascm{sfx}": f_ascm, f"f_lp{sfx}": f_lp})
        if p == 0:
            arrays["f_wo"] = f_wo
    return Result(
        "ch7.deficiency_map",
        "Fig. 7.5: percent deficiency of the force capability without ASCM, rhi4 along u = [0, 1]",
        [Table("Fig. 7.5 percent deficiency (eq. 7.19)", table_rows)],
        arrays,
        ["The thesis shows Fig. 7.5 as a map only; we report its extremes for each projector.",
         f"Configurations by IK continued along each row; projectors {', '.join(kinds)} (the first is "
         "drawn); limits ±[3, 3, 1, 1] N m."],
    )
