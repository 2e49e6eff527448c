"""Many ticks of `rhi.sim.mobile.simulate_mobile` in one compiled call, for App. A's velocity-level controller.

`VelocityLoop.build` accepts a run of a `WeightedDistributionController` (its own ``step`` and ``advance``) on a
serial chain the compiled kinematics handle, on a `MobilePlant` or kinematic, whose stages are all known.
`ticks` then runs ticks k0..k1: the controller's tick (`rhi.control._compiled.mobile_velocity.velocity_tick`),
the integration q⁺ = q + q̇T and bound checks, the wheel speeds, the log row and the control period on the plant
(`rhi.sim._compiled.mobile_loop.period`, with q̈ = 0: the servo references q + q̇ u and q̇). The arithmetic is
that of the Python loop. A tick the Python controller raises on (Jᵀu = 0, a non-finite measurement) ends the
call; `simulate_mobile` then runs the whole simulation in Python, which raises there.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rhi.control._compiled import mobile_velocity as _vel
from rhi.control.mobile import WeightedDistributionController
from rhi.jit import jit
from rhi.sim._compiled.mobile_loop import DONE, PYTHON, chain_reason, pack_plant, period, wheel_speeds

#: The compiled loop of the last `simulate_mobile` run of App. A's controller, None where it ran in Python.
last: VelocityLoop | None = None

_STAGES = {"track": _vel.TRACK, "dm_cartesian": _vel.DM_CARTESIAN, "dm_null": _vel.DM_NULL}


@jit
def ticks(k0, k1, dt, traj, ctl, stages, state, plant, JV_pinv, logs):
    """Run ticks k0 ≤ k < k1 of `simulate_mobile`, one log row each.

    Args:
        k0: the first tick to run.
        k1: the tick after the last.
        dt: control period [s].
        traj: (t (K,), x, dx (K, 3)) the trajectory.
        ctl: `velocity_tick`'s (prm, bnd, ints, joints, fc).
        stages: (K,) int64 each tick's stage code.
        state: (q_ref (n,), dq (n,), flags (2,) int64: bounds kept, ticks done), advanced.
        plant: `rhi.sim._compiled.mobile_loop.pack_plant`'s tuple.
        JV_pinv: (4, 3) wheel speeds of a body twist.
        logs: (q, q_true, dq, x, x_est, wheels, rec (K, 3): γ, η, H₂).

    Returns:
        DONE, or PYTHON (tick state[2][1] raises in the Python controller; nothing of it is written).
    """
    _, xs, dxs = traj
    prm, bnd, ints, joints, fc = ctl
    q_ref, dq, flags = state
    on, qpos, qadr = plant[0], plant[3], plant[6]
    Lq, Lqt, Ldq, Lx, Lxe, Lw, Lrec = logs
    n = q_ref.shape[0]
    x, rec, wheels = np.empty(3), np.empty(3), np.empty(4)
    dq_new, q_next, zero = np.empty(n), np.empty(n), np.zeros(n)
    for k in range(k0, k1):
        q_meas = q_ref.copy()
        if on:
            for i in range(3, n):
                q_meas[i] = qpos[qadr[i]]
        finite = True
        for i in range(n):
            finite = finite and math.isfinite(q_meas[i])
        if not finite or _vel.velocity_tick(prm, bnd, ints, joints, fc, stages[k], q_meas, xs[k], dxs[k], x, dq_new,
                                            rec) != _vel.OK:
            flags[1] = k
            return PYTHON
        ok = flags[0] != 0
        for i in range(n):
            q_next[i] = q_ref[i] + dq_new[i] * dt
            ok = ok and bnd[2, i] - 1e-9 <= dq_new[i] <= bnd[3, i] + 1e-9 and \
                bnd[0, i] - 1e-9 <= q_next[i] <= bnd[1, i] + 1e-9
        flags[0] = 1 if ok else 0
        Lrec[k] = rec
        wheel_speeds(JV_pinv, q_ref[2] + 0.5 * dq_new[2] * dt, dq_new, wheels)
        Lq[k], Ldq[k], Lxe[k], Lw[k] = q_meas, dq_new, x, wheels
        period(k, plant, q_ref, dq_new, zero, wheels, q_meas, x, Lqt, Lx)
        q_ref[:], dq[:] = q_next, dq_new
        flags[1] = k + 1
    return DONE


def settings(controller: WeightedDistributionController) -> np.ndarray:
    """`velocity_tick`'s parameter vector (P_* slots, then the DM vector) of `controller`."""
    c, g, m = controller.config, controller.geometry, controller.m
    prm = np.zeros(_vel.N_PARAMS + 3 + m + 9)
    prm[_vel.P_DT], prm[_vel.P_KX], prm[_vel.P_EPS] = c.dt, c.k_x, c.epsilon
    prm[_vel.P_DIST] = {"weighted": _vel.WEIGHTED, "pinv": _vel.PINV, "pinv_generalized": _vel.PINV_GENERALIZED}[
        c.distribution]
    prm[_vel.P_NULL] = _vel.NULL_WEIGHTED if c.null_space == "weighted" else _vel.NULL_GENERALIZED
    prm[_vel.P_WEIGHT] = _vel.GENERALIZED if c.weighting == "generalized" else _vel.WHEEL
    prm[_vel.P_R], prm[_vel.P_L] = g["wheel_radius"], g["half_length"] + g["half_width"]
    d = c.dm
    if d is not None:
        prm[_vel.P_DM], prm[_vel.P_KC], prm[_vel.P_KN] = 1.0, d.k_c, d.k_n
        prm[_vel.P_PRINTED] = float(d.gradient == "printed")
        at = _vel.N_PARAMS
        prm[at:at + 3], prm[at + 3:at + 3 + m] = d.u, d.torque_limits
        for i, ax in enumerate(d.axes):
            k = at + 3 + m + 3 * "xyz".index(ax)
            prm[k:k + 3] = 1.0, d.x_min[i], d.x_max[i]
    return prm


class VelocityLoop:
    """The compiled ticks of one `simulate_mobile` run of App. A's controller (`build`, `why_not`).

    Attributes:
        calls: compiled calls made.
    """

    def __init__(self, controller, plant, trajectory, q0: np.ndarray, JV_pinv: np.ndarray, stages: np.ndarray) -> None:
        dev, b = controller.device, controller.bounds
        self.controller, self.plant = controller, plant
        ints, joints, fc = dev._fast_maps.chain
        bnd = np.array([b.q_min, b.q_max, b.dq_min, b.dq_max, b.ddq_min, b.ddq_max])
        self._ctl = (settings(controller), bnd, ints, joints, fc)
        self._stages = stages
        self._traj = (trajectory.t, trajectory.x, trajectory.dx)
        self._state = (q0.copy(), np.zeros(dev.n), np.array([1, 0], dtype=np.int64))
        self._plant = pack_plant(plant, trajectory.t.size, float(controller.config.dt))
        self._JV_pinv = np.ascontiguousarray(JV_pinv)
        self.calls = 0

    @staticmethod
    def stage_codes(controller, trajectory, stage_of: Callable[[float], str]) -> np.ndarray | None:
        """Each tick's stage code (K,), or None where a stage is unknown or needs a DMConfig the controller lacks."""
        names = [stage_of(float(t)) for t in trajectory.t]
        if any(s not in _STAGES or (s != "track" and controller.config.dm is None) for s in names):
            return None
        return np.array([_STAGES[s] for s in names], dtype=np.int64)

    @staticmethod
    def why_not(controller) -> str:
        """Why this run is not one the compiled loop computes ("" where it is; see the module)."""
        if type(controller) is not WeightedDistributionController:
            return f"the controller is a {type(controller).__name__}, not a WeightedDistributionController"
        if {"step", "advance"} & set(controller.__dict__) or controller.n_wheels != 4:
            return "the controller's step is replaced"
        return chain_reason(controller.device)

    @staticmethod
    def build(controller, plant, trajectory, q0: np.ndarray, JV_pinv: np.ndarray,
              stage_of: Callable[[float], str]) -> VelocityLoop | None:
        """The compiled loop for this run, or None where some part of it is only Python's."""
        if VelocityLoop.why_not(controller):
            return None
        stages = VelocityLoop.stage_codes(controller, trajectory, stage_of)
        return None if stages is None else VelocityLoop(controller, plant, trajectory, q0, JV_pinv, stages)

    def run(self, log: dict[str, np.ndarray], scal: dict[str, np.ndarray],
            progress: Callable[[int, int], None] | None) -> bool | None:
        """Every tick into the log's arrays; whether the bounds were kept, or None where a tick needs Python.

        `progress` is called as the Python loop calls it (every 1 % of the run).
        """
        K = self._traj[0].size
        rec = np.empty((K, 3))
        logs = (log["q"], log["q_true"], log["dq"], log["x"], log["x_est"], log["wheels"], rec)
        step = max(1, K // 100)
        ends = sorted({min(k + 1, K) for k in range(0, K, step)} | {K})
        k0 = 0
        for k1 in ends:
            out = ticks(k0, k1, self._ctl[0][_vel.P_DT], self._traj, self._ctl, self._stages, self._state,
                        self._plant, self._JV_pinv, logs)
            self.calls += 1
            if out != DONE:
                return None
            k0 = k1
            if progress is not None:
                progress(k1, K)
        for key, col in (("gamma", _vel.R_GAMMA), ("eta", _vel.R_ETA), ("dm", _vel.R_DM)):
            scal[key][:] = rec[:, col]
        if self.plant is not None:
            self.plant._e = self._plant[-1].copy()
        return bool(self._state[2][0])
