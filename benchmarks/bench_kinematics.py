"""Batch kinematics and dynamics (`rhi.devices.batch`): J, ∂J/∂q, M, g and ρ + Λ for 10,000 configurations.

Baselines, all measured in this run and printed as ratios:

* 4 batch calls: `Device.jacobian(Q)`, `jacobian_derivative(Q)`, `mass_matrix(Q)`, `gravity(Q)`,
  each its own compiled pass (the batch column is `rhi.devices.batch.terms`, one pass for the four);
* Pinocchio loop: per configuration, θ = A q + b, `computeFrameJacobian`, `crba`,
  `computeGeneralizedGravity` and ∂J/∂θ from `computeJointJacobiansTimeVariation` along each
  θ̇ = e_k (Pinocchio's way to the same four terms), mapped to motor coordinates;
* Pinocchio J, M, g only: the same loop without ∂J/∂q, `computeJointJacobians` once (a lower bound);
* previous batch API: `Device.jacobian(Q)` ... as they were, a Python loop over Pinocchio per
  configuration (the batch module switched off);
* `Device.terms` loop: the control path's one-pass per-configuration terms (closed-form ∂J/∂q);
* Robotics Toolbox loop for ρ + Λ (thesis eqs. 3.6, 3.10) on rhi4: `jacob0` and `inertia`
  with the same actuation map, timed on --rtb-n configurations and scaled.

Timings are the best of several runs in CPU time (`batch_baselines.best_of`: steady on a shared machine);
compare the ratios.
BLAS runs on one thread unless OPENBLAS_NUM_THREADS / OMP_NUM_THREADS say otherwise: on 2 cores
shared with other jobs, OpenBLAS's thread hand-off makes one medium-size call (the finite check
of `Device.theta` on 10⁴ configurations is an `np.vdot`) take up to ~15 ms instead of ~0.02 ms,
whatever code is being measured.
Run: python benchmarks/bench_kinematics.py [--n 10000]
"""

from __future__ import annotations

import argparse
import os

from batch_baselines import arms, best_of, rtb_rho_lambda  # first: BLAS on one thread before NumPy loads

# isort: split

import numpy as np
import pinocchio as pin


def pinocchio_loop(dev, Q, with_dJ: bool = True) -> None:
    model, data, A, b, rows = dev.model, dev.model.createData(), dev.A, dev.b, dev.task_rows
    fid, E = model.getFrameId(dev.ee_frame), np.eye(model.nv)
    for q in Q:
        th = A @ q + b
        if with_dJ:
            J = pin.computeFrameJacobian(model, data, th, fid, pin.LOCAL_WORLD_ALIGNED)[rows] @ A
            H = []
            for k in range(model.nv):
                pin.computeJointJacobiansTimeVariation(model, data, th, E[k])
                pin.updateFramePlacements(model, data)
                H.append(pin.getFrameJacobianTimeVariation(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[rows])
            dJ = np.einsum("kib,ba,kc->iac", np.array(H), A, A)
        else:
            pin.computeJointJacobians(model, data, th)
            J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[rows] @ A
        M = pin.crba(model, data, th)
        M = A.T @ (np.triu(M) + np.triu(M, 1).T) @ A
        g = A.T @ pin.computeGeneralizedGravity(model, data, th)
    del J, M, g
    if with_dJ:
        del dJ


def old_batch_api(dev, Q) -> None:
    saved = dev.__dict__.get("_batch")
    dev.__dict__["_batch"] = None  # the per-configuration loop the batch API used before rhi.devices.batch
    try:
        dev.jacobian(Q), dev.jacobian_derivative(Q), dev.mass_matrix(Q), dev.gravity(Q)
    finally:
        dev.__dict__["_batch"] = saved


def terms_loop(dev, Q) -> None:
    for q in Q:
        dev.terms(q, check=False)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=10_000)
    p.add_argument("--loop-n", type=int, default=2_000, help="configurations timed in the loops (scaled to --n)")
    p.add_argument("--rtb-n", type=int, default=1_000, help="configurations timed with RTB (scaled to --n)")
    args = p.parse_args()

    import rhi
    from rhi import metrics
    from rhi.devices import batch

    scale = args.n / args.loop_n
    print(f"J, dJ/dq, M and g for {args.n} configurations (loops timed on {args.loop_n} and scaled; "
          f"BLAS threads: {os.environ['OPENBLAS_NUM_THREADS']})")
    print("batch: rhi.devices.batch.terms, the four terms from one compiled pass; ratios are baseline / batch")
    print(f"{'device':<9}{'batch':>9}{'4 batch calls':>21}{'Pinocchio loop':>22}{'Pinocchio J,M,g':>22}"
          f"{'previous batch API':>25}{'Device.terms loop':>24}")
    for dev in [rhi.device("rhi4"), rhi.device("phantom3"), rhi.device("gen3"), *arms()]:
        Q = np.random.default_rng(0).uniform(np.maximum(dev.q_min, -np.pi), np.minimum(dev.q_max, np.pi),
                                             size=(args.n, dev.n))
        Ql = Q[: args.loop_n]
        dev._batch.evaluate(dev.theta(Q[:64]), ("J",))  # build the constant maps once

        def four_calls(dev=dev, Q=Q):
            dev.jacobian(Q), dev.jacobian_derivative(Q), dev.mass_matrix(Q), dev.gravity(Q)

        t_b = best_of(lambda dev=dev, Q=Q: batch.terms(dev, Q, ("J", "dJ", "M", "g")))
        t_four = best_of(four_calls)
        t_pin = best_of(lambda dev=dev, Ql=Ql: pinocchio_loop(dev, Ql), 2) * scale
        t_lean = best_of(lambda dev=dev, Ql=Ql: pinocchio_loop(dev, Ql, with_dJ=False), 2) * scale
        t_old = best_of(lambda dev=dev, Ql=Ql: old_batch_api(dev, Ql), 2) * scale
        t_terms = best_of(lambda dev=dev, Ql=Ql: terms_loop(dev, Ql), 2) * scale
        cells = [f"{t * 1e3:8.1f} ms {t / t_b:5.1f}x" for t in (t_four, t_pin, t_lean, t_old, t_terms)]
        print(f"{dev.name:<9}{t_b * 1e3:6.1f} ms" + "".join(f"{c:>23}" for c in cells))

    dev = rhi.device("rhi4")
    Q = np.random.default_rng(0).uniform(dev.q_min, dev.q_max, size=(args.n, dev.n))
    u = np.array([0.0, 1.0])

    def rho_lambda(dev=dev, Q=Q):
        J, M = dev.jacobian(Q), dev.mass_matrix(Q)
        return metrics.effective_manipulability(J, u), metrics.effective_inertia(J, M, u)

    rtb_loop = rtb_rho_lambda(dev, u, armature=True)

    rho, lam = rho_lambda()
    np.testing.assert_allclose(rho[:50], rtb_loop(Q[:50])[:, 0], rtol=1e-8)  # same ρ as the Robotics Toolbox
    t_b = best_of(rho_lambda)
    t_rtb = best_of(lambda: rtb_loop(Q[: args.rtb_n]), 1) * args.n / args.rtb_n
    saved = dev.__dict__.pop("_batch")
    dev.__dict__["_batch"] = None
    t_old = best_of(lambda: rho_lambda(Q=Q[: args.loop_n]), 2) * scale
    dev.__dict__["_batch"] = saved
    print(f"\nrho + Lambda for {args.n} rhi4 configurations (thesis eqs. 3.6, 3.10)")
    print(f"  batch (rhi.devices.batch + metrics)     {t_b * 1e3:8.1f} ms")
    print(f"  previous batch API              {t_old * 1e3:8.1f} ms   batch is {t_old / t_b:6.1f}x faster")
    print(f"  Robotics Toolbox loop (scaled)  {t_rtb * 1e3:8.1f} ms   batch is {t_rtb / t_b:6.1f}x faster "
          "(target >= 40x)")


if __name__ == "__main__":
    main()
