"""A second, independent transcription of the thesis's App. A controller (plain NumPy, equation by equation).

Written from the thesis text (Torabiparizi 2020, §A.2–A.4), not from rhi's controller code: it
imports only the device model (forward kinematics and the generalized Jacobian of ``wmm``, its
joint limits and its Mecanum geometry data). Derivatives of the Jacobian are central finite
differences of ``Device.jacobian`` (rhi's controller uses analytic ones). Where the thesis text
allows more than one reading, the reading is an explicit argument; the default is the literal one.

Used by ``tests/test_transcription_wmm.py`` to check rhi's implementation on the same states.
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices.model import Device

PI = math.pi
#: §A.4.1: q0 = [0, 0, 0, 0, π/6, 0, π/2, 0, −π/6, 0].
Q0 = np.array([0.0, 0.0, 0.0, 0.0, PI / 6, 0.0, PI / 2, 0.0, -PI / 6, 0.0])
#: §A.4.3: W_τ = diag(1, 1, 1, 1, 2.5, 2.5, 2.5).
W_TAU = np.diag([1.0, 1.0, 1.0, 1.0, 2.5, 2.5, 2.5])


def desired_circle(x0: np.ndarray, t: float, radius: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """§A.4.2: x_d(t) = x0 + [−R(cos(πt/20) − 1), −R sin(πt/20), 0]ᵀ and its time derivative."""
    w = PI / 20
    xd = x0 + np.array([-radius * (math.cos(w * t) - 1.0), -radius * math.sin(w * t), 0.0])
    dxd = np.array([radius * w * math.sin(w * t), -radius * w * math.cos(w * t), 0.0])
    return xd, dxd


def P_matrix(theta: float, R: float, l1: float, l2: float) -> np.ndarray:
    """Eq. A.21: P(q_b) = J_I J_V (3 × 4)."""
    JI = np.array([[math.cos(theta), -math.sin(theta), 0.0], [math.sin(theta), math.cos(theta), 0.0], [0, 0, 1.0]])
    L = l1 + l2
    JV = R / 4 * np.array([[1, 1, 1, 1], [-1, 1, 1, -1], [-1 / L, 1 / L, -1 / L, 1 / L]], dtype=float)
    return JI @ JV


class Transcription:
    """App. A kinematic controller of the WMM, transcribed from eqs. A.5, A.8–A.21.

    Args:
        dev: ``rhi.device("wmm")`` (only J, fk and limits are used).
        dt: sampling time T [s] (of eq. A.13).
        jacobian: "wheel" (literal: J = [J_b P, J_m] of eq. A.5, W_x of size b + m = 11, eq. A.12) or
            "generalized" (J_q = [J_b, J_m], W_x of size n_b + m = 10; §B.2: "For a holonomic base, both
            J(q) and J_v(q) can be utilized").
        eta_from: which q̇_m enters η (eq. A.15): "arm_only" (the command with γ = 0, "the sole manipulator
            motion") or "previous" (the arm rates commanded at the previous sample).
        grad_factor: eq. A.9's factor: "exact" (−½ s^(−3/2), s = uᵀJ_mW_τᵀW_τJ_mᵀu: the derivative of
            H₂ = s^(−1/2)) or "printed" (−½ H₂^(−3/2) as printed).
        null_projector: eq. A.19's projector: "weighted" (I − J†J with the weighted J† of A.11, literal)
            or "orthogonal" (I − J_q⁺J_q of the generalized Jacobian, eq. A.7 with Q = I).
    """

    def __init__(self, dev: Device, dt: float = 0.01, *, jacobian: str = "wheel", eta_from: str = "arm_only",
                 grad_factor: str = "exact", null_projector: str = "weighted", k_x: float = 10.0,
                 epsilon: float = 0.2, u=(0.0, 0.0, 1.0), k_c: float = 0.01, k_n: float = 0.2,
                 z_limits: tuple[float, float] = (0.36, 0.56)) -> None:
        self.dev, self.dt = dev, dt
        self.jac, self.eta_from, self.grad_factor, self.null_projector = jacobian, eta_from, grad_factor, null_projector
        self.k_x, self.eps, self.k_c, self.k_n = k_x, epsilon, k_c, k_n
        self.u = np.asarray(u, dtype=float) / np.linalg.norm(u)
        self.z_limits = z_limits
        geo = dev.spec.mobile_base
        self.R, self.l1, self.l2 = geo["wheel_radius"], geo["half_length"], geo["half_width"]
        self.prev_dqm = np.zeros(dev.n - 3)

    # ------------------------------------------------------------- kinematics
    def jacobians(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(J_q (3 × 10), P (3 × 4), J used by the controller): eq. A.5 with A.21."""
        Jq = self.dev.jacobian(q)
        P = P_matrix(q[2], self.R, self.l1, self.l2)
        J = np.hstack([Jq[:, :3] @ P, Jq[:, 3:]]) if self.jac == "wheel" else Jq
        return Jq, P, J

    @property
    def nb(self) -> int:
        """Number of base inputs: b = 4 wheels or n_b = 3 generalized base coordinates."""
        return 4 if self.jac == "wheel" else 3

    def W_x(self, gamma: float) -> np.ndarray:
        """Eq. A.12: diag(γ I_b, (1 − γ) I_m)."""
        return np.diag(np.r_[np.full(self.nb, gamma), np.full(self.dev.n - 3, 1.0 - gamma)])

    @staticmethod
    def dagger(J: np.ndarray, W: np.ndarray) -> np.ndarray:
        """Eq. A.11: J† = W_x Jᵀ(J W_x Jᵀ)⁻¹.

        Where J W_x Jᵀ is singular (γ = 1: the base cannot move z) the
        inverse is read as the Moore–Penrose inverse (the thesis's formula is undefined there).
        """
        G = J @ W @ J.T
        Gi = np.linalg.inv(G) if np.linalg.cond(G) < 1e12 else np.linalg.pinv(G, rcond=1e-10)
        return W @ J.T @ Gi

    def velocity_limits(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Eq. A.13 after Flacco et al. [51] (the thesis prints no formula).

        For each arm joint Q̇_max = min{(Q_max − q)/T, V_max, √(2 A (Q_max − q))} and
        Q̇_min = max{(Q_min − q)/T, −V_max, −√(2 A (q − Q_min))}.
        """
        d = self.dev
        qm = q[3:]
        qmin, qmax = d.q_min[3:], d.q_max[3:]
        V, A = d.velocity_max[3:], d.acceleration_max[3:]
        hi = np.empty_like(qm)
        lo = np.empty_like(qm)
        for i in range(qm.size):
            up, dn = qmax[i] - qm[i], qm[i] - qmin[i]
            hi[i] = min(V[i], up / self.dt, math.sqrt(2 * A[i] * up)) if math.isfinite(up) else V[i]
            lo[i] = max(-V[i], -dn / self.dt, -math.sqrt(2 * A[i] * dn)) if math.isfinite(dn) else -V[i]
        return lo, hi

    @staticmethod
    def eta(dqm: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
        """Eq. A.15, literally: η = max_i max{|q̇_m,i|/|Q̇_max,i|, |q̇_m,i|/|Q̇_min,i|}."""
        out = 0.0
        for v, a, b in zip(dqm, lo, hi):
            for bound in (a, b):
                r = abs(v) / abs(bound) if bound != 0 else (math.inf if v != 0 else 0.0)
                out = max(out, r)
        return out

    def gamma(self, eta: float) -> float:
        """Eq. A.14."""
        if eta <= self.eps:
            return 0.0
        return eta if eta <= 1.0 else 1.0

    # ---------------------------------------------------------- DM (A.8–A.10)
    def H2(self, q: np.ndarray) -> float:
        """Eq. A.8: [uᵀ J_m W_τᵀ W_τ J_mᵀ u]^(−1/2) with J_m the arm columns (world axes)."""
        Jm = self.dev.jacobian(q)[:, 3:]
        return float((self.u @ Jm @ W_TAU.T @ W_TAU @ Jm.T @ self.u) ** -0.5)

    def grad_H2(self, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
        """Eq. A.9: ∇_{q_m,i} H₂ = factor · uᵀ ∂(J_m W_τᵀW_τ J_mᵀ)/∂q_m,i u, ∂/∂q by central differences."""
        m = self.dev.n - 3
        s = float(self.u @ self.dev.jacobian(q)[:, 3:] @ W_TAU.T @ W_TAU @ self.dev.jacobian(q)[:, 3:].T @ self.u)
        H = s ** -0.5
        factor = -0.5 * (s ** -1.5 if self.grad_factor == "exact" else H ** -1.5)
        g = np.empty(m)
        for i in range(m):
            dq = np.zeros(self.dev.n)
            dq[3 + i] = h
            Jp, Jn = self.dev.jacobian(q + dq)[:, 3:], self.dev.jacobian(q - dq)[:, 3:]
            dS = (Jp @ W_TAU.T @ W_TAU @ Jp.T - Jn @ W_TAU.T @ W_TAU @ Jn.T) / (2 * h)
            g[i] = factor * (self.u @ dS @ self.u)
        return g

    def grad_x_H2(self, q: np.ndarray) -> np.ndarray:
        """Eq. A.10: ∇_x H₂ = ∇_{q_m} H₂ J_m⁺ (J_m⁺ the Moore–Penrose pseudoinverse)."""
        return self.grad_H2(q) @ np.linalg.pinv(self.dev.jacobian(q)[:, 3:])

    # ------------------------------------------------------------- the laws
    def command(self, q: np.ndarray, t: float, x_des=None, dx_des=None, *, stage: str = "track") -> dict:
        """One sample: v (wheel speeds or base velocities; arm rates), the generalized q̇, γ, η.

        stage "track": eq. A.19 with v_n = 0 (A.16 with ẋ_d + K_x(x_d − x)); "dm_cartesian": eqs. A.17–A.18
        (only z optimised, within z_limits); "dm_null": eqs. A.19–A.20.
        """
        Jq, P, J = self.jacobians(q)
        x = self.dev.fk(q)
        nb, m = self.nb, self.dev.n - 3
        if stage == "dm_cartesian":
            xdot = np.zeros(3)
            if self.z_limits[0] <= x[2] <= self.z_limits[1]:
                xdot[2] = self.k_c * self.grad_x_H2(q)[2]  # A.18
        else:
            xdot = dx_des + self.k_x * (x_des - x)
        vn = np.r_[np.zeros(nb), self.k_n * self.grad_H2(q)] if stage == "dm_null" else None  # A.20

        def law(gamma: float) -> np.ndarray:
            Jd = self.dagger(J, self.W_x(gamma))
            v = Jd @ xdot
            if vn is not None:
                if self.null_projector == "weighted":
                    v = v + (np.eye(nb + m) - Jd @ J) @ vn  # A.19 as printed
                else:  # A.7 with Q = I on the generalized Jacobian, base part sent as generalized velocities
                    vq = np.r_[np.zeros(3), vn[nb:]]
                    vq = vq - np.linalg.pinv(Jq) @ (Jq @ vq)
                    v = v + (np.r_[np.linalg.pinv(P) @ vq[:3], vq[3:]] if nb == 4 else vq)
            return v

        lo, hi = self.velocity_limits(q)
        dqm = law(0.0)[nb:] if self.eta_from == "arm_only" else self.prev_dqm
        eta = self.eta(dqm, lo, hi)
        g = self.gamma(eta)
        v = law(g)
        dqb = P @ v[:nb] if nb == 4 else v[:nb]
        self.prev_dqm = v[nb:].copy()
        return {"v": v, "dq": np.r_[dqb, v[nb:]], "gamma": g, "eta": eta, "x": x}


def run(tr: Transcription, q0: np.ndarray, duration: float, stage_of, target, dt: float = 0.01) -> dict[str, np.ndarray]:
    """Kinematic closed loop q⁺ = q + q̇T (the robot follows the command), K = duration/T + 1 samples.

    Args:
        tr: the transcribed controller.
        q0: (10,) start configuration.
        duration: run length [s].
        stage_of: t ↦ stage.
        target: t ↦ (x_d, ẋ_d).
        dt: sampling time [s].
    """
    K = int(round(duration / dt)) + 1
    q = q0.copy()
    out: dict[str, list] = {k: [] for k in ("t", "q", "dq", "gamma", "eta")}
    for k in range(K):
        t = k * dt
        xd, dxd = target(t)
        c = tr.command(q, t, xd, dxd, stage=stage_of(t))
        for key, val in (("t", t), ("q", q.copy()), ("dq", c["dq"]), ("gamma", c["gamma"]), ("eta", c["eta"])):
            out[key].append(val)
        q = q + c["dq"] * dt
    return {k: np.asarray(v) for k, v in out.items()}


def base_stats(t: np.ndarray, dq: np.ndarray, window: str = "run") -> dict[str, np.ndarray]:
    """Table A.1's statistics of the commanded base velocity [cm/s, cm/s, °/s].

    Max |.| and RMS over the run ("run") or over the samples where the base is commanded ("moving").
    """
    v = dq[:, :3] * np.array([100.0, 100.0, 180.0 / PI])
    moving = np.any(np.abs(dq[:, :3]) > 1e-9, axis=1)
    sel = moving if window == "moving" else np.ones(len(t), bool)
    dt = float(t[1] - t[0])
    return {"max": np.abs(v).max(axis=0), "rms": np.sqrt(np.mean(v[sel] ** 2, axis=0)),
            "first": float(t[moving][0]) if moving.any() else math.nan,
            "last": float(t[moving][-1]) if moving.any() else math.nan, "duration": float(moving.sum() * dt)}
