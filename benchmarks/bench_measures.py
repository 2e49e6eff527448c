"""Batch measures vs per-configuration loops: every device (a plain Pinocchio loop) and rhi4 (ours, RTB).

All timings are taken in the same run (best CPU times, `batch_baselines.best_of`) and printed as ratios against the
baselines.

* Every bundled device, Panda and UR5 (example-robot-data), --n configurations: the batch API
  (`Device.jacobian` / `rhi.devices.batch.terms` and `rhi.metrics`) against a plain Pinocchio loop that per
  configuration computes θ = A q + b, `computeFrameJacobian` (and `crba`), and then with NumPy
  ρ = (uᵀ(JJᵀ)⁻¹u)^(-1/2) (eq. 3.6), Λ = (uᵀ J M⁻¹ Jᵀ u)⁻¹ (eq. 3.13) and μ = √det(JJᵀ) (eq. 4.7).
  Both give the same numbers (checked to 1e-10 relative). Columns: J + ρ, and J, M + ρ, Λ, μ, and the
  measures alone (ρ, Λ, μ from given J, M: the closed forms of `rhi.metrics`) per configuration.
* m = 3 against m = 2: on every device with a spatial task, each measure alone from its J (m = 3) and from the
  first two rows of the same J (m = 2, the same n and M), timed in turns, as a ratio per configuration.
* rhi4, ρ + Λ: the same against our own per-configuration loop and the Robotics Toolbox, whose model is
  the same URDF with the same actuation map applied (J_q = J_θ A, M_q = Aᵀ M_θ A).

BLAS runs on one thread unless OPENBLAS_NUM_THREADS / OMP_NUM_THREADS say otherwise (see bench_kinematics).
Run: ./run bench   (or: python benchmarks/bench_measures.py [--n 10000] [--loop-n 1000])
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time

from batch_baselines import arms, best_of, rtb_rho_lambda  # first: BLAS on one thread before NumPy loads

# isort: split

import numpy as np
import pinocchio as pin


def devices():
    """Every bundled device, then Panda and UR5 from example-robot-data (dropped with a note if not installed)."""
    import rhi
    from rhi.devices.model import available_devices

    return [rhi.device(name) for name in available_devices()] + arms()


def pinocchio_loop(dev, Q, u, dynamics: bool) -> np.ndarray:
    """(B, 3) ρ, Λ, μ (Λ, μ NaN unless `dynamics`) per configuration: Pinocchio, then NumPy's dense solvers."""
    model, data, A, b, rows = dev.model, dev.model.createData(), dev.A, dev.b, dev.task_rows
    fid, arm = dev.ee_frame_id, np.diag(dev.armature)
    out = np.full((len(Q), 3), np.nan)
    for k, q in enumerate(Q):
        th = A @ q + b
        J = pin.computeFrameJacobian(model, data, th, fid, pin.LOCAL_WORLD_ALIGNED)[rows] @ A
        JJ = J @ J.T
        out[k, 0] = (u @ np.linalg.solve(JJ, u)) ** -0.5
        if dynamics:
            M = pin.crba(model, data, th)
            M = A.T @ (np.triu(M) + np.triu(M, 1).T) @ A + arm
            Ju = J.T @ u
            out[k, 1] = 1.0 / (Ju @ np.linalg.solve(M, Ju))
            out[k, 2] = np.sqrt(np.linalg.det(JJ))
    return out


def batch_measures(dev, Q, u, dynamics: bool) -> np.ndarray:
    """The same (B, 3) from the batch API."""
    from rhi import metrics
    from rhi.devices import batch

    out = np.full((len(Q), 3), np.nan)
    if not dynamics:
        out[:, 0] = metrics.effective_manipulability(dev.jacobian(Q), u)
        return out
    t = batch.terms(dev, Q, ("J", "M"))
    out[:] = measures_of(t["J"], t["M"], u)
    return out


def measures_of(J, M, u) -> np.ndarray:
    """(B, 3) ρ, Λ, μ of J (B, m, n) and M (B, n, n) along u (m,) from `rhi.metrics`."""
    from rhi import metrics

    return np.stack([metrics.effective_manipulability(J, u), metrics.effective_inertia(J, M, u),
                     metrics.manipulability(J)], axis=-1)


def every_device(n: int, loop_n: int) -> None:
    """Print the batch-vs-Pinocchio-loop table for every device (see the module docstring)."""
    print(f"Batch measures for {n} configurations vs a plain Pinocchio loop (timed on {loop_n}, scaled); "
          "ratios are loop / batch")
    print(f"{'device':<15}{'n':>3}{'m':>3}{'J + rho':>12}{'loop':>12}{'ratio':>8}"
          f"{'J,M + rho,Lambda,mu':>22}{'loop':>12}{'ratio':>8}{'rho,Lambda,mu alone':>22}")
    from rhi.devices import batch

    spatial = []
    for dev in devices():
        rng = np.random.default_rng(0)
        Q = rng.uniform(np.maximum(dev.q_min, -np.pi), np.minimum(dev.q_max, np.pi), size=(n, dev.n))
        u = np.ones(dev.m) / np.sqrt(dev.m)
        ref = pinocchio_loop(dev, Q[:200], u, True)
        got = batch_measures(dev, Q[:200], u, True)
        ok = np.abs(ref[:, 0]) < np.inf
        np.testing.assert_allclose(got[ok], ref[ok], rtol=1e-10)  # the same numbers
        cells = []
        for dyn in (False, True):  # best of many short batch runs: one preemption on a busy machine is ~10 ms
            t_b = best_of(lambda dev=dev, Q=Q, u=u, dyn=dyn: batch_measures(dev, Q, u, dyn), 20)
            t_l = best_of(lambda dev=dev, Q=Q, u=u, dyn=dyn: pinocchio_loop(dev, Q[:loop_n], u, dyn), 3) * n / loop_n
            cells.append(f"{t_b * 1e3:9.2f} ms{t_l * 1e3:9.1f} ms{t_l / t_b:7.1f}x")
        t = batch.terms(dev, Q, ("J", "M"))
        t_m = best_of(lambda t=t, u=u: measures_of(t["J"], t["M"], u), 20)
        print(f"{dev.name:<15}{dev.n:>3}{dev.m:>3}{cells[0]:>32}{cells[1]:>42}{t_m / n * 1e9:15.0f} ns/conf")
        if dev.m == 3:
            spatial.append((dev, t["J"], t["M"]))
    print("\nEach measure alone, m = 3 (J) against m = 2 (its first two rows: the same n and M), in turns; "
          "ratio m = 3 / m = 2 per configuration")
    print(f"{'device':<15}{'n':>3}{'rho':>20}{'Lambda':>20}{'mu':>20}")
    for dev, J, M in spatial:
        ns = three_against_two(J, M) / n * 1e9
        print(f"{dev.name:<15}{dev.n:>3}" + "".join(f"{a:6.0f} /{b:4.0f} ns {a / b:4.2f}x" for a, b in ns))
    print()


def three_against_two(J, M, rounds: int = 30) -> np.ndarray:
    """(3, 2) best times [s] of ρ, Λ, μ from J (B, 3, n), M (B, n, n) (column 0) and from J's first two rows (1)."""
    from rhi import metrics

    sides = [(J, np.ones(3) / np.sqrt(3)), (np.ascontiguousarray(J[:, :2]), np.ones(2) / np.sqrt(2))]
    fns = [(lambda J=J, u=u: metrics.effective_manipulability(J, u), lambda J=J, u=u: metrics.effective_inertia(J, M, u),
            lambda J=J: metrics.manipulability(J)) for J, u in sides]
    best = np.full((3, 2), np.inf)
    for _ in range(rounds):  # in turns: a busy spell slows both sides alike
        for col, three in enumerate(fns):
            for row, fn in enumerate(three):
                best[row, col] = min(best[row, col], best_of(fn, 1))
    return best


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=10_000)
    p.add_argument("--loop-n", type=int, default=1_000, help="configurations timed in the Pinocchio loops (scaled)")
    p.add_argument("--rtb-n", type=int, default=2_000, help="configurations timed with RTB (scaled to --n)")
    args = p.parse_args()
    every_device(args.n, args.loop_n)

    t_import = float(subprocess.run(
        [sys.executable, "-c", "import time; t = time.perf_counter(); import rhi; print(time.perf_counter() - t)"],
        capture_output=True, text=True, check=True).stdout)

    import rhi
    from rhi import metrics

    dev = rhi.device("rhi4")
    rng = np.random.default_rng(0)
    Q = rng.uniform(dev.q_min, dev.q_max, size=(args.n, 4))
    u = np.array([0.0, 1.0])

    def batch():
        J, M = dev.jacobian(Q), dev.mass_matrix(Q)
        return metrics.effective_manipulability(J, u), metrics.effective_inertia(J, M, u)

    def own_loop(Qs=Q):
        out = np.empty((len(Qs), 2))
        for k, q in enumerate(Qs):
            J, M = dev.jacobian(q), dev.mass_matrix(q)
            out[k] = metrics.effective_manipulability(J, u), metrics.effective_inertia(J, M, u)
        return out

    rtb_loop = rtb_rho_lambda(dev, u, armature=False)

    rho, lam = batch()
    ref = rtb_loop(Q[:50])
    np.testing.assert_allclose(rho[:50], ref[:, 0], rtol=1e-8)
    # RTB's URDF dynamics mishandle the fixed link in the middle of the chain (phantom_base):
    # its M differs from Pinocchio's, which tests/test_rhi4.py checks against a hand derivation.
    lam_gap = float(np.max(np.abs(lam[:50] - ref[:, 1]) / lam[:50]))

    t_batch = best_of(batch, 3)
    t_loop = best_of(own_loop, 1)
    t_rtb = best_of(lambda: rtb_loop(Q[: args.rtb_n]), 1) * args.n / args.rtb_n

    q0 = Q[0]
    reps = 2000
    t = time.perf_counter()
    for _ in range(reps):
        rhi.all_measures(dev, q0, u, exact_force=False)
    t_measure = (time.perf_counter() - t) / reps
    t = time.perf_counter()
    for _ in range(200):
        rhi.all_measures(dev, q0, u)
    t_measure_lp = (time.perf_counter() - t) / 200

    print(f"rho + Lambda for {args.n} rhi4 configurations (rho identical to RTB's; RTB's Lambda off by up to "
          f"{100 * lam_gap:.0f} % from its mass matrix, see the comment above)")
    print(f"  batch API                      {t_batch * 1e3:9.1f} ms")
    print(f"  own per-configuration loop     {t_loop * 1e3:9.1f} ms   batch is {t_loop / t_batch:5.1f}x faster")
    print(f"  Robotics Toolbox loop (scaled) {t_rtb * 1e3:9.1f} ms   batch is {t_rtb / t_batch:5.1f}x faster (target >= 10x)")
    print(f"one rhi.all_measures call (no LP){t_measure * 1e6:9.1f} us   (target <= 100 us)")
    print(f"one rhi.all_measures call (LP)   {t_measure_lp * 1e6:9.1f} us")
    print(f"import rhi                       {t_import * 1e3:9.1f} ms")


if __name__ == "__main__":
    main()
