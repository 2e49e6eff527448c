"""A second, independent transcription of the thesis's §4.2–4.4 design indices (issue 23, item 2).

Plain NumPy, written from the thesis text: eqs. 4.7 (μ), 4.8 (GM), 4.9 (1/κ), 4.10 (GC), 4.18 (GM_T),
4.19–4.20 (J^q), 4.21–4.22 (‖q̇‖²), 4.25a–b (the Rehab's and the PHANToM's Jacobians), 4.26 (the HI
rotated into the slave frame), 4.23–4.24 (C1, C2); the TMI of eqs. 4.11–4.17 is `transcription.tmi`.
It imports nothing of `rhi.design` or `rhi.metrics`. Inputs it takes from rhi as data: the link lengths
and joint limits of the two devices, the workspace samples with their area weights, and the placement
radius r0 (the set-up choices the thesis leaves open, `rhi.experiments.ch4`). Inverse kinematics is
Newton's method on the forward kinematics integrated from eqs. 4.25a–b (not rhi's closed form).
"""

from __future__ import annotations

import numpy as np
import transcription as tr


def j_phantom(q: np.ndarray, l1: float, l2: float) -> np.ndarray:
    """Eq. 4.25b, (3, 3)."""
    s1, c1, s2, c2, s3, c3 = np.sin(q[0]), np.cos(q[0]), np.sin(q[1]), np.cos(q[1]), np.sin(q[2]), np.cos(q[2])
    return np.array([[-s1 * (l1 * c2 + l2 * s3), -l1 * c1 * s2, l2 * c1 * c3],
                     [c1 * (l1 * c2 + l2 * s3), -l1 * s1 * s2, l2 * c3 * s1],
                     [0.0, l1 * c2, l2 * s3]])


def fk_phantom(q: np.ndarray, l1: float, l2: float) -> np.ndarray:
    """The position whose derivative is eq. 4.25b: x = c1(l1c2 + l2s3), y = s1(l1c2 + l2s3), z = l1s2 − l2c3."""
    a = l1 * np.cos(q[1]) + l2 * np.sin(q[2])
    return np.array([np.cos(q[0]) * a, np.sin(q[0]) * a, l1 * np.sin(q[1]) - l2 * np.cos(q[2])])


def j_rehab(q: np.ndarray, d1: float, d2: float) -> np.ndarray:
    """Eq. 4.25a, (2, 2)."""
    return np.array([[-d1 * np.sin(q[0]), d2 * np.cos(q[1])], [d1 * np.cos(q[0]), d2 * np.sin(q[1])]])


def fk_rehab(q: np.ndarray, d1: float, d2: float) -> np.ndarray:
    """The position whose derivative is eq. 4.25a: x = d1c1 + d2s2, y = d1s1 − d2c2."""
    return np.array([d1 * np.cos(q[0]) + d2 * np.sin(q[1]), d1 * np.sin(q[0]) - d2 * np.cos(q[1])])


def newton_ik(fk, jac, x: np.ndarray, q0: np.ndarray, iters: int = 100) -> np.ndarray | None:
    """Q with fk(q) = x by Newton's method (least-norm step), or None if it does not converge to 1e-12 m."""
    q = np.array(q0, dtype=float)
    for _ in range(iters):
        e = x - fk(q)
        if np.linalg.norm(e) < 1e-12:
            return q
        q = q + np.linalg.pinv(jac(q)) @ e
    return None


def within(q, q_min, q_max, linear) -> bool:
    """Joint limits and the linear (parallelogram) limits lo ≤ c·q ≤ hi."""
    tol = 1e-9
    if np.any(q < q_min - tol) or np.any(q > q_max + tol):
        return False
    return all(lo - tol <= float(np.dot(c, q)) <= hi + tol for c, lo, hi in linear)


def penalty(q, q_min, q_max, k_q: float) -> np.ndarray:
    """Eq. 4.20, one factor per joint."""
    return ((1.0 - np.exp(-4.0 * k_q * (q - q_min) * (q_max - q) / (q_max - q_min) ** 2))
            / (1.0 - np.exp(-k_q)))


def mu(J: np.ndarray) -> float:
    """Eq. 4.7."""
    return float(np.sqrt(np.linalg.det(J @ J.T)))


def inv_kappa(J: np.ndarray) -> float:
    """Eq. 4.9: σ_m / σ_1."""
    s = np.linalg.svd(J, compute_uv=False)
    return float(s[-1] / s[0])


def joint_energy(Jm: np.ndarray, Js: np.ndarray, xdot: np.ndarray, squared: bool = False) -> float:
    """Eqs. 4.21–4.22: ẋᵀ U_T Λ_T⁻¹ U_Tᵀ ẋ, U_T and σ^I the axes of the larger intersection ellipsoid (eq. 4.17).

    Λ_T = diag(σ^I) as eq. 4.22 prints it, or diag(σ^I²) with `squared` (eq. 4.21's (J_T J_Tᵀ)⁻¹).
    """
    best = None
    for A, B in ((Jm @ Jm.T, Js @ Js.T), (Js @ Js.T, Jm @ Jm.T)):  # axes of the HI's ME (4.12), of the slave's (4.15)
        s, U = tr.principal_axes(A)
        Binv = np.linalg.inv(B)
        sig = np.array([min(float(U[:, i] @ Binv @ U[:, i]) ** -0.5, s[i]) for i in range(len(s))])
        if best is None or np.prod(sig) > np.prod(best[0]):
            best = (sig, U)
    sig, U = best
    lam = sig**2 if squared else sig
    return float(sum((U[:, i] @ xdot) ** 2 / lam[i] for i in range(len(sig))))


def design_indices(points, weights, center, r0, theta_z, l2, z_ph, *, l1, d, hi_limits, slave_limits, slave_q0,
                   k_q=1.0, K1=1.0, K2=20.0) -> dict[str, float]:
    """GM_M, GC_M (eqs. 4.8, 4.10 of the HI), GM_T (eq. 4.18), C1, C2 (eqs. 4.23–4.24) of one design.

    The HI's base sits at c − r0 (cos θz, sin θz) with its x axis at θz (Fig. 4.3: the HI rotated about the
    centre c of the slave workspace); a slave point p is the HI target Rz(θz)ᵀ(p − base) on the plane
    z = Z_PH. A sample either robot cannot reach within its limits counts 0 in the integrals (∫_W over
    all of W).
    """
    cz, sz = np.cos(theta_z), np.sin(theta_z)
    R = np.array([[cz, -sz], [sz, cz]])
    base = np.asarray(center) - r0 * np.array([cz, sz])
    H = np.array([[cz, -sz, 0.0], [sz, cz, 0.0]])  # eq. 4.26
    qm_min, qm_max, qm_lin = hi_limits
    qs_min, qs_max, qs_lin = slave_limits
    mus, kappas, lams = [], [], []
    for p in np.asarray(points):
        xb = R.T @ (p - base)
        target = np.array([xb[0], xb[1], z_ph])
        guess = np.array([np.arctan2(xb[1], xb[0]), 0.3, 0.3])
        qm = newton_ik(lambda q: fk_phantom(q, l1, l2), lambda q: j_phantom(q, l1, l2), target, guess)
        qs = newton_ik(lambda q: fk_rehab(q, *d), lambda q: j_rehab(q, *d), p, slave_q0)
        if qm is None or qs is None or not within(qm, qm_min, qm_max, qm_lin) or not within(qs, qs_min, qs_max,
                                                                                            qs_lin):
            mus.append(0.0), kappas.append(0.0), lams.append(0.0)
            continue
        Jm = H @ j_phantom(qm, l1, l2) * penalty(qm, qm_min, qm_max, k_q)[None, :]  # eqs. 4.19, 4.26
        Js = j_rehab(qs, *d) * penalty(qs, qs_min, qs_max, k_q)[None, :]
        mus.append(mu(Jm)), kappas.append(inv_kappa(Jm)), lams.append(tr.tmi(Jm, Js))
    w = np.asarray(weights)
    gm, gc, gmt = (float(np.sum(w * np.array(v)) / np.sum(w)) for v in (mus, kappas, lams))
    return {"GM_M": gm, "GC_M": gc, "GM_T": gmt, "C1": K1 * gc + K2 * gm, "C2": K1 * gc + K2 * gmt,
            "coverage": float(np.sum(w[np.array(mus) > 0]) / np.sum(w))}
