"""Adaptive stimulus methods for 2AFC discrimination: a transformed up-down staircase and QUEST+.

Both place the comparison (in % of the reference) from the answers so far, where the answer is 1 when the
comparison was judged stiffer. Both are deterministic given the answers, so a resumed session rebuilds them by
replaying its committed trials (`replay`). The fits stay psignifit's (`rhi.analysis.psychophysics`).

QUEST+ (Watson 2017, J. Vision 17(3):10) here: a grid posterior over the PSE μ [%] and the spread σ [%] of
``P(stiffer | x) = λ + (1 − 2λ) Φ((x − μ) / σ)`` (the equal-asymptote cumulative Gaussian of the §3.6 fits),
uniform prior, and the next stimulus the one of the grid minimising the expected posterior entropy. The
``questplus`` package (GPL-3, needs xarray) was not taken: rhi is BSD-3 and this is 40 lines.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from scipy.stats import norm

from rhi.errors import InvalidInput


class Staircase:
    """Transformed up-down staircase on the comparison [%]: `down` "stiffer" in a row step down, `up` "softer" up.

    Converges to P(stiffer) = p with p^down = 0.5 (down = 2, up = 1: 70.7 %, Levitt 1971).

    Args:
        start: first comparison [% of the reference].
        step: step [%] (> 0).
        lo, hi: the range the stimulus stays in [%].
        down, up: answers in a row that move the stimulus.
    """

    def __init__(self, start: float, step: float, lo: float, hi: float, *, down: int = 2, up: int = 1) -> None:
        if not (step > 0 and lo < hi and lo <= start <= hi and down >= 1 and up >= 1):
            raise InvalidInput(f"staircase: need step > 0, lo < hi, start in [lo, hi], down, up >= 1; got start "
                               f"{start}, step {step}, [{lo}, {hi}], down {down}, up {up}")
        self.x, self.step, self.lo, self.hi, self.down, self.up = float(start), float(step), lo, hi, down, up
        self._run = 0  # > 0: "stiffer" answers in a row, < 0: "softer" ones
        self.reversals = 0
        self._last_move = 0

    def next(self) -> float:
        """The next comparison [%]."""
        return self.x

    def update(self, x: float, answer: int) -> None:
        """Record `answer` (1: comparison stiffer) to the comparison `x` [%]."""
        self._run = max(self._run, 0) + 1 if answer else min(self._run, 0) - 1
        move = 0
        if self._run >= self.down:
            move, self._run = -1, 0
        elif -self._run >= self.up:
            move, self._run = 1, 0
        if move:
            if self._last_move and move != self._last_move:
                self.reversals += 1
            self._last_move = move
            self.x = float(np.clip(x + move * self.step, self.lo, self.hi))


class QuestPlus:
    """QUEST+ over (PSE μ, spread σ) of the equal-asymptote cumulative Gaussian (see the module docstring).

    Args:
        lo, hi: stimulus range [%]; step: stimulus grid spacing [%].
        lapse: λ (fixed).
        sigmas: (k,) candidate σ [%] (default: 15 values log-spaced over [step/2, (hi − lo)/2]).
    """

    def __init__(self, lo: float, hi: float, step: float, *, lapse: float = 0.02,
                 sigmas: Iterable[float] | None = None) -> None:
        if not (lo < hi and 0 < step <= hi - lo and 0 <= lapse < 0.5):
            raise InvalidInput(f"quest: need lo < hi, 0 < step <= hi - lo, lapse in [0, 0.5); got [{lo}, {hi}], "
                               f"step {step}, lapse {lapse}")
        self.x = np.arange(lo, hi + 0.5 * step, step)
        self.mu = self.x.copy()
        self.sigma = np.geomspace(step / 2, (hi - lo) / 2, 15) if sigmas is None else np.asarray(list(sigmas), float)
        # p[i, j, k] = P(stiffer | x_i, μ_j, σ_k)
        z = (self.x[:, None, None] - self.mu[None, :, None]) / self.sigma[None, None, :]
        self.p = lapse + (1 - 2 * lapse) * norm.cdf(z)
        self.posterior = np.full((self.mu.size, self.sigma.size), 1.0 / (self.mu.size * self.sigma.size))

    def next(self) -> float:
        """The comparison [%] of the grid with the least expected posterior entropy."""
        best, best_h = 0, math.inf
        for i in range(self.x.size):
            h = 0.0
            for p in (self.p[i], 1.0 - self.p[i]):
                joint = p * self.posterior
                m = joint.sum()
                if m > 0:
                    q = joint[joint > 0] / m
                    h += m * float(-(q * np.log(q)).sum())
            if h < best_h - 1e-12:
                best, best_h = i, h
        return float(self.x[best])

    def update(self, x: float, answer: int) -> None:
        """Bayes' rule with `answer` (1: comparison stiffer) to the comparison `x` [%] (a grid value)."""
        i = int(np.argmin(np.abs(self.x - x)))
        post = self.posterior * (self.p[i] if answer else 1.0 - self.p[i])
        self.posterior = post / post.sum()

    def estimate(self) -> tuple[float, float]:
        """Posterior means of (μ, σ) [%]."""
        return float(self.posterior.sum(axis=1) @ self.mu), float(self.posterior.sum(axis=0) @ self.sigma)


def procedure(stimulus: dict) -> Staircase | QuestPlus:
    """The adaptive procedure a protocol's ``[stimulus]`` table describes (method "staircase" or "quest")."""
    if stimulus["method"] == "staircase":
        return Staircase(stimulus["start_percent"], stimulus["step_percent"], stimulus["min_percent"],
                         stimulus["max_percent"], down=stimulus["down"], up=stimulus["up"])
    if stimulus["method"] == "quest":
        return QuestPlus(stimulus["min_percent"], stimulus["max_percent"], stimulus["step_percent"],
                         lapse=stimulus["lapse"])
    raise InvalidInput(f"stimulus.method: {stimulus['method']!r} is not adaptive")


def replay(proc: Staircase | QuestPlus, history: Iterable[tuple[float, int]]) -> Staircase | QuestPlus:
    """Feed (comparison [%], answer) pairs already recorded to `proc` (a resumed session); returns it."""
    for x, a in history:
        proc.update(x, a)
    return proc


__all__ = ["QuestPlus", "Staircase", "procedure", "replay"]
