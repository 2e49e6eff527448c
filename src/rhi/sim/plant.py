"""`Plant`: a device simulated in MuJoCo — torque-controlled motors, encoders, a 6-axis F/T sensor.

The plant is generated from the device description (`rhi.sim.mjcf`), so the controller's
Pinocchio model and the plant agree unless a study changes one of them (model mismatch:
pass a different `Device` or friction to the plant than to the controller). A controller
only ever sees `q`, `dq` and `ft()`; `x`, `xdot` and the MuJoCo structures are the
simulation's ground truth for logging and tests.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from rhi._validate import MAX_DURATION, as_array, scalar
from rhi.devices.model import Device
from rhi.errors import InvalidInput, ModelError
from rhi.sim.mjcf import PlantFriction, plant_spec

_AXES = {"x": 0, "y": 1, "z": 2}

#: Largest physics step accepted [s]: a haptic plant integrated more coarsely than 200 Hz is not one.
MAX_TIMESTEP = 5e-3


class PlantUnstable(ModelError):
    """The physics diverged (MuJoCo flagged bad accelerations, velocities or positions and reset).

    Attributes:
        t: simulated time [s] of the step that diverged (before MuJoCo's reset).
    """

    def __init__(self, message: str, t: float) -> None:
        super().__init__(message)
        self.t = t


def unstable(t: float) -> PlantUnstable:
    """The error of a physics step at time t [s] that MuJoCo flagged as diverged."""
    return PlantUnstable(f"plant: MuJoCo reported unstable physics at t={t:.4f} s "
                         "(bad accelerations, velocities or positions; it reset the state)", t)


def device_friction(device: Device) -> PlantFriction:
    """The motor friction the device carries (`Device.damping`, `Device.frictionloss`).

    Bundled devices take it from their `device.toml` [plant] table, user devices from the
    loader's `friction=` argument or their description's joint dynamics; `Device.lock` keeps it.
    """
    return PlantFriction(device.damping, device.frictionloss).check(device.n)


class Plant:
    """A device in MuJoCo.

    Args:
        device: the device to simulate.
        friction: motor friction; "device" (default): the device's `[plant]` values; None: frictionless.
        timestep: physics step [s] (the control period is a multiple of it).
        handle_mass: mass of the handle between the F/T sensor and the hand [kg].
        visual: give the model the device's visual geometry (massless; for `rhi.viz` and MuJoCo's viewer).
        collision: let that geometry collide.

    Attributes:
        spec, model, data: the MuJoCo spec, model and data (ground truth; controllers must not read them).
        n: number of motors; m: task dimension.
    """

    def __init__(self, device: Device, *, friction: PlantFriction | str | None = "device",
                 timestep: float = 5e-4, handle_mass: float = 1e-3, visual: bool = True,
                 collision: bool = False) -> None:
        if not isinstance(timestep, (int, float)) or not 0 < timestep <= MAX_TIMESTEP:
            raise InvalidInput(f"timestep: must be in (0, {MAX_TIMESTEP}] s, got {timestep!r}")
        if not isinstance(device, Device):
            raise InvalidInput(f"device: expected a rhi.Device, got {type(device).__name__}")
        handle_mass = scalar("handle_mass", handle_mass, nonnegative=True)
        if friction is not None and not isinstance(friction, (str, PlantFriction)):
            raise InvalidInput(f"friction: expected 'device', a PlantFriction or None, got {type(friction).__name__}")
        if isinstance(friction, str):
            if friction != "device":
                raise InvalidInput(f"friction: expected 'device', a PlantFriction or None, got {friction!r}")
            friction = device_friction(device)
        self.device = device
        self.friction = (friction or PlantFriction.zero(device.n)).check(device.n)
        self.spec = plant_spec(device, self.friction, timestep=timestep, handle_mass=handle_mass, visual=visual,
                               collision=collision)
        try:
            self.model = self.spec.compile()
        except ValueError as exc:
            raise ModelError(f"device: MuJoCo rejected the plant of {device.name}: {exc}") from None
        if self.model.npair == 0 and not np.any(self.model.geom_contype | self.model.geom_conaffinity):
            # no geom can collide (visual geometry only): skip MuJoCo's collision stage (same physics, ~7 % faster)
            self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self.data = mujoco.MjData(self.model)
        self.n, self.m = device.n, device.m
        self._rows = [_AXES[a] for a in device.task_axes]
        moving = np.any(device.A != 0, axis=1)
        self._A, self._b = device.A[moving], device.b[moving]
        self._const = np.linalg.pinv(self._A) @ self._b
        self._body = self.model.body("handle").id
        self._site = self.model.site("handle").id
        adr = {k: int(self.model.sensor(k).adr[0]) for k in ("ft_force", "ft_torque", "handle_pos", "handle_vel")}
        self._jac = np.zeros((3, self.model.nv))
        self._weight = self.model.body_mass[self._body] * self.model.opt.gravity
        self.timestep = float(self.model.opt.timestep)
        # Views into MjData's persistent buffers (they never move) and index arrays (a gather into a fresh
        # array is cheaper than a slice and a copy), for a cheap read/apply/step in the 1 kHz loop.
        d, rows = self.data, np.array(self._rows)
        self._task = rows
        self._sd = d.sensordata
        self._pos = rows + adr["handle_pos"]
        self._vel = rows + adr["handle_vel"]
        self._ten = d.ten_length[: self.n]
        self._tenv = d.ten_velocity[: self.n]
        self._R = d.site_xmat[self._site]
        self._ff = d.sensordata[adr["ft_force"]: adr["ft_force"] + 3]
        self._ft = d.sensordata[adr["ft_torque"]: adr["ft_torque"] + 3]
        self._read: tuple | None = None  # `sensors`: its kernel and arguments, on first use
        self._ft_adr = np.array([adr["ft_force"], adr["ft_torque"]], dtype=np.int64)
        self._ctrl = d.ctrl
        self._xfrc = d.xfrc_applied[self._body]
        # live view of MjData's warning counters; BADQACC, BADQVEL, BADQPOS flag diverged physics
        self._wnum = d.warning.number
        self._bad = tuple(int(w) for w in (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL,
                                           mujoco.mjtWarning.mjWARN_BADQPOS))

    # ------------------------------------------------------------------ state
    def reset(self, q, dq=None) -> None:
        """Place the device at motor angles q: (n,) [rad] with velocities dq: (n,) [rad/s].

        Raises:
            InvalidInput: a wrong shape, a non-finite value, or a joint outside its range (`Device.joint_limits`).
        """
        q = as_array("q", q)
        dq = np.zeros(self.n) if dq is None else as_array("dq", dq)
        if q.shape != (self.n,) or dq.shape != (self.n,):
            raise InvalidInput(f"q/dq: expected {self.n} values each, got shapes {q.shape} and {dq.shape}")
        lo, hi = self.device.joint_limits
        out = (q < lo - 1e-9) | (q > hi + 1e-9)
        if out.any():
            j = int(np.flatnonzero(out)[0])
            raise InvalidInput(f"q: joint {j + 1} at {q[j]:.6g} is outside its range [{lo[j]:.6g}, {hi[j]:.6g}]")
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = self._A @ q + self._b
        self.data.qvel[:] = self._A @ dq
        mujoco.mj_forward(self.model, self.data)  # every stage, so that `step` may start with mj_step2

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return float(self.data.time)

    @property
    def q(self) -> np.ndarray:
        """Motor encoders: (n,) [rad]."""
        return self._ten - self._const

    @property
    def dq(self) -> np.ndarray:
        """Motor velocities: (n,) [rad/s]."""
        return self._tenv.copy()

    def ft(self) -> np.ndarray:
        """The handle's 6-axis F/T sensor in world axes, tared (the handle's weight removed).

        Returns:
            (6,) force [N] and torque [N m] the hand applies to the device.
        """
        # R f and R t written out on floats: a third of the cost of two 3 × 3 NumPy products and a concatenate
        r0, r1, r2, r3, r4, r5, r6, r7, r8 = self._R.tolist()
        fx, fy, fz = self._ff.tolist()
        tx, ty, tz = self._ft.tolist()
        w0, w1, w2 = self._weight.tolist()
        return np.array([-(r0 * fx + r1 * fy + r2 * fz) - w0, -(r3 * fx + r4 * fy + r5 * fz) - w1,
                         -(r6 * fx + r7 * fy + r8 * fz) - w2,
                         -(r0 * tx + r1 * ty + r2 * tz), -(r3 * tx + r4 * ty + r5 * tz), -(r6 * tx + r7 * ty + r8 * tz)])

    def sensors(self) -> np.ndarray:
        """The encoders and the F/T sensor in one compiled call: (2 n + 6,) fresh array.

        [:n] `q` [rad], [n:2n] `dq` [rad/s], [2n:] `ft()` [N, N m]: the same values, for the simulation
        loop's tick (`rhi.sim._compiled.io.sensors`; Numba is imported on the first call).
        """
        if self._read is None:
            from rhi.sim._compiled.io import sensors

            d = self.data
            self._read = (sensors, self._ten, self._tenv, d.sensordata, self._R,
                          np.concatenate([self._const, self._weight]), self._ft_adr)
        kernel, *args = self._read
        out = np.empty(2 * self.n + 6)
        kernel(*args, out)
        return out

    # ----------------------------------------------------------- ground truth
    @property
    def x(self) -> np.ndarray:
        """True handle position on the task axes: (m,) [m]."""
        return self._sd[self._pos]

    @property
    def xdot(self) -> np.ndarray:
        """True handle velocity on the task axes: (m,) [m/s]."""
        return self._sd[self._vel]

    def site_jacobian(self) -> np.ndarray:
        """Translational Jacobian of the handle w.r.t. the chain velocities: (3, nv)."""
        mujoco.mj_jacSite(self.model, self.data, self._jac, None, self._site)
        return self._jac

    def motor_jacobian(self) -> np.ndarray:
        """Task Jacobian in motor coordinates, from MuJoCo: (m, n)."""
        return self.site_jacobian()[self._rows] @ self._A

    def motor_mass_matrix(self) -> np.ndarray:
        """Inertia in motor coordinates Aᵀ M_θ A (tendon armature included), from MuJoCo: (n, n) [kg m²]."""
        M = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, M)
        return self._A.T @ M @ self._A

    # ------------------------------------------------------------------- step
    def apply(self, tau, force=None) -> None:
        """Set the motor torques and the external force on the handle.

        Args:
            tau: (n,) motor torques [N m] (MuJoCo clips them to the torque limits).
            force: (m,) force on the handle along the task axes [N]; None: zero.

        Raises:
            InvalidInput: a wrong shape or a non-finite value (named).
        """
        tau = _finite_vector("tau", tau, self.n)
        if force is not None:
            force = _finite_vector("force", force, len(self._task))
        self._ctrl[:] = tau
        f = self._xfrc
        f[:] = 0.0
        if force is not None:
            f[self._task] = force

    def step(self, steps: int = 1) -> None:
        """Advance the physics by `steps` timesteps.

        Each step is `mj_step2` (accelerations, the F/T sensor, integration) followed by `mj_step1`
        (positions and velocities of the new state), so `q`, `dq`, `x`, `xdot` always describe the
        current state and forces set by `apply` may depend on it; `ft()` is the force of the last step.

        Raises:
            PlantUnstable: MuJoCo flagged the state as diverged (it then resets the data, time included);
                the error carries the time of the step that diverged.
        """
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 0:
            raise InvalidInput(f"steps: expected an integer >= 0, got {steps!r:.60}")
        if steps * self.model.opt.timestep > MAX_DURATION:
            raise InvalidInput(f"steps: {steps} steps of {self.model.opt.timestep:g} s exceed {MAX_DURATION:g} s "
                               "(rhi._validate.MAX_DURATION)")
        m, d, wn = self.model, self.data, self._wnum
        i, j, k = self._bad
        for _ in range(steps):
            t = d.time
            mujoco.mj_step2(m, d)
            mujoco.mj_step1(m, d)
            if wn[i] or wn[j] or wn[k]:
                raise unstable(t)


def _finite_vector(name: str, v, n: int) -> np.ndarray:
    """`v` as a finite (n,) float array (one cheap check for the usual float64 array)."""
    if not (type(v) is np.ndarray and v.dtype == np.float64):
        v = as_array(name, v)
    if v.shape != (n,):
        raise InvalidInput(f"{name}: expected shape ({n},), got {v.shape}")
    if not math.isfinite(float(v @ v)) and not np.isfinite(v).all():
        raise InvalidInput(f"{name}: contains NaN or inf: {v.tolist()}")
    return v
