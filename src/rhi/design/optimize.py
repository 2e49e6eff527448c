"""Global design optimisation: SciPy differential evolution (seeded) + bounded Nelder–Mead refinement.

Every evaluation goes through an executor (serial, local pool, Ray) and an `EvalCache`,
so a run can be resumed from its checkpoint file and gives the same numbers on every
executor. ``progress(done, total)`` is called after each batch.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import differential_evolution, minimize

from rhi.design.checkpoint import EvalCache
from rhi.design.cost import DesignProblem, evaluate
from rhi.design.executors import SerialExecutor
from rhi.errors import InvalidInput

Progress = Callable[[int, int], None]


@dataclasses.dataclass(frozen=True)
class Optimum:
    """Outcome of `optimize`.

    Attributes:
        which: "C1" or "C2".
        x: (d,) optimal design vector (order of `DesignProblem.names`).
        params: {name: value} of the optimum (plus the fixed parameters).
        values: indices and costs at the optimum (`evaluate`).
        x_global: (d,) best design of differential evolution before refinement.
        evaluations: number of distinct designs evaluated.
        history: (k,) best cost after each DE generation.
    """

    which: str
    x: np.ndarray
    params: dict[str, float]
    values: dict[str, float]
    x_global: np.ndarray
    evaluations: int
    history: np.ndarray


def _tag(problem: DesignProblem, which: str) -> str:
    ws = problem.workspace
    return (f"{which}|{problem.master!r}|{ws.description}|c={problem.center}|r0={problem.r0}|{problem.bounds}|"
            f"{problem.fixed}|kq={problem.k_q}|K={problem.K1},{problem.K2}")


def sweep(
    problem: DesignProblem,
    xs: Sequence[Sequence[float]],
    *,
    executor=None,
    checkpoint: str | None = None,
    progress: Progress | None = None,
    batch: int = 64,
) -> list[dict[str, float]]:
    """`evaluate` at each design vector of xs (in order), in batches, resumable from `checkpoint`."""
    ex = executor or SerialExecutor()
    cache = EvalCache(checkpoint, "sweep|" + _tag(problem, ""))
    fn = functools.partial(evaluate, problem)
    out: list[dict[str, float]] = []
    for i in range(0, len(xs), batch):
        out += cache.map(fn, xs[i:i + batch], ex.map)
        if progress:
            progress(len(out), len(xs))
    return out


def optimize(
    problem: DesignProblem,
    which: str = "C2",
    *,
    executor=None,
    seed: int = 0,
    popsize: int = 15,
    maxiter: int = 60,
    tol: float = 1e-7,
    refine: bool = True,
    checkpoint: str | None = None,
    progress: Progress | None = None,
) -> Optimum:
    """Maximise C1 or C2 over the problem's bounds.

    Args:
        problem: the design problem.
        which: "C1" (eq. 4.23) or "C2" (eq. 4.24).
        executor: evaluates each DE generation (default serial).
        seed: seed of differential evolution (results are reproducible bit for bit).
        popsize, maxiter, tol: differential-evolution settings (SciPy's meaning).
        refine: polish the DE optimum with bounded Nelder–Mead (serial).
        checkpoint: JSON file of finished evaluations; re-running resumes from it.
        progress: ``progress(done, total)`` after each batch of evaluations.
    """
    if which not in ("C1", "C2"):
        raise InvalidInput(f"which: expected 'C1' or 'C2', got {which!r}")
    ex = executor or SerialExecutor()
    cache = EvalCache(checkpoint, _tag(problem, which))
    fn = functools.partial(evaluate, problem)
    bounds = list(problem.bounds.values())
    d = len(bounds)
    total = popsize * d * (maxiter + 1) + (200 * d if refine else 0)
    done = [0]

    def batch_map(_func, xs):
        xs = [np.asarray(x, dtype=float) for x in xs]
        res = cache.map(fn, xs, ex.map)
        done[0] += len(xs)
        if progress:
            progress(min(done[0], total), total)
        return [-r[which] for r in res]

    history: list[float] = []

    def callback(intermediate_result):
        history.append(float(intermediate_result.fun))

    de = differential_evolution(
        lambda x: -evaluate(problem, x)[which], bounds, seed=seed, popsize=popsize, maxiter=maxiter, tol=tol,
        polish=False, updating="deferred", workers=batch_map, init="sobol" if d > 1 else "latinhypercube",
        callback=callback,
    )
    x_best = np.asarray(de.x, dtype=float)
    if refine:
        lo = np.array([b[0] for b in bounds])
        hi = np.array([b[1] for b in bounds])
        step = 0.05 * (hi - lo)
        simplex = np.vstack([x_best] + [np.clip(x_best + np.eye(d)[i] * step[i] * (1 if x_best[i] + step[i] <= hi[i]
                                                                                  else -1), lo, hi)
                                       for i in range(d)])
        loc = minimize(lambda x: batch_map(None, [np.clip(x, lo, hi)])[0], x_best, method="Nelder-Mead",
                       bounds=bounds, options={"initial_simplex": simplex, "xatol": 1e-6, "fatol": 1e-9,
                                               "maxfev": 200 * d})
        x_loc = np.clip(loc.x, lo, hi)
        if loc.fun < de.fun:
            x_best = x_loc
    if progress:
        progress(total, total)
    return Optimum(which, x_best, problem.params(x_best), evaluate(problem, x_best), np.asarray(de.x, dtype=float),
                   len(cache), np.array(history))
