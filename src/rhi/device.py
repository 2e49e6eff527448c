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

import dataclasses
import tomllib
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin

from rhi._validate import as_array, limits_pair
from rhi.errors import InvalidInput, ModelError, UnknownDevice, Unreachable

MODELS = Path(__file__).parent / "models"
_AXES = {"x": 0, "y": 1, "z": 2}


@dataclasses.dataclass(frozen=True)
class LinearLimits:
    """Linear joint inequalities `lower <= C q <= upper`.

    Attributes:
        C: (k, n) coefficient matrix.
        lower: (k,) lower bounds [rad].
        upper: (k,) upper bounds [rad].
    """

    C: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


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
    ) -> None:
        if model.nq != model.nv:
            raise ModelError(f"{name}: model has nq={model.nq} != nv={model.nv}; use bounded revolute/prismatic joints")
        if not model.existFrame(ee_frame):
            raise ModelError(f"ee_frame: no frame named {ee_frame!r} in the model of {name}")
        if not task_axes or any(a not in _AXES for a in task_axes):
            raise InvalidInput(f"task: expected a string of axes from 'xyz', got {task_axes!r}")
        self.name = name
        self.model = model
        self.data = model.createData()
        self.ee_frame = ee_frame
        self._fid = model.getFrameId(ee_frame)
        self.task_axes = task_axes
        self._rows = [_AXES[a] for a in task_axes]
        ntheta = model.nv
        self.A = np.eye(ntheta) if actuation is None else np.asarray(actuation, dtype=float)
        if self.A.shape[0] != ntheta:
            raise ModelError(f"actuation: expected {ntheta} rows (chain joints), got shape {self.A.shape}")
        self.b = np.zeros(ntheta) if offset is None else np.asarray(offset, dtype=float)
        n = self.A.shape[1]
        self.n, self.m = n, len(task_axes)
        self.joint_names = list(joint_names) if joint_names else [f"q{i + 1}" for i in range(n)]
        lo = np.full(n, -np.inf) if q_min is None else np.asarray(q_min, dtype=float)
        hi = np.full(n, np.inf) if q_max is None else np.asarray(q_max, dtype=float)
        self.q_min, self.q_max = limits_pair("q_min", lo, "q_max", hi, n)
        tmax = np.full(n, np.inf) if torque_max is None else np.asarray(torque_max, dtype=float)
        tmin = -tmax if torque_min is None else np.asarray(torque_min, dtype=float)
        self.torque_min, self.torque_max = limits_pair("torque_min", tmin, "torque_max", tmax, n)
        self.linear_limits = linear_limits
        self.armature = np.zeros(n) if armature is None else np.asarray(armature, dtype=float)
        if self.armature.shape != (n,) or np.any(self.armature < 0):
            raise ModelError(f"armature: expected {n} non-negative values, got {self.armature}")
        self.params = dict(params or {})

    # ------------------------------------------------------------------ limits
    @property
    def joint_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(q_min, q_max), each (n,) [rad or m]. See also `linear_limits`."""
        return self.q_min, self.q_max

    @property
    def torque_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(torque_min, torque_max), each (n,) [N m]."""
        return self.torque_min, self.torque_max

    def within_limits(self, q, tol: float = 1e-9) -> np.ndarray:
        """Whether q: (..., n) satisfies the box and linear joint limits. Returns (...,) bool."""
        q = self._q(q)
        ok = np.all((q >= self.q_min - tol) & (q <= self.q_max + tol), axis=-1)
        if self.linear_limits is not None:
            L = self.linear_limits
            c = q @ L.C.T
            ok &= np.all((c >= L.lower - tol) & (c <= L.upper + tol), axis=-1)
        return ok

    # ------------------------------------------------------------ kinematics
    def theta(self, q) -> np.ndarray:
        """Chain coordinates θ = A q + b: (..., nθ)."""
        return self._q(q) @ self.A.T + self.b

    def fk(self, q) -> np.ndarray:
        """End-effector position in the world frame: (..., m) [m]."""
        return self._map(q, self._m_shape(), self._fk1)

    def skeleton(self, q) -> np.ndarray:
        """World positions of every chain joint then the end-effector, for drawing: (k, 3) [m] for q: (n,)."""
        th = self.theta(self._q(q))
        pin.framesForwardKinematics(self.model, self.data, th)
        pts = [self.data.oMi[j].translation.copy() for j in range(1, self.model.njoints)]
        return np.array(pts + [self.data.oMf[self._fid].translation.copy()])

    def jacobian(self, q) -> np.ndarray:
        """Task Jacobian ∂x/∂q in the world frame: (..., m, n)."""
        return self._map(q, (self.m, self.n), self._jac1)

    def jacobian_derivative(self, q) -> np.ndarray:
        """∂J/∂q: (..., m, n, n) with [..., i, j, k] = ∂J_ij/∂q_k."""
        return self._map(q, (self.m, self.n, self.n), self._djac1)

    def mass_matrix(self, q) -> np.ndarray:
        """Joint-space inertia M(q) = Aᵀ M_θ A + diag(armature): (..., n, n) [kg m²]."""
        return self._map(q, (self.n, self.n), self._mass1)

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
        return self._map(q, (self.n,), lambda th: self.A.T @ pin.computeGeneralizedGravity(self.model, self.data, th))

    def ik(
        self,
        x,
        q0,
        *,
        weights=None,
        tol: float = 1e-9,
        max_iter: int = 200,
        k_null: float = 0.1,
        restarts: int = 8,
    ) -> np.ndarray:
        """Inverse kinematics by the weighted pseudoinverse with a null-space term (thesis eq. 3.3–3.4).

        Iterates q ← q + J†(x − f(q)) + (I − J†J) q̇₀ with J† = Q⁻¹Jᵀ(JQ⁻¹Jᵀ)⁻¹ and
        q̇₀ = −k_null ∇h(q), h the normalised squared distance from the middle of every
        finite joint range and linear joint inequality. Joints held at a bound leave the
        solve (active set); the last iterations drop the null-space term to converge to
        `tol`. If the iteration from q0 ends in a local minimum, it restarts from seeded
        configurations spread over the joint box.

        Args:
            x: (m,) target position [m].
            q0: (n,) initial configuration.
            weights: (n,) diagonal of Q (default ones).
            tol: position tolerance [m].
            max_iter: iterations per start.
            k_null: null-space gain.
            restarts: further starting points tried after q0.

        Returns:
            q: (n,) configuration within the joint limits with ‖f(q) − x‖ ≤ tol.

        Raises:
            Unreachable: no solution within the limits was found from any start.
        """
        x = as_array("x", x, shape_tail=(self.m,))
        if x.ndim != 1:
            raise InvalidInput(f"x: expected shape ({self.m},), got {x.shape}; call ik per target")
        q0 = self._q(q0, "q0")
        if q0.ndim != 1:
            raise InvalidInput(f"q0: expected shape ({self.n},), got {q0.shape}")
        w = np.ones(self.n) if weights is None else as_array("weights", weights, shape_tail=(self.n,))
        if np.any(w <= 0):
            raise InvalidInput("weights: must be positive")
        Qinv = np.diag(1.0 / w)
        lo = np.where(np.isfinite(self.q_min), self.q_min, -np.pi)
        hi = np.where(np.isfinite(self.q_max), self.q_max, np.pi)
        starts = np.vstack([q0, np.random.default_rng(0).uniform(lo, hi, size=(restarts, self.n))])
        best = np.inf
        for start in starts:
            q, err = self._ik_from(x, start, Qinv, tol, max_iter, k_null)
            if err <= tol and self.within_limits(q, 1e-9):
                return q
            best = min(best, err)
        raise Unreachable(
            f"x: target {np.round(x, 5).tolist()} not reached within the joint limits of {self.name} "
            f"from {len(starts)} starting configurations (best residual {best:.3g} m)"
        )

    def _ik_from(self, x, q, Qinv, tol, max_iter, k_null) -> tuple[np.ndarray, float]:
        q = np.clip(q, self.q_min, self.q_max)
        err = np.inf
        for it in range(max_iter):
            e = x - self._fk1(self.theta(q))
            err = float(np.linalg.norm(e))
            # null-space centering during the first half, pure Newton steps to finish
            centering = it < max_iter // 2 and self.n > self.m
            if err <= tol and not centering:
                break
            step, null = self._ik_step(self._jac1(self.theta(q)), e, Qinv, q, k_null if centering else 0.0)
            if err <= tol and np.max(np.abs(null), initial=0.0) < 1e-6:
                break
            s = float(np.max(np.abs(step)))  # keep the linearisation valid
            q = np.clip(q + step * min(1.0, 0.5 / s) if s > 0 else q, self.q_min, self.q_max)
        return q, err

    # ---------------------------------------------------------------- locking
    def lock(self, values: Mapping[str | int, float] | None = None, *, name: str | None = None, **kw: float) -> Device:
        """Fix some motor coordinates and return the non-redundant (or less redundant) device.

        Args:
            values: {joint name or index: value [rad]}; keywords work too (`lock(q1=0, q2=0)`).
            name: name of the new device.
        """
        values = {**(values or {}), **kw}
        idx = {}
        for key, v in values.items():
            i = key if isinstance(key, int) else (self.joint_names.index(key) if key in self.joint_names else None)
            if i is None or not 0 <= i < self.n:
                raise InvalidInput(f"lock: unknown joint {key!r}; joints are {self.joint_names}")
            idx[i] = float(v)
        free = [i for i in range(self.n) if i not in idx]
        locked = np.array(sorted(idx))
        qv = np.array([idx[i] for i in sorted(idx)])
        lin = None
        if self.linear_limits is not None:
            L = self.linear_limits
            shift = L.C[:, locked] @ qv if locked.size else 0.0
            C, lo, hi = L.C[:, free], L.lower - shift, L.upper - shift
            keep = np.any(C != 0, axis=1)
            if np.any(~keep & ((lo > 1e-12) | (hi < -1e-12))):
                raise InvalidInput("lock: the locked values violate a linear joint limit")
            lin = LinearLimits(C[keep], lo[keep], hi[keep]) if keep.any() else None
        return Device(
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
        )

    def __repr__(self) -> str:
        return f"Device({self.name!r}, n={self.n}, task={self.task_axes!r})"

    # ---------------------------------------------------------------- helpers
    def _ik_step(self, J, e, Qinv, q, k_null):
        """One step of eq. 3.4 with joints blocked at a bound removed from the solve (active set).

        Returns (step, null-space part), each (n,).
        """
        free = np.ones(self.n, dtype=bool)
        for _ in range(self.n):
            Jf = J * free
            JQ = Jf @ Qinv
            Jp = JQ.T @ np.linalg.solve(JQ @ Jf.T + 1e-10 * np.eye(self.m), np.eye(self.m))
            null = -k_null * ((np.eye(self.n) - Jp @ Jf) @ self._centering_gradient(q)) * free
            step = Jp @ e + null
            blocked = free & (((q <= self.q_min) & (step < 0)) | ((q >= self.q_max) & (step > 0)))
            if not blocked.any():
                break
            free &= ~blocked
        return step, null

    def _centering_gradient(self, q: np.ndarray) -> np.ndarray:
        """∇h for h(q) = Σ ((q_i − mid_i)/range_i)² + Σ ((c_j q − mid_j)/range_j)² over finite limits."""
        finite = np.isfinite(self.q_min) & np.isfinite(self.q_max)
        lo, hi = np.where(finite, self.q_min, 0.0), np.where(finite, self.q_max, 0.0)
        g = np.where(finite, 2 * (q - 0.5 * (lo + hi)) / np.maximum(hi - lo, 1e-9) ** 2, 0.0)
        if self.linear_limits is not None:
            L = self.linear_limits
            r = np.maximum(L.upper - L.lower, 1e-9)
            g = g + L.C.T @ (2 * (L.C @ q - 0.5 * (L.lower + L.upper)) / r**2)
        return g

    def _q(self, q, name: str = "q") -> np.ndarray:
        return as_array(name, q, shape_tail=(self.n,))

    def _m_shape(self) -> tuple[int]:
        return (self.m,)

    def _map(self, q, shape: tuple[int, ...], fn: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        th = self.theta(q)
        if th.ndim == 1:
            return fn(th)
        out = np.empty(th.shape[:-1] + shape)
        for idx in np.ndindex(th.shape[:-1]):
            out[idx] = fn(th[idx])
        return out

    def _fk1(self, th: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(self.model, self.data, th)
        return self.data.oMf[self._fid].translation[self._rows]

    def _jac1(self, th: np.ndarray) -> np.ndarray:
        J = pin.computeFrameJacobian(self.model, self.data, th, self._fid, pin.LOCAL_WORLD_ALIGNED)
        return J[self._rows] @ self.A

    def _djac1(self, th: np.ndarray) -> np.ndarray:
        # dJ/dt for θ̇ = e_k is ∂J_θ/∂θ_k (exact, from Pinocchio's Jacobian time variation)
        cols = []
        for k in range(self.model.nv):
            pin.computeJointJacobiansTimeVariation(self.model, self.data, th, np.eye(self.model.nv)[k])
            pin.updateFramePlacements(self.model, self.data)
            cols.append(pin.getFrameJacobianTimeVariation(self.model, self.data, self._fid, pin.LOCAL_WORLD_ALIGNED))
        H = np.stack(cols, axis=-1)[self._rows]  # (m, nθ, nθ): [i, b, j] = ∂J_ib/∂θ_j
        return np.einsum("ibj,ba,jk->iak", H, self.A, self.A)

    def _mass1(self, th: np.ndarray) -> np.ndarray:
        M = pin.crba(self.model, self.data, th)
        M = np.triu(M) + np.triu(M, 1).T
        return self.A.T @ M @ self.A + np.diag(self.armature)


# ---------------------------------------------------------------------- loading
def available_devices() -> list[str]:
    """Names of the bundled devices."""
    return sorted(p.parent.name for p in MODELS.glob("*/device.toml"))


def device(name: str, **params: float) -> Device:
    """Load a bundled device by name (see `available_devices()`).

    Args:
        name: device name, e.g. "rhi4", "phantom", "rehab", "planar3r", "gen3".
        **params: design parameters declared in the device's `device.toml`
            (e.g. `d2=0.1405` for rhi4) [m or rad].
    """
    folder = MODELS / name
    if not (folder / "device.toml").is_file():
        raise UnknownDevice(f"name: unknown device {name!r}; available: {', '.join(available_devices())}")
    return load_device(folder, **params)


def load_device(folder: str | Path, **params: float) -> Device:
    """Load a device folder holding `device.toml` (+ its URDF). See models/README.md for the format."""
    folder = Path(folder)
    try:
        spec = tomllib.loads((folder / "device.toml").read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ModelError(f"{folder}: cannot read device.toml ({exc})") from None
    if "base" in spec:  # a device derived from another by locking joints
        base = device(spec["base"], **params)
        lock = {k: np.deg2rad(v) for k, v in spec.get("lock_deg", {}).items()}
        return base.lock(lock, name=spec.get("name", folder.name))
    return _build(folder, spec, params)


def _build(folder: Path, spec: dict, params: Mapping[str, float]) -> Device:
    urdf = folder / spec["urdf"]
    model = _load_urdf(urdf)
    declared = spec.get("parameters", {})
    unknown = set(params) - set(declared)
    if unknown:
        raise InvalidInput(f"params: unknown parameter(s) {sorted(unknown)} for {folder.name}; known: {sorted(declared)}")
    values = {}
    for pname, p in declared.items():
        v = float(params.get(pname, p["default"]))
        if not np.isfinite(v):
            raise InvalidInput(f"{pname}: must be finite, got {v}")
        if "min" in p and not p["min"] <= v <= p["max"]:
            raise InvalidInput(f"{pname}: {v} outside [{p['min']}, {p['max']}]")
        _set_placement(model, p["target"], p["component"], v)
        values[pname] = v
    lim = spec.get("limits", {})
    deg = lim.get("unit", "deg") == "deg"
    conv = np.deg2rad if deg else (lambda a: np.asarray(a, dtype=float))
    lin = None
    if "linear" in lim:
        rows = lim["linear"]
        lin = LinearLimits(
            np.array([r["coefficients"] for r in rows], dtype=float),
            conv(np.array([r["min"] for r in rows], dtype=float)),
            conv(np.array([r["max"] for r in rows], dtype=float)),
        )
    q_min = conv(np.array(lim["q_min"], dtype=float)) if "q_min" in lim else None
    q_max = conv(np.array(lim["q_max"], dtype=float)) if "q_max" in lim else None
    return Device(
        model,
        name=spec.get("name", folder.name),
        ee_frame=spec["ee_frame"],
        task_axes=spec.get("task", "xyz"),
        actuation=np.array(spec["actuation"], dtype=float) if "actuation" in spec else None,
        offset=np.array(spec["offset"], dtype=float) if "offset" in spec else None,
        q_min=q_min,
        q_max=q_max,
        torque_min=lim.get("torque_min"),
        torque_max=lim.get("torque_max"),
        linear_limits=lin,
        joint_names=spec.get("joint_names"),
        armature=spec.get("armature"),
        params=values,
    )


def _load_urdf(path: Path) -> pin.Model:
    if not path.is_file():
        raise ModelError(f"path: URDF file {str(path)!r} does not exist")
    try:
        return pin.buildModelFromUrdf(str(path))
    except Exception as exc:  # Pinocchio raises ValueError/RuntimeError with its own text
        raise ModelError(f"path: malformed URDF {str(path)!r}: {exc}") from None


def _set_placement(model: pin.Model, target: str, component: str, value: float) -> None:
    """Set one component of a joint or frame placement: component in x, y, z, yaw [m or rad]."""
    kind, _, name = target.partition(":")
    if kind == "joint" and model.existJointName(name):
        M = model.jointPlacements[model.getJointId(name)]
    elif kind == "frame" and model.existFrame(name):
        M = model.frames[model.getFrameId(name)].placement
    else:
        raise ModelError(f"parameters: unknown target {target!r}")
    if component in _AXES:
        t = M.translation.copy()
        t[_AXES[component]] = value
        M.translation = t
    elif component == "yaw":
        M.rotation = pin.utils.rotate("z", value)
    else:
        raise ModelError(f"parameters: unknown component {component!r}")
    if kind == "joint":
        model.jointPlacements[model.getJointId(name)] = M
    else:
        model.frames[model.getFrameId(name)].placement = M


def device_from_urdf(path: str | Path, *, ee_frame: str, task: str = "xyz", torque_max=None, name: str | None = None) -> Device:
    """Wrap a user robot described by a URDF.

    Args:
        path: URDF file.
        ee_frame: name of the end-effector link or frame.
        task: world axes of the position task ("xy", "xyz", ...).
        torque_max: (n,) actuator limits [N m]; defaults to the URDF effort limits.
        name: device name (default: the file stem).
    """
    path = Path(path)
    model = _load_urdf(path)
    if model.nq != model.nv:
        raise ModelError(f"path: {path.name} has continuous or floating joints (nq != nv); bound them")
    tmax = model.effortLimit if torque_max is None else torque_max
    tmax = np.where(np.asarray(tmax, dtype=float) > 0, tmax, np.inf)
    return Device(
        model,
        name=name or path.stem,
        ee_frame=ee_frame,
        task_axes=task,
        q_min=np.where(model.lowerPositionLimit > -1e10, model.lowerPositionLimit, -np.inf),
        q_max=np.where(model.upperPositionLimit < 1e10, model.upperPositionLimit, np.inf),
        torque_max=tmax,
        joint_names=[model.names[j] for j in range(1, model.njoints)],
    )
