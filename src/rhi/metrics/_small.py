"""Compiled kernels for batches of small matrices (private; the spatial maps' hot path).

NumPy's batched ``svd``, ``cholesky`` and ``solve`` call LAPACK once per matrix (a few µs
each), which made them most of the time of a batch of measures on a spatial arm. Here one
compiled loop walks the batch:

* `svd_rows`: singular values and left singular vectors of (m, n) maps, m <= n: Gram–Schmidt
  with one re-orthogonalisation reduces ``B = L E`` (L lower triangular m×m, E orthonormal
  rows), then one-sided (Hestenes) Jacobi rotates pairs of rows of L until they are
  orthogonal, so that ``B = U (Σ Vᵀ)`` with the final row norms as ``Σ`` and the accumulated
  rotations as ``U``. The values agree with LAPACK's to round-off (within ~1e-16·σ₁); the
  directions agree up to the sign of each column and are as well determined as the gaps
  between the values.
* `whiten`: ``B = J L⁻ᵀ`` with the Cholesky factor ``M = L Lᵀ`` (the factor by the same
  column order as LAPACK's ``potrf``, the solve by forward substitution), and a flag per
  matrix that is not symmetric or not positive definite (a pivot <= 0, as ``potrf`` reports);
  `inertia_along` the same factor and one solve, of Jᵀu, for Λ along u (the cost of m rows only in Jᵀu).
* `radius_rows`: ρ along u and μ from the triangle L of ``B = L E`` alone (a triangular solve and a
  product of pivots instead of the Jacobi sweeps), for the clearly regular maps; the caller takes
  `svd_rows` for the few others, whose lost axes need the singular vectors.
* `gram3_rows`: the same ρ and μ of three-row maps in closed form (the 3×3 Gram by cofactors), for the well
  conditioned ones; the caller takes `radius_rows` for the others.

Numba is imported with this module, on the first large batch, not with ``import rhi.metrics``.
"""

from __future__ import annotations

import numpy as np

from rhi.jit import jit

#: Jacobi stops when every pair of rows has |cos angle| at most this times m (the round-off of their dot product).
_ORTHO_TOL = 2.0**-52
#: Jacobi sweeps at most (3-row maps converge in 3 to 5).
_MAX_SWEEPS = 40
#: Matrices per block: the block's work arrays stay in the L1 cache and each step is a SIMD loop over the block.
BLOCK = 32
_TINY = np.finfo(np.float64).tiny


@jit
def _lower(B, i0, nb, scale, E, L, d):
    """B[i0 + b] · scale[b] = L[:, :, b] E[:, :, b] for the block's b < nb, by Gram–Schmidt.

    L (m, m, K) lower triangular with L_rr >= 0, E (m, n, K) orthonormal rows (zero where B loses rank),
    scale[b] = 1 / max |B[i0 + b]| (1 for a zero B). One re-orthogonalisation; the rows are scaled first (no
    overflow or underflow in the squares). d (K,) is work.
    """
    m, n = B.shape[1], B.shape[2]
    for b in range(nb):
        scale[b] = 0.0
    for r in range(m):
        for c in range(n):
            for b in range(nb):
                scale[b] = max(scale[b], abs(B[i0 + b, r, c]))
    for b in range(nb):
        scale[b] = 1.0 / scale[b] if scale[b] > 0.0 else 1.0
    for r in range(m):
        for c in range(n):
            for b in range(nb):
                E[r, c, b] = B[i0 + b, r, c] * scale[b]
        for k in range(m):
            for b in range(nb):
                L[r, k, b] = 0.0
        for _ in range(2):
            for k in range(r):
                for b in range(nb):
                    d[b] = 0.0
                for c in range(n):
                    for b in range(nb):
                        d[b] += E[r, c, b] * E[k, c, b]
                for c in range(n):
                    for b in range(nb):
                        E[r, c, b] -= d[b] * E[k, c, b]
                for b in range(nb):
                    L[r, k, b] += d[b]
        for b in range(nb):
            d[b] = 0.0
        for c in range(n):
            for b in range(nb):
                d[b] += E[r, c, b] * E[r, c, b]
        for b in range(nb):
            d[b] = np.sqrt(d[b])
            L[r, r, b] = d[b]
            d[b] = 1.0 / d[b] if d[b] > 0.0 else 0.0
        for c in range(n):
            for b in range(nb):
                E[r, c, b] *= d[b]


@jit
def svd_rows(B, want_u, s, U):
    """Singular values s (K, m), descending, and, if want_u, left singular vectors U (K, m, m) of B (K, m, n), m <= n.

    B must be finite and is not modified; column k of U[i] is the direction of s[i, k].
    """
    K, m, n = B.shape
    nb_max = BLOCK
    E = np.empty((m, n, nb_max))  # orthonormal rows: B / scale = L E (batch index last: SIMD over the block)
    L = np.empty((m, m, nb_max))
    W = np.empty((m, m, nb_max))
    scale = np.empty(nb_max)
    d = np.empty(nb_max)
    xx = np.empty(nb_max)
    yy = np.empty(nb_max)
    gg = np.empty(nb_max)
    cs = np.empty(nb_max)
    sn = np.empty(nb_max)
    nrm = np.empty(m)
    order = np.empty(m, dtype=np.int64)
    tol = _ORTHO_TOL * m
    for i0 in range(0, K, nb_max):
        nb = min(nb_max, K - i0)
        _lower(B, i0, nb, scale, E, L, d)
        for r in range(m):
            for k in range(m):
                for b in range(nb):
                    W[r, k, b] = 1.0 if r == k else 0.0
        for _ in range(_MAX_SWEEPS):  # one-sided Jacobi on the rows of L; converged pairs rotate by 0
            rotated = 0
            for p in range(m - 1):
                for q in range(p + 1, m):
                    for b in range(nb):
                        xx[b] = yy[b] = gg[b] = 0.0
                    for c in range(m):
                        for b in range(nb):
                            xx[b] += L[p, c, b] * L[p, c, b]
                            yy[b] += L[q, c, b] * L[q, c, b]
                            gg[b] += L[p, c, b] * L[q, c, b]
                    for b in range(nb):
                        g = gg[b]
                        done = abs(g) <= tol * np.sqrt(xx[b] * yy[b])
                        rotated += 0 if done else 1
                        zeta = (yy[b] - xx[b]) / (2.0 * (1.0 if done else g))
                        t = 1.0 / (abs(zeta) + np.sqrt(1.0 + zeta * zeta))
                        t = 0.0 if done else (-t if zeta < 0.0 else t)
                        cs[b] = 1.0 / np.sqrt(1.0 + t * t)
                        sn[b] = cs[b] * t
                    for c in range(m):
                        for b in range(nb):
                            lp, lq = L[p, c, b], L[q, c, b]
                            L[p, c, b] = cs[b] * lp - sn[b] * lq
                            L[q, c, b] = sn[b] * lp + cs[b] * lq
                        if want_u:
                            for b in range(nb):
                                wp, wq = W[c, p, b], W[c, q, b]
                                W[c, p, b] = cs[b] * wp - sn[b] * wq
                                W[c, q, b] = sn[b] * wp + cs[b] * wq
            if rotated == 0:
                break
        for b in range(nb):
            for r in range(m):
                x = 0.0
                for c in range(m):
                    x += L[r, c, b] * L[r, c, b]
                nrm[r] = np.sqrt(x)
                order[r] = r
            for r in range(1, m):  # insertion sort, descending
                k = r
                while k > 0 and nrm[order[k - 1]] < nrm[order[k]]:
                    order[k - 1], order[k] = order[k], order[k - 1]
                    k -= 1
            for k in range(m):
                s[i0 + b, k] = nrm[order[k]] / scale[b]
                if want_u:
                    for r in range(m):
                        U[i0 + b, r, k] = W[r, order[k], b]


@jit
def radius_rows(B, u, cond_max, rho, mu, hard):
    """ρ = (uᵀ(BBᵀ)⁻¹u)^(-1/2) and μ = √det(BBᵀ) of B (K, m, n), m <= n, from B = L E without an SVD.

    With B·scale = L E (`_lower`): ρ = 1 / (scale |L⁻¹u|) and μ = Π L_rr / scale^m. u (K, m) unit directions,
    or (0, m): ρ not computed. hard (K,) int8 is 1 where L is not clearly regular (‖L‖_F ‖L⁻¹‖_F > cond_max or a
    zero pivot): ρ and μ are then unspecified and the caller takes the SVD, which knows the lost axes.
    """
    K, m, n = B.shape
    E = np.empty((m, n, BLOCK))
    L = np.empty((m, m, BLOCK))
    scale = np.empty(BLOCK)
    d = np.empty(BLOCK)
    Li = np.empty((m, m))
    want_rho = u.shape[0] > 0
    for i0 in range(0, K, BLOCK):
        nb = min(BLOCK, K - i0)
        _lower(B, i0, nb, scale, E, L, d)
        for b in range(nb):
            i = i0 + b
            det, big, small = 1.0, 0.0, 0.0
            for r in range(m):
                det *= L[r, r, b]
                for c in range(r + 1):
                    big += L[r, c, b] * L[r, c, b]
            hard[i] = 0 if det > 0.0 else 1
            if hard[i]:
                continue
            for c in range(m):  # columns of L⁻¹ by forward substitution
                for r in range(m):
                    e = 1.0 if r == c else 0.0
                    for k in range(c, r):
                        e -= L[r, k, b] * Li[k, c]
                    Li[r, c] = e / L[r, r, b] if r >= c else 0.0
                    small += Li[r, c] * Li[r, c]
            if big * small > cond_max * cond_max:
                hard[i] = 1
                continue
            mu[i] = det / scale[b] ** m
            if want_rho:
                q = 0.0
                for r in range(m):
                    e = 0.0
                    for c in range(r + 1):
                        e += Li[r, c] * u[i, c]
                    q += e * e
                rho[i] = 1.0 / (scale[b] * np.sqrt(q))


@jit
def _cholesky(M, i, sym_rtol, L):
    """L (n, n) lower with M[i] = L Lᵀ (the factor of the symmetric part ½(M + Mᵀ)), and a flag.

    Returns 1 where M[i] is not symmetric to ``sym_rtol`` relative to its largest entry, 2 where it is not
    positive definite (a pivot <= 0), else 0.
    """
    n = M.shape[1]
    asym = big = 0.0
    for r in range(n):
        for c in range(n):
            asym = max(asym, abs(M[i, r, c] - M[i, c, r]))
            big = max(big, abs(M[i, r, c]))
    if asym > sym_rtol * max(big, _TINY):
        return 1
    for j in range(n):  # Cholesky–Crout, column by column
        d = M[i, j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return 2
        ljj = np.sqrt(d)
        L[j, j] = ljj
        for r in range(j + 1, n):
            e = 0.5 * (M[i, r, j] + M[i, j, r])
            for k in range(j):
                e -= L[r, k] * L[j, k]
            L[r, j] = e / ljj
    return 0


@jit
def whiten(J, M, sym_rtol, B, bad):
    """B (K, m, n) = J L⁻ᵀ with M = L Lᵀ for J (K, m, n), M (K, n, n) symmetric positive definite.

    The factor is that of the symmetric part ½(M + Mᵀ). bad (K,) int8 is 1 where M is not symmetric to
    ``sym_rtol`` relative to its largest entry, 2 where it is not positive definite (B then unspecified), else 0.
    """
    K, m, n = J.shape
    L = np.empty((n, n))
    for i in range(K):
        bad[i] = _cholesky(M, i, sym_rtol, L)
        if bad[i]:
            continue
        for r in range(m):  # row r of B solves L bᵀ = J[r]ᵀ
            for j in range(n):
                e = J[i, r, j]
                for k in range(j):
                    e -= L[j, k] * B[i, r, k]
                B[i, r, j] = e / L[j, j]


@jit
def inertia_along(J, M, u, sym_rtol, zero_rtol, lam, bad):
    """Λ (K,) = (uᵀ J M⁻¹ Jᵀ u)⁻¹ for J (K, m, n), M (K, n, n) symmetric positive definite, u (K, m) unit.

    With M = L Lᵀ (the factor of ½(M + Mᵀ), as `whiten`): Λ = 1 / |y|², y = L⁻¹(Jᵀu), one triangular solve
    whatever m; inf where |y| <= zero_rtol ‖B‖_F, B = J L⁻ᵀ. The bound ‖B‖_F² <= ‖J‖_F² / λ_min(M) <= ‖J‖_F²
    t^(n-1) / det M, t = tr M / (n - 1) (AM–GM on the other n - 1 eigenvalues), settles that test for all
    but the near-singular maps, which alone solve for B row by row. bad (K,) int8 as `whiten` (Λ then
    unspecified). Blocks of `BLOCK` matrices, batch index last.
    """
    K, m, n = J.shape
    Mt = np.empty((n, n, BLOCK))
    L = np.empty((n, n, BLOCK))
    y = np.empty((n, BLOCK))
    rd = np.empty((n, BLOCK))  # 1 / L_jj
    e = np.empty(BLOCK)
    jj = np.empty(BLOCK)
    tr = np.empty(BLOCK)
    asym = np.empty(BLOCK)
    big = np.empty(BLOCK)
    row = np.empty(n)
    for i0 in range(0, K, BLOCK):
        nb = min(BLOCK, K - i0)
        for b in range(nb):
            asym[b] = big[b] = tr[b] = 0.0
        for r in range(n):
            for c in range(n):
                for b in range(nb):
                    Mt[r, c, b] = M[i0 + b, r, c]
        for r in range(n):
            for c in range(n):
                for b in range(nb):
                    asym[b] = max(asym[b], abs(Mt[r, c, b] - Mt[c, r, b]))
                    big[b] = max(big[b], abs(Mt[r, c, b]))
        for b in range(nb):
            bad[i0 + b] = 1 if asym[b] > sym_rtol * max(big[b], _TINY) else 0
        for b in range(nb):  # y = Jᵀu, ‖J‖_F² (J read in memory order: m enters the cost only here)
            s = 0.0
            for j in range(n):
                w = 0.0
                for r in range(m):
                    x = J[i0 + b, r, j]
                    w += u[i0 + b, r] * x
                    s += x * x
                y[j, b] = w
            jj[b] = s
        for j in range(n):  # Cholesky–Crout, column by column; a failed pivot is flagged and replaced by 1
            for b in range(nb):
                e[b] = Mt[j, j, b]
                tr[b] += Mt[j, j, b]
            for k in range(j):
                for b in range(nb):
                    e[b] -= L[j, k, b] * L[j, k, b]
            for b in range(nb):
                if not e[b] > 0.0:
                    bad[i0 + b] = 2 if bad[i0 + b] == 0 else bad[i0 + b]
                    e[b] = 1.0
                L[j, j, b] = np.sqrt(e[b])
                rd[j, b] = 1.0 / L[j, j, b]
            for r in range(j + 1, n):
                for b in range(nb):
                    e[b] = 0.5 * (Mt[r, j, b] + Mt[j, r, b])
                for k in range(j):
                    for b in range(nb):
                        e[b] -= L[r, k, b] * L[j, k, b]
                for b in range(nb):
                    L[r, j, b] = e[b] * rd[j, b]
        for b in range(nb):  # e = t^(n-1) / det M >= 1 / λ_min(M), as (1/t) Π_j t / L_jj²
            e[b] = (n - 1) / tr[b] if n > 1 else 1.0
        for j in range(n):
            for k in range(j):  # y = L⁻¹ y by forward substitution
                for b in range(nb):
                    y[j, b] -= L[j, k, b] * y[k, b]
            for b in range(nb):
                y[j, b] *= rd[j, b]
                e[b] *= (tr[b] / (n - 1) if n > 1 else 1.0) * rd[j, b] * rd[j, b]
        for b in range(nb):
            q = 0.0
            for j in range(n):
                q += y[j, b] * y[j, b]
            lam[i0 + b] = 1.0 / q
            if q > zero_rtol * zero_rtol * jj[b] * e[b]:  # > zero_rtol² ‖B‖_F²: finite
                continue
            fro = 0.0  # near Jᵀu = 0: ‖B‖_F² exactly, row r of B solving L bᵀ = J[r]ᵀ
            for r in range(m):
                for j in range(n):
                    x = J[i0 + b, r, j]
                    for k in range(j):
                        x -= L[j, k, b] * row[k]
                    row[j] = x * rd[j, b]
                    fro += row[j] * row[j]
            if q <= zero_rtol * zero_rtol * fro:
                lam[i0 + b] = np.inf


@jit
def gram3_rows(B, u, cond_max, rho, mu, hard):
    """ρ and μ as `radius_rows` for three-row maps B (K, 3, n) in closed form, from the Gram G = BBᵀ by cofactors.

    With scale = 1 / max |B| and G of B·scale: μ = √det G / scale³, ρ = √(det G / uᵀ adj(G) u) / scale. Forming G
    squares the condition number, so hard (K,) int8 is 1 where ‖G‖_F ‖G⁻¹‖_F > cond_max (or det G <= 0): ρ and μ
    are then unspecified and the caller takes `radius_rows`. u (K, 3) unit directions, or (0, 3): ρ not computed.
    Blocks of `BLOCK` maps, batch index last (SIMD over the block).
    """
    K, _, n = B.shape
    want_rho = u.shape[0] > 0
    G = np.empty((6, BLOCK))  # g00 g01 g02 g11 g12 g22
    sc = np.empty(BLOCK)
    for i0 in range(0, K, BLOCK):
        nb = min(BLOCK, K - i0)
        for b in range(nb):
            sc[b] = 0.0
        for r in range(3):
            for c in range(n):
                for b in range(nb):
                    sc[b] = max(sc[b], abs(B[i0 + b, r, c]))
        for b in range(nb):
            sc[b] = 1.0 / sc[b] if sc[b] > 0.0 else 1.0
        for k in range(6):
            for b in range(nb):
                G[k, b] = 0.0
        for c in range(n):
            for b in range(nb):
                x, y, z = B[i0 + b, 0, c] * sc[b], B[i0 + b, 1, c] * sc[b], B[i0 + b, 2, c] * sc[b]
                G[0, b] += x * x
                G[1, b] += x * y
                G[2, b] += x * z
                G[3, b] += y * y
                G[4, b] += y * z
                G[5, b] += z * z
        for b in range(nb):
            g00, g01, g02, g11, g12, g22 = G[0, b], G[1, b], G[2, b], G[3, b], G[4, b], G[5, b]
            a00, a01, a02 = g11 * g22 - g12 * g12, g02 * g12 - g01 * g22, g01 * g12 - g02 * g11  # adj(G), symmetric
            a11, a12, a22 = g00 * g22 - g02 * g02, g01 * g02 - g00 * g12, g00 * g11 - g01 * g01
            det = g00 * a00 + g01 * a01 + g02 * a02
            big = g00 * g00 + g11 * g11 + g22 * g22 + 2.0 * (g01 * g01 + g02 * g02 + g12 * g12)
            small = a00 * a00 + a11 * a11 + a22 * a22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)
            ok = det > 0.0 and big * small <= (cond_max * det) ** 2
            hard[i0 + b] = 0 if ok else 1
            d = det if ok else 1.0
            s = sc[b]
            mu[i0 + b] = np.sqrt(d) / (s * s * s)
            if want_rho:
                x, y, z = u[i0 + b, 0], u[i0 + b, 1], u[i0 + b, 2]
                q = a00 * x * x + a11 * y * y + a22 * z * z + 2.0 * (a01 * x * y + a02 * x * z + a12 * y * z)
                rho[i0 + b] = np.sqrt(d / (q if ok else 1.0)) / s
