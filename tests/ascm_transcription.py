"""A second, independent transcription of the thesis's Algorithm 1 (ASCM, §7.3, eqs. 7.5–7.9) (issue 23).

Plain NumPy, one line of the algorithm per line, written from the thesis text alone; it imports
nothing of rhi. Tests (tests/test_transcription_ch7.py) compare it with rhi's
`rhi.control.allocation.ascm` on the same inputs.

Algorithm 1 as printed (line numbers in the comments):

    1:  S = 0, α = 1, τ_s = 0, limit = 1
    2:  while limit = 1
    3:    limit = 0
    4:    τ_N = (I − S Jᵀ J#ᵀ S)^# (τ_s − (J S)ᵀ F̃_m)
    5:    τ = Jᵀ F̃ + (I − Jᵀ J#ᵀ) τ_N
    6–9:  if a joint is outside its bounds: limit = 1, k = the most overloaded joint
    10:   S̃ = S, τ̃_s = τ_s, S_kk = 1
    11–15: τ_s,k = T_max,k or T_min,k
    16:   if rank(J (I − S)) < m
    17:     S = S̃, τ_s = τ̃_s
    18:     N_0 = (I − Jᵀ J#ᵀ)(I − S Jᵀ J#ᵀ S)^#
    19:     N_1 = (−Jᵀ + N_0 (J S)ᵀ) F_e
    20:     N_2 = N_0 τ_s + (Jᵀ − N_0 (J S)ᵀ) μ
    21:     α = (T_max(min),k − N_2,k) / N_1,k
    22–23:  τ_N and τ as lines 4–5 with F̃_m = −α F_e + μ
    24:     break

with F̃_m = −α F_e + μ (eq. 7.9) and J# = M⁻¹Jᵀ(JM⁻¹Jᵀ)⁻¹ (§7.2). Lines 10–25 run only when line 8
found a joint k (otherwise k is undefined and `limit` = 0 ends the loop). The outer ``^#`` of the
n × n matrix (I − S Jᵀ J#ᵀ S) is its inverse where it is invertible (any generalized inverse of an
invertible matrix is its inverse); the pseudoinverse is used, which is the same there.

Readings the text leaves open, each an argument: the projector ("J#": §7.2's J#, the text's; "J+": the
plain pseudoinverse), and what "the most overloaded joint" measures ("absolute": the excess over the
limit [N m]; "relative": the excess over the limit divided by the limit's span).
"""

from __future__ import annotations

import numpy as np


def generalized_inverse(J: np.ndarray, M: np.ndarray | None) -> np.ndarray:
    """§7.2: J# = M⁻¹Jᵀ[JM⁻¹Jᵀ]⁻¹ (n, m); M None: the pseudoinverse Jᵀ(JJᵀ)⁻¹."""
    Mi = np.eye(J.shape[1]) if M is None else np.linalg.inv(M)
    return Mi @ J.T @ np.linalg.inv(J @ Mi @ J.T)


def algorithm1(J, M, F_e, mu, tmin, tmax, *, overload: str = "absolute"):
    """Algorithm 1 line by line. Returns (τ (n,), α, S (n,) bool).

    Args:
        J: (m, n) Jacobian.
        M: (n, n) inertia for J#, or None for J⁺.
        F_e: (m,) environment wrench; the rendered force is −α F_e + μ (eq. 7.9).
        mu: (m,) the unscaled part μ of eq. 7.9.
        tmin: (n,) lower torque bounds.
        tmax: (n,) upper torque bounds.
        overload: "absolute" or "relative" (see the module docstring).
    """
    m, n = J.shape
    I = np.eye(n)
    Jsh = generalized_inverse(J, M)
    JJ = J.T @ Jsh.T                                    # Jᵀ J#ᵀ
    S = np.zeros((n, n))                                 # line 1
    alpha = 1.0
    ts = np.zeros(n)
    limit = 1
    tau = np.zeros(n)
    while limit == 1:                                    # line 2
        limit = 0                                        # line 3
        Fm = -alpha * F_e + mu
        tauN = np.linalg.pinv(I - S @ JJ @ S) @ (ts - (J @ S).T @ Fm)   # line 4
        tau = J.T @ Fm + (I - JJ) @ tauN                 # line 5
        excess = np.maximum(tau - tmax, tmin - tau)      # line 6
        if not np.any(excess > 1e-12):
            break
        limit = 1                                        # line 7
        if overload == "relative":
            excess = excess / (tmax - tmin)
        excess[np.diag(S) > 0] = -np.inf
        k = int(np.argmax(excess))                       # line 8
        S_old, ts_old = S.copy(), ts.copy()              # line 10
        S[k, k] = 1.0
        ts[k] = tmax[k] if tau[k] > tmax[k] else tmin[k]  # lines 11–15
        if np.linalg.matrix_rank(J @ (I - S)) < m:       # line 16
            S, ts = S_old, ts_old                        # line 17
            N0 = (I - JJ) @ np.linalg.pinv(I - S @ JJ @ S)                # line 18
            N1 = (-J.T + N0 @ (J @ S).T) @ F_e           # line 19
            N2 = N0 @ ts + (J.T - N0 @ (J @ S).T) @ mu   # line 20
            bound = tmax[k] if tau[k] > tmax[k] else tmin[k]
            alpha = (bound - N2[k]) / N1[k]              # line 21
            Fm = -alpha * F_e + mu
            tauN = np.linalg.pinv(I - S @ JJ @ S) @ (ts - (J @ S).T @ Fm)  # line 22
            tau = J.T @ Fm + (I - JJ) @ tauN             # line 23
            break                                        # line 24
    return tau, float(alpha), np.diag(S) > 0


def capability(J, M, u, tmin, tmax, *, forces, overload: str = "absolute"):
    """Largest force along u Algorithm 1 renders over a ramp of requests f u, f in `forces` [N].

    The request is F̃_m = f u (F_e = −f u, μ = 0); a request counts when Algorithm 1's τ is within the
    bounds (1e-9 N m); its force is α f. Returns (peak force [N], the request f that gave it [N]).
    """
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    best, at = 0.0, float("nan")
    for f in forces:
        tau, alpha, _ = algorithm1(J, M, -f * u, np.zeros(len(u)), tmin, tmax, overload=overload)
        if np.all(tau <= tmax + 1e-9) and np.all(tau >= tmin - 1e-9) and 0.0 <= alpha <= 1.0 + 1e-12:
            if alpha * f > best:
                best, at = alpha * f, float(f)
    return best, at


def scaling_capability(J, u, tmin, tmax) -> float:
    """Simple scaling (no ASCM): the largest f with Jᵀ f u within the bounds [N]."""
    t = J.T @ (np.asarray(u, dtype=float) / np.linalg.norm(u))
    lim = np.where(t > 0, tmax / np.where(t > 0, t, 1.0), np.where(t < 0, tmin / np.where(t < 0, t, -1.0), np.inf))
    return float(np.min(lim))
