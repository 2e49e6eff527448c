"""What the batch benchmarks share: BLAS on one thread, best-of CPU timing, the arms, the Robotics Toolbox loop.

bench_kinematics and bench_measures: Panda and UR5 of example-robot-data, and ρ, Λ on rhi4 with the Robotics Toolbox.

Import it before NumPy: it sets OPENBLAS_NUM_THREADS / OMP_NUM_THREADS to 1 unless they are set (on 2 cores shared
with other jobs, OpenBLAS's thread hand-off makes one medium-size call take up to ~15 ms instead of ~0.02 ms).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before NumPy loads its BLAS

import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402


def best_of(fn, repeat: int = 5) -> float:
    """Minimum CPU time of this process (user + system, all threads) over `repeat` calls [s].

    Not the wall clock: on a machine shared with other jobs a call longer than the scheduler's time slice
    (a few ms) is preempted on every run, so its best wall time grows with the load while a short call's
    does not, and the ratios between them drift; the CPU time stays what the call costs. On a quiet
    machine the two agree (everything timed runs on one thread).
    """
    times = []
    for _ in range(repeat):
        t = time.process_time()
        fn()
        times.append(time.process_time() - t)
    return min(times)


def arms():
    """Panda and UR5 from example-robot-data (dropped with a note when it is not installed)."""
    from rhi.devices.loaders import device_from_description

    out = []
    for name, ee in (("panda", "panda_hand_tcp"), ("ur5", "tool0")):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out.append(device_from_description(name, ee_frame=ee))
        except Exception as exc:  # noqa: BLE001 - a missing optional package only drops a row
            print(f"({name}: {exc})")
    return out


def rtb_rho_lambda(dev, u, *, armature: bool):
    """``loop(Q) -> (B, 2) ρ, Λ`` along u (m,) per configuration of rhi4 `dev` with the Robotics Toolbox.

    Thesis eqs. 3.6, 3.10 on its model of the same URDF with the same actuation map (J_q = J_θ A, M_q = Aᵀ M_θ A,
    plus the motors' armature when `armature`).
    """
    from rhi.devices.model import MODELS

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import roboticstoolbox as rtb

        robot = rtb.Robot.URDF(str((MODELS / "rhi4" / "rhi4.urdf").resolve()))
    A, b = dev.A, dev.b
    arm = np.diag(dev.armature) if armature else 0.0

    def loop(Qs):
        out = np.empty((len(Qs), 2))
        for k, q in enumerate(Qs):
            th = A @ q + b
            J = robot.jacob0(th, end="handle")[:2] @ A
            M = A.T @ robot.inertia(th) @ A + arm
            out[k] = (u @ np.linalg.solve(J @ J.T, u)) ** -0.5, 1.0 / (u @ J @ np.linalg.solve(M, J.T) @ u)
        return out

    return loop
