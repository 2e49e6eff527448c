"""Table 3.1 and Figs 3.6–3.8: ρ and Λ of the RHI, PHANToM and Rehab at the §3.5 points, and the ratio maps.

Set-up (thesis §3.5): rhi4 with d = [0.254, 0.141, 0.21, 0.181] m; the PHANToM and
Rehab are the RHI with (q1, q2) resp. (q3, q4) locked at 0; direction of motion
u = [0, 1]; the RHI configuration at a point is the one minimising the JBLD
objective of eq. 3.22–3.23 with β = 0.01 within the joint limits of §5.4.

Why our numbers differ from the thesis's:
- ρ depends on kinematics only. At the thesis's own configurations it matches Table 3.1 to
  its rounding except the RHI at (0.49, −0.22) (0.3752 vs 0.371: the printed configuration
  is itself rounded) and the Rehab at (0.49, −0.14) (0.31446 vs 0.315); at our eq.-3.22
  optimum the RHI's ρ is larger than the table's (0.430 and 0.403 vs 0.371 and 0.387).
- Λ depends on the inertial model. The thesis's model (from [23] and [45]) is not
  published; ours is documented in models/rhi4/README.md, so Λ differs in value
  while the ordering RHI < PHANToM < Rehab is what we check.
- Our optimised RHI configurations come from SLSQP on the same objective; where they
  differ from the thesis's (which come from running the controller on the hardware),
  both are reported.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from rhi import thesis as T
from rhi.control import VMEMatching
from rhi.control.configuration import optimal_configuration
from rhi.design.executors import parallel_map
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput, Unreachable
from rhi.experiments.arguments import checked
from rhi.experiments.result import Result, Row, Table
from rhi.metrics import effective_inertia, effective_manipulability, jbld

U = np.array([0.0, 1.0])
POINTS = ((0.49, -0.22), (0.49, -0.14))
#: Optimised RHI configurations reported in §3.5 [rad].
THESIS_Q, THESIS_RHO, THESIS_LAMBDA = T.TABLE_3_1_Q, T.TABLE_3_1_RHO, T.TABLE_3_1_LAMBDA
BETA = 0.01
#: The three interfaces of §3.5: name -> `rhi.device` name.
DEVICE_NAMES = {"RHI": "rhi4", "PHANToM": "phantom", "Rehab": "rehab"}


def devices() -> dict[str, Device]:
    """The three interfaces of §3.5."""
    return {name: device(d) for name, d in DEVICE_NAMES.items()}


def measures(dev: Device, q: np.ndarray, u: np.ndarray = U) -> tuple[float, float]:
    """(ρ [m/s per rad/s], Λ [kg]) of `dev` at q along u (eq. 3.6, 3.13)."""
    J = dev.jacobian(q)
    return float(effective_manipulability(J, u)), float(effective_inertia(J, dev.mass_matrix(q), u))


@checked
def table_3_1() -> Result:
    """Table 3.1: Λ and ρ along u = [0, 1] at the two points, RHI vs PHANToM vs Rehab."""
    devs = devices()
    rhi = devs["RHI"]
    objective = VMEMatching(tuple(U), BETA)
    rows_rho, rows_lam, rows_q = [], [], []
    arrays: dict[str, np.ndarray] = {}
    for i, x in enumerate(POINTS):
        where = f"({x[0]}, {x[1]})"
        q_thesis = np.array(THESIS_Q[i])
        rho, lam = measures(rhi, q_thesis)
        rows_rho.append(Row(f"ρ RHI at {where} (thesis configuration)", THESIS_RHO["RHI"][i], rho, "m/s"))
        rows_lam.append(Row(f"Λ RHI at {where} (thesis configuration)", THESIS_LAMBDA["RHI"][i], lam, "kg",
                            "inertial model differs (see models/rhi4/README.md)"))
        q_opt = optimal_configuration(rhi, x, objective, q_thesis)
        rho_o, lam_o = measures(rhi, q_opt)
        rows_rho.append(Row(f"ρ RHI at {where} (our optimum of eq. 3.22)", THESIS_RHO["RHI"][i], rho_o, "m/s"))
        rows_lam.append(Row(f"Λ RHI at {where} (our optimum of eq. 3.22)", THESIS_LAMBDA["RHI"][i], lam_o, "kg"))
        arrays[f"q_opt_{i}"] = q_opt
        arrays[f"fk_thesis_q_{i}"] = rhi.fk(q_thesis)
        for k in range(4):
            rows_q.append(Row(f"optimised q{k + 1} at {where}", THESIS_Q[i][k], float(q_opt[k]), "rad"))
        for nm in ("PHANToM", "Rehab"):
            dev = devs[nm]
            q = dev.ik(x, np.full(dev.n, 0.3))
            rho_n, lam_n = measures(dev, q)
            arrays[f"q_{nm}_{i}"] = q
            rows_rho.append(Row(f"ρ {nm} at {where}", THESIS_RHO[nm][i], rho_n, "m/s"))
            rows_lam.append(Row(f"Λ {nm} at {where}", THESIS_LAMBDA[nm][i], lam_n, "kg",
                                "inertial model differs (see models/rhi4/README.md)"))
    return Result(
        "ch3.table_3_1",
        "Table 3.1: effective manipulability ρ and effective apparent inertia Λ along u = [0, 1]",
        [Table("Effective manipulability ρ", rows_rho), Table("Effective apparent inertia Λ", rows_lam),
         Table("Optimised RHI configuration (§3.5)", rows_q)],
        arrays,
        [
            "ρ of PHANToM and Rehab come from IK at the two points; ρ of the RHI at the thesis's optimised "
            "configurations and at our own optimum of eq. 3.22 (β = 0.01, SLSQP within the §5.4 limits).",
            "Λ uses our documented inertial estimates; the thesis's inertial model is not published.",
        ],
    )


def maybe_reachable(dev: Device, points: np.ndarray, n: int = 201) -> np.ndarray:
    """Screen points against a 2-DoF device's workspace: False only where a point is certainly unreachable.

    The joint box is sampled on an n × n grid. A reachable point f(q*), q* within the
    limits, lies within ``margin`` of the image of a feasible grid node: the largest
    end-effector step between neighbouring nodes bounds the distance across one cell,
    and ``margin`` = 3 steps covers a cell's diagonal plus one more cell where a linear
    limit cuts the cell off from its feasible neighbours. Points farther than that from
    every feasible node cannot be reached, so their IK (which would try every restart
    before failing) is skipped. tests/test_ch3.py checks that no FK image of a random
    feasible configuration is screened out.

    Args:
        dev: device with n = 2 joints and finite joint limits.
        points: (N, 2) end-effector positions [m].
        n: grid nodes per joint.

    Returns:
        (N,) bool, True where IK must decide.
    """
    if dev.n != 2 or not (np.all(np.isfinite(dev.q_min)) and np.all(np.isfinite(dev.q_max))):
        raise InvalidInput(f"dev: the workspace screen needs 2 joints with finite limits, got {dev.name}")
    g = [np.linspace(lo, hi, n) for lo, hi in zip(dev.q_min, dev.q_max)]
    Q = np.stack(np.meshgrid(*g, indexing="ij"), -1)  # (n, n, 2)
    X = dev.fk(Q.reshape(-1, 2)).reshape(n, n, -1)
    step = max(np.linalg.norm(np.diff(X, axis=0), axis=-1).max(), np.linalg.norm(np.diff(X, axis=1), axis=-1).max())
    feasible = dev.within_limits(Q.reshape(-1, 2))
    dist, _ = cKDTree(X.reshape(-1, X.shape[-1])[feasible]).query(np.asarray(points, dtype=float))
    return dist <= 3.0 * step


def _ratio_row(row: tuple[float, np.ndarray], xs: np.ndarray) -> tuple[np.ndarray, ...]:
    """ρ_r, Λ_r along a grid row, the RHI at its eq.-3.22 optimum and at the PHANToM's angles: four (len(xs),) arrays.

    ``row = (y [m], candidates (len(xs),))``; NaN where unreached.

    "At the PHANToM's own angles" is the RHI with its added joints at 0, where its last two links are the
    PHANToM at the PHANToM's base, and those links at the PHANToM's IK angles: q = [0, 0, q_PHANToM] (the
    NHI inside the RHI that the proofs of Remarks I–II compare, eqs. 3.8 and 3.12); NaN outside the RHI's limits.

    The PHANToM's IK is warm-started from the previous point of the row. The RHI's configuration is the lowest
    ν of eq. 3.22 that SLSQP reaches from the previous point's and from the lowest samples of the self-motion
    manifold (`_lowest`): the thesis's optimum "does not depend on the initial configuration" (§3.4), while
    one warm-started SLSQP stops at the local minimum of its basin (42 % of the quick grid's points). Every
    row starts from the same configurations ([0.5, 0.3] rad and the thesis's first optimised RHI
    configuration), so a row's values do not depend on which process computes it or on the other rows.
    Points with ``candidates`` False are outside the PHANToM's workspace (`maybe_reachable`) and skipped.
    """
    y, candidates = row
    devs = _devices_cached()
    rhi, ph = devs["RHI"], devs["PHANToM"]
    objective = VMEMatching(tuple(U), BETA)
    rho, lam, rho_at, lam_at = (np.full(len(xs), np.nan) for _ in range(4))
    q_ph = np.array([0.5, 0.3])
    q_rhi = np.array(THESIS_Q[0])
    for i, x in enumerate(xs):
        if not candidates[i]:
            continue
        try:
            q_ph = ph.ik((x, y), q_ph if ph.within_limits(q_ph) else np.array([0.5, 0.3]))
            q_rhi = _lowest(rhi, (x, y), objective, q_rhi)
        except Unreachable:
            continue
        r1, l1 = measures(rhi, q_rhi)
        r0, l0 = measures(ph, q_ph)
        rho[i], lam[i] = r1 / r0, l1 / l0
        q_at = np.concatenate([np.zeros(2), q_ph])
        if rhi.within_limits(q_at):
            r2, l2 = measures(rhi, q_at)
            rho_at[i], lam_at[i] = r2 / r0, l2 / l0
    return rho, lam, rho_at, lam_at


#: The RHI's self-motion manifold is sampled on (q1, q2) nodes per axis (`manifold_samples`), and SLSQP polishes
#: this many of the lowest-ν samples (`_lowest`).
MANIFOLD_NODES, POLISHED = 13, 3


def manifold_samples(dev: Device, x, nodes: int = MANIFOLD_NODES, iters: int = 30) -> np.ndarray:
    """Configurations of a 4-joint planar device at x within its limits: (k, 4), k ≥ 0 [rad].

    (q1, q2) on a ``nodes`` × ``nodes`` grid of their joint box; (q3, q4) by Newton steps on the last two
    Jacobian columns from two starts (the two branches of the last two links), kept where they reach x
    within 1e-9 m and the limits.
    """
    g1 = np.linspace(dev.q_min[0], dev.q_max[0], nodes)
    g2 = np.linspace(dev.q_min[1], dev.q_max[1], nodes)
    head = np.stack(np.meshgrid(g1, g2, indexing="ij"), -1).reshape(-1, 2)
    Q = np.concatenate([np.hstack([head, np.tile(tail, (len(head), 1))]) for tail in ((0.3, 0.3), (1.2, 0.0))])
    x = np.asarray(x, dtype=float)
    for _ in range(iters):
        e = x - dev.fk(Q)
        J = dev.jacobian(Q)[:, :, 2:]
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        ok = np.abs(det) > 1e-12
        step = np.zeros((len(Q), 2))
        step[ok] = np.linalg.solve(J[ok], e[ok][:, :, None])[:, :, 0]
        Q[:, 2:] += np.clip(step, -0.5, 0.5)
    reached = np.linalg.norm(x - dev.fk(Q), axis=1) < 1e-9
    return Q[reached & dev.within_limits(Q)]


def _lowest(dev: Device, x, objective: VMEMatching, warm: np.ndarray) -> np.ndarray:
    """The lowest ν that `optimal_configuration` reaches at x from `warm` and the `POLISHED` lowest-ν samples.

    The samples are `manifold_samples`: the result is the global minimum within the limits up to the sampling.

    Raises:
        Unreachable: the warm start reaches no configuration at x within the limits.
    """
    best = optimal_configuration(dev, x, objective, warm)
    v = objective.value(dev, best)
    samples = manifold_samples(dev, x)
    J = dev.jacobian(samples)  # (k, m, n): one batch
    values = jbld(objective.desired(), J @ J.swapaxes(-1, -2)) if len(samples) else np.empty(0)  # ν, one batch
    for s in samples[np.argsort(values)[:POLISHED]]:
        q = optimal_configuration(dev, x, objective, s)
        vq = objective.value(dev, q)
        if vq < v:
            best, v = q, vq
    return best


_DEVICES: dict[str, Device] = {}


def _devices_cached() -> dict[str, Device]:
    """`devices()` built once per process (map workers reuse them across rows)."""
    if not _DEVICES:
        _DEVICES.update(devices())
    return _DEVICES


@checked
def ratio_maps(
    resolution: int = 41,
    progress: Callable[[int, int], None] | None = None,
    *,
    executor=None,
    workers: int | None = None,
) -> Result:
    """Figs 3.6–3.8: workspaces and the ρ and Λ ratios RHI/PHANToM over their common workspace.

    The grid covers the PHANToM's workspace; at each point the PHANToM configuration comes
    from IK and the RHI's from minimising eq. 3.22 (β = 0.01) within the joint limits, both
    warm-started along the grid row. Rows are evaluated through `rhi.design.executors`
    (one row per task), so the map is identical on every executor.

    Args:
        resolution: grid points per axis.
        progress: optional callback(done, total) in grid points, after each finished row.
        executor: an executor, a name ("serial", "local", "ray") or None (``workers``, else
            the default of `rhi.design.executors.configure`: a local process pool).
        workers: processes of a new local pool (1: in this process).
    """
    if not isinstance(resolution, (int, np.integer)) or resolution < 2:
        raise InvalidInput(f"resolution: expected an integer >= 2, got {resolution!r}")
    xs = np.linspace(0.25, 0.70, resolution)
    ys = np.linspace(-0.55, 0.05, resolution)
    grid = np.stack(np.meshgrid(xs, ys), -1)  # (ny, nx, 2)
    cand = maybe_reachable(_devices_cached()["PHANToM"], grid.reshape(-1, 2)).reshape(resolution, resolution)
    # longest rows first (most IK candidates), so the pool's last tasks are short; values do not depend on order
    order = np.argsort(-cand.sum(axis=1), kind="stable")
    done = parallel_map(functools.partial(_ratio_row, xs=xs), [(ys[j], cand[j]) for j in order], executor=executor,
                        workers=workers, progress=progress, units=[resolution] * resolution)
    rows: list = [None] * resolution
    for j, r in zip(order, done):
        rows[j] = r
    rho_r = np.array([r[0] for r in rows])
    lam_r = np.array([r[1] for r in rows])
    rho_at, lam_at = np.array([r[2] for r in rows]), np.array([r[3] for r in rows])
    ok = np.isfinite(rho_r)
    at = np.isfinite(rho_at)
    tag = ", the RHI at the PHANToM's angles"
    res = Result(
        "ch3.ratio_maps",
        "Figs 3.7–3.8: ratios ρ_RHI/ρ_PHANToM and Λ_RHI/Λ_PHANToM over the common workspace",
        [Table("Ratio maps (Remarks I and II: ρ_r ≥ 1, Λ_r ≤ 1)", [
            Row("min ρ_r over the common workspace", None, float(np.min(rho_r[ok])) if ok.any() else np.nan),
            Row("max ρ_r", None, float(np.max(rho_r[ok])) if ok.any() else np.nan),
            Row("max Λ_r over the common workspace", None, float(np.max(lam_r[ok])) if ok.any() else np.nan),
            Row("min Λ_r", None, float(np.min(lam_r[ok])) if ok.any() else np.nan),
            Row("fraction of points with ρ_r ≥ 1", None, float(np.mean(rho_r[ok] >= 1 - 1e-9)) if ok.any() else np.nan),
            Row("fraction of points with Λ_r ≤ 1", None, float(np.mean(lam_r[ok] <= 1 + 1e-9)) if ok.any() else np.nan),
            Row("points with the RHI at the PHANToM's angles within the RHI's limits", None, float(at.sum()), "",
                "q = [0, 0, q_PHANToM]: the RHI's last two links are the PHANToM"),
            Row("fraction of points with ρ_r ≥ 1" + tag, None,
                float(np.mean(rho_at[at] >= 1 - 1e-9)) if at.any() else np.nan),
            Row("fraction of points with Λ_r ≤ 1" + tag, None,
                float(np.mean(lam_at[at] <= 1 + 1e-9)) if at.any() else np.nan),
            Row("max Λ_r" + tag, None, float(np.max(lam_at[at])) if at.any() else np.nan),
        ])],
        {"x": xs, "y": ys, "rho_ratio": rho_r, "lambda_ratio": lam_r, "rho_ratio_at_phantom": rho_at,
         "lambda_ratio_at_phantom": lam_at, "workspaces": workspaces()},
        ["The thesis shows these maps as figures only; we report their extremes.",
         "Λ_r uses our documented inertial model; ρ_r is kinematic.",
         "Configurations are warm-started along each grid row; rows run in parallel (rhi.design.executors)."],
    )
    return res


def workspaces(devs: dict[str, Device] | None = None, samples: int = 20000, seed: int = 0) -> np.ndarray:
    """Fig. 3.6: reachable end-effector points of RHI, PHANToM, Rehab within their joint limits.

    Returns:
        (3, samples, 2) end-effector positions [m]; NaN where the sampled q violates a linear limit.
    """
    devs = devs or devices()
    rng = np.random.default_rng(seed)
    out = np.full((3, samples, 2), np.nan)
    for k, dev in enumerate(devs.values()):
        q = rng.uniform(dev.q_min, dev.q_max, size=(samples, dev.n))
        ok = dev.within_limits(q)
        out[k, ok] = dev.fk(q[ok])
    return out
