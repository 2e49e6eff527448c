"""The design problem: evaluate a design D of the HI and the costs C1, C2 (thesis eqs. 4.23, 4.24).

For a design (a mapping of parameter name → value) every slave workspace sample p is
mapped into the HI's world frame, the HI's configuration there is found by IK, and
GM_M, GC_M (eqs. 4.8, 4.10) of the HI and GM_T (eq. 4.18) of the pair are integrated
over the samples with the joint-limit-penalized Jacobians (eqs. 4.19–4.20).

Placement (the thesis's "rotation of the HI around the center of the slave workspace",
§4.4): the HI's base is rotated by θz about the workspace centre c, and the centre
corresponds to the HI's base-frame point (r0, 0, Z_PH). A slave point p is therefore
the HI target ``w = (p − c) + Rz(θz)(r0, 0)`` in the HI's (yawed) world frame, at
height Z_PH; ``J_M^2D = jacobian(q)[:2]`` is eq. 4.26 there, and velocities map 1:1.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import as_array, scalar
from rhi.design.indices import penalize
from rhi.design.kinematics import Master, Solution
from rhi.design.planar import planar_indices_many
from rhi.design.workspace import Workspace
from rhi.errors import InfeasibleLimits, InvalidInput, Unreachable

#: Design parameters that are link lengths (must be > 0).
LENGTHS = ("l1", "l2", "l3", "d1", "d2", "d3", "d4")


def check_bounds(bounds: Mapping[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """Validate design bounds {name: (lower, upper)}.

    Raises:
        InvalidInput: empty bounds, a non-finite bound, or a link length whose lower bound is <= 0.
        InfeasibleLimits: a lower bound above its upper bound.
    """
    if not bounds:
        raise InvalidInput("bounds: no design parameter to optimise")
    out = {}
    for k, b in bounds.items():
        if not isinstance(k, str):
            raise InvalidInput(f"bounds: parameter names must be strings, got {k!r}")
        try:
            lo, hi = (scalar(f"bounds[{k!r}]", v, allow_inf=True) for v in b)
        except (TypeError, ValueError):
            raise InvalidInput(f"bounds[{k!r}]: expected (lower, upper), got {b!r}") from None
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise InvalidInput(f"bounds[{k!r}]: must be finite, got ({lo}, {hi})")
        if lo > hi:
            raise InfeasibleLimits(f"bounds[{k!r}]: lower bound {lo} > upper bound {hi}")
        if k in LENGTHS and lo <= 0:
            raise InvalidInput(f"bounds[{k!r}]: a link length must be > 0, got lower bound {lo}")
        out[k] = (lo, hi)
    return out


@dataclasses.dataclass(frozen=True)
class DesignProblem:
    """Everything needed to score a design, picklable so executors can ship it to workers.

    Attributes:
        master: HI kinematic model (`Phantom3Master` or `DeviceMaster`).
        workspace: slave workspace samples (slave base frame).
        slave: IK solution of the slave at the samples (J: (N, 2, n_S)).
        center: (2,) workspace centre c in the slave frame [m] (rotation centre of θz).
        r0: distance of c from the HI's yaw axis [m], or "auto": the middle of the radial interval the HI
            reaches on its working plane for this design (`Phantom3Master.radial_range`), i.e. the
            centre of the HI's planar workspace is put on the centre of the slave workspace.
        bounds: {parameter: (lower, upper)} of the optimised parameters D.
        fixed: parameters held constant.
        k_q: joint-limit penalty shape (eq. 4.20), None for no penalty.
        K1, K2: weights of eqs. 4.23–4.24.
    """

    master: Master
    workspace: Workspace
    slave: Solution
    center: tuple[float, float]
    r0: float | str
    bounds: dict[str, tuple[float, float]]
    fixed: dict[str, float] = dataclasses.field(default_factory=dict)
    k_q: float | None = 1.0
    K1: float = 1.0
    K2: float = 10.0
    _slave_Jq: np.ndarray = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "bounds", check_bounds(self.bounds))
        declared = getattr(self.master, "bounds", None)
        if callable(declared):
            known = set(declared()) | {"theta_z"}
            for arg, keys in (("bounds", self.bounds), ("fixed", self.fixed)):
                unknown = sorted(set(keys) - known)
                if unknown:
                    raise InvalidInput(f"{arg}: unknown design parameter(s) {unknown}; known: {sorted(known)}")
        if not isinstance(self.fixed, dict):
            raise InvalidInput(f"fixed: expected {{parameter: value}}, got {self.fixed!r:.60}")
        for k, v in self.fixed.items():
            v = scalar(f"fixed[{k!r}]", v)
            if k in LENGTHS and not v > 0:
                raise InvalidInput(f"fixed[{k!r}]: a link length must be > 0, got {v}")
        c = as_array("center", self.center, shape_tail=(2,))
        if c.shape != (2,):
            raise InvalidInput(f"center: expected (x, y) [m], got shape {c.shape}")
        if self.r0 != "auto" and not (isinstance(self.r0, (int, float)) and np.isfinite(self.r0)):
            raise InvalidInput(f"r0: expected a distance [m] or 'auto', got {self.r0!r}")
        if not self.slave.ok.any():
            raise Unreachable("workspace: the slave's inverse kinematics failed at every workspace sample")
        # the slave does not change with D: its penalized Jacobians are computed once per problem
        object.__setattr__(self, "_slave_Jq", penalize(self.slave.J, self.slave.q, self.slave.q_min,
                                                       self.slave.q_max, self.k_q))

    @property
    def names(self) -> list[str]:
        """Names of the optimised parameters, in the order of a design vector."""
        return list(self.bounds)

    def params(self, x: ArrayLike) -> dict[str, float]:
        """Full parameter mapping of design vector x."""
        xv = np.atleast_1d(as_array("x", x))
        if xv.shape != (len(self.bounds),):
            raise InvalidInput(f"x: expected {len(self.bounds)} values ({', '.join(self.names)}), got shape {xv.shape}")
        return {**self.fixed, **dict(zip(self.names, map(float, xv)))}

    def targets(self, params: Mapping[str, float]) -> np.ndarray:
        """HI world targets (N, 2) [m] of the workspace samples under placement θz (module docstring)."""
        tz = float(params.get("theta_z", 0.0))
        off = self.offset(params) * np.array([np.cos(tz), np.sin(tz)])
        return self.workspace.points - np.asarray(self.center) + off

    def offset(self, params: Mapping[str, float]) -> float:
        """r0 of this design [m]."""
        if self.r0 == "auto":
            radial_range = getattr(self.master, "radial_range", None)
            if radial_range is None:
                raise InvalidInput(f"r0: 'auto' needs a master with radial_range, got {type(self.master).__name__}")
            lo, hi = radial_range(params)
            return 0.5 * (lo + hi)
        return float(self.r0)

    def solve(self, x: ArrayLike) -> Solution:
        """HI IK solution at every workspace sample for design x."""
        p = self.params(x)
        return self.master.solve(p, self.targets(p))


def evaluate(problem: DesignProblem, x: ArrayLike) -> dict[str, float]:
    """Indices and costs of design x.

    Returns:
        {"GM_M", "GC_M", "GM_T", "coverage", "C1", "C2"}; C1 = K1 GC_M + K2 GM_M (eq. 4.23),
        C2 = K1 GC_M + K2 GM_T (eq. 4.24). A design that reaches no sample scores 0
        everywhere with coverage 0 (the optimiser must be able to visit it).
    """
    sol = problem.solve(x)
    Jm = penalize(sol.J, sol.q, sol.q_min, sol.q_max, problem.k_q)
    return _scores(problem, Jm[None], (sol.ok & problem.slave.ok)[None])[0]


def _scores(problem: DesignProblem, Jm: np.ndarray, ok: np.ndarray) -> list[dict[str, float]]:
    """`evaluate`'s dicts from the master's penalized Jacobians Jm (P, N, 2, n) and the reached samples ok (P, N)."""
    out = [{"GM_M": 0.0, "GC_M": 0.0, "GM_T": 0.0, "coverage": 0.0, "C1": 0.0, "C2": 0.0} for _ in ok]
    reached = np.flatnonzero(ok.any(axis=-1))
    if reached.size:
        for i, d in zip(reached, planar_indices_many(Jm[reached], problem._slave_Jq, ok[reached],
                                                     problem.workspace.weights), strict=True):
            gmt = d["GM_T"]
            out[i] = {"GM_M": d["GM"], "GC_M": d["GC"], "GM_T": gmt, "coverage": d["coverage"],
                      "C1": problem.K1 * d["GC"] + problem.K2 * d["GM"], "C2": problem.K1 * d["GC"] + problem.K2 * gmt}
    return out


def evaluate_many(problem: DesignProblem, xs: Sequence[ArrayLike]) -> list[dict[str, float]]:
    """`evaluate` at each design vector of xs, the IK and penalty of all of them in one vectorized pass.

    A master with ``solve_many`` (`Phantom3Master`) solves the P designs' targets as one (P, N) batch and
    the joint-limit penalty runs once over it; the same numbers as `evaluate` design by design (element-wise
    operations over a leading design axis). Other masters are evaluated one design at a time.
    """
    solve_many = getattr(problem.master, "solve_many", None)
    if solve_many is None or len(xs) < 2:
        return [evaluate(problem, x) for x in xs]
    params = [problem.params(x) for x in xs]
    sol = solve_many(params, np.stack([problem.targets(p) for p in params]))
    ok = sol.ok & problem.slave.ok
    return _scores(problem, penalize(sol.J, sol.q, sol.q_min, sol.q_max, problem.k_q), ok)


def evaluate_strict(problem: DesignProblem, x: ArrayLike) -> dict[str, float]:
    """`evaluate`, but raise `Unreachable` when the HI reaches no workspace sample."""
    sol = problem.solve(x)
    if not (sol.ok & problem.slave.ok).any():
        raise Unreachable(f"workspace: the HI's inverse kinematics failed at every workspace sample for design "
                          f"{problem.params(x)}")
    return evaluate(problem, x)


def cost(problem: DesignProblem, x: ArrayLike, which: str = "C2") -> float:
    """−C (to minimise) of design x, which = "C1" or "C2"."""
    if which not in ("C1", "C2"):
        raise InvalidInput(f"which: expected 'C1' or 'C2', got {which!r}")
    return -evaluate(problem, x)[which]
