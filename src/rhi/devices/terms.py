"""`DeviceTerms`: the kinematic and dynamic terms of a device at one state.

`Device.terms` fills a `DeviceTerms` in one pass (`rhi.devices.terms_pass`): for chains of one-DoF joints
every term (∂J/∂q in closed form from the 6-D frame Jacobian, the task-space dynamics of thesis eqs.
5.2 / 7.1) lies in one flat buffer the snapshot's attributes view (`layout`); otherwise the task-space
dynamics are computed on first access. Also the small numeric helpers the 1 kHz paths
share: `eye`, `inv_small` and the `lazy` attribute.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np
import pinocchio as pin

from rhi._linalg import torque_null_projector
from rhi.errors import InvalidInput

if TYPE_CHECKING:
    from rhi.devices.spec import LinearLimits

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
        size = int(math.prod(shp))  # not np.prod: 5 µs a call, and `rhi.sim.simulate` builds its loop from this
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

    def jacobian_derivative_theta(self, th: np.ndarray) -> np.ndarray:
        """∂J/∂q (m, n, n) at chain coordinates θ."""
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
