"""A second, independent transcription of the thesis's App. B controller (AMD, eqs. B.2–B.20; plain NumPy).

Written from the thesis text (§B.2–B.4), not from rhi's controller code: only the device model is
shared (fk, the generalized Jacobian J of eq. B.2, Table B.1's limits). J̇q̇, ∇H and ∇²H q̇ are
finite differences (rhi's controller uses analytic kernels). Readings where the text is ambiguous:

* B.8 prints "max{…}" for the upper bound; a max with A_max is never below A_max, so the bound would
  never bind: read as min (Flacco et al. [50], and Fig. B.2 shows the bound binding).
* "if the i-th joint … is over-driven … [disable it]. … repeated iteratively": one joint per
  iteration, the one with the smallest residual ratio ρ of Fig. B.4 (the SNS of [50]); a joint whose fixed
  part is already beyond the bound its λ moves away from limits the scaling from below ([50]).
* The base is enabled while σ_m < σ_m,min or while the arm alone cannot realise ẍ (rank(JS) < r or
  joints left over-driven); α and β are min(Φ, 1) of Fig. B.4.
* "The AMD method without having a tertiary objective" (§B.4.2, Fig. B.7's run without singularity
  avoidance): no σ_m test (the arm tries the task alone while it can) and no q̈_t (eq. B.19 is q̈_amd).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices.model import Device


class AMDTranscription:
    """One sample of the AMD with singularity avoidance (eqs. B.4–B.19), base stop B.20 given by the caller.

    Args:
        dev: ``rhi.device("wmm")``.
        dt: sampling time T [s].
        kp, kd, gamma1, gamma2, sigma_min: K_p, K_d, γ₁, γ₂, σ_m,min of §B.4.2 (20, 10, 5, 0.5, 0.15).
        avoidance: False: the plain AMD of §B.4.2 (no σ_m test, no tertiary objective).
    """

    def __init__(self, dev: Device, dt: float = 0.005, kp: float = 20.0, kd: float = 10.0, gamma1: float = 5.0,
                 gamma2: float = 0.5, sigma_min: float = 0.15, avoidance: bool = True) -> None:
        self.dev, self.T, self.avoidance = dev, dt, avoidance
        self.kp, self.kd, self.g1, self.g2, self.sigma_min = kp, kd, gamma1, gamma2, sigma_min
        self.V, self.A = dev.velocity_max, dev.acceleration_max
        self.nb = 3

    def accel_limits(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Eqs. B.7–B.8 (B.8's max read as min), Q_low/Q_up of §B.3.1; A_min = −A_max, V_min = −V_max."""
        T, d = self.T, self.dev
        lo, hi = np.empty(d.n), np.empty(d.n)
        for i in range(d.n):
            qmin, qmax, V, A, qi, vi = d.q_min[i], d.q_max[i], self.V[i], self.A[i], q[i], dq[i]
            q_low = qmin - abs(vi) * vi / (2 * A)
            q_up = qmax + abs(vi) * vi / (2 * -A)
            if qi > q_low:
                lo[i] = max(2 * (qmin - qi - vi * T) / T**2 if math.isfinite(qmin) else -math.inf, (-V - vi) / T, -A)
            else:
                lo[i] = A
            if qi < q_up:
                hi[i] = min(2 * (qmax - qi - vi * T) / T**2 if math.isfinite(qmax) else math.inf, (V - vi) / T, A)
            else:
                hi[i] = -A
        return lo, hi

    def drift(self, q: np.ndarray, dq: np.ndarray, h: float = 1e-6) -> np.ndarray:
        """J̇q̇ of eq. B.4, J̇ = dJ/dt along q̇ by a central difference."""
        return (self.dev.jacobian(q + h * dq) - self.dev.jacobian(q - h * dq)) @ dq / (2 * h)

    def H(self, q: np.ndarray) -> float:
        """The tertiary objective of §B.3.2: det(J_m J_mᵀ)."""
        Jm = self.dev.jacobian(q)[:, self.nb:]
        return float(np.linalg.det(Jm @ Jm.T))

    def grad_H(self, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
        """Eq. B.14 (∇_{q_m} H) by central differences of H."""
        g = np.empty(self.dev.n - self.nb)
        for i in range(g.size):
            e = np.zeros(self.dev.n)
            e[self.nb + i] = h
            g[i] = (self.H(q + e) - self.H(q - e)) / (2 * h)
        return g

    def qdd_A(self, q: np.ndarray, dq: np.ndarray, h: float = 1e-5) -> np.ndarray:
        """Eq. B.13: [0; γ₁ ∇²H q̇_m + γ₂(γ₁ ∇Hᵀ − q̇_m)], ∇²H q̇_m = d∇H/dt along q̇ (central difference)."""
        v = np.r_[np.zeros(self.nb), dq[self.nb:]]
        hv = (self.grad_H(q + h * v) - self.grad_H(q - h * v)) / (2 * h)
        return np.r_[np.zeros(self.nb), self.g1 * hv + self.g2 * (self.g1 * self.grad_H(q) - dq[self.nb:])]

    @staticmethod
    def scaling(lam: np.ndarray, xi: np.ndarray, lo: np.ndarray, hi: np.ndarray, joints) -> tuple[float, int]:
        """Fig. B.4 with the SNS of [50]: (scaling, critical joint).

        Per joint the ratios ρ of the residual to the required acceleration
        towards each bound; Φ = min of the upper ratios, the scaling min(Φ, 1). Where no scaling in [0, 1] keeps
        every joint within its bounds (Φ < 0, or a joint already beyond the bound λ moves away from needs more
        than min(Φ, 1)), the scaling is 0 with that joint as the critical one.
        """
        phi, arg, need, arg_need = math.inf, -1, -math.inf, -1
        for i in joints:
            if abs(lam[i]) < 1e-12:
                if not lo[i] - 1e-12 <= xi[i] <= hi[i] + 1e-12:
                    return 0.0, i
                continue
            r_hi, r_lo = (hi[i] - xi[i]) / lam[i], (lo[i] - xi[i]) / lam[i]
            up, down = (r_hi, r_lo) if lam[i] > 0 else (r_lo, r_hi)
            if up < phi:
                phi, arg = up, i
            if down > need:
                need, arg_need = down, i
        if phi < 0.0:
            return 0.0, arg
        s = min(phi, 1.0)
        if need > s and (need - s) * abs(lam[arg_need]) > 1e-12:
            return 0.0, arg_need
        return s, arg

    def sns(self, J, b, ddx, lo, hi, enabled: np.ndarray, fixed: np.ndarray) -> dict:
        """Eq. B.9 with the selection loop of §B.3.2: q̈ = (JS)†(αẍ − J̇q̇) + [I − (JS)†J] q̈_N."""
        n = J.shape[1]
        S = enabled.astype(float).copy()
        qN = np.where(enabled, 0.0, fixed)
        best = None
        for _ in range(n + 1):
            JS = J * S
            if np.linalg.matrix_rank(JS, tol=1e-3 * np.linalg.norm(JS, 2)) < J.shape[0]:
                break
            JSd = np.linalg.pinv(JS)
            a = JSd @ ddx  # the part α scales
            c = JSd @ (-b) + (np.eye(n) - JSd @ J) @ qN
            active = np.flatnonzero(S)
            alpha, crit = self.scaling(a, c, lo, hi, active)
            if best is None or alpha > best[0]:
                best = (alpha, a, c, S.copy())
            if alpha >= 1.0:
                return {"ddq": a + c, "alpha": 1.0, "active": S.astype(bool), "feasible": True}
            S[crit] = 0.0
            qN[crit] = hi[crit] if a[crit] + c[crit] > hi[crit] else lo[crit]
        # infeasible: where even α = 0 over-drives a joint, the command is kept within B.6's bounds
        if best is None:
            return {"ddq": np.clip(qN, lo, hi), "alpha": 0.0, "active": S.astype(bool), "feasible": False}
        alpha, a, c, S = best
        return {"ddq": np.clip(c + alpha * a, lo, hi), "alpha": alpha, "active": S.astype(bool), "feasible": False}

    def step(self, q, dq, x_d, dx_d, ddx_d, base_stop: np.ndarray) -> dict:
        """One sample. base_stop: (3,) the disabled base's acceleration (B.20), supplied by the caller."""
        J = self.dev.jacobian(q)
        x = self.dev.fk(q)
        ddx = ddx_d + self.kd * (dx_d - J @ dq) + self.kp * (x_d - x)  # §B.4.2
        b = self.drift(q, dq)
        lo, hi = self.accel_limits(q, dq)
        sigma = float(np.linalg.svd(J[:, self.nb:], compute_uv=False)[-1])
        n = self.dev.n
        res = None
        if sigma >= self.sigma_min or not self.avoidance:  # base disabled (S = diag(0, I)), the base at its stopping acceleration
            fixed = np.r_[base_stop, np.zeros(n - self.nb)]
            res = self.sns(J, b, ddx, lo, hi, np.arange(n) >= self.nb, fixed)
            if not res["feasible"]:
                res = None
        base_active = res is None
        if res is None:
            res = self.sns(J, b, ddx, lo, hi, np.ones(n, bool), np.zeros(n))
        if not self.avoidance:  # eq. B.19 without q̈_t
            return {"ddq": res["ddq"], "alpha": res["alpha"], "beta": 0.0, "base_active": base_active,
                    "sigma": sigma, "lo": lo, "hi": hi}
        # tertiary objective (B.10–B.11, B.13) with β of Fig. B.4, then B.19
        PN = np.eye(n) - np.linalg.pinv(J) @ J
        IS = np.diag((~res["active"]).astype(float))
        PA = (np.eye(n) - np.linalg.pinv(IS @ PN, rcond=1e-10)) @ PN
        lam = PA @ self.qdd_A(q, dq)
        beta, _ = self.scaling(lam, res["ddq"], lo, hi, range(n))
        return {"ddq": res["ddq"] + beta * lam, "alpha": res["alpha"], "beta": beta, "base_active": base_active,
                "sigma": sigma, "lo": lo, "hi": hi}
