"""Secondary objectives ν(q) with analytic gradients (gradient projection, thesis eq. 3.21).

An objective provides `value(device, q)` and `gradient(device, q)`; controllers and
configuration optimisers compose objectives without special-casing them. The bundled
objectives also provide `gradient_at(terms)`, the same gradient from a `DeviceTerms`
snapshot a controller already holds (J and ∂J/∂q from one Pinocchio pass); a
controller wraps objectives without it once, at construction (`gradient_function`).
The ASO-switched FME matching of chapter 6 (`rhi.control.schedule.FMESchedule`) is a scheduled
objective: each tick it gives the `FMEMatching` for that tick's activation Ω, which the controller
follows with the other terms.

Every JBLD gradient below uses ∂ν/∂q_k = Σ_ij (Y)_ij ∂J_ij/∂q_k for an (m, n) matrix Y,
evaluated as one product ``Y.ravel() @ dJ.reshape(m n, n)``.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np

from rhi._validate import as_array, scalar
from rhi.control.compiled import CompiledObjective
from rhi.control.registry import MATRIX, POSITIVE, REQUIRED, VECTOR, Key, ObjectiveType, register, shaped
from rhi.devices.model import Device, DeviceTerms, inv_small
from rhi.errors import InvalidInput
from rhi.metrics import desired_vme
from rhi.metrics.spd import jbld_spd, spd_matrix


class Objective(Protocol):
    """A scalar cost ν(q) to decrease in the null space of the primary task.

    Optionally also:

    - ``gradient_at(terms: DeviceTerms) -> (n,)``: the same gradient from the controller's per-tick
      snapshot (see `gradient_function`);
    - ``compiled(device) -> CompiledObjective | None``: the objective as the compiled tick computes it
      (`rhi.control.compiled`); without it the controller runs its gradient in Python each tick, on the
      composed route, and says so (`NullSpaceController.route`);
    - ``safety = True`` (a class attribute): the term belongs to the safety torque τ_s, which acts
      whatever the allocation holds (the joint-limit barrier), not to the objectives' τ_to;
    - ``check(device)``: raise InvalidInput where it does not fit the device (the controller calls it when built);
    - ``advance`` and ``objective``: a scheduled objective (`rhi.control.schedule`).
    """

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν(q) for q: (n,)."""
        ...

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q: (n,)."""
        ...


@dataclasses.dataclass(frozen=True)
class ObjectiveTerm:
    """A null-space objective with its gradient step size (β of eq. 6.6, Λ of eq. 7.17)."""

    objective: Objective
    gain: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "gain", scalar("gain", self.gain, nonnegative=True))


def contract(Y: np.ndarray, dJ: np.ndarray) -> np.ndarray:
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
        """ν(q) = JBLD(M_des, J Jᵀ) for q: (n,) [rad]."""
        J = device.jacobian(q)
        return jbld_spd(self._desired, J @ J.T)

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q_k = tr((½ M̄⁻¹ − ½ M⁻¹) ∂M/∂q_k), M = JJᵀ, M̄ = (M_des + M)/2, ∂M = ∂J Jᵀ + J ∂Jᵀ."""
        return jbld_velocity_gradient(self._desired, device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return jbld_velocity_gradient(self._desired, terms.J, terms.dJ)

    def compiled(self, device: Device) -> CompiledObjective:
        """VME matching to M_des, computed by the compiled tick."""
        return CompiledObjective("vme", desired=self.desired())


def jbld_velocity_gradient(D: np.ndarray, J: np.ndarray, dJ: np.ndarray, H: np.ndarray | None = None) -> np.ndarray:
    """∂/∂q of JBLD(D, H J Jᵀ Hᵀ): (n,), the one implementation of the velocity-ellipsoid JBLD gradient.

    2 Σ (Hᵀ G H J)_ij ∂J_ij/∂q_k with G = ½((D + M)/2)⁻¹ − ½ M⁻¹ (symmetric), M = H J Jᵀ Hᵀ (H = I: none).

    Args:
        D: (m, m) SPD desired ellipsoid.
        J: (m_J, n) Jacobian.
        dJ: (m_J, n, n) its derivative ∂J/∂q.
        H: (m, m_J) map from the Jacobian's rows, or None (identity).
    """
    HJ = J if H is None else H.dot(J)
    M = HJ.dot(HJ.T)
    G = inv_small(0.5 * (D + M)) - inv_small(M)
    return contract(G.dot(HJ) if H is None else H.T.dot(G).dot(HJ), dJ)


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


def fme_axes(device: Device, torque_max, mu: float = 5.0, home=None) -> tuple[float, float]:
    """(𝒦, ζ) of `fme_shape` at the home configuration `home` (n,) [rad] (None: q = 0) of `device`."""
    home = np.zeros(device.n) if home is None else shaped("home", home, (device.n,))
    return fme_shape(device.jacobian(home), torque_max, mu)


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
    _w2: np.ndarray = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "desired", spd_matrix("desired", self.desired))
        t = np.asarray(self.torque_max, dtype=float)
        if not np.all(np.isfinite(t)) or np.any(t <= 0):
            raise InvalidInput(f"torque_max: every torque limit must be finite and > 0, got {t.tolist()}")
        object.__setattr__(self, "torque_max", t)
        object.__setattr__(self, "_w2", np.atleast_1d(t**-2.0))

    def fme(self, J: np.ndarray) -> np.ndarray:
        """M̂: (m, m) for J: (m, n)."""
        w2 = self._w2 if self._w2.shape[0] in (1, J.shape[-1]) else np.broadcast_to(self.torque_max, (J.shape[-1],)) ** -2.0
        return np.linalg.inv((J * w2) @ J.T)

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν(q) = JBLD(M_des, M̂(q)) for q: (n,) [rad]."""
        return jbld_spd(self.desired, self.fme(device.jacobian(q)))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q_k = −2 tr(H ∂J_k W² Jᵀ), H = M̂ G M̂, G = ½(M̄⁻¹ − M̂⁻¹), M̄ = (M̂ + M_des)/2."""
        return self.gradient_from(device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self.gradient_from(terms.J, terms.dJ)

    def compiled(self, device: Device) -> CompiledObjective | None:
        """FME matching to the fixed M_des, computed by the whole compiled tick (None: a subclass, or misfit shapes)."""
        n, m = device.n, device.m
        w2 = self._w2
        if type(self) is not FMEMatching or self.desired.shape != (m, m) or w2.shape not in ((1,), (n,)):
            return None
        return CompiledObjective("fme", desired=self.desired, w2=np.broadcast_to(w2, (n,)))

    def gradient_from(self, J: np.ndarray, dJ: np.ndarray, desired: np.ndarray | None = None) -> np.ndarray:
        """Gradient from J: (m, n) and ∂J/∂q: (m, n, n) (for callers that already hold them).

        `desired` overrides M_des without re-validation (a convex blend of validated SPD
        matrices, eq. 6.16, inside the controller's loop).
        """
        D = self.desired if desired is None else desired
        w2 = self._w2
        if w2.shape[0] != J.shape[-1]:
            w2 = np.broadcast_to(self.torque_max, (J.shape[-1],)) ** -2.0
        Jw = J * w2
        A = Jw.dot(J.T)  # M̂⁻¹
        Mh = inv_small(A)
        G = 0.5 * (inv_small(0.5 * (Mh + D)) - A)
        H = Mh.dot(G).dot(Mh)
        return -2.0 * contract(H.T.dot(Jw), dJ)


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
        object.__setattr__(self, "desired", spd_matrix("desired", self.desired))
        if self.H is not None:
            object.__setattr__(self, "H", as_array("H", self.H, ndim_min=2))

    def _J(self, J: np.ndarray) -> np.ndarray:
        return J if self.H is None else self.H @ J

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν(q) = JBLD(M_des, H J Jᵀ Hᵀ) for q: (n,) [rad]."""
        J = self._J(device.jacobian(q))
        return jbld_spd(self.desired, J @ J.T)

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q_k = 2 tr(G ∂(HJ)_k (HJ)ᵀ), G = ½ M̄⁻¹ − ½ M⁻¹ (as `VMEMatching` with J → HJ)."""
        return self._gradient(device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self._gradient(terms.J, terms.dJ)

    def compiled(self, device: Device) -> CompiledObjective | None:
        """VME matching to `desired`, computed by the compiled tick (None with a map H: in Python)."""
        return CompiledObjective("vme", desired=self.desired) if self.H is None else None

    def _gradient(self, J: np.ndarray, dJ: np.ndarray) -> np.ndarray:
        return jbld_velocity_gradient(self.desired, J, dJ, self.H)


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
        g = np.zeros(device.n)
        for t in self.terms:
            g = g + t.gain * np.asarray(t.objective.gradient(device, q), dtype=float)
        return g


# ------------------------------------------------------------------------- configuration files (rhi.control.registry)
def _vme(device: Device, torque_max, *, u, beta: float) -> VMEMatching:
    return VMEMatching(tuple(shaped("u", u, (device.m,))), beta)


def _ellipsoid(device: Device, torque_max, *, desired, H) -> EllipsoidMatching:
    return EllipsoidMatching(shaped("desired", desired, (device.m, device.m)), H)


def _fme(device: Device, torque_max, *, desired, shape, direction, mu: float, home) -> FMEMatching:
    if (desired is None) == (shape is None) or (shape is not None and direction is None):
        raise InvalidInput("give either desired (a matrix) or shape and direction")
    if desired is None:
        K, z = fme_axes(device, torque_max, mu, home)
        desired = (desired_fme_free if shape == "free" else desired_fme_stiff)(shaped("direction", direction, (device.m,)),
                                                                               K, z)
    return FMEMatching(shaped("desired", desired, (device.m, device.m)), torque_max)


register(ObjectiveType("vme", _vme, {"u": (VECTOR, REQUIRED), "beta": (POSITIVE, 0.01)}))
register(ObjectiveType("ellipsoid", _ellipsoid, {"desired": (MATRIX, REQUIRED), "H": (MATRIX, None)}))
register(ObjectiveType("fme", _fme, {"desired": (MATRIX, None), "shape": (Key("choice", options=("free", "stiff")), None),
                                     "direction": (VECTOR, None), "mu": (POSITIVE, 5.0), "home": (VECTOR, None)}))
