"""Actuator saturation: the torque box, the null-space bases every allocation works in, and the tertiary scaling β.

The allocation strategies themselves (none, scaling, ASCM, LP, active set) are
`rhi.control.allocation`, one module each; they all write the torque in one form:

    τ(α, y) = α a + b + Z y

with ``a = Jᵀ F_render`` the scalable (rendered-force) torque, ``b`` the torque that is not
scaled (damping, gravity), and ``Z`` (n, n−m) an orthonormal basis of the range of the
torque null-space projector ``N = I − Jᵀ J#ᵀ`` (eq. 7.5), i.e. of the torques with
``J#ᵀ τ = 0`` (`null_basis`). ``N τ_N = Z y`` for ``τ_N = Z y``, so every allocation produces
the task-space force ``J#ᵀ τ = J#ᵀ(α a + b)`` exactly. Here: the limits' check, the bases
and projectors, the largest feasible scaling (`scaling_alpha`) and the tertiary objective's
scaling β of Algorithm 2 (thesis §7.3–7.4; the ASO and the FME transition of §6.3.2 are
`rhi.control.transition`).

The ``*_projector`` variants (`tertiary_projector`, and ASCM's `ascm_projector`) compute the
same result from the orthogonal projector ``P = Z Zᵀ`` onto those torques, which a
controller gets from J and M⁻¹ by two small products instead of an SVD: the least-norm
null-space torque that puts the joints 𝒮 at ``r`` is ``P[:, 𝒮] P[𝒮, 𝒮]⁻¹ r``.
"""

from __future__ import annotations

import math

import numpy as np

from rhi._validate import as_array
from rhi.control import _compiled as kernels
from rhi.devices.model import eye
from rhi.errors import InfeasibleLimits, InvalidInput, Singular

_TOL = 1e-12
# Z_𝒮 counts as rank-deficient (ASCM cannot hold the joints 𝒮) when its smallest singular value is
# below this; Z is orthonormal, so the threshold is relative.
RANK_TOL = 1e-9


# ------------------------------------------------------------------ limits, bases
def check_torque_limits(*, torque_min, torque_max, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Validate torque limits for control: finite, ``torque_min < 0 < torque_max``.

    Args:
        torque_min: (n,) lower limits [N m], each < 0.
        torque_max: (n,) upper limits [N m], each > 0.
        n: expected number of joints.

    Raises:
        InvalidInput: NaN/inf or wrong shape.
        InfeasibleLimits: a limit of the wrong sign (zero torque must lie strictly inside).
    """
    lo = as_array("torque_min", torque_min, ndim_min=1, shape_tail=(n,) if n else ())
    hi = as_array("torque_max", torque_max, ndim_min=1, shape_tail=(n,) if n else ())
    if lo.shape != hi.shape or lo.ndim != 1:
        raise InvalidInput(f"torque_min/torque_max: expected two (n,) vectors, got {lo.shape} and {hi.shape}")
    if np.any(lo >= 0):
        raise InfeasibleLimits(f"torque_min: every entry must be < 0, got {lo.tolist()}")
    if np.any(hi <= 0):
        raise InfeasibleLimits(f"torque_max: every entry must be > 0, got {hi.tolist()}")
    return lo, hi


def check_allocation(a, b, Z=None, *, torque_min, torque_max, basis: bool = False):
    """Validate an allocation problem (the arguments of every strategy).

    Args:
        a: (n,) scaled torque [N m], finite.
        b: (n,) unscaled torque [N m], finite.
        Z: (n, r) null-space basis, finite, or None.
        torque_min: (n,) lower limits [N m] (`check_torque_limits`).
        torque_max: (n,) upper limits [N m].
        basis: Z is required.

    Returns:
        (a, b, Z, torque_min, torque_max) as float arrays.

    Raises:
        InvalidInput, InfeasibleLimits: naming the argument.
    """
    lo, hi = check_torque_limits(torque_min=torque_min, torque_max=torque_max)
    n = lo.shape[0]
    a = as_array("a", a, shape_tail=(n,))
    b = as_array("b", b, shape_tail=(n,))
    if a.ndim != 1 or b.ndim != 1:
        raise InvalidInput(f"a/b: expected ({n},) vectors, got {a.shape} and {b.shape}")
    if Z is None and basis:
        raise InvalidInput(f"Z: expected an ({n}, r) basis of the null-space torques, got None")
    if Z is not None:
        Z = as_array("Z", Z, shape_tail=(n, None))
        if Z.ndim != 2:
            raise InvalidInput(f"Z: expected an ({n}, r) basis, got shape {Z.shape}")
    return a, b, Z, lo, hi


def null_basis(J: np.ndarray, M: np.ndarray | None = None) -> np.ndarray:
    """Orthonormal basis Z (n, n−m) of range(I − Jᵀ J#ᵀ) = null(J M⁻¹) (pseudoinverse: null(J)).

    Args:
        J: (m, n) Jacobian, full row rank.
        M: (n, n) joint-space inertia [kg m²] for the dynamically consistent J#, or None.

    Raises:
        InvalidInput: a non-finite or misshapen J or M (named).
    """
    J = as_array("J", J, shape_tail=(None, None))
    if J.ndim != 2 or J.shape[0] > J.shape[1]:
        raise InvalidInput(f"J: expected an (m, n) Jacobian with m <= n, got shape {J.shape}")
    if M is not None:
        M = as_array("M", M, shape_tail=(J.shape[1], J.shape[1]))
        if M.ndim != 2:
            raise InvalidInput(f"M: expected shape ({J.shape[1]}, {J.shape[1]}), got {M.shape}")
    A = J if M is None else np.linalg.solve(M, J.T).T  # J M⁻¹ (M symmetric)
    m = J.shape[0]
    _, _, Vt = np.linalg.svd(A)
    return Vt[m:].T.copy()


def null_projector(J: np.ndarray, M: np.ndarray | None = None, *, JMinv: np.ndarray | None = None) -> np.ndarray:
    """Orthogonal projector P = Z Zᵀ (n, n) onto range(I − Jᵀ J#ᵀ) = null(J M⁻¹) (pseudoinverse: null(J)).

    ``P = I − Q Qᵀ`` with Q an orthonormal basis of the rows of ``A = J M⁻¹`` (or J), by
    Gram–Schmidt with re-orthogonalisation (accurate to rounding whatever cond(A)): the
    subspace of `null_basis` without an SVD.

    Args:
        J: (m, n) Jacobian, full row rank.
        M: (n, n) joint-space inertia [kg m²] for the dynamically consistent J#, or None.
        JMinv: (m, n) J M⁻¹ if already known (then M is not used).

    Raises:
        Singular: J does not have full row rank.
    """
    A = JMinv if JMinv is not None else (J if M is None else np.linalg.solve(M, J.T).T)
    Q: list[np.ndarray] = []
    for i in range(A.shape[0]):
        v = A[i]
        scale = math.sqrt(v.dot(v))
        for _ in range(2):  # CGS2: twice is enough
            for qv in Q:
                v = v - qv.dot(v) * qv
        nv = math.sqrt(v.dot(v))
        if not nv > 1e-12 * scale:
            raise Singular(f"J: rank-deficient Jacobian (row {i} depends on the others)")
        Q.append(v / nv)
    Qm = np.array(Q)
    return eye(A.shape[1]) - Qm.T.dot(Qm)


def basis_from_projector(P: np.ndarray, rank: int | None = None) -> np.ndarray:
    """An orthonormal basis Z (n, r) of the range of an orthogonal projector P (eigenvectors of eigenvalue 1)."""
    w, V = np.linalg.eigh(0.5 * (P + P.T))
    r = int(round(float(np.trace(P)))) if rank is None else rank
    return V[:, w.size - r:]


def scaling_alpha(p, c, *, lo, hi) -> float | None:
    """Largest α in [0, 1] with ``lo <= α p + c <= hi``; None when no α in [0, 1] is feasible.

    Entries with |p| negligible only need c itself in the box.

    Args:
        p: (k,) direction of the scaled part.
        c: (k,) constant part.
        lo: (k,) lower bounds.
        hi: (k,) upper bounds.
    """
    a_lo, a_hi = 0.0, 1.0
    for pi, ci, l, h in zip(*(np.asarray(v, dtype=float).tolist() for v in (p, c, lo, hi))):
        api = abs(pi)
        if api <= 1e-12 * (1.0 + api + abs(ci)):
            if ci > h + 1e-12 or ci < l - 1e-12:
                return None
            continue
        r1, r2 = (l - ci) / pi, (h - ci) / pi
        if r1 > r2:
            r1, r2 = r2, r1
        a_lo, a_hi = max(a_lo, r1), min(a_hi, r2)
    if a_lo > a_hi + 1e-12:
        return None
    return max(a_hi, 0.0)


def tertiary(tau, saturated, Z, tau_to, *, torque_min, torque_max, N: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Tertiary-objective torque in the null space of the primary task and of ASCM (eqs. 7.16, Algorithm 2).

    The objective torque is projected by N (eq. 3.20; orthogonally onto range(Z) if N is
    None), then onto the torques that leave the held joints 𝒮 unchanged, and scaled by
    the largest β <= 1 that keeps every joint in the box (Algorithm 2). β = 0 when no
    redundancy is left after ASCM (fewer than m + 1 joints free), or when the projected
    torque is negligible (every entry below 1e-12 (1 + max|τ_to|) N m).

    Args:
        tau: (n,) torque from the allocation [N m], within the box.
        saturated: (n,) bool, ASCM's 𝒮.
        Z: (n, n−m) null-space basis.
        tau_to: (n,) tertiary torque τ_to, e.g. −Λ ∂ν/∂q − k_D q̇ [N m].
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        N: (n, n) torque null-space projector I − JᵀJ#ᵀ, or None.

    Returns:
        (β δ (n,) [N m] to add to tau, β).
    """
    n, r = Z.shape
    if n - int(np.count_nonzero(saturated)) <= n - r:  # no redundancy left (Algorithm 2, line 2)
        return np.zeros_like(tau), 0.0
    c = Z.T @ (tau_to if N is None else N @ tau_to)
    if saturated.any():
        ZS = Z[saturated]
        c = c - np.linalg.pinv(ZS) @ (ZS @ c)
    delta = Z @ c
    if not np.any(np.abs(delta) > negligible(tau_to)):
        return np.zeros_like(tau), 0.0
    lo, hi = torque_min, torque_max
    beta = scaling_alpha(delta, np.clip(tau, lo, hi), lo=lo, hi=hi)
    beta = 0.0 if beta is None else beta
    return beta * delta, beta


def negligible(tau) -> float:
    """Null-space torques below this [N m] are rounding noise of the projections (tau: (n,) [N m])."""
    return 1e-12 * (1.0 + float(np.max(np.abs(tau))))


def tertiary_projector(
    tau, saturated, P, tau_to, *, torque_min, torque_max, N: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """`tertiary` from the projector P = Z Zᵀ instead of a basis (same result).

    Args:
        tau: (n,) torque from the allocation [N m], within the box.
        saturated: (n,) bool, ASCM's 𝒮.
        P: (n, n) orthogonal projector onto the null-space torques (`null_projector`).
        tau_to: (n,) tertiary torque τ_to [N m].
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        N: (n, n) torque null-space projector I − JᵀJ#ᵀ, or None (then P).

    Returns:
        (β δ (n,) [N m] to add to tau, β).
    """
    r = int(round(float(np.trace(P))))
    tau, P, tau_to, lo, hi = (np.ascontiguousarray(v, dtype=float) for v in (tau, P, tau_to, torque_min, torque_max))
    saturated = np.ascontiguousarray(saturated, dtype=bool)
    Ntau = (P if N is None else np.asarray(N, dtype=float)).dot(tau_to)
    delta, beta, ok = kernels.tertiary(tau, saturated, P, tau_to, Ntau, lo, hi, r)
    if not ok:
        return tertiary(tau, saturated, basis_from_projector(P, r), tau_to, torque_min=lo, torque_max=hi, N=N)
    return delta, beta


