"""Secondary objectives ν(q) with analytic gradients (gradient projection, thesis eq. 3.21).

An objective provides `value(device, q)` and `gradient(device, q)`; controllers and
configuration optimisers compose objectives without special-casing them.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np

from rhi.device import Device
from rhi.metrics import desired_vme, jbld


class Objective(Protocol):
    """A scalar cost ν(q) to decrease in the null space of the primary task."""

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν(q) for q: (n,)."""
        ...

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q: (n,)."""
        ...


@dataclasses.dataclass(frozen=True)
class VMEMatching:
    """Match the velocity manipulability ellipsoid JJᵀ to M_des by the JBLD (thesis eq. 3.22–3.23).

    ν(q) = logdet((M_des + JJᵀ)/2) − ½ logdet(M_des JJᵀ), with M_des = u uᵀ + β (I − u uᵀ)
    built from the desired direction of motion u (eq. 3.23).

    Attributes:
        u: (m,) desired direction of motion (normalised internally).
        beta: minor-axis scale β of M_des (thesis: 0.01).
    """

    u: tuple[float, ...]
    beta: float = 0.01

    def desired(self) -> np.ndarray:
        """M_des: (m, m)."""
        return desired_vme(np.asarray(self.u, dtype=float), self.beta)

    def value(self, device: Device, q: np.ndarray) -> float:
        J = device.jacobian(q)
        return float(jbld(self.desired(), J @ J.T))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q_k = tr((½ M̄⁻¹ − ½ M⁻¹) ∂M/∂q_k), M = JJᵀ, M̄ = (M_des + M)/2, ∂M = ∂J Jᵀ + J ∂Jᵀ."""
        J = device.jacobian(q)
        dJ = device.jacobian_derivative(q)  # (m, n, n): [i, j, k] = ∂J_ij/∂q_k
        M = J @ J.T
        G = 0.5 * (np.linalg.inv(0.5 * (self.desired() + M)) - np.linalg.inv(M))
        # tr(G (dJ_k Jᵀ + J dJ_kᵀ)) = 2 tr(G dJ_k Jᵀ) since G is symmetric
        return 2.0 * np.einsum("ab,ajk,bj->k", G, dJ, J)


def _spd(name: str, A) -> np.ndarray:
    """Validate one symmetric positive definite (m, m) matrix; raise NotSPD/InvalidInput naming `name`."""
    from rhi.errors import InvalidInput
    from rhi.metrics._common import cholesky, square

    A = square(name, A)
    if A.ndim != 2:
        raise InvalidInput(f"{name}: expected a square (m, m) matrix, got shape {A.shape}")
    cholesky(name, A)
    return A


def _torque_scale(name: str, torque_max, n: int) -> np.ndarray:
    from rhi._validate import as_array
    from rhi.errors import InvalidInput

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
    from rhi.errors import InvalidInput
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
        from rhi.errors import InvalidInput

        if not np.all(np.isfinite(t)) or np.any(t <= 0):
            raise InvalidInput(f"torque_max: every torque limit must be finite and > 0, got {t.tolist()}")
        object.__setattr__(self, "torque_max", t)

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

    def gradient_from(self, J: np.ndarray, dJ: np.ndarray, desired: np.ndarray | None = None) -> np.ndarray:
        """Gradient from J: (m, n) and ∂J/∂q: (m, n, n) (for controllers that already hold them).

        `desired` overrides M_des without re-validation (a convex blend of validated SPD
        matrices, eq. 6.16, inside the controller's loop).
        """
        D = self.desired if desired is None else desired
        w2 = np.broadcast_to(self.torque_max, (J.shape[-1],)) ** -2.0
        A = (J * w2) @ J.T  # M̂⁻¹
        Mh = np.linalg.inv(A)
        G = 0.5 * (np.linalg.inv(0.5 * (Mh + D)) - A)
        H = Mh @ G @ Mh
        return -2.0 * np.einsum("ab,bjk,aj->k", H, dJ, J * w2)


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
            from rhi._validate import as_array

            object.__setattr__(self, "H", as_array("H", self.H, ndim_min=2))

    def _J(self, J: np.ndarray) -> np.ndarray:
        return J if self.H is None else self.H @ J

    def value(self, device: Device, q: np.ndarray) -> float:
        J = self._J(device.jacobian(q))
        return float(jbld(self.desired, J @ J.T))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        J = self._J(device.jacobian(q))
        dJ = device.jacobian_derivative(q)
        if self.H is not None:
            dJ = np.einsum("ab,bjk->ajk", self.H, dJ)
        M = J @ J.T
        G = 0.5 * (np.linalg.inv(0.5 * (self.desired + M)) - np.linalg.inv(M))
        return 2.0 * np.einsum("ab,ajk,bj->k", G, dJ, J)


@dataclasses.dataclass(frozen=True)
class Manipulability:
    """Maximise Yoshikawa's manipulability μ(q) = sqrt(det(J Jᵀ)) (thesis eq. 5.14): ν = −μ.

    Attributes:
        log: minimise −log μ instead (same maximiser, better scaled gradient).
    """

    log: bool = False

    def value(self, device: Device, q: np.ndarray) -> float:
        J = device.jacobian(q)
        ld = np.linalg.slogdet(J @ J.T)[1]
        return float(-0.5 * ld if self.log else -np.exp(0.5 * ld))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂(log μ)/∂q_k = tr((JJᵀ)⁻¹ ∂J_k Jᵀ); ∂μ/∂q_k = μ ∂(log μ)/∂q_k."""
        J = device.jacobian(q)
        dJ = device.jacobian_derivative(q)
        A = J @ J.T
        g = np.einsum("ab,bjk,aj->k", np.linalg.inv(A), dJ, J)
        return -g if self.log else -np.sqrt(np.linalg.det(A)) * g
