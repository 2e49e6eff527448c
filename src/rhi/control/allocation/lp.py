"""The LP optimum (``saturation="lp"``): the largest α over every null-space torque, and its two solvers.

The allocation problem of thesis §7.3 as a linear program in the (1 + r) variables x = (α, y):

    max α   s.t.   lo <= α a + b + Z y <= hi,   0 <= α <= 1.                     (LP)

ASCM (Algorithm 1, `rhi.control.allocation.compensation`) holds the most overloaded joint at its limit,
then the next, and never lets a held joint go: a greedy path to a vertex of (LP) that need not be the
optimum (the optimum may put a joint at its *opposite* limit, or leave it inside the box). This strategy
is the optimum. One computation, two solvers (`LPOptimum.solver`):

- ``"highs"`` (`allocate_lp`): HiGHS through scipy's `linprog`, the independent reference.
- ``"active_set"`` (`allocate_active_set`): a primal active-set method warm-started at ASCM. With the
  working set W of active constraints it moves along the projection of the objective onto the null space
  of W until a constraint blocks (ratio test), and at a vertex it drops the constraint of W with the most
  negative Lagrange multiplier (a held joint released; a joint at one limit that the ratio test then stops
  at the other is flipped). It ends where every multiplier is >= 0, at a per-tick cost of a few small solves.

The compiled tick always runs the active set (its ACTIVE_SET branch, `rhi.control._compiled.lp`);
the solver chooses what runs in Python: ``implementation="reference"`` and the ticks the compiled tick
hands back. With ``"active_set"`` the reference is the compiled branch's oracle (same torques). Where the
optimal face is more than a point (α* = 1 reached with room to spare, or a degenerate vertex), the two
solvers return different null-space torques of it; both keep α*, the handle force (J#ᵀ τ = J#ᵀ(α* a + b))
and the box, and the tests compare those, not the vertex (HiGHS's choice of vertex is its own).

``saturation="active_set"`` (the name of the active-set solver when it was a strategy of its own) is an
alias: ``LPOptimum(solver="active_set")``, so configurations that name it run as before.
"""

from __future__ import annotations

import dataclasses
from typing import Literal, get_args

import numpy as np
from scipy.optimize import linprog

from rhi.control import _compiled as kernels
from rhi.control.allocation.base import Allocation, register
from rhi.control.allocation.scaling import allocate_scaling
from rhi.control.saturation import check_allocation
from rhi.errors import InvalidInput

#: The solvers of the LP optimum.
Solver = Literal["highs", "active_set"]


def allocate_lp(a, b, Z, *, torque_min, torque_max) -> Allocation:
    """The LP optimum by HiGHS: the largest α <= 1 over every null-space torque.

    Solves (LP): ``max α`` s.t. ``torque_min <= α a + b + Z y <= torque_max``, ``0 <= α <= 1``. For
    ``b = 0`` and a request at or above the capability, ``α |F|`` equals the optimum of
    `rhi.metrics.max_force`. Falls back to simple scaling if the LP fails.
    """
    a, b, Z, lo, hi = check_allocation(a, b, Z, torque_min=torque_min, torque_max=torque_max, basis=True)
    n, r = Z.shape
    tau0 = a + b
    if np.all(tau0 <= hi) and np.all(tau0 >= lo):
        return Allocation(tau0, 1.0, np.zeros(n, bool), np.zeros(n), "lp")
    A = np.concatenate([a[:, None], Z], axis=1)
    c = np.zeros(r + 1)
    c[0] = -1.0
    res = linprog(
        c,
        A_ub=np.concatenate([A, -A]),
        b_ub=np.concatenate([hi - b, b - lo]),
        bounds=[(0.0, 1.0)] + [(None, None)] * r,
        method="highs",
    )
    if res.status != 0:
        return dataclasses.replace(allocate_scaling(a, b, torque_min=lo, torque_max=hi), method="lp")
    alpha = float(res.x[0])
    d = Z @ res.x[1:]
    tau = np.clip(alpha * a + b + d, lo, hi)
    sat = (np.abs(tau - hi) <= 1e-9) | (np.abs(tau - lo) <= 1e-9)
    return Allocation(tau, alpha, sat, d, "lp")


def allocate_active_set(a, b, Z, *, torque_min, torque_max, start: Allocation | None = None, max_iter: int = 50) -> Allocation:
    """The LP optimum by a primal active-set method warm-started at ASCM (the compiled tick's method).

    Same problem and optimum α* as `allocate_lp`. Falls back to `allocate_lp` if ASCM's start is not
    feasible (b itself outside the box) or the iteration does not settle within `max_iter` steps
    (degenerate cycling). The iteration is the compiled `rhi.control._compiled.lp.active_set`.

    Args:
        a: (n,) torque of the rendered force, Jᵀ F_render [N m] (scaled by α).
        b: (n,) unscaled torque [N m].
        Z: (n, r) orthonormal basis of the null-space torques (`null_basis`, either projector).
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        start: a feasible allocation to start from (default: ASCM in projector form on P = Z Zᵀ, or
            simple scaling where that form cannot decide; `rhi.control._compiled.lp.active_set_start`).
        max_iter: iteration limit.

    Returns:
        Allocation with method "lp"; ``saturated`` marks the joints at a limit, and
        ``J#ᵀ τ = J#ᵀ(α a + b)`` (or J⁺ᵀ with the pseudoinverse basis).
    """
    a, b, Z, lo, hi = (np.ascontiguousarray(v) for v in check_allocation(a, b, Z, torque_min=torque_min,
                                                                          torque_max=torque_max, basis=True))
    n, r = Z.shape
    tau0 = a + b
    if np.all(tau0 <= hi) and np.all(tau0 >= lo):
        return Allocation(tau0, 1.0, np.zeros(n, bool), np.zeros(n), "lp")
    if start is None:
        sat = np.zeros(n, bool)
        tau, alpha, clipped = kernels.active_set_start(a, b, Z @ Z.T, lo, hi, r, sat)
        start = Allocation(tau, alpha, sat, tau - alpha * a - b, "ascm", clipped)
    if start.clipped or not a.any():
        return allocate_lp(a, b, Z, torque_min=lo, torque_max=hi)
    ok, alpha, y = kernels.active_set(a, b, Z, lo, hi, float(start.alpha), np.ascontiguousarray(start.tau, dtype=float),
                                      np.ascontiguousarray(start.saturated, dtype=bool), max_iter)
    if not ok:
        return allocate_lp(a, b, Z, torque_min=lo, torque_max=hi)
    sat = np.zeros(n, bool)
    tau, alpha = kernels.active_set_result(alpha, y, a, b, Z, lo, hi, sat)
    return Allocation(tau, alpha, sat, Z @ y, "lp")


@dataclasses.dataclass(frozen=True)
class LPOptimum:
    """The LP-optimum strategy: an `AllocationMethod` named "lp", whose compiled branch is the active set.

    Attributes:
        solver: what solves (LP) in Python (the reference, and the ticks the compiled tick hands back):
            "highs" (`allocate_lp`) or "active_set" (`allocate_active_set`, the compiled branch's method).

    Raises:
        InvalidInput: an unknown solver.
    """

    solver: Solver = "highs"

    def __post_init__(self) -> None:
        if self.solver not in get_args(Solver):
            raise InvalidInput(f"solver: expected one of {', '.join(map(repr, get_args(Solver)))}, got {self.solver!r}")

    @property
    def name(self) -> str:
        """"lp", whatever the solver."""
        return "lp"

    @property
    def safe(self) -> bool:
        """True: the safety torque acts whatever the allocation holds."""
        return True

    @property
    def kernel(self) -> int:
        """The compiled tick's ACTIVE_SET branch."""
        return kernels.ACTIVE_SET

    def allocate(self, a, b, Z, *, torque_min, torque_max) -> Allocation:
        """The LP optimum by `solver` (see `allocate_lp`)."""
        solve = allocate_lp if self.solver == "highs" else allocate_active_set
        return solve(a, b, Z, torque_min=torque_min, torque_max=torque_max)


LP = register(LPOptimum())
register(LPOptimum(solver="active_set"), name="active_set")  # the alias (see the module's docstring)

__all__ = ["LP", "LPOptimum", "Solver", "allocate_active_set", "allocate_lp"]
