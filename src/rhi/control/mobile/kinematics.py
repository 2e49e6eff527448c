"""Kinematics of a serial mobile manipulator for its controllers (thesis App. A, B).

`WMMKinematics` gives the end-effector position, the 6-D world-aligned Jacobian and the
drift J̇q̇ from one Pinocchio call each. From the 6-D Jacobian of a serial chain follow by
cross products ∂J/∂q and ∂²J/∂q² (`chain_jacobian_derivatives`; ∂J/∂q equals
`Device.jacobian_derivative`, tested) and, in O(m²), the determinant manipulability
H = det(J Jᵀ) with its gradient and Hessian-vector product (`det_terms`, the AMD's fast
kernel of eqs. B.14–B.18, tested against `rhi.control.mobile.measures`).
Derivative conventions: ``dJ[..., i, j, k] = ∂J_ij/∂q_k``, ``d2J[..., i, j, k, l] = ∂²J_ij/∂q_k∂q_l``.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from rhi._validate import all_finite, as_array
from rhi.control.mobile.bounds import EPS
from rhi.devices.mobile_base import BASE_JOINTS, check_mobile_manipulator
from rhi.devices.model import Device
from rhi.devices.terms import LEVI_CIVITA
from rhi.errors import InvalidInput, ModelError


class WMMKinematics:
    """End-effector position, Jacobians and their derivatives of a serial mobile manipulator.

    One Pinocchio call per configuration gives the 6-D world-aligned Jacobian; the
    position Jacobian's derivatives follow from it by cross products
    (`chain_jacobian_derivatives`), the drift J̇q̇ from the frame's classical acceleration.

    Args:
        device: a device whose chain coordinates are its motor coordinates (A = I, b = 0)
            and whose joints form one serial chain (e.g. ``wmm``, ``gen3``).
    """

    def __init__(self, device: Device) -> None:
        if device.A.shape[0] != device.A.shape[1] or not np.allclose(device.A, np.eye(device.n)) or np.any(device.b):
            raise ModelError(f"device: {device.name} has an actuation map; WMMKinematics needs chain coordinates")
        parents = list(device.model.parents)
        if parents[1:] != list(range(len(parents) - 1)):
            raise ModelError(f"device: {device.name} is not a serial chain")
        self.device = device
        self.model = device.model
        self.data = device.model.createData()
        self.fid = device.model.getFrameId(device.ee_frame)
        self._zero = np.zeros(device.n)

    def jacobian6(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, J6): end-effector position (3,) [m] and [linear; angular] world-aligned Jacobian (6, n)."""
        J6 = pin.computeFrameJacobian(self.model, self.data, q, self.fid, pin.LOCAL_WORLD_ALIGNED)
        return self.data.oMf[self.fid].translation.copy(), J6

    def drift(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """J̇q̇: (3,) [m/s²], the end-effector acceleration at q̈ = 0."""
        pin.forwardKinematics(self.model, self.data, q, dq, self._zero)
        return pin.getFrameClassicalAcceleration(self.model, self.data, self.fid, pin.LOCAL_WORLD_ALIGNED).linear.copy()


def check_vector(name: str, v, n: int) -> np.ndarray:
    """`v` as a finite (n,) float array (InvalidInput naming `name` otherwise)."""
    a = np.asarray(v, dtype=float)
    if a.shape != (n,):
        raise InvalidInput(f"{name}: expected shape ({n},), got {a.shape}")
    if not all_finite(a):
        raise InvalidInput(f"{name}: contains NaN or inf")
    return a


def check_base(device: Device, n_base: int) -> None:
    """Require a mobile manipulator with ``n_base`` = 3 base coordinates (InvalidInput naming `device`)."""
    if n_base != len(BASE_JOINTS):
        raise InvalidInput(f"device: the base has {len(BASE_JOINTS)} coordinates {list(BASE_JOINTS)}, got n_base={n_base}")
    check_mobile_manipulator(device)


_CHAIN_INDEX: dict[int, tuple[np.ndarray, ...]] = {}
# (a @ _E9).reshape(3, 3) = [a]×, the cross-product matrix: [a]×_ik = Σ_j ε_ijk a_j
_E9 = np.ascontiguousarray(LEVI_CIVITA.transpose(1, 0, 2).reshape(3, 9))


def _chain_index(n: int) -> tuple[np.ndarray, ...]:
    """Index arrays of `chain_jacobian_derivatives` for n joints (cached)."""
    if n not in _CHAIN_INDEX:
        idx = np.arange(n)
        S = np.minimum.outer(idx, idx)
        T = np.maximum.outer(idx, idx)
        j, k, l_ = np.meshgrid(idx, idx, idx, indexing="ij")
        s, t = S[j, k], T[j, k]
        before = (idx[:, None] < idx[None, :]).astype(float)
        _CHAIN_INDEX[n] = (S, T, l_, s, t, np.minimum(t, l_), np.maximum(t, l_), before)
    return _CHAIN_INDEX[n]


def _skew(A: np.ndarray) -> np.ndarray:
    """Cross-product matrices of the columns of A: (..., 3, n) -> (..., n, 3, 3)."""
    return (np.swapaxes(A, -1, -2) @ _E9).reshape(A.shape[:-2] + (A.shape[-1], 3, 3))


def chain_jacobian_derivatives(J6, *, second: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """∂J/∂q and ∂²J/∂q² of a serial chain's position Jacobian from its 6-D Jacobian.

    For 1-DoF joints in chain order with world angular columns a_j (0 for a prismatic
    joint) and linear columns v_j of the end-effector point: ∂a_j/∂q_k = a_k × a_j (k < j),
    ∂v_j/∂q_k = a_s × v_t with s = min(j, k), t = max(j, k); differentiating once more
    gives ∂²v_j/∂q_k∂q_l = [l < s](a_l × a_s) × v_t + a_s × (a_min(t,l) × v_max(t,l)).

    Args:
        J6: (..., 6, n) [linear; angular] Jacobian of the end-effector point in world-aligned axes.
        second: also return the second derivatives.

    Returns:
        (dJ, d2J): (..., 3, n, n) and (..., 3, n, n, n) (None if not `second`).
    """
    J6 = as_array("J6", J6, ndim_min=2)
    if J6.shape[-2] != 6:
        raise InvalidInput(f"J6: expected shape (..., 6, n), got {J6.shape}")
    V, A = J6[..., :3, :], J6[..., 3:, :]
    S, T, L, s, t, tl_lo, tl_hi, before = _chain_index(J6.shape[-1])
    SkA = _skew(A)  # (..., n, 3, 3)
    C = np.swapaxes(SkA @ V[..., None, :, :], -1, -2)  # C[..., s, t, :] = a_s × v_t
    dJ = np.moveaxis(C[..., S, T, :], -1, -3)  # (..., 3, j, k)
    if not second:
        return dJ, None
    AA = np.swapaxes(SkA @ A[..., None, :, :], -1, -2) * before[:, :, None]  # [..., l, s, :] = a_l × a_s, l < s
    Vt, At = np.swapaxes(V, -1, -2), np.swapaxes(A, -1, -2)  # (..., n, 3)
    d2V = np.cross(AA[..., L, s, :], Vt[..., t, :]) + np.cross(At[..., s, :], C[..., tl_lo, tl_hi, :])
    return dJ, np.moveaxis(d2V, -1, -4)


def sym3(P: np.ndarray) -> tuple[float, np.ndarray | None, float, float]:
    """det, inverse (None if singular), smallest and largest eigenvalue of a symmetric 3×3 matrix (closed forms)."""
    (a, b, c), (_, d, e), (_, _, f) = P.tolist()
    A0, A1, A2 = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A0 + b * A1 + c * A2
    # eigenvalues: trigonometric solution of the characteristic cubic
    p1 = b * b + c * c + e * e
    qm = (a + d + f) / 3.0
    a_, d_, f_ = a - qm, d - qm, f - qm
    p2 = a_ * a_ + d_ * d_ + f_ * f_ + 2.0 * p1
    if p2 <= 1e-300:
        lmin = lmax = qm
    else:
        p = math.sqrt(p2 / 6.0)
        detB = (a_ * (d_ * f_ - e * e) - b * (b * f_ - e * c) + c * (b * e - d_ * c)) / p**3
        phi = math.acos(min(1.0, max(-1.0, 0.5 * detB))) / 3.0
        lmax = qm + 2.0 * p * math.cos(phi)
        lmin = qm + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    if not det > 0:
        return det, None, lmin, lmax
    B4, B5 = a * f - c * c, b * c - a * e
    inv = np.array([[A0, A1, A2], [A1, B4, B5], [A2, B5, a * d - b * b]]) / det
    return det, inv, lmin, lmax


def gram_inverse(JS: np.ndarray, rank_tol: float) -> np.ndarray | None:
    """(JS JSᵀ)⁻¹ of an (r, k) JS, or None where JS is rank deficient (λ_min ≤ rank_tol λ_max)."""
    G = JS @ JS.T
    if G.shape == (3, 3):
        _, inv, lmin, lmax = sym3(G)
        return inv if inv is not None and lmin > rank_tol * max(lmax, EPS) else None
    ev = np.linalg.eigvalsh(G)
    return np.linalg.inv(G) if ev[0] > rank_tol * max(ev[-1], EPS) else None


def det_terms(J6m: np.ndarray, dqm: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
    """H = det(J Jᵀ), ∇H (B.14), the Hessian-vector product ∇²H q̇ (B.18 contracted) and σ_min(J).

    ∇²H q̇ is d/dt ∇H along q̇, evaluated in O(m²) with ∂J/∂q (cross products) and its time
    derivative ∂J̇/∂q_k = (ω_s × a_s) × v_t + a_s × J̇_t (ω_s = Σ_{l<s} a_l q̇_l), the same
    numbers as `manipulability_det_hessian` @ q̇ without the m³ tensor.

    Args:
        J6m: (6, m) [linear; angular] Jacobian of the arm columns.
        dqm: (m,) arm joint velocities.
    """
    V, A = J6m[:3], J6m[3:]
    m = V.shape[1]
    S, T = _chain_index(m)[:2]
    SkA = (A.T @ _E9).reshape(m, 3, 3)
    D = (SkA @ V)[S, :, T]  # (j, k, 3): ∂v_j/∂q_k
    Jd = (dqm @ D).T  # J̇ (3, m)
    aq = A * dqm
    Om = np.cumsum(aq, axis=1) - aq  # ω_s, angular velocity of the link before joint s
    Ad = (SkA @ Om.T[:, :, None])[:, :, 0].T  # a_s × ω_s = −ȧ_s, (3, m)
    Dd = (SkA @ Jd - (Ad.T @ _E9).reshape(m, 3, 3) @ V)[S, :, T]  # d/dt ∂v_j/∂q_k
    Psi = V @ V.T
    det, G, lam, _ = sym3(Psi)
    if G is None:
        raise InvalidInput("J: J_m J_mᵀ is singular (the arm is at a singular configuration)")
    W = G @ V  # Ψ⁻¹J
    Dk = D.transpose(1, 0, 2).reshape(m, 3 * m)
    Wf = W.T.ravel()
    gt = Dk @ Wf  # tr(Ψ⁻¹ ∂_kJ Jᵀ)
    Pd = Jd @ V.T
    Pd = Pd + Pd.T  # Ψ̇
    Wd = G @ (Jd - Pd @ W)
    gdot = Dk @ Wd.T.ravel() + Dd.transpose(1, 0, 2).reshape(m, 3 * m) @ Wf
    trd = float(G.ravel() @ Pd.ravel())
    grad = 2.0 * det * gt
    hvp = 2.0 * det * (trd * gt + gdot)
    return det, grad, hvp, math.sqrt(max(lam, 0.0))
