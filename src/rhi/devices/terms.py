"""`DeviceTerms`: the kinematic and dynamic terms of a device at one state, and the constant maps behind them.

`Device.terms` fills a `DeviceTerms` from one pass: for trees of revolute/prismatic joints the
compiled `rhi.devices._compiled.chain` computes the chain's kinematics and dynamics (otherwise Pinocchio);
for chains of one-DoF joints the compiled `rhi.devices._compiled.terms.task_terms` writes every term
(∂J/∂q in closed form from the 6-D frame Jacobian, the task-space dynamics of thesis eqs.
5.2 / 7.1) into one flat buffer the snapshot's attributes view; otherwise the task-space
dynamics are computed on first access. Also the small numeric helpers the 1 kHz paths
share: `eye`, `inv_small` and the `lazy` attribute.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np
import pinocchio as pin

from rhi._linalg import torque_null_projector
from rhi.errors import InvalidInput

if TYPE_CHECKING:
    from rhi.devices.spec import LinearLimits

#: one-DoF joints whose kinematic Hessian has the closed form used by `Device.terms`
ONE_DOF_JOINT = re.compile(r"JointModel(R[XYZ]|P[XYZ]|RevoluteUnaligned|PrismaticUnaligned|Helical\w*)$")
#: (3, 3, 3) Levi-Civita symbol ε_ijk: (a × b)_i = Σ ε_ijk a_j b_k
LEVI_CIVITA = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    LEVI_CIVITA[_i, _j, _k], LEVI_CIVITA[_i, _k, _j] = 1.0, -1.0

_EYE: dict[int, np.ndarray] = {}

#: The terms the compiled `task_terms` writes (`rhi.devices._compiled.terms`), in order, with their shapes as functions of (n, m).
TERMS = (
    ("J", lambda n, m: (m, n)), ("dJ", lambda n, m: (m, n, n)), ("M", lambda n, m: (n, n)), ("g", lambda n, m: (n,)),
    ("Minv", lambda n, m: (n, n)), ("JMinv", lambda n, m: (m, n)), ("Lambda", lambda n, m: (m, m)),
    ("Jsharp", lambda n, m: (n, m)), ("Gx", lambda n, m: (m,)), ("xdot", lambda n, m: (m,)),
    ("Jdot", lambda n, m: (m, n)), ("C", lambda n, m: (n, n)), ("Cx", lambda n, m: (m, m)),
)


def layout(n: int, m: int) -> tuple[dict[str, tuple[int, int, tuple[int, ...]]], np.ndarray, int]:
    """Where each term of `TERMS` lies in the flat output of the compiled `task_terms`.

    Returns:
        ({name: (start, stop, shape)}, (len(TERMS),) int64 start offsets, total length).
    """
    out: dict[str, tuple[int, int, tuple[int, ...]]] = {}
    pos = 0
    for name, shape in TERMS:
        shp: tuple[int, ...] = shape(n, m)
        size = int(np.prod(shp))
        out[name] = (pos, pos + size, shp)
        pos += size
    return out, np.array([v[0] for v in out.values()], dtype=np.int64), pos


class lazy:
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


class term(lazy):
    """A `DeviceTerms` attribute: a view into the snapshot's flat buffer, or computed on first access.

    The view when `Device.terms` filled the buffer (`rhi.devices._compiled.terms`); otherwise the
    function runs once and its value is cached, like `lazy`.
    """

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        where = obj._layout.get(self.name) if obj._buf is not None else None
        value = self.fn(obj) if where is None else obj._buf[where[0]:where[1]].reshape(where[2])
        obj.__dict__[self.name] = value
        return value


def eye(n: int) -> np.ndarray:
    """The (n, n) identity, cached and read-only (use it in expressions such as ``eye(n) − X``)."""
    eye_n = _EYE.get(n)
    if eye_n is None:
        eye_n = _EYE[n] = np.eye(n)
        eye_n.flags.writeable = False
    return eye_n


class DeviceModel(Protocol):
    """What the per-state terms, their readers and the inverse kinematics use of a device.

    `rhi.devices.model.Device` is the one implementation; the terms and `rhi.devices.ik` are typed
    against this protocol so that the model imports them and they do not import the model.
    """

    name: str
    n: int
    m: int
    model: pin.Model
    data: pin.Data
    ee_frame_id: int
    A: np.ndarray
    b: np.ndarray
    armature: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    torque_min: np.ndarray
    torque_max: np.ndarray
    joint_names: list[str]
    linear_limits: LinearLimits | None

    @property
    def task_rows(self) -> list[int]:
        """World-axis indices of the task coordinates."""
        ...

    def coriolis(self, q, dq) -> np.ndarray:
        """C_q(q, q̇) (n, n)."""
        ...

    def coriolis_theta(self, th: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """C_q at chain coordinates θ (n, n)."""
        ...

    def fk_theta(self, th: np.ndarray) -> np.ndarray:
        """End-effector position (m,) [m] at chain coordinates θ."""
        ...

    def jacobian_theta(self, th: np.ndarray) -> np.ndarray:
        """Task Jacobian (m, n) at chain coordinates θ."""
        ...

    def within_limits(self, q, tol: float = 1e-9) -> np.ndarray:
        """Whether q satisfies the joint limits: (...,) bool."""
        ...


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
    return np.linalg.inv(A)


@dataclasses.dataclass(frozen=True)
class FastMaps:
    """Constant maps and flags of `Device.terms` (built once per device by `fast_maps`)."""

    rows: slice | np.ndarray
    offset: bool
    identity: bool
    At: np.ndarray
    armature: np.ndarray
    tril: tuple[np.ndarray, np.ndarray]
    crba_symmetric: bool
    rows_idx: np.ndarray  # (m,) int64 task rows of the 6-D frame Jacobian
    supports: np.ndarray | None  # (nθ, nθ) bool: chain joint k supports joint j (or is j); None: not all one-DoF
    kernel: Callable | None  # _compiled.chain.chain_terms (with `chain`), else _compiled.terms.task_terms, else None
    chain: tuple[np.ndarray, ...] | None  # rhi.devices.batch.pack constants: trees of revolute/prismatic joints
    layout: dict[str, tuple[int, int, tuple[int, ...]]]  # where each term lies in the kernel's output
    position_layout: dict[str, tuple[int, int, tuple[int, ...]]]  # the same without the velocity terms
    size: int  # length of the kernel's output


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
        device: DeviceModel,
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

    _buf: np.ndarray | None = None
    _layout: dict = {}

    @classmethod
    def from_buffer(cls, device: DeviceModel, q: np.ndarray, dq: np.ndarray | None, x: np.ndarray, theta: np.ndarray,
                    buf: np.ndarray, layout: dict[str, tuple[int, int, tuple[int, ...]]]) -> DeviceTerms:
        """A snapshot whose terms are views into `buf`, the flat output of `rhi.devices._compiled.terms.task_terms`.

        Args:
            device: the device.
            q: (n,) joint positions [rad or m].
            dq: (n,) joint velocities [rad/s], or None.
            x: (m,) end-effector position [m].
            theta: (nθ,) chain coordinates.
            buf: the kernel's output.
            layout: {name: (start, stop, shape)} of the terms in buf (`layout`).
        """
        self = cls.__new__(cls)
        self.device, self.q, self.dq, self.x, self._theta = device, q, dq, x, theta
        self._buf, self._layout = buf, layout
        return self

    def _absent(self) -> np.ndarray:  # pragma: no cover - set by the constructor or a view of the buffer
        raise AttributeError("term missing")

    J = term(_absent)
    dJ = term(_absent)
    M = term(_absent)
    g = term(_absent)

    def _need_dq(self, what: str) -> np.ndarray:
        if self.dq is None:
            raise InvalidInput(f"dq: {what} needs the joint velocity; call Device.terms(q, dq)")
        return self.dq

    @term
    def xdot(self) -> np.ndarray:
        """(m,) end-effector velocity ẋ = J q̇ [m/s] (eq. 6.1)."""
        return self.J.dot(self._need_dq("xdot"))

    @term
    def Jdot(self) -> np.ndarray:
        """(m, n) time derivative J̇ = Σ_k ∂J/∂q_k q̇_k [m/(rad s)]."""
        return self.dJ.dot(self._need_dq("Jdot"))

    @term
    def C(self) -> np.ndarray:
        """(n, n) joint Coriolis/centrifugal matrix C_q(q, q̇) (Ṁ − 2C skew-symmetric); C q̇ [N m]."""
        dq = self._need_dq("C")
        if self._theta is None:
            return self.device.coriolis(self.q, dq)
        return self.device.coriolis_theta(self._theta, dq)

    def _cartesian(self) -> None:
        """Compute M_q⁻¹, J M_q⁻¹, M_x and J# together (one call on first access of any)."""
        d = self.__dict__
        Minv = d["Minv"] = np.linalg.inv(self.M)
        JMinv = d["JMinv"] = self.J.dot(Minv)
        Lam = d["Lambda"] = inv_small(JMinv.dot(self.J.T))
        d["Jsharp"] = JMinv.T.dot(Lam)

    @term
    def Minv(self) -> np.ndarray:
        """(n, n) M_q⁻¹ [1/(kg m²)] (M_q is positive definite for any physical model)."""
        self._cartesian()
        return self.__dict__["Minv"]

    @term
    def JMinv(self) -> np.ndarray:
        """(m, n) J M_q⁻¹."""
        self._cartesian()
        return self.__dict__["JMinv"]

    @term
    def Lambda(self) -> np.ndarray:
        """(m, m) apparent (end-effector) inertia M_x = (J M_q⁻¹ Jᵀ)⁻¹ [kg] (eqs. 5.2, 7.1)."""
        self._cartesian()
        return self.__dict__["Lambda"]

    @term
    def Jsharp(self) -> np.ndarray:
        """(n, m) dynamically consistent inverse J# = M_q⁻¹ Jᵀ (J M_q⁻¹ Jᵀ)⁻¹ (eq. 5.3)."""
        self._cartesian()
        return self.__dict__["Jsharp"]

    @term
    def N(self) -> np.ndarray:
        """(n, n) dynamically consistent torque null-space projector I − Jᵀ J#ᵀ (eqs. 3.20, 5.9, 7.5)."""
        return torque_null_projector(self.J, self.Jsharp)

    @term
    def Cx(self) -> np.ndarray:
        """(m, m) end-effector Coriolis/centrifugal matrix C_x = M_x (J M_q⁻¹ C_q − J̇) J# (eqs. 5.2, 7.1).

        With the Christoffel C_q of Pinocchio, Ṁ_x = C_x + C_xᵀ along any q̇.
        """
        return self.Lambda.dot(self.JMinv.dot(self.C) - self.Jdot).dot(self.Jsharp)

    @term
    def Gx(self) -> np.ndarray:
        """(m,) gravity force reflected at the end-effector G_x = J#ᵀ G_q [N] (eqs. 5.2, 7.1)."""
        g = self.g
        if g.dot(g) == 0.0:  # planar devices: no projection needed
            return np.zeros(self.J.shape[0])
        return self.Jsharp.T.dot(g)

    def __repr__(self) -> str:
        return f"DeviceTerms({self.device.name!r}, q={np.round(self.q, 4).tolist()})"


def fast_maps(model: pin.Model, frame_id: int, A: np.ndarray, b: np.ndarray, armature: np.ndarray,
              rows: list[int]) -> FastMaps:
    """The constant maps and flags of `Device.terms` for a chain model with actuation map θ = A q + b.

    Args:
        model: Pinocchio model of the chain (nv = nθ).
        frame_id: end-effector frame id in `model`.
        A: (nθ, n) actuation map.
        b: (nθ,) actuation offset.
        armature: (n,) rotor inertia [kg m²].
        rows: world-axis indices of the task coordinates (m of them).
    """
    nt, n, m = model.nv, A.shape[1], len(rows)
    rows_idx = slice(rows[0], rows[-1] + 1) if rows == list(range(rows[0], rows[-1] + 1)) else np.array(rows)
    data = model.createData()
    th = np.random.default_rng(0).uniform(-1.0, 1.0, nt)
    Mt = pin.crba(model, data, th)
    mask = hessian_mask(model)
    from rhi.devices import batch  # Numba: imported on the first `Device.terms`, not with `import rhi`
    from rhi.devices._compiled import chain as chain_kernel, terms as terms_kernel

    where, _, size = layout(n, m)
    chain = batch.pack(model, frame_id) if mask is not None and batch.supported(model) else None
    return FastMaps(
        rows=rows_idx,
        offset=bool(np.any(b != 0)),
        identity=A.shape == (nt, nt) and bool(np.array_equal(A, np.eye(nt))),
        At=np.ascontiguousarray(A.T),
        armature=np.diag(armature),
        tril=np.tril_indices(nt, -1),
        crba_symmetric=bool(np.array_equal(Mt, Mt.T)) and bool(np.any(np.tril(Mt, -1) != 0) or nt == 1),
        rows_idx=np.array(rows, dtype=np.int64),
        supports=mask,
        kernel=None if mask is None else chain_kernel.chain_terms if chain is not None else terms_kernel.task_terms,
        chain=chain,
        layout=where,
        position_layout={k: v for k, v in where.items() if k not in ("xdot", "Jdot", "C", "Cx")},
        size=size,
    )


def compiled_terms(device: DeviceModel, fast: FastMaps, kernel: Callable, q: np.ndarray, dq: np.ndarray | None,
                   th: np.ndarray) -> DeviceTerms:
    """Every term of one state, the task-space dynamics included, from compiled kernels.

    Trees of revolute/prismatic joints (``fast.chain``): one `rhi.devices._compiled.chain.chain_terms` call
    computes Pinocchio's terms too; other one-DoF joints: Pinocchio's algorithms, then
    `rhi.devices._compiled.terms.task_terms`.

    Args:
        device: the device.
        fast: its `FastMaps`.
        kernel: ``fast.kernel``.
        q: (n,) joint positions [rad or m].
        dq: (n,) joint velocities [rad/s], or None.
        th: (nθ,) chain coordinates θ = A q + b.
    """
    v = np.zeros(device.n) if dq is None else np.ascontiguousarray(dq, dtype=float)
    buf = np.empty(fast.size)
    if fast.chain is not None:
        x = np.empty(fast.rows_idx.shape[0])
        kernel(*fast.chain, th, device.A, fast.rows_idx, device.armature, fast.supports, fast.identity, v, x, buf)
    else:
        model, data, fid = device.model, device.data, device.ee_frame_id
        pin.computeJointJacobians(model, data, th)
        J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        x = data.oMf[fid].translation[fast.rows].copy()
        Ct = pin.computeCoriolisMatrix(model, data, th, device.A.dot(v))
        kernel(J6, pin.crba(model, data, th), pin.computeGeneralizedGravity(model, data, th), Ct, device.A,
                    fast.rows_idx, device.armature, fast.supports, fast.identity, not fast.crba_symmetric, v, buf)
    return DeviceTerms.from_buffer(device, q, dq, x, th, buf, fast.position_layout if dq is None else fast.layout)


def hessian_mask(model: pin.Model) -> np.ndarray | None:
    """(nθ, nθ) bool, [j, k]: joint k supports joint j (or is j); None if a joint is not one-DoF."""
    if model.njoints - 1 != model.nv:
        return None
    vidx = {}
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        if jm.nv != 1 or jm.nq != 1 or not ONE_DOF_JOINT.match(jm.shortname()):
            return None
        vidx[jid] = jm.idx_v
    mask = np.zeros((model.nv, model.nv), bool)
    for jid, j in vidx.items():
        for kid in model.supports[jid]:
            if kid in vidx:
                mask[j, vidx[kid]] = True
    return mask
