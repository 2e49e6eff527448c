"""Many ticks of `rhi.sim.mobile.simulate_mobile` in one compiled call, for the acceleration-level controllers.

`MobileLoop.build` accepts a run of an `AMDController` or a `PinvAccelController` (their own ``step``) on a
serial chain the compiled kinematics handle, on a `MobilePlant` (not a subclass: `simulate_mobile` checks) or
kinematic (no plant). `ticks` then runs
ticks k0..k1: the controller's tick (`rhi.control._compiled.mobile.accel_tick`), the integration and bound
checks, the wheel speeds, the log row and, on the plant, the slip (the seeded noise drawn beforehand from the
plant's generator, the same numbers `MobilePlant.realised_twist` draws) and the control period's MuJoCo steps
with the arm's servo references (`rhi.sim.mjc`). The arithmetic is that of the Python loop.

A tick the Python controller raises on (a singular arm, a non-finite measurement) ends the call; `MobileLoop.run`
then says so and `simulate_mobile` runs the whole simulation in Python, which raises there.
Imported by `simulate_mobile`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rhi.control._compiled import mobile as _mobile
from rhi.control.mobile import AMDController, PinvAccelController
from rhi.jit import jit
from rhi.sim.mjc import step1, step2

#: How a call of `ticks` ended: every tick ran; tick `done` needs the Python loop.
DONE, PYTHON = 0, 1

#: The compiled loop of the last `simulate_mobile` run, None where it ran in Python.
last: MobileLoop | None = None


@jit
def _finite(v):
    """Whether every entry of v is finite."""
    for i in range(v.shape[0]):
        if not math.isfinite(v[i]):
            return False
    return True


@jit
def ticks(k0, k1, dt, traj, ctl, state, plant, JV_pinv, logs):
    """Run ticks k0 ≤ k < k1 of `simulate_mobile`, one log row each.

    Args:
        k0: the first tick to run.
        k1: the tick after the last.
        dt: control period [s].
        traj: (t (K,), x, dx, ddx (K, 3)) the trajectory.
        ctl: `accel_tick`'s (kind, prm, bnd, ints, joints, fc, st).
        state: (q_ref (n,), dq (n,), flags (2,) int64: bounds kept, ticks done), advanced.
        plant: (on, model, data, qpos, ctrl, xpos (3,), qadr, act (3 + 2 m,), sub, h, JV (3, 4), eff (3,),
            ou (2,): the noise's decay and scale, noise (K, 3) normals, e (3,) the noise state).
        JV_pinv: (4, 3) wheel speeds of a body twist.
        logs: (q, q_true, dq, ddq, x, x_est, wheels, rec (K, 4): α, β, σ, base enabled).

    Returns:
        DONE, or PYTHON (tick state[2][1] raises in the Python controller; nothing of it is written).
    """
    t_, xs, dxs, ddxs = traj
    kind, prm, bnd, ints, joints, fc, st = ctl
    q_ref, dq, flags = state
    on, qpos, qadr = plant[0], plant[3], plant[6]
    Lq, Lqt, Ldq, Lddq, Lx, Lxe, Lw, Lrec = logs
    n = q_ref.shape[0]
    m = n - 3
    x = np.empty(3)
    ddq = np.empty(n)
    rec = np.empty(4)
    wheels = np.empty(4)
    dq_new, q_next, dq_mid = np.empty(n), np.empty(n), np.empty(n)
    for k in range(k0, k1):
        t = t_[k]
        q_meas = q_ref.copy()
        if on:
            for i in range(m):
                q_meas[3 + i] = qpos[qadr[3 + i]]
        if not (_finite(q_meas) and _finite(dq)):
            flags[1] = k
            return PYTHON
        st0 = st.copy()
        if _mobile.accel_tick(kind, prm, bnd, ints, joints, fc, st, t, q_meas, dq, xs[k], dxs[k], ddxs[k], x, ddq,
                              rec) != _mobile.OK:
            st[:] = st0
            flags[1] = k
            return PYTHON
        ok = flags[0] != 0
        for i in range(n):
            dq_new[i] = dq[i] + ddq[i] * dt
            q_next[i] = q_ref[i] + dq[i] * dt + 0.5 * ddq[i] * dt * dt
            dq_mid[i] = 0.5 * (dq[i] + dq_new[i])
            ok = ok and bnd[4, i] - 1e-9 <= ddq[i] <= bnd[5, i] + 1e-9 and bnd[2, i] - 1e-9 <= dq_new[i] <= \
                bnd[3, i] + 1e-9 and bnd[0, i] - 1e-9 <= q_next[i] <= bnd[1, i] + 1e-9
        flags[0] = 1 if ok else 0
        Lddq[k] = ddq
        Lrec[k] = rec
        wheel_speeds(JV_pinv, q_ref[2] + 0.5 * dq_mid[2] * dt, dq_mid, wheels)
        Lq[k], Ldq[k], Lxe[k], Lw[k] = q_meas, dq_new, x, wheels
        period(k, plant, q_ref, dq, ddq, wheels, q_meas, x, Lqt, Lx)
        q_ref[:], dq[:] = q_next, dq_new
        flags[1] = k + 1
    return DONE


@jit(inline=True)
def wheel_speeds(JV_pinv, th, v, wheels):
    """The wheels' speeds (4,) [rad/s] into `wheels` for the base velocity v[:3] = (ẋ, ẏ, θ̇) in the world at heading th [rad]."""
    c, s = math.cos(th), math.sin(th)
    tw0, tw1, tw2 = c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]
    for i in range(4):
        wheels[i] = JV_pinv[i, 0] * tw0 + JV_pinv[i, 1] * tw1 + JV_pinv[i, 2] * tw2


@jit(inline=True)
def period(k, plant, q_ref, dq, ddq, wheels, q_meas, x, Lqt, Lx):
    """Tick k's control period on the plant, or the kinematic run's log (q_meas, x).

    On the plant: its true q and x logged first, then the slip and the MuJoCo steps with the arm's servo references
    q + q̇ u + q̈ u²/2 and q̇ + q̈ u.
    """
    on, model, data, qpos, ctrl, xpos, qadr, act, sub, h, JV, eff, ou, noise, e = plant
    if not on:
        Lqt[k], Lx[k] = q_meas, x
        return
    n = q_ref.shape[0]
    m = n - 3
    v = np.empty(3)
    for i in range(n):
        Lqt[k, i] = qpos[qadr[i]]
    Lx[k] = xpos
    if ou[1] != 0.0:
        for r in range(3):
            e[r] = ou[0] * e[r] + ou[1] * noise[k, r]
    for r in range(3):
        v[r] = eff[r] * (JV[r, 0] * wheels[0] + JV[r, 1] * wheels[1] + JV[r, 2] * wheels[2] +
                         JV[r, 3] * wheels[3]) * (1.0 + e[r])
    for i in range(sub):
        u = (i + 1) * h
        ct, sn = math.cos(qpos[qadr[2]]), math.sin(qpos[qadr[2]])
        ctrl[act[0]], ctrl[act[1]], ctrl[act[2]] = ct * v[0] - sn * v[1], sn * v[0] + ct * v[1], v[2]
        for j in range(m):
            ctrl[act[3 + j]] = q_ref[3 + j] + dq[3 + j] * u + 0.5 * ddq[3 + j] * u * u
            ctrl[act[3 + m + j]] = dq[3 + j] + ddq[3 + j] * u
        step1(model, data)
        step2(model, data)


class MobileLoop:
    """The compiled ticks of one `simulate_mobile` run (`build` decides whether they apply, `why_not` says why not).

    Attributes:
        calls: compiled calls made.
    """

    def __init__(self, controller, plant, trajectory, q0: np.ndarray, JV_pinv: np.ndarray) -> None:
        dev, c, b = controller.device, controller.config, controller.bounds
        amd = isinstance(controller, AMDController)
        prm = np.zeros(_mobile.N_PARAMS)
        prm[_mobile.P_DT], prm[_mobile.P_KP], prm[_mobile.P_KD] = c.dt, c.kp, c.kd
        prm[_mobile.P_G1], prm[_mobile.P_G2], prm[_mobile.P_RANK] = c.gamma1, c.gamma2, 1e-6
        if amd:
            prm[_mobile.P_SIGMA], prm[_mobile.P_AVOID] = c.sigma_min, float(c.singularity_avoidance)
            prm[_mobile.P_RELEASE] = c.sigma_min if c.sigma_release is None else c.sigma_release
        else:
            prm[_mobile.P_MANIP], prm[_mobile.P_CLIP] = float(c.manipulability), float(c.limit == "clip")
        self.controller, self.plant, self.amd = controller, plant, amd
        ints, joints, fc = dev._fast_maps.chain
        bnd = np.array([b.q_min, b.q_max, b.dq_min, b.dq_max, b.ddq_min, b.ddq_max])
        self._st = np.zeros(_mobile.N_STATE)
        if amd:  # the controller's state as it is (fresh after its reset)
            cs = controller.state
            self._st[_mobile.S_BASE] = float(cs.base_active)
            self._st[_mobile.S_STOP_T0] = math.nan if cs.stop_t0 is None else cs.stop_t0
            self._st[_mobile.S_STOP_V:] = math.nan if cs.stop_v is None else cs.stop_v
        self._ctl = (_mobile.AMD if amd else _mobile.PINV, prm, bnd, ints, joints, fc, self._st)
        self._traj = (trajectory.t, trajectory.x, trajectory.dx, trajectory.ddx)
        self._state = (q0.copy(), np.zeros(dev.n), np.array([1, 0], dtype=np.int64))
        self._plant = pack_plant(plant, trajectory.t.size, float(c.dt))
        self._JV_pinv = np.ascontiguousarray(JV_pinv)
        self.calls = 0

    @staticmethod
    def why_not(controller, plant) -> str:
        """Why this run is not one the compiled loop computes ("" where it is; see the module)."""
        if type(controller) not in (AMDController, PinvAccelController):
            return f"the controller is a {type(controller).__name__}, not an AMDController or PinvAccelController"
        if "step" in controller.__dict__ or controller.n_base != 3:
            return "the controller's step is replaced"
        return chain_reason(controller.device)

    @staticmethod
    def build(controller, plant, trajectory, q0: np.ndarray, JV_pinv: np.ndarray) -> MobileLoop | None:
        """The compiled loop for this run, or None where some part of it is only Python's (`why_not`)."""
        if MobileLoop.why_not(controller, plant):
            return None
        return MobileLoop(controller, plant, trajectory, q0, JV_pinv)

    def run(self, log: dict[str, np.ndarray], scal: dict[str, np.ndarray],
            progress: Callable[[int, int], None] | None) -> bool | None:
        """Every tick into the log's arrays; whether the bounds were kept, or None where a tick needs Python.

        `progress` is called as the Python loop calls it (every 1 % of the run).
        """
        K = self._traj[0].size
        rec = np.empty((K, 4))
        logs = (log["q"], log["q_true"], log["dq"], log["ddq"], log["x"], log["x_est"], log["wheels"], rec)
        step = max(1, K // 100)
        ctl = self.controller
        ends = sorted({min(k + 1, K) for k in range(0, K, step)} | {K})
        k0 = 0
        for k1 in ends:
            out = ticks(k0, k1, self._ctl[1][_mobile.P_DT], self._traj, self._ctl, self._state, self._plant,
                        self._JV_pinv, logs)
            self.calls += 1
            if out != DONE:
                return None
            k0 = k1
            if progress is not None:
                progress(k1, K)
        for key, col in (("alpha", _mobile.R_ALPHA), ("beta", _mobile.R_BETA), ("sigma", _mobile.R_SIGMA),
                         ("base_active", _mobile.R_BASE)):
            scal[key][:] = rec[:, col]
        st = self._st.tolist()
        if self.amd:
            s = ctl.state
            s.t, s.base_active, s.steps = st[_mobile.S_T], st[_mobile.S_BASE] != 0.0, s.steps + int(st[_mobile.S_STEPS])
            stop = not math.isnan(st[_mobile.S_STOP_T0])
            s.stop_t0 = st[_mobile.S_STOP_T0] if stop else None
            s.stop_v = np.array(st[_mobile.S_STOP_V:]) if stop else None
        else:
            ctl.clipped += int(st[_mobile.S_CLIPPED])
        if self.plant is not None:
            self.plant._e = self._plant[-1].copy()
        return bool(self._state[2][0])


def pack_plant(plant, K: int, dt: float) -> tuple:
    """`ticks`' plant tuple of a run of K ticks of dt [s] on `plant` (a `MobilePlant`, or None: kinematic)."""
    if plant is None:
        z = np.zeros(1, dtype=np.int64)
        return (False, 0, 0, np.zeros(1), np.zeros(1), np.zeros(3), z, z, 0, 0.0, np.zeros((3, 4)), np.zeros(3),
                np.zeros(2), np.zeros((K, 3)), np.zeros(3))
    s = plant.slip
    ou, noise = np.zeros(2), np.zeros((K, 3))
    if s.noise > 0:
        a = math.exp(-dt / s.noise_tau)
        ou[:] = a, s.noise * math.sqrt(1.0 - a * a)
        noise = plant._rng.standard_normal((K, 3))  # the draws `realised_twist` makes, one row per tick
    d = plant.data
    act = np.concatenate([plant._base_act, plant._pos_act, plant._vel_act]).astype(np.int64)
    return (True, plant.model._address, d._address, d.qpos, d.ctrl, d.site_xpos[plant._site],
            plant._qadr.astype(np.int64), act, max(1, int(round(dt / plant.timestep))), plant.timestep, plant.JV,
            s.efficiency, ou, noise, plant._e.copy())

def chain_reason(dev) -> str:
    """Why `dev`'s chain is not one the compiled mobile kinematics handle ("" where it is)."""
    chain = dev._fast_maps.chain
    if chain is None or list(dev.model.parents)[1:] != list(range(dev.n)) or chain[1].shape[0] != dev.n:
        return f"the chain of {dev.name!r} is not a serial chain the compiled kinematics handle"
    return ""
