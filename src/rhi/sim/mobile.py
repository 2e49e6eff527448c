"""MuJoCo plant of the wheeled mobile manipulator and its simulation loop (thesis App. A and B).

**Plant.** The ``wmm`` chain (slide x, slide y, yaw hinge, then the Gen3 arm) is written as
an `MjSpec` (`rhi.sim.mobile_spec`) from the same Pinocchio model the controllers use. The base is *velocity
commanded* through stiff velocity servos on its three planar joints and is *less
accurate than the arm*: the commanded wheel speeds v_b produce the body twist
J_V v_b (eq. A.21 / B.21), of which the ground transmits only

    twist_real = (1 − s) ⊙ twist_cmd ⊙ (1 + e(t)),

s = [s_x, s_y, s_θ] constant slip ratios (lateral slip of Mecanum rollers is the
largest, §A.4.2) and e(t) a seeded Ornstein–Uhlenbeck tracking noise with relative
standard deviation ``noise`` and correlation time ``noise_tau`` (`SlipModel`). The arm is
commanded in joint velocity: its position/velocity servos (Kinova's low-level loop,
gravity compensated, torques within 32/13 N m) track the integrated command.

**Sensing.** As on the thesis's robot, the controllers see the arm encoders and the
*odometry* of the base (the forward kinematics of the commanded wheel speeds), never the
base's true pose: slip therefore shows up as end-effector tracking error, measured on
the true end-effector (the motion-capture role of §A.4.1, §B.4.1).

**Loop.** `simulate_mobile` runs a velocity-level (App. A) or acceleration-level (App. B)
controller at its sampling time over a sampled `Trajectory` and returns a `MobileLog`.
Without a plant (``plant=None``) the robot follows its command exactly (kinematic
simulation, as the thesis's §A.4.3 simulation).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from rhi._validate import as_array
from rhi.devices.mobile_base import body_map, wheel_geometry
from rhi.devices.model import Device, device as load_device
from rhi.errors import InvalidInput, ModelError
from rhi.sim.mobile_spec import wmm_spec

if TYPE_CHECKING:
    from rhi.control.mobile import MobileController

# ================================================================== trajectories
@dataclasses.dataclass(frozen=True, eq=False)
class Trajectory:
    """A desired end-effector trajectory sampled at the control period.

    Attributes:
        t: (K,) sample times [s], uniformly spaced.
        x, dx, ddx: (K, 3) position [m], velocity [m/s], acceleration [m/s²] (world frame).
    """

    t: np.ndarray
    x: np.ndarray
    dx: np.ndarray
    ddx: np.ndarray

    def __post_init__(self) -> None:
        t = as_array("trajectory.t", self.t, ndim_min=1)
        if t.ndim != 1 or t.size < 1:
            raise InvalidInput(f"trajectory.t: expected shape (K,), got {t.shape}")
        for name in ("x", "dx", "ddx"):
            a = as_array(f"trajectory.{name}", getattr(self, name), shape_tail=(t.size, 3))
            if a.ndim != 2:
                raise InvalidInput(f"trajectory.{name}: expected shape ({t.size}, 3), got {a.shape}")
            object.__setattr__(self, name, a)
        if t.size > 1 and np.any(np.diff(t) <= 0):
            raise InvalidInput("trajectory.t: must increase strictly")
        object.__setattr__(self, "t", t)

    @property
    def dt(self) -> float:
        """Sampling period [s] (0 for a single sample)."""
        return float(self.t[1] - self.t[0]) if self.t.size > 1 else 0.0


def circle(x0, radius: float, *, duration: float, dt: float, omega: float = math.pi / 20) -> Trajectory:
    """x_d(t) = x0 + [−R(cos ωt − 1), −R sin ωt, 0] (thesis §A.4.2, §B.4.2; ω = π/20 rad/s).

    Args:
        x0: (3,) start (and leftmost point) of the circle [m].
        radius: R [m] (thesis 0.25 m beyond the arm's workspace, 0.1 m within).
        duration: length [s] (one turn is 2π/ω = 40 s).
        dt: sampling period [s].
        omega: angular rate ω [rad/s].
    """
    x0 = as_array("x0", x0, shape_tail=(3,))
    if not math.isfinite(radius) or radius < 0:
        raise InvalidInput(f"radius: must be finite and >= 0 [m], got {radius!r}")
    if not math.isfinite(dt) or dt <= 0 or not math.isfinite(duration) or duration <= 0:
        raise InvalidInput(f"dt/duration: must be finite and > 0, got {dt!r}, {duration!r}")
    t = np.arange(int(round(duration / dt)) + 1) * dt
    c, s = np.cos(omega * t), np.sin(omega * t)
    z = np.zeros_like(t)
    x = x0 + np.stack([-radius * (c - 1), -radius * s, z], axis=1)
    dx = np.stack([radius * omega * s, -radius * omega * c, z], axis=1)
    ddx = np.stack([radius * omega**2 * c, radius * omega**2 * s, z], axis=1)
    return Trajectory(t, x, dx, ddx)


def hold(x, *, duration: float, dt: float) -> Trajectory:
    """Hold the end-effector at x: (3,) [m] for `duration` [s]."""
    x = as_array("x", x, shape_tail=(3,))
    if not math.isfinite(dt) or dt <= 0 or not math.isfinite(duration) or duration <= 0:
        raise InvalidInput(f"dt/duration: must be finite and > 0, got {dt!r}, {duration!r}")
    t = np.arange(int(round(duration / dt)) + 1) * dt
    z = np.zeros((t.size, 3))
    return Trajectory(t, np.broadcast_to(x, z.shape).copy(), z, z.copy())


# ========================================================================= slip
@dataclasses.dataclass(frozen=True)
class SlipModel:
    """How the ground realises the commanded base twist (our model; the thesis measures, not models, it).

    Attributes:
        longitudinal: s_x, fraction of the commanded forward velocity lost.
        lateral: s_y, fraction of the commanded sideways velocity lost (largest on Mecanum wheels, §A.4.2).
        yaw: s_θ, fraction of the commanded turn rate lost.
        noise: relative standard deviation of the coloured tracking noise e(t).
        noise_tau: correlation time of e(t) [s].
        seed: seed of e(t).
    """

    longitudinal: float = 0.03
    lateral: float = 0.08
    yaw: float = 0.05
    noise: float = 0.05
    noise_tau: float = 0.5
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("longitudinal", "lateral", "yaw"):
            v = getattr(self, name)
            if not math.isfinite(v) or not 0.0 <= v < 1.0:
                raise InvalidInput(f"{name}: slip ratio must lie in [0, 1), got {v!r}")
        if not math.isfinite(self.noise) or self.noise < 0:
            raise InvalidInput(f"noise: must be finite and >= 0, got {self.noise!r}")
        if not math.isfinite(self.noise_tau) or self.noise_tau <= 0:
            raise InvalidInput(f"noise_tau: must be finite and > 0 [s], got {self.noise_tau!r}")

    @classmethod
    def none(cls) -> SlipModel:
        """A perfect base (pure rolling, the assumption of eq. A.3)."""
        return cls(0.0, 0.0, 0.0, 0.0)

    @property
    def efficiency(self) -> np.ndarray:
        """(3,) 1 − s."""
        return 1.0 - np.array([self.longitudinal, self.lateral, self.yaw])


def base_to_wheels(JV_pinv: np.ndarray, dq_b, theta_b: float) -> np.ndarray:
    """Wheel speeds (4,) [rad/s] of the generalized base velocity dq_b = [ẋ_b, ẏ_b, θ̇_b] at heading θ_b [rad].

    The world velocity is rotated into the base frame and mapped by JV_pinv, the
    pseudoinverse of `rhi.devices.mobile_base.body_map` (eq. A.21 inverted; no slip).
    """
    c, s = math.cos(theta_b), math.sin(theta_b)
    return JV_pinv @ np.array([c * dq_b[0] + s * dq_b[1], -s * dq_b[0] + c * dq_b[1], dq_b[2]])


# ======================================================================== plant
class MobilePlant:
    """The wmm in MuJoCo: a slipping velocity-commanded base carrying a servoed arm.

    Args:
        device: the mobile manipulator (default ``rhi.device("wmm")``).
        slip: ground model of the base (`SlipModel`); `SlipModel.none()` for a perfect base.
        timestep: physics step [s].
        geometry: Mecanum geometry {wheel_radius, half_length, half_width} [m]; None: the device's.
        visual: give the model visual geometry (arm, Mecanum chassis and wheels, floor).
        **gains: `wmm_spec` servo gains (arm_kp, arm_kv, base_kv, armature).

    Attributes:
        spec, model, data: the MuJoCo spec, model and data (ground truth; controllers never read them).
    """

    def __init__(self, device: Device | None = None, *, slip: SlipModel | None = None, timestep: float = 1e-3,
                 geometry: dict | None = None, visual: bool = True, **gains: float) -> None:
        self.device = device or load_device("wmm")
        self.slip = slip if slip is not None else SlipModel()
        self.geometry = dict(geometry or wheel_geometry(self.device))
        self.JV = body_map(**self.geometry)
        self.JV_pinv = np.linalg.pinv(self.JV)
        self.spec = wmm_spec(self.device, timestep=timestep, geometry=self.geometry, visual=visual, **gains)
        try:
            self.model = self.spec.compile()
        except ValueError as exc:
            raise ModelError(f"device: MuJoCo rejected the plant of {self.device.name}: {exc}") from None
        self.data = mujoco.MjData(self.model)
        self.timestep = float(timestep)
        self.n = self.device.n
        names = self.device.joint_names
        self._qadr = np.array([self.model.joint(nm).qposadr[0] for nm in names])
        self._vadr = np.array([self.model.joint(nm).dofadr[0] for nm in names])
        self._base_act = np.array([self.model.actuator(f"vel_{nm}").id for nm in names[:3]])
        self._pos_act = np.array([self.model.actuator(f"pos_{nm}").id for nm in names[3:]])
        self._vel_act = np.array([self.model.actuator(f"vel_{nm}").id for nm in names[3:]])
        self._site = self.model.site("ee").id
        self._rng = np.random.default_rng(self.slip.seed)
        self._e = np.zeros(3)

    def reset(self, q0) -> None:
        """Place the robot at rest at q0: (n,) [x_b, y_b, θ_b, q_m] and re-seed the slip noise.

        Raises:
            InvalidInput: q0 has the wrong shape, is not finite or lies outside the joint limits.
        """
        q0 = as_array("q0", q0, shape_tail=(self.n,))
        if q0.ndim != 1:
            raise InvalidInput(f"q0: expected shape ({self.n},), got {q0.shape}")
        if not self.device.within_limits(q0):
            raise InvalidInput(f"q0: start configuration outside the joint limits of {self.device.name}")
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self._qadr] = q0
        self.data.ctrl[self._pos_act] = q0[3:]
        mujoco.mj_forward(self.model, self.data)
        self._rng = np.random.default_rng(self.slip.seed)
        self._e = np.zeros(3)

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return float(self.data.time)

    @property
    def q(self) -> np.ndarray:
        """(n,) true configuration [x_b, y_b, θ_b, q_m] (the arm part is what its encoders read)."""
        return self.data.qpos[self._qadr].copy()

    @property
    def dq(self) -> np.ndarray:
        """(n,) true joint velocities."""
        return self.data.qvel[self._vadr].copy()

    @property
    def x(self) -> np.ndarray:
        """(3,) true end-effector position [m] (world frame): the motion-capture measurement."""
        return self.data.site_xpos[self._site].copy()

    def realised_twist(self, wheels: np.ndarray, duration: float) -> np.ndarray:
        """Body twist [v_x, v_y, ω] the ground gives for wheel speeds (4,) [rad/s] over `duration` [s]."""
        s = self.slip
        if s.noise > 0:
            a = math.exp(-duration / s.noise_tau)
            self._e = a * self._e + s.noise * math.sqrt(1.0 - a * a) * self._rng.standard_normal(3)
        return s.efficiency * (self.JV @ wheels) * (1.0 + self._e)

    def step(self, wheels, q_arm, dq_arm, duration: float) -> None:
        """Advance by `duration` [s] (a multiple of the timestep).

        Args:
            wheels: (4,) commanded wheel speeds [rad/s] (front-left, front-right, back-left, back-right).
            q_arm: callable s ↦ (m,) or (m,) arm position reference [rad], 0 ≤ s ≤ duration [s].
            dq_arm: callable s ↦ (m,) or (m,) arm velocity reference [rad/s].
            duration: time to advance [s].
        """
        h = self.timestep
        k = max(1, int(round(duration / h)))
        v0, v1, w = self.realised_twist(np.asarray(wheels, dtype=float), duration).tolist()
        # everything the substeps reuse, fetched once (MjData's arrays never move); the arithmetic is unchanged
        model, qpos, ctrl, step = self.model, self.data.qpos, self.data.ctrl, mujoco.mj_step
        i_th, base, pos, vel = int(self._qadr[2]), self._base_act, self._pos_act, self._vel_act
        q_fn, dq_fn = callable(q_arm), callable(dq_arm)
        for i in range(k):
            s = (i + 1) * h
            th = qpos[i_th]
            c, sn = math.cos(th), math.sin(th)
            ctrl[base] = (c * v0 - sn * v1, sn * v0 + c * v1, w)
            ctrl[pos] = q_arm(s) if q_fn else q_arm
            ctrl[vel] = dq_arm(s) if dq_fn else dq_arm
            step(model, self.data)

    def wheel_speeds(self, dq_b, theta_b: float) -> np.ndarray:
        """Wheel speeds (4,) [rad/s] realising the generalized base velocity dq_b = [ẋ_b, ẏ_b, θ̇_b] at heading θ_b (no slip)."""
        return base_to_wheels(self.JV_pinv, dq_b, theta_b)


# ========================================================================== log
@dataclasses.dataclass
class MobileLog:
    """What a run recorded, one row per control step (K steps).

    Attributes:
        t: (K,) time [s].
        q: (K, n) configuration the controller saw: base odometry + arm encoders.
        q_true: (K, n) true configuration (MuJoCo; = q for a kinematic run).
        dq: (K, n) commanded generalized velocities [m/s, rad/s] after the step.
        ddq: (K, n) commanded accelerations (NaN for velocity-level controllers).
        x: (K, 3) true end-effector position [m].
        x_est: (K, 3) end-effector position from the controller's kinematics [m].
        x_des: (K, 3) desired position [m].
        wheels: (K, 4) commanded wheel speeds [rad/s].
        base_active, alpha, beta, gamma, eta, sigma, dm: (K,) controller state (NaN where
            the controller has none): base enabled (AMD), task / tertiary scaling, motion
            weight γ and η (App. A), σ_min(J_m) [m/rad], directional manipulability [N].
        bounds_ok: whether every commanded position, velocity and acceleration stayed within
            the joint bounds.
        params: the run's settings (controller, slip model, rates).
    """

    t: np.ndarray
    q: np.ndarray
    q_true: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    x: np.ndarray
    x_est: np.ndarray
    x_des: np.ndarray
    wheels: np.ndarray
    base_active: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    gamma: np.ndarray
    eta: np.ndarray
    sigma: np.ndarray
    dm: np.ndarray
    bounds_ok: bool
    params: dict

    @property
    def error(self) -> np.ndarray:
        """(K, 3) true tracking error x − x_des [m]."""
        return self.x - self.x_des

    @property
    def base_velocity(self) -> np.ndarray:
        """(K, 3) commanded generalized base velocity [ẋ_b [m/s], ẏ_b [m/s], θ̇_b [rad/s]]."""
        return self.dq[:, :3]

    def base_stats(self, tol: float = 1e-9) -> dict[str, np.ndarray]:
        """Max |.|, RMS (over the whole run) and commanded duration (|.| > tol) of each base velocity component.

        Returns:
            {"max": (3,), "rms": (3,), "duration": (3,) [s], "first": first time any base
            velocity is commanded [s] (NaN if never), "last": last such time [s]}.
        """
        v = self.base_velocity
        dt = float(self.t[1] - self.t[0]) if self.t.size > 1 else 0.0
        moving = np.abs(v) > tol
        anym = moving.any(axis=1)
        return {
            "max": np.abs(v).max(axis=0),
            "rms": np.sqrt(np.mean(v**2, axis=0)),
            "duration": moving.sum(axis=0) * dt,
            "first": float(self.t[anym][0]) if anym.any() else math.nan,
            "last": float(self.t[anym][-1]) if anym.any() else math.nan,
        }


# ========================================================================= loop
def _compiled(controller, plant, trajectory, q0, JV_pinv, stage_of):
    """The compiled loop of this run (`rhi.sim._compiled.mobile_loop`, `velocity_loop`), or None where none applies."""
    from rhi.control.mobile import AMDController, PinvAccelController, WeightedDistributionController

    if plant is not None and type(plant) is not MobilePlant:
        return None
    if type(controller) is WeightedDistributionController:
        from rhi.sim._compiled import velocity_loop  # Numba: only for the controllers it computes

        vloop = velocity_loop.VelocityLoop.build(controller, plant, trajectory, q0, JV_pinv, stage_of)
        velocity_loop.last = vloop
        return vloop
    if type(controller) not in (AMDController, PinvAccelController):
        return None
    from rhi.sim._compiled import mobile_loop  # Numba: only for the controllers it computes

    loop = mobile_loop.MobileLoop.build(controller, plant, trajectory, q0, JV_pinv)
    mobile_loop.last = loop
    return loop


def simulate_mobile(
    controller: MobileController,
    trajectory: Trajectory,
    q0,
    *,
    plant: MobilePlant | None = None,
    stage: str | Callable[[float], str] = "track",
    progress: Callable[[int, int], None] | None = None,
) -> MobileLog:
    """Run a mobile-manipulator controller over a trajectory.

    The controller (`rhi.control.mobile.MobileController`) runs at its sampling time
    ``controller.config.dt``, which must equal the trajectory's; each sample it returns a
    `MobileStep`. Acceleration-level controllers (`rhi.control.mobile.AMDController`,
    `PinvAccelController`) are integrated as the thesis does (§B.4.1: the integral of the
    computed acceleration is commanded): q̇⁺ = q̇ + q̈T, q⁺ = q + q̇T + q̈T²/2. Velocity-level
    controllers (`WeightedDistributionController`) command v = [v_b; q̇_m] directly. The AMD and the
    traditional controller run on the compiled loop (`rhi.sim._compiled.mobile_loop`, the same arithmetic), App. A's
    `WeightedDistributionController` on `rhi.sim._compiled.velocity_loop`.

    Args:
        controller: the controller (its ``advance`` is called once per sample).
        trajectory: desired end-effector motion, sampled at the control period.
        q0: (n,) start configuration [x_b, y_b, θ_b, q_m]; the robot starts at rest.
        plant: MuJoCo plant (reset to q0 here), or None for a kinematic run.
        stage: App. A controllers: "track", "dm_cartesian", "dm_null", or t ↦ stage.
        progress: called as progress(k, K) every 1 % of the run.

    Returns:
        `MobileLog`.

    Raises:
        InvalidInput: q0 outside the joint limits, a trajectory sampled at another period,
            or a controller without a supported interface.
    """
    dev = controller.device
    n = dev.n
    q0 = as_array("q0", q0, shape_tail=(n,))
    if q0.ndim != 1:
        raise InvalidInput(f"q0: expected shape ({n},), got {q0.shape}")
    if not dev.within_limits(q0):
        raise InvalidInput(f"q0: start configuration outside the joint limits of {dev.name}")
    if not isinstance(trajectory, Trajectory):
        raise InvalidInput(f"trajectory: expected a Trajectory, got {type(trajectory).__name__}")
    dt = float(controller.config.dt)
    if trajectory.t.size > 1 and abs(trajectory.dt - dt) > 1e-9 * max(dt, 1.0):
        raise InvalidInput(f"trajectory: sampled every {trajectory.dt} s but the controller runs every {dt} s")
    if not callable(getattr(controller, "advance", None)):
        raise InvalidInput(f"controller: {type(controller).__name__} has no advance method "
                           "(rhi.control.mobile.MobileController)")
    stage_of = stage if callable(stage) else (lambda _t, s=stage: s)
    bounds = controller.bounds
    geom = plant.geometry if plant is not None else wheel_geometry(dev)
    JV_pinv = np.linalg.pinv(body_map(**geom))
    if plant is not None:
        if plant.device.joint_names != dev.joint_names:
            raise InvalidInput("plant: simulates another device than the controller's")
        plant.reset(q0)
    controller.reset()
    K = trajectory.t.size
    nan = np.full(K, np.nan)
    log = {k: np.empty((K, n)) for k in ("q", "q_true", "dq")}
    log["ddq"] = np.full((K, n), np.nan)
    for name in ("x", "x_est"):
        log[name] = np.empty((K, 3))
    log["wheels"] = np.empty((K, 4))
    scal = {k: nan.copy() for k in ("base_active", "alpha", "beta", "gamma", "eta", "sigma", "dm")}
    q_ref = q0.copy()  # base: odometry; arm: integrated reference
    dq = np.zeros(n)
    ok, done = True, 0
    tick = max(1, K // 100)
    fast = _compiled(controller, plant, trajectory, q0, JV_pinv, stage_of)
    if fast is not None:
        kept = fast.run(log, scal, progress)
        if kept is None:  # a tick the controller raises on: the whole run in Python, which raises there
            if plant is not None:
                plant.reset(q0)
            controller.reset()
        else:
            ok, done = kept, K
    for k in range(done, K):
        t = float(trajectory.t[k])
        xd, dxd, ddxd = trajectory.x[k], trajectory.dx[k], trajectory.ddx[k]
        q_meas = q_ref.copy()
        if plant is not None:
            q_meas[3:] = plant.q[3:]
        cmd = controller.advance(t, q_meas, dq, xd, dxd, ddxd, stage=stage_of(t))
        dq_new, ddq = cmd.dq, cmd.ddq
        if ddq is not None:
            ok &= bool(np.all(ddq >= bounds.ddq_min - 1e-9) & np.all(ddq <= bounds.ddq_max + 1e-9))
            q_next = q_ref + dq * dt + 0.5 * ddq * dt * dt
            dq_mid = 0.5 * (dq + dq_new)
            log["ddq"][k] = ddq
        else:
            dq_mid = dq_new
            q_next = q_ref + dq_new * dt
        for key, value in cmd.record.items():
            scal[key][k] = value
        ok &= bool(np.all(dq_new >= bounds.dq_min - 1e-9) & np.all(dq_new <= bounds.dq_max + 1e-9))
        ok &= bool(bounds.contains(q_next, 1e-9))
        th_mid = q_ref[2] + 0.5 * dq_mid[2] * dt
        wheels = base_to_wheels(JV_pinv, dq_mid, th_mid)
        log["q"][k], log["dq"][k], log["x_est"][k], log["wheels"][k] = q_meas, dq_new, cmd.x, wheels
        if plant is not None:
            log["q_true"][k], log["x"][k] = plant.q, plant.x
            qa, dqa, dda = q_ref[3:], dq[3:], (ddq[3:] if ddq is not None else None)
            if dda is None:
                plant.step(wheels, lambda u, qa=qa, v=dq_new[3:]: qa + v * u, dq_new[3:], dt)
            else:
                plant.step(wheels, lambda u, qa=qa, dqa=dqa, a=dda: qa + dqa * u + 0.5 * a * u * u,
                           lambda u, dqa=dqa, a=dda: dqa + a * u, dt)
        else:
            log["q_true"][k] = q_meas
            log["x"][k] = cmd.x
        q_ref, dq = q_next, dq_new
        if progress is not None and (k % tick == 0 or k == K - 1):
            progress(k + 1, K)
    params = {"controller": type(controller).__name__, "config": repr(controller.config), "dt": dt,
              "plant": None if plant is None else {"timestep": plant.timestep, "slip": dataclasses.asdict(plant.slip)}}
    return MobileLog(trajectory.t.copy(), log["q"], log["q_true"], log["dq"], log["ddq"], log["x"], log["x_est"],
                     trajectory.x.copy(), log["wheels"], scal["base_active"], scal["alpha"], scal["beta"],
                     scal["gamma"], scal["eta"], scal["sigma"], scal["dm"], ok, params)
