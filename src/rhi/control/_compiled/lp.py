"""Compiled LP optimum of the allocation: the primal active-set method warm-started at ASCM.

The compiled solver of `rhi.control.allocation.lp` (the ACTIVE_SET branch of the controller's tick,
`rhi.control._compiled.step.allocate`): a feasible start (`active_set_start`), the iteration
(`active_set`) and the torque it gives (`active_set_result`).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.control._compiled.allocation import allocate_scaling, ascm, clip
from rhi.devices._compiled.terms import add, assign, axpy, inv as _inv
from rhi.jit import jit


@jit(inline=True)
def active_set_start(a, b, P, lo, hi, r, sat):
    """A feasible start for `active_set`: ASCM, or simple scaling where the projector form cannot decide.

    Returns (τ, α, clipped) and the held joints in sat.
    """
    tau, alpha, clipped, ok = ascm(a, b, P, lo, hi, r, sat)
    if ok:
        return tau, alpha, clipped
    return allocate_scaling(a, b, lo, hi, sat)


@jit(inline=True)
def active_set(a, b, Z, lo, hi, alpha0, tau0, sat0, max_iter):
    """The primal active-set method of `rhi.control.allocation.lp` from a feasible start: (ok, α, y).

    Maximises α s.t. lo <= α a + b + Z y <= hi, 0 <= α <= 1 over x = (α |a|, y), from the
    start (α0, τ0 with the joints sat0 held); ok False when it does not settle (use the LP).
    """
    n, r = Z.shape
    k = r + 1
    sa = math.sqrt(a @ a)
    G = np.zeros((2 * n + 2, k))
    h = np.empty(2 * n + 2)
    for i in range(n):
        G[i, 0] = a[i] / sa
        G[n + i, 0] = -a[i] / sa
        for j in range(r):
            G[i, 1 + j] = Z[i, j]
            G[n + i, 1 + j] = -Z[i, j]
        h[i] = hi[i] - b[i]
        h[n + i] = b[i] - lo[i]
    G[2 * n, 0], G[2 * n + 1, 0] = 1.0, -1.0
    h[2 * n], h[2 * n + 1] = sa, 0.0
    e0 = np.zeros(k)
    e0[0] = 1.0
    x = np.empty(k)
    x[0] = alpha0 * sa
    assign(x[1:], np.ascontiguousarray(Z.T) @ (tau0 - alpha0 * a - b))
    W = np.empty(k, np.int64)
    nw = 0
    for j in range(n):
        if sat0[j]:
            W[nw] = j if tau0[j] >= 0.5 * (hi[j] + lo[j]) else n + j
            nw += 1
    if nw < k and (alpha0 >= 1.0 - 1e-12 or alpha0 <= 1e-12):  # α at its upper or its lower bound
        W[nw] = 2 * n if alpha0 >= 1.0 - 1e-12 else 2 * n + 1
        nw += 1
    gnorm = np.empty(2 * n + 2)
    for i in range(2 * n + 2):
        gnorm[i] = 1e-12 * math.sqrt(G[i] @ G[i])
    for _ in range(max_iter):
        GW = G[W[:nw]]
        GWt = np.ascontiguousarray(GW.T)
        g0 = GWt[0].copy()
        if nw < k:
            d = e0 - GWt @ (_inv(GW @ GWt) @ g0) if nw else e0.copy()
            if d @ d > 1e-20:
                Gd = G @ d
                slack = h - G @ x
                best, i_best = np.inf, -1
                for i in range(2 * n + 2):
                    if Gd[i] > gnorm[i] and not np.any(W[:nw] == i):
                        ratio = max(slack[i], 0.0) / Gd[i]
                        if ratio < best:
                            best, i_best = ratio, i
                if i_best < 0:
                    return False, 0.0, x[1:].copy()  # unbounded cannot happen with α <= 1
                x = x + best * d
                W[nw] = i_best
                nw += 1
                continue
        Ginv = _inv(GW @ GWt)
        lam = Ginv @ g0  # GWᵀ λ = e0 (GW has independent rows)
        i_min = np.argmin(lam)
        if lam[i_min] >= -1e-12:  # one refinement step onto GW x = h_W: rounding left held joints ~1e-11 N m off
            x = x + GWt @ (Ginv @ (h[W[:nw]] - GW @ x))  # (the box clip would turn that into a handle force)
            return True, x[0] / sa, x[1:].copy()
        for j in range(i_min, nw - 1):
            W[j] = W[j + 1]
        nw -= 1
    return False, 0.0, x[1:].copy()


@jit(inline=True)
def active_set_result(alpha, y, a, b, Z, lo, hi, sat):
    """τ = clip(α a + b + Z y) into the box with the joints at a limit in sat: (τ, α)."""
    alpha = min(max(alpha, 0.0), 1.0)
    tau = clip(add(axpy(alpha, a, b), Z @ y), lo, hi)
    for i in range(tau.shape[0]):
        tol = 1e-9 * (1.0 + abs(hi[i] - lo[i]))
        sat[i] = abs(tau[i] - hi[i]) <= tol or abs(tau[i] - lo[i]) <= tol
    return tau, alpha
