"""Secondary objectives ν(q) with analytic gradients (gradient projection, thesis eq. 3.21).

An objective provides `value(device, q)` and `gradient(device, q)`; controllers and
configuration optimisers compose objectives without special-casing them. The bundled
objectives also provide `gradient_at(terms)`, the same gradient from a `DeviceTerms`
snapshot a controller already holds (J and ∂J/∂q from one Pinocchio pass); a
controller wraps objectives without it once, at construction (`gradient_function`).

Every JBLD gradient below uses ∂ν/∂q_k = Σ_ij (Y)_ij ∂J_ij/∂q_k for an (m, n) matrix Y,
evaluated as one product ``Y.ravel() @ dJ.reshape(m n, n)``.
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np

from rhi._validate import as_array
from rhi.device import Device, DeviceTerms, inv_small
from rhi.errors import InvalidInput, Singular
from rhi.metrics import desired_vme, jbld

if TYPE_CHECKING:
    from rhi.control.controller import ObjectiveTerm


class Objective(Protocol):
    """A scalar cost ν(q) to decrease in the null space of the primary task.

    Optionally also ``gradient_at(terms: DeviceTerms) -> (n,)``: the same gradient from the
    controller's per-tick snapshot (see `gradient_function`).
    """

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν(q) for q: (n,)."""
        ...

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q: (n,)."""
        ...


def _contract(Y: np.ndarray, dJ: np.ndarray) -> np.ndarray:
    """Σ_ij Y_ij ∂J_ij/∂q_k: (n,) for Y: (m, n) and dJ: (m, n, n)."""
    return Y.reshape(-1).dot(dJ.reshape(-1, dJ.shape[-1]))


def gradient_function(objective: Objective, device: Device):
    """A callable terms -> ∂ν/∂q: `objective.gradient_at` when it has one, else `objective.gradient(device, terms.q)`."""
    fast = getattr(objective, "gradient_at", None)
    if callable(fast):
        return fast
    return lambda terms: np.asarray(objective.gradient(device, terms.q), dtype=float)


@dataclasses.dataclass(frozen=True)
class VMEMatching:
    """Match the velocity manipulability ellipsoid JJᵀ to M_des by the JBLD (thesis eq. 3.22–3.23).

    ν(q) = logdet((M_des + JJᵀ)/2) − ½ logdet(M_des JJᵀ), with M_des = u uᵀ + β (I − u uᵀ)
    built from the desired direction of motion u (eq. 3.23).

    Attributes:
        u: (m,) desired direction of motion (normalised internally).
        beta: minor-axis scale β of M_des (thesis: 0.01), > 0.
    """

    u: tuple[float, ...]
    beta: float = 0.01
    _desired: np.ndarray = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_desired", desired_vme(self.u, self.beta))

    def desired(self) -> np.ndarray:
        """M_des: (m, m)."""
        return self._desired.copy()

    def value(self, device: Device, q: np.ndarray) -> float:
        J = device.jacobian(q)
        return float(jbld(self._desired, J @ J.T))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q_k = tr((½ M̄⁻¹ − ½ M⁻¹) ∂M/∂q_k), M = JJᵀ, M̄ = (M_des + M)/2, ∂M = ∂J Jᵀ + J ∂Jᵀ."""
        return _jbld_velocity_gradient(self._desired, device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return _jbld_velocity_gradient(self._desired, terms.J, terms.dJ)


def _inv2(a: float, b: float, c: float, d: float) -> tuple[float, float, float, float]:
    """Entries of the inverse of [[a, b], [c, d]] (Python floats; raises on a singular matrix)."""
    det = a * d - b * c
    if det == 0.0 or not math.isfinite(det):
        raise Singular(f"matrix [[{a}, {b}], [{c}, {d}]] is singular")
    return d / det, -b / det, -c / det, a / det


def _jbld_velocity_gradient(D: np.ndarray, J: np.ndarray, dJ: np.ndarray) -> np.ndarray:
    """∂/∂q of JBLD(D, JJᵀ): 2 Σ (G J)_ij ∂J_ij/∂q_k with G = ½((D + JJᵀ)/2)⁻¹ − ½(JJᵀ)⁻¹ (symmetric)."""
    M = J.dot(J.T)
    if M.shape == (2, 2):  # the planar case on Python floats: fewer array operations
        (m11, m12), (m21, m22) = M.tolist()
        (d11, d12), (d21, d22) = D.tolist()
        a11, a12, a21, a22 = _inv2(0.5 * (d11 + m11), 0.5 * (d12 + m12), 0.5 * (d21 + m21), 0.5 * (d22 + m22))
        b11, b12, b21, b22 = _inv2(m11, m12, m21, m22)
        G = np.array([[a11 - b11, a12 - b12], [a21 - b21, a22 - b22]])
    else:
        G = inv_small(0.5 * (D + M)) - inv_small(M)
    return _contract(G.dot(J), dJ)


def _spd(name: str, A) -> np.ndarray:
    """Validate one symmetric positive definite (m, m) matrix; raise NotSPD/InvalidInput naming `name`."""
    from rhi.metrics._common import cholesky, square

    A = square(name, A)
    if A.ndim != 2:
        raise InvalidInput(f"{name}: expected a square (m, m) matrix, got shape {A.shape}")
    cholesky(name, A)
    return A


def _torque_scale(name: str, torque_max, n: int) -> np.ndarray:
    t = np.broadcast_to(as_array(name, torque_max), (n,)).astype(float)
    if np.any(t <= 0) or not np.all(np.isfinite(t)):
        raise InvalidInput(f"{name}: every torque limit must be finite and > 0, got {t.tolist()}")
    return t


def fme_shape(J_home, torque_max, mu: float = 5.0) -> tuple[float, float]:
    """Axis scales (𝒦, ζ) of the desired FMEs: 𝒦 = μ λ_max(M̂₀), ζ = λ_min(M̂₀)/μ (thesis §6.3.1).

    M̂₀ = (J W W Jᵀ)⁻¹ is the torque-weighted FME (eq. 6.9) at the non-singular home
    configuration. The thesis's rhi4 (home q = 0, μ = 5) gives 𝒦 ≈ 123, ζ ≈ 3.3.

    Args:
        J_home: (m, n) Jacobian at the home configuration [m/rad].
        torque_max: (n,) or scalar torque limits T_i [N m], > 0.
        mu: shape factor μ > 0.

    Returns:
        (𝒦, ζ) [N²/(N m)²] eigenvalues of the desired FMEs.
    """
    from rhi.metrics import force_ellipsoid

    if not np.isfinite(mu) or mu <= 0:
        raise InvalidInput(f"mu: must be finite and > 0, got {mu!r}")
    lam = np.linalg.eigvalsh(force_ellipsoid(J_home, torque_max))
    return float(mu * lam[-1]), float(lam[0] / mu)


def desired_fme_free(u, K: float, zeta: float) -> np.ndarray:
    """M_Free^des = U_F diag(ζ, 𝒦, …) U_Fᵀ: minor axis ζ along the motion u (thesis eq. 6.12). (m, m)."""
    from rhi.metrics import desired_fme

    return desired_fme(u, zeta, K)


def desired_fme_stiff(F_e, K: float, zeta: float) -> np.ndarray:
    """M_Stiff^des = U_e diag(𝒦, ζ, …) U_eᵀ: major axis 𝒦 along the contact force F_e (thesis eq. 6.13). (m, m)."""
    from rhi.metrics import desired_fme

    return desired_fme(F_e, K, zeta)


@dataclasses.dataclass(frozen=True, eq=False)
class FMEMatching:
    """Match the torque-weighted FME M̂ = (J W W Jᵀ)⁻¹ to M_des by the JBLD (thesis eqs. 6.9–6.10).

    ν(q) = logdet((M̂ + M_des)/2) − ½ logdet(M̂ M_des), W = diag(1/T_i).

    Attributes:
        desired: (m, m) SPD desired FME M_des [N²/(N m)²] (e.g. `desired_fme_free`/`desired_fme_stiff`).
        torque_max: (n,) torque limits T_i [N m], > 0 (or a scalar for every joint).
    """

    desired: np.ndarray
    torque_max: np.ndarray | float

    def __post_init__(self) -> None:
        object.__setattr__(self, "desired", _spd("desired", self.desired))
        t = np.asarray(self.torque_max, dtype=float)
        if not np.all(np.isfinite(t)) or np.any(t <= 0):
            raise InvalidInput(f"torque_max: every torque limit must be finite and > 0, got {t.tolist()}")
        object.__setattr__(self, "torque_max", t)
        object.__setattr__(self, "_w2", np.atleast_1d(t**-2.0))

    def with_desired(self, desired) -> FMEMatching:
        """The same objective with another desired FME (e.g. during a transition, eq. 6.16)."""
        return FMEMatching(desired, self.torque_max)

    def fme(self, J: np.ndarray) -> np.ndarray:
        """M̂: (m, m) for J: (m, n)."""
        w2 = np.broadcast_to(self.torque_max, (J.shape[-1],)) ** -2.0
        return np.linalg.inv((J * w2) @ J.T)

    def value(self, device: Device, q: np.ndarray) -> float:
        return float(jbld(self.desired, self.fme(device.jacobian(q))))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q_k = −2 tr(H ∂J_k W² Jᵀ), H = M̂ G M̂, G = ½(M̄⁻¹ − M̂⁻¹), M̄ = (M̂ + M_des)/2."""
        return self.gradient_from(device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self.gradient_from(terms.J, terms.dJ)

    def gradient_from(self, J: np.ndarray, dJ: np.ndarray, desired: np.ndarray | None = None) -> np.ndarray:
        """Gradient from J: (m, n) and ∂J/∂q: (m, n, n) (for controllers that already hold them).

        `desired` overrides M_des without re-validation (a convex blend of validated SPD
        matrices, eq. 6.16, inside the controller's loop).
        """
        D = self.desired if desired is None else desired
        w2 = self._w2
        if w2.shape[0] != J.shape[-1]:
            w2 = np.broadcast_to(self.torque_max, (J.shape[-1],)) ** -2.0
        Jw = J * w2
        A = Jw.dot(J.T)  # M̂⁻¹
        if A.shape == (2, 2):  # the planar case on Python floats: fewer array operations
            (a11, a12), (a21, a22) = A.tolist()
            (d11, d12), (d21, d22) = D.tolist()
            h11, h12, h21, h22 = _inv2(a11, a12, a21, a22)  # M̂
            n11, n12, n21, n22 = _inv2(0.5 * (h11 + d11), 0.5 * (h12 + d12), 0.5 * (h21 + d21), 0.5 * (h22 + d22))
            g11, g12, g21, g22 = 0.5 * (n11 - a11), 0.5 * (n12 - a12), 0.5 * (n21 - a21), 0.5 * (n22 - a22)
            # H = M̂ G M̂; Y = Hᵀ (J W²)
            t11, t12 = h11 * g11 + h12 * g21, h11 * g12 + h12 * g22
            t21, t22 = h21 * g11 + h22 * g21, h21 * g12 + h22 * g22
            H11, H12 = t11 * h11 + t12 * h21, t11 * h12 + t12 * h22
            H21, H22 = t21 * h11 + t22 * h21, t21 * h12 + t22 * h22
            Y = np.array([[-2.0 * H11, -2.0 * H21], [-2.0 * H12, -2.0 * H22]]).dot(Jw)
            return _contract(Y, dJ)
        Mh = inv_small(A)
        G = 0.5 * (inv_small(0.5 * (Mh + D)) - A)
        H = Mh.dot(G).dot(Mh)
        return -2.0 * _contract(H.T.dot(Jw), dJ)


@dataclasses.dataclass(frozen=True, eq=False)
class EllipsoidMatching:
    """Match the velocity ME H J Jᵀ Hᵀ to a given SPD ellipsoid by the JBLD (thesis eq. 5.11, TMI matching).

    With `desired` the slave's ME ˢM = J_s J_sᵀ and H the master-to-task map, this is the
    teleoperation objective of eq. 5.11 (master ME matched to the slave's).

    Attributes:
        desired: (m, m) SPD desired ellipsoid [(m/s)²/(rad/s)²].
        H: (m, m_J) optional map from the device's task space (None: identity).
    """

    desired: np.ndarray
    H: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "desired", _spd("desired", self.desired))
        if self.H is not None:
            object.__setattr__(self, "H", as_array("H", self.H, ndim_min=2))

    def _J(self, J: np.ndarray) -> np.ndarray:
        return J if self.H is None else self.H @ J

    def value(self, device: Device, q: np.ndarray) -> float:
        J = self._J(device.jacobian(q))
        return float(jbld(self.desired, J @ J.T))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q_k = 2 tr(G ∂(HJ)_k (HJ)ᵀ), G = ½ M̄⁻¹ − ½ M⁻¹ (as `VMEMatching` with J → HJ)."""
        return self._gradient(device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self._gradient(terms.J, terms.dJ)

    def _gradient(self, J: np.ndarray, dJ: np.ndarray) -> np.ndarray:
        if self.H is None:
            return _jbld_velocity_gradient(self.desired, J, dJ)
        HJ = self.H.dot(J)
        M = HJ.dot(HJ.T)
        G = inv_small(0.5 * (self.desired + M)) - inv_small(M)
        return _contract(self.H.T.dot(G).dot(HJ), dJ)


@dataclasses.dataclass(frozen=True)
class Manipulability:
    """Maximise Yoshikawa's manipulability μ(q) = sqrt(det(J Jᵀ)) (thesis eq. 5.14): ν = −μ.

    With `k_q`, J is the joint-limit penalised Jacobian J^q = J diag(P(q)) (eqs. 4.19–4.20),
    as §4.3.2 substitutes J^q for J "considering the robot mechanical constraints".

    Attributes:
        log: minimise −log μ instead (same maximiser, better scaled gradient; a log-det like
            the JBLD objectives, so one step size serves both).
        k_q: penalty shape of eq. 4.20 (> 0), or None for the plain Jacobian.
    """

    log: bool = False
    k_q: float | None = None

    def __post_init__(self) -> None:
        if self.k_q is not None and (not np.isfinite(self.k_q) or self.k_q <= 0):
            raise InvalidInput(f"k_q: must be finite and > 0 (or None), got {self.k_q!r}")

    def value(self, device: Device, q: np.ndarray) -> float:
        q = np.asarray(q, dtype=float)
        J = device.jacobian(q)
        if self.k_q is not None:
            J = J * _penalty(q, device.q_min, device.q_max, self.k_q)[0]
        ld = np.linalg.slogdet(J @ J.T)[1]
        return float(-0.5 * ld if self.log else -np.exp(0.5 * ld))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂(log μ)/∂q_k = tr((JJᵀ)⁻¹ ∂J_k Jᵀ); ∂μ/∂q_k = μ ∂(log μ)/∂q_k (J → J^q with `k_q`)."""
        q = np.asarray(q, dtype=float)
        return self._gradient(device, q, device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self._gradient(terms.device, terms.q, terms.J, terms.dJ)

    def _gradient(self, device: Device, q: np.ndarray, J: np.ndarray, dJ: np.ndarray) -> np.ndarray:
        J, dJ = _penalized(device, q, J, dJ, self.k_q)
        A = J.dot(J.T)
        g = _contract(inv_small(A).T.dot(J), dJ)
        return -g if self.log else -np.sqrt(np.linalg.det(A)) * g


# ---------------------------------------------------------------- joint-limit penalty (eqs. 4.19–4.20)
def _penalty(q: np.ndarray, lo: np.ndarray, hi: np.ndarray, k_q: float) -> tuple[np.ndarray, np.ndarray]:
    """P_i (eq. 4.20, as `rhi.metrics.joint_limit_penalty`) and dP_i/dq_i for q: (n,) [rad].

    Joints without finite limits get P = 1, dP = 0; outside its limits P is clipped to 0 (dP = 0).
    Inlined (no input validation) because it runs every control tick.
    """
    span2 = (hi - lo) ** 2
    with np.errstate(invalid="ignore"):
        e = np.exp(-4.0 * k_q * (q - lo) * (hi - q) / span2)
        c = -np.expm1(-k_q)
        p = (1.0 - e) / c
        dp = e * 4.0 * k_q * (hi + lo - 2.0 * q) / span2 / c
    finite = np.isfinite(span2)
    inside = finite & (q > lo) & (q < hi)
    return np.where(finite, np.clip(p, 0.0, 1.0), 1.0), np.where(inside, dp, 0.0)


def _penalized(device: Device, q: np.ndarray, J: np.ndarray, dJ: np.ndarray, k_q: float | None):
    """(J^q, ∂J^q/∂q) with J^q = J diag(P(q)) (eq. 4.19): ∂J^q_k = ∂J_k diag(P) + J_k P'_k e_kᵀ."""
    if k_q is None:
        return J, dJ
    p, dp = _penalty(q, device.q_min, device.q_max, k_q)
    dJ = dJ * p[None, :, None]
    idx = np.arange(q.size)
    dJ[:, idx, idx] += J * dp
    return J * p, dJ


class TMIMatching:
    """Teleoperation-manipulability objective ν = JBLD(ˢM, ᵐM) (thesis eq. 5.11).

    ν = logdet((ˢM + ᵐM)/2) − ½ logdet(ˢM ᵐM) with ˢM = J_s J_sᵀ, the slave's velocity ME
    at its current configuration, and ᵐM = (H J^q)(H J^q)ᵀ the HI's ME from the joint-limit
    penalised Jacobian J^q = J diag(P(q)) (eqs. 4.19–4.20). Minimising ν reshapes the HI's ME
    towards the slave's, maximising their intersection (the TME, eq. 4.17).

    The slave's configuration is an input (its encoders, sent to the master side): the
    gradient treats ˢM as constant. That is exact for the projected null-space torque:
    ˢM depends on q only through the end-effector position, so its gradient lies in
    range(Jᵀ), which the null-space projector of eq. 5.9 removes.

    Args:
        slave: the slave device.
        slave_q: (n_s,) slave configuration [rad], or a callable returning it (the slave's encoders).
        k_q: penalty shape of eq. 4.20 (> 0; chapter 5 uses 10), or None for the plain ME ᵐM = H J Jᵀ Hᵀ.
        penalize_slave: also use the slave's penalised Jacobian in ˢM.
        H: (m, m) master-to-slave velocity map (None: identity).

    Raises:
        InvalidInput: k_q ≤ 0, a slave configuration of the wrong shape or not finite.
    """

    def __init__(self, slave: Device, slave_q, *, k_q: float | None = None, penalize_slave: bool = False,
                 H=None) -> None:
        if k_q is not None and (not np.isfinite(k_q) or k_q <= 0):
            raise InvalidInput(f"k_q: must be finite and > 0 (or None), got {k_q!r}")
        self.slave, self.k_q, self.penalize_slave = slave, k_q, bool(penalize_slave)
        self.H = None if H is None else as_array("H", H, shape_tail=(slave.m, slave.m))
        self._slave_q = slave_q if callable(slave_q) else as_array("slave_q", slave_q, shape_tail=(slave.n,))
        self._cache: tuple[bytes, np.ndarray] | None = None
        self.slave_ellipsoid()  # validate now

    def slave_configuration(self) -> np.ndarray:
        """Current slave configuration: (n_s,) [rad]."""
        q = self._slave_q() if callable(self._slave_q) else self._slave_q
        q = np.asarray(q, dtype=float)
        if q.shape != (self.slave.n,) or not np.all(np.isfinite(q)):
            raise InvalidInput(f"slave_q: expected {self.slave.n} finite values, got {q.tolist()}")
        return q

    def slave_ellipsoid(self) -> np.ndarray:
        """ˢM: (m, m) [(m/s)²/(rad/s)²] at the slave's current configuration."""
        qs = self.slave_configuration()
        key = qs.tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        Js = self.slave.jacobian(qs)
        if self.penalize_slave and self.k_q is not None:
            Js = Js * _penalty(qs, self.slave.q_min, self.slave.q_max, self.k_q)[0]
        M = Js @ Js.T
        self._cache = (key, M)
        return M

    def master_jacobian(self, device: Device, q) -> np.ndarray:
        """H J^q: (m, n), the Jacobian whose ME is matched, at q: (n,) [rad]."""
        q = np.asarray(q, dtype=float)
        J = device.jacobian(q)
        if self.k_q is not None:
            J = J * _penalty(q, device.q_min, device.q_max, self.k_q)[0]
        return J if self.H is None else self.H @ J

    def value(self, device: Device, q) -> float:
        """ν(q) for the HI configuration q: (n,) [rad]."""
        J = self.master_jacobian(device, q)
        return float(jbld(self.slave_ellipsoid(), J @ J.T))

    def gradient(self, device: Device, q) -> np.ndarray:
        """∂ν/∂q: (n,). With A = ᵐM, ∂ν/∂q_k = tr((Ā⁻¹ − A⁻¹) ∂J^q_k J^qᵀ), Ā = (ˢM + A)/2,
        ∂J^q_k = ∂J_k diag(P) + J_k P'_k e_kᵀ."""
        q = np.asarray(q, dtype=float)
        return self._gradient(device, q, device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a controller's `DeviceTerms` snapshot (J, ∂J/∂q already computed): (n,)."""
        return self._gradient(terms.device, terms.q, terms.J, terms.dJ)

    def _gradient(self, device: Device, q: np.ndarray, J: np.ndarray, dJ: np.ndarray) -> np.ndarray:
        J, dJ = _penalized(device, q, J, dJ, self.k_q)
        if self.H is not None:
            J = self.H @ J
            dJ = np.einsum("ab,bjk->ajk", self.H, dJ)
        A = J @ J.T
        G = inv_small(0.5 * (self.slave_ellipsoid() + A)) - inv_small(A)
        return (G @ J).reshape(-1) @ dJ.reshape(-1, dJ.shape[-1])


# ------------------------------------------------------------------------- joint limits
_LIMIT_ROWS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _limit_rows(device: Device) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(C, lower, upper) with lower ≤ C q ≤ upper for every limited row: (k, n), (k,), (k,); cached per device.

    Rows: the box limits q_min ≤ q ≤ q_max (joints with at least one finite bound), then the
    device's linear limits. Unlimited sides are ±inf.
    """
    cached = _LIMIT_ROWS.get(device)
    if cached is not None:
        return cached
    rows, lo, hi = [np.eye(device.n)], [device.q_min], [device.q_max]
    if device.linear_limits is not None:
        L = device.linear_limits
        rows.append(np.asarray(L.C, dtype=float))
        lo.append(np.asarray(L.lower, dtype=float))
        hi.append(np.asarray(L.upper, dtype=float))
    C, lower, upper = np.vstack(rows), np.concatenate(lo), np.concatenate(hi)
    keep = np.isfinite(lower) | np.isfinite(upper)
    out = (C[keep], lower[keep], upper[keep])
    _LIMIT_ROWS[device] = out
    return out


@dataclasses.dataclass(frozen=True)
class JointLimitBarrier:
    """Keep the joints off their range limits: a null-space objective that is zero farther than δ from every limit.

    With d_r(q) the distance of q to limit r (box limits q_min ≤ q ≤ q_max and the device's
    linear limits lower ≤ C q ≤ upper, each side a separate r), two shapes:

    - ``kind="quadratic"``: ν_lim = w ½ Σ_r max(0, δ − d_r)², a penalty that stays finite past
      a limit (the rhi4 palpation controller of chapter 6).
    - ``kind="inverse"``: ν_lim = w Σ_{d_r < δ} (δ/d_r − 1)², a barrier that grows without bound
      at the limit; d_r is floored at 10⁻³ δ so ν stays finite if a plant penetrates a soft
      stop (the chapter 3/7 null-space runs).

    Both are continuously differentiable and leave minima of other objectives away from the
    limits unchanged. Not a thesis equation: the thesis assumes no joint is at its range limit;
    this objective enforces that assumption in simulation.

    Attributes:
        margin: δ, distance from a limit where the objective starts [rad], > 0.
        weight: w, scale of ν_lim (dimensionless), > 0.
        kind: "quadratic" or "inverse".

    Raises:
        InvalidInput: margin or weight not finite and positive, or an unknown kind.
    """

    margin: float
    weight: float = 1.0
    kind: Literal["quadratic", "inverse"] = "quadratic"

    def __post_init__(self) -> None:
        for name in ("margin", "weight"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v > 0):
                raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.kind not in ("quadratic", "inverse"):
            raise InvalidInput(f"kind: expected 'quadratic' or 'inverse', got {self.kind!r}")

    def distances(self, device: Device, q: np.ndarray) -> np.ndarray:
        """Distances (2k,) of q: (n,) [rad] to every lower then every upper limit [rad] (inf where unlimited)."""
        C, lower, upper = _limit_rows(device)
        c = C @ np.asarray(q, dtype=float)
        return np.concatenate([c - lower, upper - c])

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν_lim(q) for q: (n,) [rad]."""
        d = self.distances(device, q)
        if self.kind == "quadratic":
            p = np.maximum(0.0, self.margin - d.reshape(2, -1).T.ravel())  # summed row by row: lower, upper
            return float(self.weight * (0.5 * p @ p))
        a = d < self.margin
        r = self.margin / np.maximum(d[a], 1e-3 * self.margin)
        return float(self.weight * np.sum((r - 1.0) ** 2))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν_lim/∂q = Cᵀ (∂ν/∂d_lo − ∂ν/∂d_hi): (n,) [1/rad]."""
        d = self.distances(device, q)
        if self.kind == "quadratic":
            g = -np.maximum(0.0, self.margin - d)  # ∂/∂d of ½ max(0, δ − d)²
            if self.weight != 1.0:
                g = self.weight * g
        else:
            a = d < self.margin
            g = np.zeros_like(d)
            dd = np.maximum(d[a], 1e-3 * self.margin)
            r = self.margin / dd
            g[a] = -2.0 * self.weight * (r - 1.0) * r / dd  # ∂/∂d of w (δ/d − 1)²
        C = _limit_rows(device)[0]
        k = C.shape[0]
        return C.T @ (g[:k] - g[k:])  # ∂d_lo/∂q = C, ∂d_hi/∂q = −C

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self.gradient(terms.device, terms.q)


# ------------------------------------------------------------------------- combinators
@dataclasses.dataclass(frozen=True)
class WeightedSum:
    """ν(q) = Σ gain_i ν_i(q): the cost whose negative gradient a null-space controller follows (eqs. 3.21, 6.6).

    For the static optimum of what a controller with these terms minimises (e.g. by
    `rhi.control.configuration.optimal_configuration`).

    Attributes:
        terms: `ObjectiveTerm`s (anything with `.objective` and `.gain`), e.g. a controller's.
    """

    terms: tuple[ObjectiveTerm, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "terms", tuple(self.terms))

    def value(self, device: Device, q: np.ndarray) -> float:
        """Σ gain_i ν_i(q) for q: (n,)."""
        return float(sum(t.gain * t.objective.value(device, q) for t in self.terms))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """Σ gain_i ∂ν_i/∂q: (n,)."""
        return sum(t.gain * np.asarray(t.objective.gradient(device, q), dtype=float) for t in self.terms)
