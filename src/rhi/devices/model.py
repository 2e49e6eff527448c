"""`Device`: the one stateful model object (Pinocchio model + data, limits, actuation map).

Kinematics and dynamics come from Pinocchio on the serial chain described by the
device's URDF, in *chain* coordinates θ. Haptic devices with parallelogram or
cable transmissions are driven in *motor* coordinates q (the thesis's own joint
angles), related by a constant actuation map

    θ = A q + b,          so  J_q = J_θ A,  M_q = Aᵀ M_θ A,  g_q = Aᵀ g_θ.

Locking joints (`Device.lock`) only folds columns of A into b, which is how the
non-redundant halves of the 4-DoF RHI are made. All public methods take
`q: (..., n) [rad or m]` and broadcast over leading axes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, cast

import numpy as np
import pinocchio as pin

from rhi import plugins
from rhi._validate import as_array, limits_pair, per_joint
from rhi.devices import batch
from rhi.devices.ik import ik as solve_ik
from rhi.devices.spec import MODELS, DeviceSpec, LinearLimits, available_devices, build_model, bundled_spec, read_spec
from rhi.devices.terms import DeviceTerms, eye, inv_small, lazy
from rhi.devices.terms_pass import FastMaps, compiled_terms, fast_maps, pinocchio_terms
from rhi.devices.variant import read_variant
from rhi.errors import InvalidInput, ModelError

__all__ = ["BATCH_MIN", "MODELS", "Device", "DeviceTerms", "LinearLimits", "available_devices", "device", "eye",
           "from_spec", "inv_small", "load_device"]
_AXES = {"x": 0, "y": 1, "z": 2}
BATCH_MIN = 16  # batched inputs with at least this many configurations go through `rhi.devices.batch`


class Device:
    """A robot model in motor coordinates with limits and a task (end-effector) definition.

    Args:
        model: Pinocchio model of the serial chain (nq == nv).
        name: device name.
        ee_frame: name of the end-effector frame in `model`.
        task_axes: world axes of the position task, e.g. "xy" for planar devices.
        actuation: (nθ, n) constant actuation map A (θ = A q + b). Identity if None.
        offset: (nθ,) constant offset b [rad or m].
        q_min, q_max: (n,) joint limits [rad or m].
        torque_min, torque_max: (n,) actuator limits [N m or N].
        linear_limits: optional joint inequalities.
        joint_names: (n,) names of the motor coordinates.
        armature: (n,) rotor inertia reflected to each motor coordinate [kg m²], added to M(q).
        params: design parameters this device was built with.
        damping: (n,) viscous motor friction for the plant [N m s/rad] (default 0).
        frictionloss: (n,) Coulomb motor friction for the plant [N m] (default 0).
        velocity_max, acceleration_max: (n,) symmetric joint velocity [rad/s or m/s] and
            acceleration [rad/s² or m/s²] limits (thesis Table B.1), or None when not declared.

    Attributes:
        ee_frame_id: index of `ee_frame` in ``model.frames``.
        spec: the `DeviceSpec` (device.toml) the device was loaded from, None for devices
            built otherwise; a locked device keeps its base's spec.

    Raises:
        ModelError: torque limits missing, non-finite, or not torque_min < 0 < torque_max;
            `ee_frame` unknown or a joint.
        InvalidInput: bad `task_axes`, limits, armature or friction.
    """

    def __init__(
        self,
        model: pin.Model,
        *,
        name: str,
        ee_frame: str,
        task_axes: str = "xyz",
        actuation: np.ndarray | None = None,
        offset: np.ndarray | None = None,
        q_min: np.ndarray | None = None,
        q_max: np.ndarray | None = None,
        torque_min: np.ndarray | None = None,
        torque_max: np.ndarray | None = None,
        linear_limits: LinearLimits | None = None,
        joint_names: list[str] | None = None,
        armature: np.ndarray | None = None,
        params: Mapping[str, float] | None = None,
        damping: np.ndarray | None = None,
        frictionloss: np.ndarray | None = None,
        velocity_max: np.ndarray | None = None,
        acceleration_max: np.ndarray | None = None,
    ) -> None:
        if model.nq != model.nv:
            raise ModelError(f"{name}: model has nq={model.nq} != nv={model.nv}; use bounded revolute/prismatic joints")
        if not isinstance(ee_frame, str) or not model.existFrame(ee_frame):
            frames = [f.name for f in model.frames if f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)]
            raise ModelError(f"ee_frame: no frame named {ee_frame!r} in the model of {name}; valid: {', '.join(frames)}")
        if model.frames[model.getFrameId(ee_frame)].type == pin.FrameType.JOINT:
            raise ModelError(f"ee_frame: {ee_frame!r} is a joint of {name}, not a link; name its child link")
        if (not isinstance(task_axes, str) or not task_axes or any(a not in _AXES for a in task_axes)
                or len(set(task_axes)) != len(task_axes)):
            raise InvalidInput(f"task: expected a string of distinct axes from 'xyz', got {task_axes!r}")
        self.name = name
        self.model = model
        self.data = model.createData()
        self.ee_frame = ee_frame
        self.ee_frame_id = model.getFrameId(ee_frame)
        self.task_axes = task_axes
        self._rows = [_AXES[a] for a in task_axes]
        ntheta = model.nv
        self.A = np.eye(ntheta) if actuation is None else np.ascontiguousarray(actuation, dtype=float)  # C order: 1 kernel build
        if self.A.shape[0] != ntheta:
            raise ModelError(f"actuation: expected {ntheta} rows (chain joints), got shape {self.A.shape}")
        self.b = np.zeros(ntheta) if offset is None else np.asarray(offset, dtype=float)
        n = self.A.shape[1]
        self.n, self.m = n, len(task_axes)
        self.joint_names = list(joint_names) if joint_names else [f"q{i + 1}" for i in range(n)]
        lo = np.full(n, -np.inf) if q_min is None else np.asarray(q_min, dtype=float)
        hi = np.full(n, np.inf) if q_max is None else np.asarray(q_max, dtype=float)
        self.q_min, self.q_max = limits_pair("q_min", lo, "q_max", hi, n)
        if torque_max is None:
            raise ModelError(f"torque_max: {name} needs finite, positive torque limits [N m]")
        tmax = np.asarray(torque_max, dtype=float)
        tmin = -tmax if torque_min is None else np.asarray(torque_min, dtype=float)
        self.torque_min, self.torque_max = limits_pair("torque_min", tmin, "torque_max", tmax, n)
        if not (np.all(np.isfinite(self.torque_max)) and np.all(self.torque_max > 0)):
            raise ModelError(f"torque_max: {name} needs finite, positive torque limits, got {self.torque_max.tolist()}")
        if not (np.all(np.isfinite(self.torque_min)) and np.all(self.torque_min < 0)):
            raise ModelError(f"torque_min: {name} needs finite, negative torque limits, got {self.torque_min.tolist()}")
        self.linear_limits = linear_limits
        self.armature = per_joint("armature", 0.0 if armature is None else armature, n)
        self.damping = per_joint("damping", 0.0 if damping is None else damping, n)
        self.frictionloss = per_joint("frictionloss", 0.0 if frictionloss is None else frictionloss, n)
        self.velocity_max = None if velocity_max is None else per_joint("velocity_max", velocity_max, n, positive=True)
        self.acceleration_max = (None if acceleration_max is None
                                 else per_joint("acceleration_max", acceleration_max, n, positive=True))
        self.params = dict(params or {})
        self.spec: DeviceSpec | None = None
        #: the description whose visuals are drawn (rhi.viz), or None: ("urdf", its XML, folders for its mesh
        #: paths) or ("mjcf", the file's path, ())
        self.visual_description: tuple[str, str, tuple[str, ...]] | None = None
        self.locked_joints: dict[str, float] = {}

    # ------------------------------------------------------------------ limits
    @property
    def joint_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(q_min, q_max), each (n,) [rad or m]. See also `linear_limits`."""
        return self.q_min, self.q_max

    @property
    def task_rows(self) -> list[int]:
        """World-axis indices (0: x, 1: y, 2: z) of the task coordinates, e.g. [0, 1] for "xy"."""
        return list(self._rows)

    @property
    def torque_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(torque_min, torque_max), each (n,) [N m]."""
        return self.torque_min, self.torque_max

    def within_limits(self, q, tol: float = 1e-9) -> np.ndarray:
        """Whether q: (..., n) satisfies the box and linear joint limits. Returns (...,) bool."""
        return self._within(self._q(q), tol)

    def _within(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """`within_limits` of a checked q: (..., n)."""
        ok = np.all((q >= self.q_min - tol) & (q <= self.q_max + tol), axis=-1)
        if self.linear_limits is not None:
            L, c = self.linear_limits, q @ self.linear_limits.C.T
            ok &= np.all((c >= L.lower - tol) & (c <= L.upper + tol), axis=-1)
        return ok

    # ------------------------------------------------------------ kinematics
    def theta(self, q) -> np.ndarray:
        """Chain coordinates θ = A q + b: (..., nθ)."""
        return self._theta(self._q(q))

    def _theta(self, q: np.ndarray) -> np.ndarray:
        """`theta` of a checked q: (..., n)."""
        return q @ self.A.T + self.b

    def fk(self, q) -> np.ndarray:
        """End-effector position in the world frame: (..., m) [m]."""
        return self._map(q, self._m_shape(), self.fk_theta, "x")

    def skeleton(self, q) -> np.ndarray:
        """World positions of every chain joint then the end-effector, for drawing: (k, 3) [m] for q: (n,)."""
        th = self.theta(self._q(q))
        pin.framesForwardKinematics(self.model, self.data, th)
        pts = [self.data.oMi[j].translation.copy() for j in range(1, self.model.njoints)]
        return np.array(pts + [self.data.oMf[self.ee_frame_id].translation.copy()])

    def jacobian(self, q) -> np.ndarray:
        """Task Jacobian ∂x/∂q in the world frame: (..., m, n)."""
        return self._map(q, (self.m, self.n), self.jacobian_theta, "J")

    def jacobian_derivative(self, q) -> np.ndarray:
        """∂J/∂q: (..., m, n, n) with [..., i, j, k] = ∂J_ij/∂q_k."""
        return self._map(q, (self.m, self.n, self.n), self.jacobian_derivative_theta, "dJ")

    def mass_matrix(self, q) -> np.ndarray:
        """Joint-space inertia M(q) = Aᵀ M_θ A + diag(armature): (..., n, n) [kg m²]."""
        return self._map(q, (self.n, self.n), self._mass1, "M")

    def coriolis(self, q, dq) -> np.ndarray:
        """Coriolis/centrifugal matrix C(q, q̇): (..., n, n); C q̇ is the torque [N m]."""
        q, dq = np.broadcast_arrays(self._q(q), self._q(dq, "dq"))
        out = np.empty(q.shape[:-1] + (self.n, self.n))
        for idx in np.ndindex(q.shape[:-1]):
            th = self.A @ q[idx] + self.b
            C = pin.computeCoriolisMatrix(self.model, self.data, th, self.A @ dq[idx])
            out[idx] = self.A.T @ C @ self.A
        return out

    def gravity(self, q) -> np.ndarray:
        """Gravity torque g(q) = Aᵀ g_θ: (..., n) [N m]."""
        return self._map(q, (self.n,), lambda th: self.A.T @ pin.computeGeneralizedGravity(self.model, self.data, th),
                         "g")

    def terms(self, q, dq=None, *, check: bool = True) -> DeviceTerms:
        """Every kinematic and dynamic term of one state from a single pass.

        Trees of revolute/prismatic joints: one compiled call (`rhi.devices._compiled.chain`, equal to
        Pinocchio's algorithms to round-off); other one-DoF joints: Pinocchio's, then a compiled call; otherwise
        Pinocchio's alone (`rhi.devices.terms_pass`). Equal to `fk`, `jacobian`, `jacobian_derivative`,
        `mass_matrix` and `gravity` called one by one, several times faster; with one-DoF joints M_x, J#, C_x,
        G_x too (∂J/∂q in closed form from the 6-D frame Jacobian, `rhi.devices._compiled.terms`).
        A call with the same q and dq as the previous one returns the same snapshot (a
        simulation tick reads it for the virtual environment, then the controller).

        Args:
            q: (n,) joint positions [rad or m].
            dq: (n,) joint velocities [rad/s], or None.
            check: validate shape and finiteness (a controller that already did passes False).

        Returns:
            The terms snapshot.

        Raises:
            InvalidInput: wrong shape or non-finite values (with check=True).
        """
        if check:
            q = self._q(q)
            if q.ndim != 1:
                raise InvalidInput(f"q: expected shape ({self.n},), got {q.shape}; call terms per configuration")
            if dq is not None:
                dq = self._q(dq, "dq")
                if dq.shape != q.shape:
                    raise InvalidInput(f"dq: expected shape ({self.n},), got {dq.shape}")
        key = (q.tobytes(), None if dq is None else dq.tobytes())
        last = self.__dict__.get("_last_terms")
        if last is not None and last[0] == key:  # same state again (the loop's virtual environment, then the controller)
            return last[1]
        fast = self._fast_maps
        th = self.A.dot(q)
        if fast.offset:
            th += self.b
        if fast.kernel is not None:  # every term, the task-space dynamics included, compiled
            terms = compiled_terms(self, fast, fast.kernel, q, dq, th)
        else:
            terms = pinocchio_terms(self, fast, q, dq, th)
        self._last_terms = (key, terms)
        return terms

    @lazy
    def _fast_maps(self) -> FastMaps:
        """Constant maps and flags of `terms`, built on first use."""
        return fast_maps(self.model, self.ee_frame_id, self.A, self.b, self.armature, self._rows)

    def coriolis_theta(self, th: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """C_q (n, n) at chain coordinates θ: (nθ,) and q̇: (n,), unchecked (for `DeviceTerms.C`)."""
        A = self.A
        C = pin.computeCoriolisMatrix(self.model, self.data, th, A.dot(dq))
        return self._fast_maps.At.dot(C).dot(A)

    def ik(self, x, q0, *, weights=None, tol: float = 1e-9, max_iter: int = 200, k_null: float = 0.1,
           restarts: int = 8) -> np.ndarray:
        """Inverse kinematics x ↦ q within the joint limits (thesis eqs. 3.3–3.4); see `rhi.devices.ik.ik`.

        Args:
            x: (m,) target position [m].
            q0: (n,) initial configuration.
            weights: (n,) diagonal of the weight Q (default ones).
            tol: position tolerance [m].
            max_iter: iterations per start.
            k_null: null-space centering gain.
            restarts: further seeded starting points tried after q0.

        Returns:
            q: (n,) configuration within the joint limits with ‖f(q) − x‖ ≤ tol.

        Raises:
            Unreachable: no solution within the limits was found from any start.
        """
        return solve_ik(self, x, q0, weights=weights, tol=tol, max_iter=max_iter, k_null=k_null,
                        restarts=restarts)

    # ---------------------------------------------------------------- locking
    def lock(self, values: Mapping[Any, float] | None = None, *, name: str | None = None, **kw: float) -> Device:
        """Fix some motor coordinates and return the non-redundant (or less redundant) device.

        Args:
            values: {joint name or index: value [rad]}; keywords work too (`lock(q1=0, q2=0)`).
            name: name of the new device.
            **kw: joints to lock by name, as keywords [rad].
        """
        if values is not None and not isinstance(values, Mapping):
            raise InvalidInput(f"values: expected a dict {{joint name or index: value}}, got {type(values).__name__}")
        values = {**(values or {}), **kw}
        idx = {}
        for key, v in values.items():
            i = key if isinstance(key, int) else (self.joint_names.index(key) if key in self.joint_names else None)
            if i is None or isinstance(i, bool) or not 0 <= i < self.n:
                raise InvalidInput(f"lock: unknown joint {key!r}; joints are {self.joint_names}")
            val = as_array(f"lock[{key!r}]", v)
            if val.ndim != 0:
                raise InvalidInput(f"lock[{key!r}]: expected one value, got shape {val.shape}")
            if not self.q_min[i] - 1e-12 <= val <= self.q_max[i] + 1e-12:
                raise InvalidInput(f"lock[{key!r}]: {float(val)} outside the joint range [{self.q_min[i]:g}, {self.q_max[i]:g}]")
            idx[i] = float(val)
        free = [i for i in range(self.n) if i not in idx]
        locked = np.array(sorted(idx))
        qv = np.array([idx[i] for i in sorted(idx)])
        lin = None if self.linear_limits is None else self.linear_limits.fix(locked, qv)
        dev = Device(
            self.model,
            name=name or f"{self.name}-locked",
            ee_frame=self.ee_frame,
            task_axes=self.task_axes,
            actuation=self.A[:, free],
            offset=self.b + (self.A[:, locked] @ qv if locked.size else 0.0),
            q_min=self.q_min[free],
            q_max=self.q_max[free],
            torque_min=self.torque_min[free],
            torque_max=self.torque_max[free],
            linear_limits=lin,
            joint_names=[self.joint_names[i] for i in free],
            armature=self.armature[free],
            params=self.params,
            damping=self.damping[free],
            frictionloss=self.frictionloss[free],
            velocity_max=None if self.velocity_max is None else self.velocity_max[free],
            acceleration_max=None if self.acceleration_max is None else self.acceleration_max[free],
        )
        dev.spec = self.spec
        dev.locked_joints = {**self.locked_joints, **{self.joint_names[i]: v for i, v in idx.items()}}
        dev.visual_description = self.visual_description
        return dev

    def __repr__(self) -> str:
        return f"Device({self.name!r}, n={self.n}, task={self.task_axes!r})"

    # ---------------------------------------------------------------- helpers
    def _q(self, q, name: str = "q") -> np.ndarray:
        return as_array(name, q, shape_tail=(self.n,))

    def _m_shape(self) -> tuple[int]:
        return (self.m,)

    def _map(self, q, shape: tuple[int, ...], fn: Callable[[np.ndarray], np.ndarray], term: str) -> np.ndarray:
        """Fn per configuration, or the vectorized `rhi.devices.batch` term for batches of >= BATCH_MIN configurations."""
        th = self.theta(q)
        if th.ndim == 1:
            return fn(th)
        if self._batch is not None and th.size >= BATCH_MIN * th.shape[-1]:
            return self._batch.evaluate(th, (term,))[term]
        out = np.empty(th.shape[:-1] + shape)
        for idx in np.ndindex(th.shape[:-1]):
            out[idx] = fn(th[idx])
        return out

    @lazy
    def _batch(self) -> batch.BatchChain | None:
        """Vectorized kinematics and dynamics for batched inputs; None if a joint type is not supported."""
        if not batch.supported(self.model):
            return None
        return batch.BatchChain(self.model, self.ee_frame_id, rows=self._rows, A=self.A, armature=self.armature)

    def fk_theta(self, th: np.ndarray) -> np.ndarray:
        """End-effector position (m,) [m] at chain coordinates θ: (nθ,), unchecked."""
        pin.framesForwardKinematics(self.model, self.data, th)
        return self.data.oMf[self.ee_frame_id].translation[self._rows]

    def jacobian_theta(self, th: np.ndarray) -> np.ndarray:
        """Task Jacobian (m, n) in motor coordinates at chain coordinates θ: (nθ,), unchecked."""
        J = pin.computeFrameJacobian(self.model, self.data, th, self.ee_frame_id, pin.LOCAL_WORLD_ALIGNED)
        return J[self._rows] @ self.A

    def jacobian_derivative_theta(self, th: np.ndarray) -> np.ndarray:
        """∂J/∂q (m, n, n) at chain coordinates θ: (nθ,), unchecked (∂J_θ/∂θ_k is dJ/dt at θ̇ = e_k, Pinocchio)."""
        cols = []
        for k in range(self.model.nv):
            pin.computeJointJacobiansTimeVariation(self.model, self.data, th, np.eye(self.model.nv)[k])
            pin.updateFramePlacements(self.model, self.data)
            cols.append(pin.getFrameJacobianTimeVariation(self.model, self.data, self.ee_frame_id, pin.LOCAL_WORLD_ALIGNED))
        H = np.stack(cols, axis=-1)[self._rows]  # (m, nθ, nθ): [i, b, j] = ∂J_ib/∂θ_j
        return np.einsum("ibj,ba,jk->iak", H, self.A, self.A)

    def _mass1(self, th: np.ndarray) -> np.ndarray:
        M = pin.crba(self.model, self.data, th)
        M = np.triu(M) + np.triu(M, 1).T
        return self.A.T @ M @ self.A + np.diag(self.armature)


# ---------------------------------------------------------------------- loading
def device(name: str, **params: float | str) -> Device:
    """Load a bundled device by name (see `available_devices()`), else an installed plugin's (`rhi.plugins`).

    Args:
        name: device name, e.g. "rhi4", "phantom", "rehab", "planar3r", "gen3".
        **params: design parameters declared in the device's `device.toml` (e.g. `d2=0.1405` for rhi4) [m or rad];
            ``params``: a named parameter variant from the model folder (`rhi.devices.variant`), e.g. "thesis-fit"
            for rhi4 and its halves (models/rhi4/README.md), absent or "default" the default model (or a plugin's).

    Raises:
        UnknownDevice: no bundled device and no installed plugin (``rhi.devices``) has that name.
        InvalidInput: an unknown parameter variant.
    """
    if isinstance(name, str) and name not in available_devices() and name in plugins.names("rhi.devices"):
        return plugins.device(name, params, Device)
    return from_spec(bundled_spec(name), **params)


def load_device(folder: str | Path, **params: float | str) -> Device:
    """Load a device folder holding `device.toml` (+ its URDF). See models/README.md for the format."""
    return from_spec(read_spec(folder), **params)


def from_spec(spec: DeviceSpec, **params: float | str) -> Device:
    """Build the device a `DeviceSpec` describes, with design parameters set [m or rad].

    A derived spec (``base = ...``) loads its bundled base (with the same `variant`) and locks the
    joints it names. ``params``: a parameter variant's name (`device`), absent or "default".
    """
    variant = params.pop("params", "default")
    design = cast(dict[str, float], params)  # build_model names any value that is not a number
    if spec.base is not None:  # a device derived from another by locking joints
        name = spec.name if variant == "default" else f"{spec.name}:{variant}"
        return device(spec.base, params=variant, **design).lock(spec.lock, name=name)
    urdf, ee_frame = spec.chain()
    var = None if variant == "default" else read_variant(spec.folder, variant, spec.name)  # type: ignore[arg-type]
    model, values = build_model(spec, design, None if var is None else var.links)
    dev = Device(
        model,
        name=spec.name if var is None else f"{spec.name}:{var.name}",  # the variant is part of the label
        ee_frame=ee_frame,
        task_axes=spec.task,
        actuation=spec.actuation,
        offset=spec.offset,
        q_min=spec.q_min,
        q_max=spec.q_max,
        torque_min=spec.torque_min,
        torque_max=spec.torque_max,
        linear_limits=spec.linear_limits,
        joint_names=spec.joint_names,
        armature=spec.armature if var is None or var.armature is None else var.armature,
        params=values,
        damping=spec.damping,
        frictionloss=spec.frictionloss,
        velocity_max=spec.velocity_max,
        acceleration_max=spec.acceleration_max,
    )
    dev.spec = spec
    dev.visual_description = ("urdf", urdf.read_text(), (str(spec.folder),))
    return dev
