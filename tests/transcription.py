"""A second, independent transcription of the thesis's ch. 5 and ch. 6 equations (issue 23, item 2).

Plain NumPy, one equation per line, written from the thesis text alone. It imports nothing of
rhi's controller, objectives, metrics or transition code: only the device model (J, M, FK)
through the arguments it is given. Tests compare it with rhi's implementation
(tests/test_transcription_ch5_ch6.py).

Equations: 6.4 (J#), 6.6 (τ_S), 6.9 (M̂), 6.10 (ν), 6.14 (ASO), 6.15–6.19 (switch and
transition), 6.21 (spring), §6.3.1 (force scaling α); 4.11–4.17 (TMI), 5.14 (Yoshikawa μ).
"""

from __future__ import annotations

import math

import numpy as np


# ------------------------------------------------------------------------------ chapter 6
def fme_weighted(J: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Eq. 6.9: M̂ = (J W W Jᵀ)⁻¹ with W = diag(1/T_i)."""
    W = np.diag(1.0 / np.asarray(T, dtype=float))
    return np.linalg.inv(J @ W @ W @ J.T)


def jbld(A: np.ndarray, B: np.ndarray) -> float:
    """Eq. 6.10 (and 5.11): log det((A + B)/2) − ½ log det(A B)."""
    return float(np.log(np.linalg.det((A + B) / 2.0)) - 0.5 * np.log(np.linalg.det(A @ B)))


def nu_fme(jacobian, q: np.ndarray, M_des: np.ndarray, T: np.ndarray) -> float:
    """Eq. 6.10 with M̂ of eq. 6.9 at q; `jacobian(q)` -> (m, n)."""
    return jbld(fme_weighted(jacobian(q), T), M_des)


def gradient_fd(f, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """∂f/∂q by central differences (the transcription's own derivative, no analytic formula)."""
    g = np.zeros(len(q))
    for i in range(len(q)):
        e = np.zeros(len(q))
        e[i] = h
        g[i] = (f(q + e) - f(q - e)) / (2.0 * h)
    return g


def jsharp(J: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Eq. 6.4: J# = M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹, (n, m)."""
    Mi = np.linalg.inv(M)
    return Mi @ J.T @ np.linalg.inv(J @ Mi @ J.T)


def aso(tau: np.ndarray, tmin: np.ndarray, tmax: np.ndarray, S: float) -> float:
    """Eq. 6.14, V = (1 − exp(−S(−1)ⁿ Π (τ−T_max)(τ−T_min)/(T_max−T_min)²)) / (1 − exp(−S/4ⁿ)).

    "V is a scalar that spans the [0, 1] interval": outside the box the product changes sign; V = 0 there.
    """
    n = len(tau)
    if np.any(tau >= tmax) or np.any(tau <= tmin):
        return 0.0
    p = 1.0
    for i in range(n):
        p *= (tau[i] - tmax[i]) * (tau[i] - tmin[i]) / (tmax[i] - tmin[i]) ** 2
    return (1.0 - math.exp(-S * (-1.0) ** n * p)) / (1.0 - math.exp(-S / 4.0**n))


class LiteralOmega:
    """Eqs. 6.17–6.19 read literally: two cases, each with its own threshold and no memory beyond t₀, t_f.

    Case 1 (at or towards M_Free → M_Stiff): Ω = 1 if V ≥ ε₁; the cosine from t₀ (the first tick with
    V < ε₁) while t < t_f; 0 once t ≥ t_f, which ends case 1. Case 2 (M_Stiff → M_Free): Ω = 0 if
    V < ε₂; the rising cosine from t₀ (the first tick with V ≥ ε₂) while t < t_f; 1 once t ≥ t_f.
    t_f = t₀ + ρ‖M_Free − M_Stiff‖_F (eq. 6.19). With ε₁ = ε₂ = ε and ρ = 0 it is eq. 6.15.
    """

    def __init__(self, eps1: float, eps2: float, rho: float, distance: float) -> None:
        self.eps1, self.eps2, self.duration = eps1, eps2, rho * distance
        self.case = 1
        self.t0: float | None = None

    def __call__(self, t: float, V: float) -> float:
        """Ω at time t [s] for the ASO volume V of that tick."""
        if self.case == 1:
            if V >= self.eps1:
                self.t0 = None
                return 1.0
            if self.t0 is None:
                self.t0 = t
            if t - self.t0 < self.duration:
                return 0.5 * (1.0 + math.cos(math.pi * (t - self.t0) / self.duration))
            self.case, self.t0 = 2, None
            return 0.0
        if V < self.eps2:
            self.t0 = None
            return 0.0
        if self.t0 is None:
            self.t0 = t
        if t - self.t0 < self.duration:
            return 0.5 * (1.0 - math.cos(math.pi * (t - self.t0) / self.duration))
        self.case, self.t0 = 1, None
        return 1.0


def spring_force(x: np.ndarray, x0: np.ndarray, u: np.ndarray, K_e: float) -> np.ndarray:
    """Eq. 6.21, F_m = K_e δX for a one-sided spring wall along u: −K_e max(0, (x − X₀)·u) u [N]."""
    return -K_e * max(0.0, float((x - x0) @ u)) * u


def force_scale(tau_m: np.ndarray, tmin: np.ndarray, tmax: np.ndarray) -> float:
    """§6.3.1: α ∈ [0, 1], the largest scale of the desired force feedback that keeps τ_m = α JᵀF in the box."""
    alpha = 1.0
    for t, lo, hi in zip(tau_m, tmin, tmax):
        if t > hi:
            alpha = min(alpha, hi / t)
        elif t < lo:
            alpha = min(alpha, lo / t)
    return alpha


def fme_torque(jacobian, mass, q, dq, tau_m, M_des, T, beta, k_d):
    """Eqs. 6.2–6.6: τ = τ_m + (I − Jᵀ J#ᵀ) τ_S with τ_S = −β ∂ν/∂q − K_d q̇ (no torque limits). (n,) [N m]."""
    J, M = jacobian(q), mass(q)
    tau_s = -beta * gradient_fd(lambda p: nu_fme(jacobian, p, M_des, T), q) - k_d * dq
    N = np.eye(len(q)) - J.T @ jsharp(J, M).T
    return tau_m + N @ tau_s


class ThesisPalpation:
    """The §6.4 palpation controller as the thesis writes it, for `rhi.sim.simulate` (step, state).

    τ_m = α Jᵀ F_m (eq. 6.21, α of §6.3.1), V from the unscaled τ_m (eq. 6.14), Ω from `omega`
    (eqs. 6.15–6.19), M_des = Ω M_Free + (1 − Ω) M_Stiff (eq. 6.16), τ = τ_m + (I − JᵀJ#ᵀ)τ_S
    (eq. 6.6), and the programmed torque limits clip each joint (the thesis says nothing else about
    the null-space torque at a limit).
    """

    class State:
        """What `simulate` logs: V, Ω, α, β (always 1: nothing scales τ_S), stop flag."""

        def __init__(self) -> None:
            self.V, self.omega, self.alpha, self.beta = 1.0, 1.0, 1.0, 1.0
            self.stopped, self.fault = False, None

    def __init__(self, dev, Mf, Ms, omega, *, x0, u, K_e=1000.0, beta=20.0, k_d=0.1, S=50.0, extra=None):
        self.device, self.Mf, self.Ms, self.omega_of = dev, Mf, Ms, omega
        self.x0, self.u, self.K_e, self.beta, self.k_d, self.S = np.asarray(x0), np.asarray(u), K_e, beta, k_d, S
        self.tmin, self.tmax = np.asarray(dev.torque_min), np.asarray(dev.torque_max)
        self.extra = extra  # optional extra null-space gradient term q -> (n,) (e.g. a limit barrier)
        self.state = ThesisPalpation.State()

    def step(self, t, q, dq, sensors=None):
        """τ (n,) [N m] at time t [s] from q, q̇ (n,)."""
        dev, s = self.device, self.state
        J = dev.jacobian(q)
        F = spring_force(dev.fk(q), self.x0, self.u, self.K_e)
        tau_m = J.T @ F
        s.V = aso(tau_m, self.tmin, self.tmax, self.S)
        s.omega = self.omega_of(t, s.V)
        s.alpha = force_scale(tau_m, self.tmin, self.tmax)
        M_des = s.omega * self.Mf + (1.0 - s.omega) * self.Ms
        tau = fme_torque(dev.jacobian, dev.mass_matrix, q, dq, s.alpha * tau_m, M_des, self.tmax, self.beta, self.k_d)
        if self.extra is not None:
            N = np.eye(dev.n) - J.T @ jsharp(J, dev.mass_matrix(q)).T
            tau = tau + N @ self.extra(q)
        return np.clip(tau, self.tmin, self.tmax)


# ------------------------------------------------------------------------------ chapter 5
def principal_axes(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Semi-axes σ_i (descending) and unit axes u_i (columns) of the ellipsoid xᵀA⁻¹x = 1, A = J Jᵀ."""
    w, V = np.linalg.eigh(A)
    order = np.argsort(w)[::-1]
    return np.sqrt(w[order]), V[:, order]


def tmi(Jm: np.ndarray, Js: np.ndarray) -> float:
    """Eqs. 4.11–4.17 with H = I: the larger of the two intersection ellipsoids' axis products."""
    Am, As = Jm @ Jm.T, Js @ Js.T
    sm, Um = principal_axes(Am)
    ss, Us = principal_axes(As)
    As_inv, Am_inv = np.linalg.inv(As), np.linalg.inv(Am)
    p1 = p2 = 1.0
    for i in range(len(sm)):
        eta1 = float(Um[:, i] @ As_inv @ Um[:, i]) ** -0.5  # eq. 4.14
        p1 *= eta1 if eta1 < sm[i] else sm[i]  # eq. 4.12
        eta2 = float(Us[:, i] @ Am_inv @ Us[:, i]) ** -0.5  # eq. 4.16
        p2 *= eta2 if eta2 < ss[i] else ss[i]  # eq. 4.15
    return max(p1, p2)  # eq. 4.17


def yoshikawa(J: np.ndarray) -> float:
    """Eq. 5.14: μ = √det(J Jᵀ)."""
    return float(np.sqrt(np.linalg.det(J @ J.T)))


def null_torque_5_9(J: np.ndarray, M: np.ndarray, tau_n: np.ndarray, dq: np.ndarray, k_d: float) -> np.ndarray:
    """Eq. 5.9's null-space part: (I − Jᵀ J#ᵀ)(τ_N − k_D q̇)."""
    return (np.eye(len(dq)) - J.T @ jsharp(J, M).T) @ (tau_n - k_d * dq)
