"""Compiled allocation within the torque box (thesis Algorithms 1 and 2, eqs. 7.5–7.16).

ASCM in projector form, simple scaling, the null-space basis of a projector, the safety room and the
tertiary scaling β (the active-set method on the LP: `rhi.control._compiled.lp`).

The projector form writes the least-norm null-space torque that puts the joints 𝒮 at r as
``P[:, 𝒮] P[𝒮, 𝒮]⁻¹ r`` with P = Z Zᵀ; it is trusted only while λ_min(P[𝒮, 𝒮]) > 1e-4
(σ_min(Z_𝒮) > 0.01, since P[𝒮, 𝒮] squares Z_𝒮's condition number), where a held torque is
accurate to ~ε r / λ < 1e-11 N m per N m; otherwise the functions say so (`ok` False) and
the caller uses the basis form (`rhi.control.allocation`, `rhi.control.saturation`).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices._compiled.terms import assign, axpy, dot, inv as _inv, inv_to, mv
from rhi.jit import jit, stack_empty

_TOL = 1e-12  # ASCM: relative overload below this is no overload
_FAST_TOL = 1e-4  # smallest eigenvalue of P[S, S] the projector form trusts (σ_min(Z_S) >= 0.01)
_RANK_FULL, _RANK_LOW = 1e-8, 1e-10  # σ_min(Z_S) of a square Z_S: surely above / below the reference's 1e-9


@jit
def any_true(mask):
    """Whether any entry of the 1-D bool array mask is True (a loop: less code to compile than np.any)."""
    for i in range(mask.shape[0]):
        if mask[i]:
            return True
    return False


@jit
def any_nonzero(x):
    """Whether any entry of the 1-D array x is not 0 (NaN counts)."""
    for i in range(x.shape[0]):
        if x[i] != 0.0:
            return True
    return False


@jit
def max_abs(x):
    """The largest |x_i| of a non-empty 1-D array (NaN if any entry is NaN, as np.max)."""
    m = abs(x[0])
    for i in range(1, x.shape[0]):
        v = abs(x[i])
        if v > m or v != v:
            m = v
    return m


@jit
def null_projector(A, P):
    """Write I − Qᵀ Q into P (n, n), Q an orthonormal basis of the rows of A (m, n), by CGS2; returns ok.

    ok False: A is rank-deficient (P unspecified).
    """
    m, n = A.shape
    Q, v = stack_empty((m, n), np.float64), stack_empty(n, np.float64)
    for i in range(m):
        assign(v, A[i])
        scale = math.sqrt(dot(v, v))
        for _ in range(2):
            for j in range(i):
                s = dot(Q[j], v)
                for c in range(n):
                    v[c] = v[c] - s * Q[j, c]
        nv = math.sqrt(dot(v, v))
        if not nv > 1e-12 * scale:
            return False
        for c in range(n):
            Q[i, c] = v[c] / nv
    for r in range(n):  # Qᵀ Q (`mm`'s arithmetic), then I − Qᵀ Q in place (loops: less code than array expressions)
        for c in range(n):
            P[r, c] = 0.0
        for j in range(m):
            a = Q[j, r]
            for c in range(n):
                P[r, c] += a * Q[j, c]
    for r in range(n):
        for c in range(n):
            P[r, c] = (1.0 if r == c else 0.0) - P[r, c]
    return True


@jit
def scaling_alpha(p, c, lo, hi, mask):
    """Largest α ∈ [0, 1] with lo <= α p + c <= hi on the entries where mask; −1 when none is feasible."""
    a_lo, a_hi = 0.0, 1.0
    for i in range(p.shape[0]):
        if not mask[i]:
            continue
        pi, ci = p[i], c[i]
        api = abs(pi)
        if api <= 1e-12 * (1.0 + api + abs(ci)):
            if ci > hi[i] + 1e-12 or ci < lo[i] - 1e-12:
                return -1.0
            continue
        r1, r2 = (lo[i] - ci) / pi, (hi[i] - ci) / pi
        if r1 > r2:
            r1, r2 = r2, r1
        if r1 > a_lo:
            a_lo = r1
        if r2 < a_hi:
            a_hi = r2
    if a_lo > a_hi + 1e-12:
        return -1.0
    return a_hi if a_hi > 0.0 else 0.0


@jit
def well_conditioned(P, S, k):
    """Whether P[S, S] (S[:k]) has its smallest eigenvalue above _FAST_TOL."""
    if k == 1:
        return P[S[0], S[0]] > _FAST_TOL
    if k == 2:
        a, b, d = P[S[0], S[0]], P[S[0], S[1]], P[S[1], S[1]]
        return 0.5 * (a + d) - math.sqrt(0.25 * (a - d) ** 2 + b * b) > _FAST_TOL
    PSS = np.empty((k, k))
    for i in range(k):
        for j in range(k):
            PSS[i, j] = 0.5 * (P[S[i], S[j]] + P[S[j], S[i]])
    return above(PSS, _FAST_TOL)


@jit
def above(G, tol):
    """Whether the symmetric G has its smallest eigenvalue above tol (G − tol I has a Cholesky factor)."""
    k = G.shape[0]
    L = np.zeros((k, k))
    for i in range(k):
        for j in range(i + 1):
            v = G[i, j] - (tol if i == j else 0.0)
            for l in range(j):
                v -= L[i, l] * L[j, l]
            if i == j:
                if not v > 0.0:
                    return False
                L[i, i] = math.sqrt(v)
            else:
                L[i, j] = v / L[j, j]
    return True


@jit(inline=True)
def blocks_all(P, S, k, r):
    """Whether the joints S[:k] (k >= r) leave no null-space torque: Z_S has full column rank r, accurately.

    Then every null-space torque changes a held joint, and the held part of any d in range(P) is d
    itself; σ_min(Z_S) > 0.01 (as `well_conditioned`) for the decision to be safe.
    """
    Z = basis(P, r)
    G = np.zeros((r, r))
    for a in range(r):
        for c in range(r):
            s = 0.0
            for i in range(k):
                s += Z[S[i], a] * Z[S[i], c]
            G[a, c] = s
    return above(G, _FAST_TOL)


@jit
def held_torque(P, S, k, r, out):
    """Least-norm null-space torque with entries r[:k] on the joints S[:k]: P[:, S] P[S, S]⁻¹ r, written into out (n,)."""
    n = P.shape[0]
    PSS, G, y = stack_empty((k, k), np.float64), stack_empty((k, k), np.float64), stack_empty(k, np.float64)
    for i in range(k):
        for j in range(k):
            PSS[i, j] = P[S[i], S[j]]
    inv_to(PSS, G)
    for i in range(k):  # `mv`'s arithmetic
        s = 0.0
        for j in range(k):
            s += G[i, j] * r[j]
        y[i] = s
    for i in range(n):
        out[i] = 0.0
        for j in range(k):
            out[i] += P[i, S[j]] * y[j]


@jit
def square_rank(Z, S, k):
    """Whether Z_𝒮 (rows S[:k] of the basis Z (n, k)), square, has full rank: 1 yes, 0 no, −1 too close to call.

    The reference's test is σ_min(Z_𝒮) > 1e-9 (`rhi.control.saturation.RANK_TOL`); from
    1/‖Z_𝒮⁻¹‖_F <= σ_min <= √k/‖Z_𝒮⁻¹‖_F this says 1 above 1e-8 and 0 below 1e-10.
    """
    G = _inv(_rows(Z, S, k))
    f = 0.0
    for i in range(k):
        for j in range(k):
            f += G[i, j] * G[i, j]
    f = math.sqrt(f)
    if 1.0 / f > _RANK_FULL:
        return 1
    if math.sqrt(k) / f < _RANK_LOW:
        return 0
    return -1


@jit
def held_torque_square(Z, S, k, r, out):
    """`held_torque` from the basis Z (n, k) when Z_𝒮 is square: Z Z_𝒮⁻¹ r, accurate to ε cond(Z_𝒮), into out (n,)."""
    assign(out, mv(Z, mv(_inv(_rows(Z, S, k)), r)))


@jit
def _rows(Z, S, k):
    """Z_𝒮: the rows S[:k] of Z, (k, Z.shape[1])."""
    out = np.empty((k, Z.shape[1]))
    for i in range(k):
        for j in range(Z.shape[1]):
            out[i, j] = Z[S[i], j]
    return out


@jit
def clip(x, lo, hi):
    """X clipped to the box [lo, hi] (NaN stays NaN); a loop, a tenth of the code NumPy's broadcasting compiles to."""
    out = np.empty(x.shape[0])
    clip_to(x, lo, hi, out)
    return out


@jit
def clip_to(x, lo, hi, out):
    """`clip` written into out (n,)."""
    for i in range(x.shape[0]):
        v = x[i]
        if v < lo[i]:
            v = lo[i]
        if v > hi[i]:
            v = hi[i]
        out[i] = v


@jit
def allocate_scaling(a, b, lo, hi, sat):
    """Simple scaling into sat (n,) bool; returns (τ, α, clipped)."""
    n = a.shape[0]
    every = stack_empty(n, np.bool_)
    every[:], sat[:] = True, False
    alpha = scaling_alpha(a, b, lo, hi, every)
    if alpha < 0.0:
        return clip(b, lo, hi), 0.0, True
    tau = clip(axpy(alpha, a, b), lo, hi)
    if alpha < 1.0:
        for i in range(n):
            sat[i] = abs(tau[i] - hi[i]) <= 1e-12 * (1.0 + abs(hi[i])) or abs(tau[i] - lo[i]) <= 1e-12 * (1.0 + abs(lo[i]))
    return tau, alpha, False


@jit
def ascm(a, b, P, lo, hi, r, sat):
    """ASCM (Algorithm 1) in projector form into sat; returns (τ, α, clipped, ok) (`ascm_into` on a new τ)."""
    tau = np.empty(a.shape[0])
    alpha, clipped, ok = ascm_into(a, b, P, lo, hi, r, sat, tau)
    return tau, alpha, clipped, ok


@jit
def ascm_into(a, b, P, lo, hi, r, sat, tau):
    """`ascm` with τ (n,) [N m] written into tau (another array than a and b): (α, clipped, ok).

    ok False: use the basis form. A held set of r joints (no redundancy left) whose P[𝒮, 𝒮] is ill-conditioned
    is decided with a basis Z of P instead (Z_𝒮 square: `square_rank`, `held_torque_square`).
    """
    n = a.shape[0]
    base = stack_empty(n, np.float64)  # a + b
    for i in range(n):
        base[i] = a[i] + b[i]
    S, S2 = stack_empty(n, np.int64), stack_empty(n, np.int64)  # held joints, sorted; the next set (swapped)
    k = np.int64(0)  # not the literal 0: one compiled version of held_torque
    held, ts, d, rr = stack_empty(n, np.bool_), stack_empty(n, np.float64), stack_empty(n, np.float64), stack_empty(n, np.float64)
    tl, Z = tau, stack_empty((n, r), np.float64)  # τ with the held joints at their limits
    assign(tl, base)
    held[:], ts[:], d[:], Z[:, :] = False, 0.0, 0.0, 0.0
    square = False  # S holds r joints: held torques from the basis Z
    for _ in range(n + 1):
        if k:
            for i in range(k):
                rr[i] = ts[S[i]] - base[S[i]]
            if square:
                held_torque_square(Z, S, k, rr, d)
            else:
                held_torque(P, S, k, rr, d)  # reads rr[:k]
            for i in range(n):
                tl[i] = base[i] + d[i]
        j, worst = -1, _TOL
        for i in range(n):
            if held[i]:
                continue
            o = max(tl[i] - hi[i], lo[i] - tl[i]) / (hi[i] - lo[i])
            if o > worst:
                j, worst = i, o
        if j < 0:
            assign(sat, held)
            return 1.0, False, True
        if k + 1 > r:
            break
        for i in range(k):
            S2[i] = S[i]
        pos = k
        while pos > 0 and S2[pos - 1] > j:
            S2[pos] = S2[pos - 1]
            pos -= 1
        S2[pos] = j
        if not well_conditioned(P, S2, k + 1):
            if k + 1 != r:
                return 1.0, False, False
            Z = basis(P, r)
            full = square_rank(Z, S2, r)
            if full < 0:
                return 1.0, False, False
            if full == 0:  # the reference's Z_𝒮 loses rank: scale with the joints held so far
                break
            square = True
        S, S2, k = S2, S, k + 1
        held[j] = True
        ts[j] = hi[j] if tl[j] > hi[j] else lo[j]
    if k:
        # τ(α) = α p + c with S held at ts: p = a − P_S P_SS⁻¹ a_S, c = b + d + (a − p)
        for i in range(k):
            rr[i] = a[S[i]]
        ha = stack_empty(n, np.float64)
        if square:
            held_torque_square(Z, S, k, rr, ha)
        else:
            held_torque(P, S, k, rr, ha)
        p, c = stack_empty(n, np.float64), stack_empty(n, np.float64)
        for i in range(n):
            p[i] = a[i] - ha[i]
            c[i] = (b[i] + d[i]) + ha[i]
        free = stack_empty(n, np.bool_)
        for i in range(n):
            free[i] = not held[i]
        alpha = scaling_alpha(p, c, lo, hi, free)
        if alpha >= 0.0:
            assign(sat, held)
            for i in range(n):  # `axpy`'s arithmetic, then the box
                tau[i] = alpha * p[i] + c[i]
            clip_to(tau, lo, hi, tau)
            return alpha, False, True
    scaled, alpha, clipped = allocate_scaling(a, b, lo, hi, sat)
    assign(tau, scaled)
    return alpha, clipped, True


@jit
def basis(P, r):
    """An orthonormal basis (n, r) of the range of the orthogonal projector P: its columns by pivoted CGS2."""
    n = P.shape[0]
    Z, R, v = np.empty((n, r)), np.empty((n, n)), np.empty(n)  # R: residual columns, stored as rows (P symmetric)
    for i in range(n):
        for j in range(n):
            R[i, j] = 0.5 * (P[i, j] + P[j, i])
    for c in range(r):  # scalar loops: no temporary vectors (an allocation and reference counts each)
        best, jb = -1.0, 0
        for j in range(n):
            s = 0.0
            for l in range(n):
                s += R[j, l] * R[j, l]
            if s > best:
                best, jb = s, j
        assign(v, R[jb])
        for _ in range(2):
            for i in range(c):
                s = 0.0
                for l in range(n):
                    s += Z[l, i] * v[l]
                for l in range(n):
                    v[l] = v[l] - s * Z[l, i]
        s = math.sqrt(dot(v, v))
        for l in range(n):
            Z[l, c] = v[l] / s
        for j in range(n):
            s = 0.0
            for l in range(n):
                s += Z[l, c] * R[j, l]
            for l in range(n):
                R[j, l] = R[j, l] - s * Z[l, c]
    return Z


@jit
def negligible(x):
    """Null-space torques below this [N m] are rounding noise of the projections."""
    return 1e-12 * (1.0 + max_abs(x))


@jit
def held_set(sat):
    """The held joints: (indices (n,) of which the first k are the True entries of sat, k)."""
    S = np.empty(sat.shape[0], np.int64)
    return S, held_into(sat, S)


@jit
def held_into(sat, S):
    """`held_set` written into S (n,) int64: returns k."""
    k = 0
    for i in range(sat.shape[0]):
        if sat[i]:
            S[k] = i
            k += 1
    return k


@jit(inline=True)
def safety_room(tau, b, delta, lo, hi, out):
    """`rhi.control.safety.safety_room` (not skipped): (τ', γ), τ' tau itself or written into out (n,)."""
    if not max_abs(delta) > negligible(delta):
        return tau, 1.0
    n = tau.shape[0]
    every, c, d = stack_empty(n, np.bool_), stack_empty(n, np.float64), stack_empty(n, np.float64)
    every[:] = True
    for i in range(n):  # c = b + δ, d = τ − b
        c[i] = b[i] + delta[i]
        d[i] = tau[i] - b[i]
    gamma = scaling_alpha(d, c, lo, hi, every)
    if gamma < 0.0:
        box = stack_empty(n, np.float64)
        clip_to(tau, lo, hi, box)
        sigma = max(scaling_alpha(delta, box, lo, hi, every), 0.0)
        for i in range(n):  # `axpy`'s arithmetic
            out[i] = sigma * delta[i] + tau[i]
        return out, 1.0
    for i in range(n):  # `axpy`'s arithmetic, into d
        d[i] = gamma * d[i] + c[i]
    clip_to(d, lo, hi, out)
    return out, gamma


@jit
def tertiary(tau, sat, P, tau_to, Ntau, lo, hi, r):
    """Algorithm 2 in projector form: (β δ, β, ok); ok False: use the basis form."""
    dl = np.empty(tau.shape[0])
    beta, ok = tertiary_to(tau, sat, P, tau_to, Ntau, lo, hi, r, dl)
    return dl, beta, ok


@jit
def tertiary_to(tau, sat, P, tau_to, Ntau, lo, hi, r, dl):
    """`tertiary` with β δ written into dl (n,), another array than Ntau (zero where β is 0): (β, ok)."""
    n = tau.shape[0]
    assign(dl, Ntau)
    S = stack_empty(n, np.int64)
    k = held_into(sat, S)
    beta, ok = 0.0, True
    if k:
        if n - k <= n - r:  # no redundancy left (Algorithm 2, line 2)
            dl[:] = 0.0
            return beta, ok
        if not well_conditioned(P, S, k):
            dl[:] = 0.0
            return beta, False
        rr = stack_empty(k, np.float64)
        for i in range(k):
            rr[i] = dl[S[i]]
        held = stack_empty(n, np.float64)
        held_torque(P, S, k, rr, held)
        for i in range(n):
            dl[i] = dl[i] - held[i]
    if max_abs(dl) <= negligible(tau_to):
        dl[:] = 0.0
        return beta, ok
    box, every = stack_empty(n, np.float64), stack_empty(n, np.bool_)
    clip_to(tau, lo, hi, box)
    every[:] = True
    beta = scaling_alpha(dl, box, lo, hi, every)
    if beta < 0.0:
        dl[:] = 0.0
        return 0.0, ok
    for i in range(n):
        dl[i] *= beta
    return beta, ok
