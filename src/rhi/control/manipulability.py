"""Manipulability objectives: Yoshikawa's μ (eq. 5.14) and teleoperation ME matching (eq. 5.11).

Both with the joint-limit penalised Jacobian J^q = J diag(P(q)) of eqs. 4.19–4.20.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rhi._validate import as_array
from rhi.control.compiled import CompiledObjective
from rhi.control.objectives import jbld_velocity_gradient
from rhi.control.registry import BOOLEAN, MATRIX, NUMBERS, POSITIVE, REQUIRED, STRING, VECTOR, ObjectiveType, register
from rhi.devices.model import Device, DeviceTerms, device as load_device
from rhi.devices.terms import DeviceModel
from rhi.errors import InvalidInput, RhiError
from rhi.metrics import jbld, log_det_gradient


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
        """ν(q) = −μ (or −log μ) for q: (n,) [rad]."""
        q = np.asarray(q, dtype=float)
        J = device.jacobian(q)
        if self.k_q is not None:
            J = J * penalty(q, q_min=device.q_min, q_max=device.q_max, k_q=self.k_q)[0]
        ld = np.linalg.slogdet(J @ J.T)[1]
        return float(-0.5 * ld if self.log else -np.exp(0.5 * ld))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂(log μ)/∂q_k = tr((JJᵀ)⁻¹ ∂J_k Jᵀ); ∂μ/∂q_k = μ ∂(log μ)/∂q_k (J → J^q with `k_q`)."""
        q = np.asarray(q, dtype=float)
        return self._gradient(device, q, device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self._gradient(terms.device, terms.q, terms.J, terms.dJ)

    def _gradient(self, device: DeviceModel, q: np.ndarray, J: np.ndarray, dJ: np.ndarray) -> np.ndarray:
        J, dJ = penalized(device, q, J, dJ, self.k_q)
        g = 0.5 * log_det_gradient(J, dJ)  # ∇ log μ
        return -g if self.log else -np.sqrt(np.linalg.det(J.dot(J.T))) * g

    def compiled(self, device: Device) -> CompiledObjective:
        """−log μ or −μ on J^q, computed by the whole compiled tick."""
        return CompiledObjective("manipulability", penalty=self.k_q, log=self.log)


def penalty(q: np.ndarray, *, q_min: np.ndarray, q_max: np.ndarray, k_q: float) -> tuple[np.ndarray, np.ndarray]:
    """P_i (eq. 4.20, as `rhi.metrics.joint_limit_penalty`) and dP_i/dq_i for q: (n,) [rad].

    Joints without finite limits get P = 1, dP = 0; outside its limits P is clipped to 0 (dP = 0).
    Inlined (no input validation) because it runs every control tick.
    """
    lo, hi = q_min, q_max
    span2 = (hi - lo) ** 2
    with np.errstate(invalid="ignore"):
        e = np.exp(-4.0 * k_q * (q - lo) * (hi - q) / span2)
        c = -np.expm1(-k_q)
        p = (1.0 - e) / c
        dp = e * 4.0 * k_q * (hi + lo - 2.0 * q) / span2 / c
    finite = np.isfinite(span2)
    inside = finite & (q > lo) & (q < hi)
    return np.where(finite, np.clip(p, 0.0, 1.0), 1.0), np.where(inside, dp, 0.0)


def penalized(device: DeviceModel, q: np.ndarray, J: np.ndarray, dJ: np.ndarray, k_q: float | None):
    """(J^q, ∂J^q/∂q) with J^q = J diag(P(q)) (eq. 4.19): ∂J^q_k = ∂J_k diag(P) + J_k P'_k e_kᵀ."""
    if k_q is None:
        return J, dJ
    p, dp = penalty(q, q_min=device.q_min, q_max=device.q_max, k_q=k_q)
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
        slave_q: (n_s,) slave configuration [rad], a callable returning it, or the slave `rhi.sim.Plant` (its
            encoders `q` at each evaluation; `rhi.sim.simulate`'s compiled loop then computes ˢM itself).
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
        self._plant = slave_q if hasattr(slave_q, "q") and hasattr(slave_q, "device") else None
        self._slave_q = slave_q if callable(slave_q) or self._plant is not None else as_array(
            "slave_q", slave_q, shape_tail=(slave.n,)).copy()  # fixed: the compiled tick holds its ˢM
        self._cache: tuple[bytes, np.ndarray] | None = None
        self.slave_ellipsoid()  # validate now

    def slave_configuration(self) -> np.ndarray:
        """Current slave configuration: (n_s,) [rad]."""
        q = self._plant.q if self._plant is not None else self._slave_q() if callable(self._slave_q) else self._slave_q
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
            Js = Js * penalty(qs, q_min=self.slave.q_min, q_max=self.slave.q_max, k_q=self.k_q)[0]
        M = Js @ Js.T
        self._cache = (key, M)
        return M

    def master_jacobian(self, device: Device, q) -> np.ndarray:
        """H J^q: (m, n), the Jacobian whose ME is matched, at q: (n,) [rad]."""
        q = np.asarray(q, dtype=float)
        J = device.jacobian(q)
        if self.k_q is not None:
            J = J * penalty(q, q_min=device.q_min, q_max=device.q_max, k_q=self.k_q)[0]
        return J if self.H is None else self.H @ J

    def value(self, device: Device, q) -> float:
        """ν(q) for the HI configuration q: (n,) [rad]."""
        J = self.master_jacobian(device, q)
        return float(jbld(self.slave_ellipsoid(), J @ J.T))

    def gradient(self, device: Device, q) -> np.ndarray:
        """∂ν/∂q: (n,).

        With A = ᵐM, ∂ν/∂q_k = tr((Ā⁻¹ − A⁻¹) ∂J^q_k J^qᵀ), Ā = (ˢM + A)/2,
        ∂J^q_k = ∂J_k diag(P) + J_k P'_k e_kᵀ.
        """
        q = np.asarray(q, dtype=float)
        return self._gradient(device, q, device.jacobian(q), device.jacobian_derivative(q))

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a controller's `DeviceTerms` snapshot (J, ∂J/∂q already computed): (n,)."""
        return self._gradient(terms.device, terms.q, terms.J, terms.dJ)

    def _gradient(self, device: DeviceModel, q: np.ndarray, J: np.ndarray, dJ: np.ndarray) -> np.ndarray:
        J, dJ = penalized(device, q, J, dJ, self.k_q)
        return jbld_velocity_gradient(self.slave_ellipsoid(), J, dJ, self.H)

    def compiled(self, device: Device) -> CompiledObjective | None:
        """VME matching of J^q J^qᵀ to ˢM (the whole compiled tick); None with H or a penalised ˢM.

        ˢM is read at each tick from a callable or a plant, and held as `desired` for a fixed configuration.
        """
        if self.H is not None or (self.penalize_slave and self.k_q is not None):
            return None
        if self._plant is None and not callable(self._slave_q):
            return CompiledObjective("vme_live", penalty=self.k_q, desired=self.slave_ellipsoid())
        return CompiledObjective("vme_live", penalty=self.k_q, live=self.slave_ellipsoid, slave=self._plant)



def _tmi(device: Device, torque_max, *, slave: str, slave_params: dict, slave_q, k_q, penalize_slave: bool,
         H) -> TMIMatching:
    try:
        model = load_device(slave, **slave_params)
    except RhiError as exc:
        raise type(exc)(f"slave: {exc}") from None
    return TMIMatching(model, slave_q, k_q=k_q, penalize_slave=penalize_slave, H=H)


register(ObjectiveType("tmi", _tmi, {"slave": (STRING, REQUIRED), "slave_params": (NUMBERS, {}), "slave_q": (VECTOR, REQUIRED),
                                     "k_q": (POSITIVE, None), "penalize_slave": (BOOLEAN, False), "H": (MATRIX, None)}))
register(ObjectiveType("manipulability", lambda device, torque_max, *, log, k_q: Manipulability(log=log, k_q=k_q),
                       {"log": (BOOLEAN, False), "k_q": (POSITIVE, None)}))


__all__ = ["Manipulability", "TMIMatching", "penalized", "penalty"]
