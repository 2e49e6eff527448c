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
import math
import re
import tomllib
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin

from rhi import batch
from rhi._validate import as_array, limits_pair
from rhi.errors import InvalidInput, ModelError, UnknownDevice, Unreachable

MODELS = Path(__file__).parent / "models"
_AXES = {"x": 0, "y": 1, "z": 2}
# one-DoF joints whose kinematic Hessian has the closed form used by `Device.terms`
_ONE_DOF_JOINT = re.compile(r"JointModel(R[XYZ]|P[XYZ]|RevoluteUnaligned|PrismaticUnaligned|Helical\w*)$")
_LEVI_CIVITA = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _LEVI_CIVITA[_i, _j, _k], _LEVI_CIVITA[_i, _k, _j] = 1.0, -1.0


_EYE: dict[int, np.ndarray] = {}
BATCH_MIN = 16  # batched inputs with at least this many configurations go through `rhi.batch`


class _lazy:
    """Compute an attribute on first access and store it on the instance.

    functools.cached_property without the per-access lock it takes on Python 3.11
    (several µs per attribute, too much inside a 1 kHz control tick).
    """

    def __init__(self, fn: Callable) -> None:
        self.fn = fn
        self.name = fn.__name__
        self.__doc__ = fn.__doc__

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        value = obj.__dict__[self.name] = self.fn(obj)
        return value


def eye(n: int) -> np.ndarray:
    """The (n, n) identity, cached and read-only (use it in expressions such as ``eye(n) − X``)."""
    eye_n = _EYE.get(n)
    if eye_n is None:
        eye_n = _EYE[n] = np.eye(n)
        eye_n.flags.writeable = False
    return eye_n


try:  # the gufunc behind np.linalg.inv, without its Python-level checks (~3 µs per call)
    from numpy.linalg import _umath_linalg

    _umath_linalg.inv(np.eye(2), signature="d->d")

    def _inv(A: np.ndarray) -> np.ndarray:
        return _umath_linalg.inv(A, signature="d->d")

except (ImportError, AttributeError, TypeError):  # pragma: no cover - other NumPy builds
    _inv = np.linalg.inv


def inv_small(A: np.ndarray) -> np.ndarray:
    """Inverse of a small square float matrix: closed form for 2 × 2, LAPACK otherwise.

    Args:
        A: (k, k) non-singular matrix.

    Returns:
        (k, k) inverse.

    Raises:
        numpy.linalg.LinAlgError: a 2 × 2 A is singular (larger ones give non-finite entries).
    """
    if A.shape == (2, 2):
        (a, b), (c, d) = A.tolist()
        det = a * d - b * c
        if det != 0.0 and math.isfinite(det):
            return np.array([[d / det, -b / det], [-c / det, a / det]])
        return np.linalg.inv(A)  # raises LinAlgError
    return _inv(A)


@dataclasses.dataclass(frozen=True)
class _FastMaps:
    rows: slice | np.ndarray
    offset: bool
    identity: bool
    At: np.ndarray
    armature: np.ndarray
    tril: tuple[np.ndarray, np.ndarray]
    crba_symmetric: bool
    hessian: np.ndarray | None
    dJ_shape: tuple[int, int, int]


class DeviceTerms:
    """Kinematic and dynamic terms of a device at one state (q, q̇), computed together (`Device.terms`).

    The per-tick snapshot a controller and its primary law read: eager attributes come
    from one Pinocchio pass; the Cartesian (task-space) dynamics of thesis eq. 5.2 / 7.1
    are computed on first access and cached.

    Attributes:
        device: the device these terms belong to.
        q: (n,) joint positions [rad or m].
        dq: (n,) joint velocities [rad/s], or None (velocity terms then raise InvalidInput).
        x: (m,) end-effector position [m].
        J: (m, n) task Jacobian ∂x/∂q [m/rad].
        dJ: (m, n, n) ∂J/∂q with [i, j, k] = ∂J_ij/∂q_k [m/rad²].
        M: (n, n) joint-space inertia M_q incl. armature [kg m²].
        g: (n,) gravity torque G_q [N m].

    Computed on first access (cached): ``xdot`` ẋ = J q̇ (m,) [m/s]; ``Jdot`` J̇ (m, n);
    ``C`` C_q(q, q̇) (n, n); ``Minv`` M_q⁻¹; ``JMinv`` J M_q⁻¹ (m, n); ``Lambda`` M_x (m, m)
    [kg]; ``Jsharp`` J# (n, m); ``N`` I − JᵀJ#ᵀ (n, n); ``Cx`` C_x (m, m) [N s/m]; ``Gx`` G_x
    (m,) [N]. The snapshot is read-only by convention: do not modify its arrays.
    """

    def __init__(
        self,
        device: Device,
        q: np.ndarray,
        dq: np.ndarray | None,
        *,
        x: np.ndarray,
        J: np.ndarray,
        dJ: np.ndarray,
        M: np.ndarray,
        g: np.ndarray,
        theta: np.ndarray | None = None,
    ) -> None:
        self.device = device
        self.q, self.dq, self.x, self.J, self.dJ, self.M, self.g = q, dq, x, J, dJ, M, g
        self._theta = theta

    def _need_dq(self, what: str) -> np.ndarray:
        if self.dq is None:
            raise InvalidInput(f"dq: {what} needs the joint velocity; call Device.terms(q, dq)")
        return self.dq

    @_lazy
    def xdot(self) -> np.ndarray:
        """(m,) end-effector velocity ẋ = J q̇ [m/s] (eq. 6.1)."""
        return self.J.dot(self._need_dq("xdot"))

    @_lazy
    def Jdot(self) -> np.ndarray:
        """(m, n) time derivative J̇ = Σ_k ∂J/∂q_k q̇_k [m/(rad s)]."""
        return self.dJ.dot(self._need_dq("Jdot"))

    @_lazy
    def C(self) -> np.ndarray:
        """(n, n) joint Coriolis/centrifugal matrix C_q(q, q̇) (Ṁ − 2C skew-symmetric); C q̇ [N m]."""
        dq = self._need_dq("C")
        if self._theta is None:
            return self.device.coriolis(self.q, dq)
        return self.device._coriolis1(self._theta, dq)

    def _cartesian(self) -> None:
        """Compute M_q⁻¹, J M_q⁻¹, M_x and J# together (one call on first access of any)."""
        d = self.__dict__
        Minv = d["Minv"] = _inv(self.M)
        JMinv = d["JMinv"] = self.J.dot(Minv)
        Lam = d["Lambda"] = inv_small(JMinv.dot(self.J.T))
        d["Jsharp"] = JMinv.T.dot(Lam)

    @_lazy
    def Minv(self) -> np.ndarray:
        """(n, n) M_q⁻¹ [1/(kg m²)] (M_q is positive definite for any physical model)."""
        self._cartesian()
        return self.__dict__["Minv"]

    @_lazy
    def JMinv(self) -> np.ndarray:
        """(m, n) J M_q⁻¹."""
        self._cartesian()
        return self.__dict__["JMinv"]

    @_lazy
    def Lambda(self) -> np.ndarray:
        """(m, m) apparent (end-effector) inertia M_x = (J M_q⁻¹ Jᵀ)⁻¹ [kg] (eqs. 5.2, 7.1)."""
        self._cartesian()
        return self.__dict__["Lambda"]

    @_lazy
    def Jsharp(self) -> np.ndarray:
        """(n, m) dynamically consistent inverse J# = M_q⁻¹ Jᵀ (J M_q⁻¹ Jᵀ)⁻¹ (eq. 5.3)."""
        self._cartesian()
        return self.__dict__["Jsharp"]

    @_lazy
    def N(self) -> np.ndarray:
        """(n, n) dynamically consistent torque null-space projector I − Jᵀ J#ᵀ (eqs. 3.20, 5.9, 7.5)."""
        return eye(self.J.shape[1]) - self.J.T.dot(self.Jsharp.T)

    @_lazy
    def Cx(self) -> np.ndarray:
        """(m, m) end-effector Coriolis/centrifugal matrix C_x = M_x (J M_q⁻¹ C_q − J̇) J# (eqs. 5.2, 7.1).

        With the Christoffel C_q of Pinocchio, Ṁ_x = C_x + C_xᵀ along any q̇.
        """
        return self.Lambda.dot(self.JMinv.dot(self.C) - self.Jdot).dot(self.Jsharp)

    @_lazy
    def Gx(self) -> np.ndarray:
        """(m,) gravity force reflected at the end-effector G_x = J#ᵀ G_q [N] (eqs. 5.2, 7.1)."""
        g = self.g
        if g.dot(g) == 0.0:  # planar devices: no projection needed
            return np.zeros(self.J.shape[0])
        return self.Jsharp.T.dot(g)

    def __repr__(self) -> str:
        return f"DeviceTerms({self.device.name!r}, q={np.round(self.q, 4).tolist()})"


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
        damping: (n,) viscous motor friction for the plant [N m s/rad] (default 0).
        frictionloss: (n,) Coulomb motor friction for the plant [N m] (default 0).

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
        self.armature = self._nonneg("armature", armature, n)
        self.damping = self._nonneg("damping", damping, n)
        self.frictionloss = self._nonneg("frictionloss", frictionloss, n)
        self.params = dict(params or {})
        #: (URDF XML, folders for its mesh paths) of the description, for drawing its visuals (rhi.viz); or None
        self.visual_description: tuple[str, tuple[str, ...]] | None = None
        self.locked_joints: dict[str, float] = {}

    @staticmethod
    def _nonneg(arg: str, value, n: int) -> np.ndarray:
        v = np.zeros(n) if value is None else as_array(arg, value)
        v = np.full(n, float(v)) if v.ndim == 0 else v
        if v.shape != (n,) or np.any(v < 0):
            raise InvalidInput(f"{arg}: expected {n} finite non-negative values, got {v.tolist()}")
        return v

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
        return self._map(q, self._m_shape(), self._fk1, "x")

    def skeleton(self, q) -> np.ndarray:
        """World positions of every chain joint then the end-effector, for drawing: (k, 3) [m] for q: (n,)."""
        th = self.theta(self._q(q))
        pin.framesForwardKinematics(self.model, self.data, th)
        pts = [self.data.oMi[j].translation.copy() for j in range(1, self.model.njoints)]
        return np.array(pts + [self.data.oMf[self._fid].translation.copy()])

    def jacobian(self, q) -> np.ndarray:
        """Task Jacobian ∂x/∂q in the world frame: (..., m, n)."""
        return self._map(q, (self.m, self.n), self._jac1, "J")

    def jacobian_derivative(self, q) -> np.ndarray:
        """∂J/∂q: (..., m, n, n) with [..., i, j, k] = ∂J_ij/∂q_k."""
        return self._map(q, (self.m, self.n, self.n), self._djac1, "dJ")

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
        """Every kinematic and dynamic term of one state from a single Pinocchio pass.

        One `computeJointJacobians` (forward kinematics + joint Jacobians), the frame
        Jacobian, `crba` and `computeGeneralizedGravity`; ∂J/∂q follows in closed form
        from the 6-D frame Jacobian (∂J_j/∂θ_k = ω_k × J_j when joint k supports joint j,
        ω_j × J_k otherwise; one-DoF joints). Equal to `fk`, `jacobian`,
        `jacobian_derivative`, `mass_matrix` and `gravity` called one by one, several
        times faster. The task-space dynamics (M_x, J#, C_x, G_x) are computed on demand.
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
        model, data, fid = self.model, self.data, self._fid
        fast = self._fast_maps
        th = self.A.dot(q)
        if fast.offset:
            th += self.b
        pin.computeJointJacobians(model, data, th)
        J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        x = data.oMf[fid].translation[fast.rows].copy()
        Mt = pin.crba(model, data, th)
        if not fast.crba_symmetric:
            il = fast.tril
            Mt[il] = Mt.T[il]  # this Pinocchio fills only the upper triangle
        gt = pin.computeGeneralizedGravity(model, data, th)
        if fast.identity:
            J = J6[fast.rows].copy()
            M = Mt + fast.armature
            g = gt.copy()
        else:
            At = fast.At
            J = J6[fast.rows].dot(self.A)
            M = At.dot(Mt).dot(self.A) + fast.armature
            g = At.dot(gt)
        if fast.hessian is None:
            dJ = self._djac1(th)
        else:
            # ∂J/∂q is bilinear in the angular (ω) and linear (v) columns of the 6-D frame Jacobian
            W = J6[3:].reshape(-1, 1)
            dJ = fast.hessian.dot((W * J6[:3].reshape(1, -1)).reshape(-1)).reshape(fast.dJ_shape)
        terms = DeviceTerms(self, q, dq, x=x, J=J, dJ=dJ, M=M, g=g, theta=th)
        self._last_terms = (key, terms)
        return terms

    @_lazy
    def _fast_maps(self) -> _FastMaps:
        """Constant maps and flags of `terms`, built on first use."""
        model, A = self.model, self.A
        nt, n, m = model.nv, self.n, self.m
        rows = self._rows
        rows_idx = slice(rows[0], rows[-1] + 1) if rows == list(range(rows[0], rows[-1] + 1)) else np.array(rows)
        data = model.createData()
        th = np.random.default_rng(0).uniform(-1.0, 1.0, nt)
        Mt = pin.crba(model, data, th)
        hessian = None
        mask = self._hessian_mask()
        if mask is not None:
            # dJ[i, a, c] = Σ_{p,x,r,y} K[(i,a,c), (p,x), (r,y)] ω[p, x] v[r, y], from ∂J_j/∂θ_k = ω_k × v_j if k
            # supports j, else ω_j × v_k (one-DoF joints), and J_q = J_θ A
            eps = _LEVI_CIVITA[rows]  # (m, 3, 3): [i, p, r]
            Mk = mask.astype(float)
            # S[a, c, x, y] = A[y, a] A[x, c] mask[y, x] + A[x, a] A[y, c] (1 − mask[x, y])
            S = np.einsum("ya,xc,yx->acxy", A, A, Mk) + np.einsum("xa,yc,xy->acxy", A, A, 1.0 - Mk)
            K = np.einsum("ipr,acxy->iacpxry", eps, S)
            hessian = np.ascontiguousarray(K.reshape(m * n * n, 3 * nt * 3 * nt))
        return _FastMaps(
            rows=rows_idx,
            offset=bool(np.any(self.b != 0)),
            identity=A.shape == (nt, nt) and bool(np.array_equal(A, np.eye(nt))),
            At=np.ascontiguousarray(A.T),
            armature=np.diag(self.armature),
            tril=np.tril_indices(nt, -1),
            crba_symmetric=bool(np.array_equal(Mt, Mt.T)) and bool(np.any(np.tril(Mt, -1) != 0) or nt == 1),
            hessian=hessian,
            dJ_shape=(m, n, n),
        )

    def _hessian_mask(self) -> np.ndarray | None:
        """(nθ, nθ) bool, [j, k]: joint k supports joint j (or is j); None if a joint is not one-DoF."""
        model = self.model
        if model.njoints - 1 != model.nv:
            return None
        vidx = {}
        for jid in range(1, model.njoints):
            jm = model.joints[jid]
            if jm.nv != 1 or jm.nq != 1 or not _ONE_DOF_JOINT.match(jm.shortname()):
                return None
            vidx[jid] = jm.idx_v
        mask = np.zeros((model.nv, model.nv), bool)
        for jid, j in vidx.items():
            for kid in model.supports[jid]:
                if kid in vidx:
                    mask[j, vidx[kid]] = True
        return mask

    def _coriolis1(self, th: np.ndarray, dq: np.ndarray) -> np.ndarray:
        A = self.A
        C = pin.computeCoriolisMatrix(self.model, self.data, th, A.dot(dq))
        return self._fast_maps.At.dot(C).dot(A)

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
        At, b = self.A.T, self.b
        for it in range(max_iter):
            th = q @ At + b  # = theta(q), without re-validating q
            e = x - self._fk1(th)
            err = float(np.linalg.norm(e))
            # null-space centering during the first half, pure Newton steps to finish
            centering = it < max_iter // 2 and self.n > self.m
            if err <= tol and not centering:
                break
            step, null = self._ik_step(self._jac1(th), e, Qinv, q, k_null if centering else 0.0)
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
        lin = None
        if self.linear_limits is not None:
            L = self.linear_limits
            shift = L.C[:, locked] @ qv if locked.size else 0.0
            C, lo, hi = L.C[:, free], L.lower - shift, L.upper - shift
            keep = np.any(C != 0, axis=1)
            if np.any(~keep & ((lo > 1e-12) | (hi < -1e-12))):
                raise InvalidInput("lock: the locked values violate a linear joint limit")
            lin = LinearLimits(C[keep], lo[keep], hi[keep]) if keep.any() else None
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
        )
        dev.locked_joints = {**self.locked_joints, **{self.joint_names[i]: v for i, v in idx.items()}}
        dev.visual_description = self.visual_description
        return dev

    def __repr__(self) -> str:
        return f"Device({self.name!r}, n={self.n}, task={self.task_axes!r})"

    # ---------------------------------------------------------------- helpers
    def _ik_step(self, J, e, Qinv, q, k_null):
        """One step of eq. 3.4 with joints blocked at a bound removed from the solve (active set).

        Returns (step, null-space part), each (n,).
        """
        free = np.ones(self.n, dtype=bool)
        eye_m, eye_n = eye(self.m), eye(self.n)
        grad = self._centering_gradient(q) if k_null else None
        for _ in range(self.n):
            Jf = J * free
            JQ = Jf @ Qinv
            Jp = JQ.T @ np.linalg.solve(JQ @ Jf.T + 1e-10 * eye_m, eye_m)
            null = -k_null * ((eye_n - Jp @ Jf) @ grad) * free if k_null else np.zeros(self.n)
            step = Jp @ e + null
            blocked = free & (((q <= self.q_min) & (step < 0)) | ((q >= self.q_max) & (step > 0)))
            if not blocked.any():
                break
            free &= ~blocked
        return step, null

    def _centering_gradient(self, q: np.ndarray) -> np.ndarray:
        """∇h for h(q) = Σ ((q_i − mid_i)/range_i)² + Σ ((c_j q − mid_j)/range_j)² over finite limits."""
        finite, mid, den, lin = self._centering_constants
        g = np.where(finite, 2 * (q - mid) / den, 0.0)
        if lin is not None:
            C, Ct, mid_l, den_l = lin
            g = g + Ct @ (2 * (C @ q - mid_l) / den_l)
        return g

    @_lazy
    def _centering_constants(self):
        """Constant parts of `_centering_gradient` (finite mask, mid-ranges, squared ranges)."""
        finite = np.isfinite(self.q_min) & np.isfinite(self.q_max)
        lo, hi = np.where(finite, self.q_min, 0.0), np.where(finite, self.q_max, 0.0)
        lin = None
        if self.linear_limits is not None:
            L = self.linear_limits
            lin = (L.C, L.C.T, 0.5 * (L.lower + L.upper), np.maximum(L.upper - L.lower, 1e-9) ** 2)
        return finite, 0.5 * (lo + hi), np.maximum(hi - lo, 1e-9) ** 2, lin

    def _q(self, q, name: str = "q") -> np.ndarray:
        return as_array(name, q, shape_tail=(self.n,))

    def _m_shape(self) -> tuple[int]:
        return (self.m,)

    def _map(self, q, shape: tuple[int, ...], fn: Callable[[np.ndarray], np.ndarray], term: str) -> np.ndarray:
        """fn per configuration, or the vectorized `rhi.batch` term for batches of >= BATCH_MIN configurations."""
        th = self.theta(q)
        if th.ndim == 1:
            return fn(th)
        if self._batch is not None and th.size >= BATCH_MIN * th.shape[-1]:
            return self._batch.evaluate(th, (term,))[term]
        out = np.empty(th.shape[:-1] + shape)
        for idx in np.ndindex(th.shape[:-1]):
            out[idx] = fn(th[idx])
        return out

    @_lazy
    def _batch(self) -> batch.BatchChain | None:
        """Vectorized kinematics and dynamics for batched inputs; None if a joint type is not supported."""
        if not batch.supported(self.model):
            return None
        return batch.BatchChain(self.model, self._fid, rows=self._rows, A=self.A, armature=self.armature)

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
    if not isinstance(name, str) or not name or "/" in name or name.startswith("."):
        raise UnknownDevice(f"name: expected a bundled device name, got {name!r}; available: {', '.join(available_devices())}")
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
        arr = as_array(pname, params[pname]) if pname in params else np.asarray(float(p["default"]))
        if arr.ndim != 0:
            raise InvalidInput(f"{pname}: expected one value, got shape {arr.shape}")
        v = float(arr)
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
    dev = Device(
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
        damping=spec.get("plant", {}).get("damping"),
        frictionloss=spec.get("plant", {}).get("frictionloss"),
    )
    dev.visual_description = (urdf.read_text(), (str(folder),))
    return dev


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
