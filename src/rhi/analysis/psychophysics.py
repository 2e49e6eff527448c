"""Stiffness discrimination: the protocol of thesis §3.5 and the psychometric analysis of §3.6.

Protocol (§3.5): two-alternative forced choice (2AFC) by the method of constant
stimuli. On every trial the subject probes a reference virtual spring (50 N/m)
and a comparison spring and says which is stiffer. Nine comparisons, -35, -25,
-15, -5, 0, +5, +15, +25, +35 % of the reference, ten repetitions each, in
random order, for each haptic interface (RHI, PHANToM, Rehab): 90 trials per
device and subject.

Analysis (§3.6): the "positive fraction" is the proportion of trials on which
the *comparison* was judged stiffer. A psychometric function is fitted to it per
subject and device (the thesis used psignifit 2.5.6 for MATLAB; we use
psignifit 4, its successor), and from it

    PSE = x(50 %),  UT = x(75 %),  LT = x(25 %),
    JND = (UT − LT) / 2                                   (thesis eq. 3.26)
    WF  = JND / PSE                                       (thesis eq. 3.25)

Why a yes/no-type ("equal asymptote") fit and not psignifit's "2AFC": in
psignifit, "2AFC" means the response is *correct/incorrect* and the function
rises from a guess rate of 1/2 to 1 as the signal grows. Here the response is
"comparison stiffer", which runs from 0 (comparison much softer) through 1/2
(at the PSE) to 1 (comparison much stiffer): the full 0-1 range, like a yes/no
task, with the 25/50/75 % points the thesis reads off. Its asymptotes are lapses
(pressing the wrong answer by mistake), equally likely at both ends, so the
lower asymptote γ and the upper lapse λ are tied (psignifit's
``experiment_type="equal asymptote"``), which also keeps the 50 % point of the
fitted curve at its threshold parameter. ``experiment_type="yes/no"`` (γ and λ
free) is available.

Thresholds are read off the lapse-free sigmoid F by default (``lapse_corrected=
True``): lapses say nothing about sensitivity, and psignifit 2.5.6 defined its
thresholds ("cuts") on F too. Confidence intervals of PSE, LT, UT, JND and WF are
percentiles of psignifit's posterior over its parameter grid (JND and WF depend
on the threshold and the width jointly, so they are computed point by point on
the grid and weighted by the posterior mass), not psignifit's own
``Result.threshold`` intervals, which combine the interval ends of each
parameter and are documented as upper bounds only.

Measured with `simulate_responses` (observers with PSE ~ N(50, 1.5) N/m, JND
uniform in 4-8 N/m, lapse 0.02, the 90 trials of §3.5): with η fixed at 0
(``overdispersion=False``, 150 observers) the 95 % intervals covered the true PSE
in 96 % and the true JND and WF in 99 % of fits (conservative), JND error
-0.05 ± 1.8 N/m; with η estimated (40 observers) 95 %, 97.5 % and 97.5 %.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import float_array, scalar
from rhi.analysis.stats import AnovaResult, PairedTest, Summary, describe, one_way_anova, paired_t_tests
from rhi.analysis.stats import repeated_measures_anova
from rhi.analysis._csv import read_rows
from rhi.errors import InvalidInput

#: reference stiffness of §3.5 [N/m].
REFERENCE_STIFFNESS = 50.0
#: comparison stimuli of §3.5 [% of the reference].
COMPARISON_PERCENT = (-35.0, -25.0, -15.0, -5.0, 0.0, 5.0, 15.0, 25.0, 35.0)
#: the three haptic interfaces of §3.5.
DEVICES = ("RHI", "PHANToM", "Rehab")
#: repetitions of every comparison per device and subject (§3.5).
REPETITIONS = 10
#: z such that Φ(z) = 0.75: for a cumulative Gaussian of s.d. σ, JND = Z75 σ.
Z75 = 0.6744897501960817

MEASURES = ("pse", "lt", "ut", "jnd", "wf")


# --------------------------------------------------------------------------- protocol


@dataclasses.dataclass(frozen=True)
class Trial:
    """One 2AFC trial of the method of constant stimuli.

    Attributes:
        subject: subject identifier.
        device: haptic interface the pair is felt through.
        index: position of the trial in the subject's whole session (0-based).
        block: position of the device's block in the subject's session (0-based).
        reference: reference stiffness [N/m].
        comparison: comparison stiffness [N/m].
        comparison_percent: comparison relative to the reference [%].
        comparison_first: whether the comparison is probed first in the pair.
    """

    subject: str
    device: str
    index: int
    block: int
    reference: float
    comparison: float
    comparison_percent: float
    comparison_first: bool


def protocol(
    subjects: int | Sequence[str] = 10,
    devices: Sequence[str] = DEVICES,
    *,
    reference: float = REFERENCE_STIFFNESS,
    comparison_percent: Sequence[float] = COMPARISON_PERCENT,
    repetitions: int = REPETITIONS,
    shuffle_devices: bool = True,
    seed: int = 0,
) -> list[Trial]:
    """The trial list of the §3.5 experiment, in presentation order.

    Every subject works through one block per device; within a block each
    comparison appears ``repetitions`` times in random order, and which spring of
    a pair comes first is a fair coin. The thesis does not state the device order
    or the order within a pair; we randomise both (counterbalancing) and make
    each subject's session depend only on ``(seed, subject position)``, so adding
    a subject does not reshuffle the others.

    Args:
        subjects: number of subjects (named "S01", "S02", ...) or their names.
        devices: device names, one block each.
        reference: reference stiffness [N/m] (thesis: 50 N/m).
        comparison_percent: comparisons in % of the reference (thesis: 0, ±5, ±15, ±25, ±35).
        repetitions: presentations of every comparison per device (thesis: 10).
        shuffle_devices: randomise the device order per subject (else as given).
        seed: seed of the ordering.

    Returns:
        list of `Trial`: ``len(subjects) · len(devices) · len(comparison_percent) · repetitions``
        trials, grouped by subject, each subject's trials in presentation order.

    Raises:
        InvalidInput: no subjects or devices, duplicate names, non-positive
            reference or repetitions, or a comparison at or below -100 %.
    """
    if isinstance(subjects, int | np.integer):
        if subjects < 1:
            raise InvalidInput(f"subjects: need at least one subject, got {subjects}")
        names = [f"S{i + 1:02d}" for i in range(int(subjects))]
    else:
        names = [str(s) for s in subjects]
    devs = [str(d) for d in devices]
    for arg, items in (("subjects", names), ("devices", devs)):
        if not items:
            raise InvalidInput(f"{arg}: empty")
        if len(set(items)) != len(items):
            raise InvalidInput(f"{arg}: duplicate names in {items}")
    if not (math.isfinite(reference) and reference > 0):
        raise InvalidInput(f"reference: must be a positive stiffness in N/m, got {reference!r}")
    pct = np.asarray(comparison_percent, dtype=float)
    if pct.ndim != 1 or pct.size == 0 or not np.isfinite(pct).all() or (pct <= -100).any():
        raise InvalidInput(f"comparison_percent: need finite values above -100 %, got {comparison_percent!r}")
    if int(repetitions) != repetitions or repetitions < 1:
        raise InvalidInput(f"repetitions: must be a positive integer, got {repetitions!r}")

    trials: list[Trial] = []
    base = np.repeat(pct, int(repetitions))
    for s_idx, subject in enumerate(names):
        rng = np.random.default_rng([int(seed), s_idx])
        order = rng.permutation(len(devs)) if shuffle_devices else np.arange(len(devs))
        index = 0
        for block, d_idx in enumerate(order):
            p = base[rng.permutation(base.size)]
            first = rng.random(base.size) < 0.5
            for k in range(base.size):
                trials.append(
                    Trial(
                        subject=subject,
                        device=devs[d_idx],
                        index=index,
                        block=block,
                        reference=float(reference),
                        comparison=float(reference * (1.0 + p[k] / 100.0)),
                        comparison_percent=float(p[k]),
                        comparison_first=bool(first[k]),
                    )
                )
                index += 1
    return trials


# --------------------------------------------------------------------------- responses


@dataclasses.dataclass(frozen=True)
class Responses:
    """Responses of a stiffness-discrimination experiment, one entry per trial.

    Attributes:
        subject: (T,) subject identifiers (str).
        device: (T,) device names (str).
        comparison: (T,) comparison stiffness [N/m].
        response: (T,) 1 if the comparison was judged stiffer than the reference, else 0.
        line: (T,) source line of each trial in a CSV file, or -1 (for error messages).
    """

    subject: np.ndarray
    device: np.ndarray
    comparison: np.ndarray
    response: np.ndarray
    line: np.ndarray = dataclasses.field(default=None, repr=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        subj = np.asarray(self.subject, dtype=object).astype(str)
        dev = np.asarray(self.device, dtype=object).astype(str)
        try:
            comp = np.asarray(self.comparison, dtype=float)
        except (TypeError, ValueError):
            raise InvalidInput("comparison: cannot be read as numbers") from None
        resp_raw = np.asarray(self.response)
        n = comp.shape[0] if comp.ndim == 1 else -1
        for name, arr in (("subject", subj), ("device", dev), ("comparison", comp), ("response", resp_raw)):
            if arr.ndim != 1 or arr.shape[0] != n:
                raise InvalidInput(f"{name}: expected shape ({n},) like comparison, got {arr.shape}")
        line = np.full(n, -1, dtype=int) if self.line is None else np.asarray(self.line, dtype=int)
        if line.shape != (n,):
            raise InvalidInput(f"line: expected shape ({n},), got {line.shape}")

        def where(i: int) -> str:
            return f"line {line[i]}" if line[i] >= 0 else f"trial {i}"

        bad = np.flatnonzero(~np.isfinite(comp) | (comp <= 0))
        if bad.size:
            i = int(bad[0])
            raise InvalidInput(f"{where(i)}, column 'comparison': {comp[i]!r} is not a positive stiffness")
        try:
            resp = resp_raw.astype(float)
        except (TypeError, ValueError):
            resp = np.full(n, np.nan)
        bad = np.flatnonzero(~np.isin(resp, (0.0, 1.0)))
        if bad.size:
            i = int(bad[0])
            raise InvalidInput(f"{where(i)}, column 'response': {resp_raw[i]!r} is not 0 or 1")
        object.__setattr__(self, "subject", subj)
        object.__setattr__(self, "device", dev)
        object.__setattr__(self, "comparison", comp)
        object.__setattr__(self, "response", resp.astype(np.int8))
        object.__setattr__(self, "line", line)

    def __len__(self) -> int:
        return int(self.comparison.shape[0])

    @classmethod
    def from_trials(cls, trials: Sequence[Trial], response: ArrayLike) -> Responses:
        """Join a `protocol` trial list with its responses (1 = comparison judged stiffer).

        Args:
            trials: (T,) trials.
            response: (T,) responses in {0, 1}.
        """
        r = np.asarray(response)
        if r.shape != (len(trials),):
            raise InvalidInput(f"response: expected shape ({len(trials)},) like trials, got {r.shape}")
        return cls(
            subject=np.array([t.subject for t in trials], dtype=object),
            device=np.array([t.device for t in trials], dtype=object),
            comparison=np.array([t.comparison for t in trials], dtype=float),
            response=r,
        )

    def groups(self) -> dict[tuple[str, str], np.ndarray]:
        """Indices of the trials of every (subject, device), in order of first appearance."""
        out: dict[tuple[str, str], list[int]] = {}
        for i, key in enumerate(zip(self.subject.tolist(), self.device.tolist())):
            out.setdefault(key, []).append(i)
        return {k: np.asarray(v) for k, v in out.items()}

    def select(self, subject: str, device: str) -> tuple[np.ndarray, np.ndarray]:
        """(comparison [N/m], response) of one subject and device."""
        m = (self.subject == str(subject)) & (self.device == str(device))
        if not m.any():
            raise InvalidInput(f"subject/device: no trials for subject {subject!r} on device {device!r}")
        return self.comparison[m], self.response[m]


def pool(comparison: ArrayLike, response: ArrayLike) -> np.ndarray:
    """Trials pooled per stimulus level: psignifit's ``[level, n_stiffer, n_trials]`` rows.

    Args:
        comparison: (T,) comparison stiffness [N/m].
        response: (T,) 0/1.

    Returns:
        (k, 3) array, levels ascending.
    """
    c = np.asarray(comparison, dtype=float)
    r = np.asarray(response, dtype=float)
    levels, inv = np.unique(c, return_inverse=True)
    n = np.bincount(inv, minlength=levels.size).astype(float)
    k = np.bincount(inv, weights=r, minlength=levels.size)
    return np.column_stack([levels, k, n])


def simulate_responses(
    trials: Sequence[Trial],
    *,
    pse: float | Mapping[tuple[str, str], float],
    jnd: float | Mapping[tuple[str, str], float],
    lapse: float = 0.0,
    seed: int = 0,
) -> Responses:
    """Synthetic responses from a known cumulative-Gaussian observer (for tests and power studies).

    ``P(comparison judged stiffer) = λ + (1 − 2λ) Φ((c − PSE) / σ)`` with
    ``σ = JND / z₀.₇₅``, so the lapse-free function has exactly the given PSE and
    JND (eq. 3.26). Independent of any physics: the perceptual model of the
    simulated-device experiment lives in `rhi.sim`.

    Args:
        trials: trial list (e.g. from `protocol`).
        pse: PSE [N/m], one value or a mapping ``(subject, device) -> PSE``.
        jnd: JND [N/m] > 0, one value or a mapping ``(subject, device) -> JND``.
        lapse: lapse rate λ in [0, 0.5) at both ends.
        seed: seed of the Bernoulli draws.

    Returns:
        `Responses` in the order of ``trials``.

    Raises:
        InvalidInput: non-positive JND, lapse outside [0, 0.5), or a mapping without
            an entry for some (subject, device).
    """
    from scipy.stats import norm

    if not (0.0 <= lapse < 0.5):
        raise InvalidInput(f"lapse: must lie in [0, 0.5), got {lapse!r}")

    def value(name: str, spec: Any, t: Trial) -> float:
        if isinstance(spec, Mapping):
            try:
                return float(spec[(t.subject, t.device)])
            except KeyError:
                raise InvalidInput(f"{name}: no value for subject {t.subject!r}, device {t.device!r}") from None
        return float(spec)

    c = np.array([t.comparison for t in trials], dtype=float)
    mu = np.array([value("pse", pse, t) for t in trials])
    j = np.array([value("jnd", jnd, t) for t in trials])
    if not np.isfinite(mu).all() or not (np.isfinite(j).all() and (j > 0).all()):
        raise InvalidInput("pse/jnd: need finite values and a positive JND")
    p = lapse + (1.0 - 2.0 * lapse) * norm.cdf((c - mu) / (j / Z75))
    rng = np.random.default_rng(seed)
    return Responses.from_trials(trials, (rng.random(c.size) < p).astype(np.int8))


def from_csv(path: str | Path) -> Responses:
    """Read an experiment's responses from a CSV file (one trial per row).

    Columns (header required; case and surrounding spaces ignored; others ignored):
    ``subject``, ``device``, ``comparison`` (comparison stiffness [N/m]) and
    ``response`` (1 if the comparison was judged stiffer than the reference, 0 if
    not).

    Args:
        path: CSV file.

    Returns:
        `Responses`, with each trial's file line kept for later error messages.

    Raises:
        InvalidInput: unreadable file, a missing column, an empty subject or device,
            a comparison that is not a positive number, or a response outside
            {0, 1} -- each naming the line and column.
    """
    path, cols, index, body = read_rows(path)
    for c in ("subject", "device", "comparison", "response"):
        if c not in index:
            raise InvalidInput(f"{path.name}: missing column '{c}' (found {cols})")
    subj, dev, comp, resp, lines = [], [], [], [], []
    for line, row in body:
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) < len(cols):
            raise InvalidInput(f"{path.name}, line {line}: {len(row)} fields; the header has {len(cols)}")
        s, d = row[index["subject"]].strip(), row[index["device"]].strip()
        if not s:
            raise InvalidInput(f"{path.name}, line {line}, column 'subject': empty")
        if not d:
            raise InvalidInput(f"{path.name}, line {line}, column 'device': empty")
        text = row[index["comparison"]].strip()
        try:
            c = float(text)
        except ValueError:
            raise InvalidInput(f"{path.name}, line {line}, column 'comparison': {text!r} is not a number") from None
        if not (math.isfinite(c) and c > 0):
            raise InvalidInput(f"{path.name}, line {line}, column 'comparison': {text!r} is not a positive stiffness")
        text = row[index["response"]].strip()
        try:
            r = float(text)
        except ValueError:
            r = float("nan")
        if r not in (0.0, 1.0):
            raise InvalidInput(f"{path.name}, line {line}, column 'response': {text!r} is not 0 or 1")
        subj.append(s)
        dev.append(d)
        comp.append(c)
        resp.append(int(r))
        lines.append(line)
    if not comp:
        raise InvalidInput(f"{path.name}: no data rows")
    return Responses(
        subject=np.array(subj, dtype=object),
        device=np.array(dev, dtype=object),
        comparison=np.array(comp),
        response=np.array(resp),
        line=np.array(lines),
    )


# --------------------------------------------------------------------------- fitting


@dataclasses.dataclass(frozen=True)
class PsychometricFit:
    """Psychometric function of one subject on one device and its measures (thesis §3.6).

    All stimulus-valued quantities are stiffnesses [N/m]; WF is dimensionless.

    Attributes:
        subject, device: whose data.
        pse: point of subjective equality, x at 50 % "comparison stiffer".
        lt, ut: lower (25 %) and upper (75 %) thresholds.
        jnd: (UT − LT)/2 (eq. 3.26).
        wf: JND/PSE (eq. 3.25).
        pse_ci, lt_ci, ut_ci, jnd_ci, wf_ci: (low, high) posterior intervals at ``confidence``.
        confidence: level of the intervals.
        lapse_corrected: thresholds read off the lapse-free sigmoid (True) or the fitted curve.
        threshold, width, lapse, guess, eta: psignifit's MAP parameters (threshold at 50 % of
            the sigmoid, width from 5 % to 95 %, upper lapse λ, lower asymptote γ,
            overdispersion η).
        sigmoid: psignifit sigmoid name.
        experiment_type: psignifit experiment type.
        n_trials: number of trials fitted.
        data: (k, 3) pooled ``[comparison, n_stiffer, n_trials]`` (Fig. 3.9's points).
        warnings: psignifit's warnings during the fit (e.g. posterior at a grid bound).
        result: the psignifit ``Result`` (without its debug posterior), for psignifit's own plots.
    """

    subject: str
    device: str
    pse: float
    lt: float
    ut: float
    jnd: float
    wf: float
    pse_ci: tuple[float, float]
    lt_ci: tuple[float, float]
    ut_ci: tuple[float, float]
    jnd_ci: tuple[float, float]
    wf_ci: tuple[float, float]
    confidence: float
    lapse_corrected: bool
    threshold: float
    width: float
    lapse: float
    guess: float
    eta: float
    sigmoid: str
    experiment_type: str
    n_trials: int
    data: np.ndarray = dataclasses.field(repr=False)
    warnings: tuple[str, ...] = dataclasses.field(default=(), repr=False)
    result: Any = dataclasses.field(default=None, repr=False, compare=False)

    def curve(self, comparison: ArrayLike) -> np.ndarray:
        """Fitted proportion "comparison stiffer" (with lapses) at stiffnesses ``comparison`` [N/m]."""
        import psignifit.sigmoids as sg

        x = np.asarray(comparison, dtype=float)
        if self.result is not None:
            s = self.result.configuration.make_sigmoid()
        else:
            s = sg.sigmoid_by_name(self.sigmoid, PC=0.5, alpha=0.05)
        return np.asarray(s(x, self.threshold, self.width, self.guess, self.lapse), dtype=float)

    def ci(self, measure: str) -> tuple[float, float]:
        """Interval of one of "pse", "lt", "ut", "jnd", "wf"."""
        if measure not in MEASURES:
            raise InvalidInput(f"measure: expected one of {MEASURES}, got {measure!r}")
        return getattr(self, f"{measure}_ci")

    def row(self) -> dict[str, Any]:
        """Tidy row: subject, device, each measure with its interval, parameters, n_trials."""
        out: dict[str, Any] = {"subject": self.subject, "device": self.device}
        for m in MEASURES:
            lo, hi = self.ci(m)
            out[m] = getattr(self, m)
            out[f"{m}_low"] = lo
            out[f"{m}_high"] = hi
        out.update(
            threshold=self.threshold,
            width=self.width,
            lapse=self.lapse,
            guess=self.guess,
            eta=self.eta,
            n_trials=self.n_trials,
            n_warnings=len(self.warnings),
        )
        return out


def _weighted_interval(values: np.ndarray, weights: np.ndarray, confidence: float) -> tuple[float, float]:
    """Central interval of a discrete distribution on a grid.

    Weighted percentiles with mid-point interpolation between neighbouring grid
    values; where a neighbour is infinite (a threshold the fitted curve never
    reaches) the outer neighbour is taken, so the interval stays conservative.
    """
    v = values.ravel()
    w = weights.ravel()
    keep = (w > 0) & ~np.isnan(v)
    v, w = v[keep], w[keep]
    order = np.argsort(v, kind="stable")
    v, w = v[order], w[order]
    cdf = (np.cumsum(w) - 0.5 * w) / w.sum()

    def quantile(q: float, lower: bool) -> float:
        j = int(np.searchsorted(cdf, q))
        if j == 0:
            return float(v[0])
        if j == v.size:
            return float(v[-1])
        a, b = v[j - 1], v[j]
        if np.isfinite(a) and np.isfinite(b):
            return float(a + (b - a) * (q - cdf[j - 1]) / (cdf[j] - cdf[j - 1]))
        return float(a if lower else b)

    return quantile(0.5 - confidence / 2, True), quantile(0.5 + confidence / 2, False)


def _measures(sigmoid, thr, width, gamma, lam, lapse_corrected: bool) -> dict[str, np.ndarray]:
    """PSE, LT, UT, JND, WF for arrays of parameters (broadcast)."""
    out = {}
    for name, p in (("pse", 0.5), ("lt", 0.25), ("ut", 0.75)):
        if lapse_corrected:
            f = np.full(np.broadcast(thr, width).shape, p)
        else:
            f = (p - gamma) / (1.0 - gamma - lam)
        f = np.broadcast_to(f, np.broadcast(thr, width, f).shape)
        inside = (f > 0) & (f < 1)
        x = np.where(f >= 1, np.inf, -np.inf).astype(float)
        thr_b = np.broadcast_to(thr, f.shape)
        wid_b = np.broadcast_to(width, f.shape)
        if inside.any():
            x[inside] = sigmoid.inverse(f[inside], thr_b[inside], wid_b[inside])
        out[name] = x
    with np.errstate(invalid="ignore"):
        out["jnd"] = (out["ut"] - out["lt"]) / 2.0
        out["wf"] = out["jnd"] / out["pse"]
    return out


_FAST_GAUSSIAN_CLASS = None


def _fast_gaussian_class() -> type:
    """psignifit's cumulative-Gaussian sigmoid evaluated through ``scipy.special`` (same values).

    psignifit's ``Gaussian`` calls ``scipy.stats.norm``, whose per-call overhead
    dominates the MAP search; ``ndtr``/``ndtri`` are the functions ``norm``
    evaluates, so the fit is unchanged (tests/test_analysis.py compares it with a
    direct psignifit call) and about twice as fast. Created on first use (psignifit
    is imported lazily) and reachable as the module attribute ``_FastGaussian``,
    so fits pickle (process pools).
    """
    global _FAST_GAUSSIAN_CLASS
    if _FAST_GAUSSIAN_CLASS is None:
        from psignifit.sigmoids import Gaussian
        from scipy import special

        class _FastGaussian(Gaussian):
            def _ppf(self, x, loc=0, scale=1):
                return loc + scale * special.ndtri(x)

            def _cdf(self, x, loc=0, scale=1):
                return special.ndtr((np.asarray(x) - loc) / scale)

            def _pdf(self, x, loc=0, scale=1):
                z = (np.asarray(x) - loc) / scale
                return np.exp(-0.5 * z * z) / (math.sqrt(2.0 * math.pi) * scale)

        _FastGaussian.__module__ = __name__
        _FastGaussian.__qualname__ = "_FastGaussian"
        _FAST_GAUSSIAN_CLASS = _FastGaussian
    return _FAST_GAUSSIAN_CLASS


def __getattr__(name: str) -> Any:  # PEP 562: lets pickle find the lazily created class
    if name == "_FastGaussian":
        return _fast_gaussian_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def fit_psychometric(
    comparison: ArrayLike,
    response: ArrayLike,
    *,
    subject: str = "",
    device: str = "",
    confidence: float = 0.95,
    lapse_corrected: bool = True,
    sigmoid: str = "norm",
    experiment_type: Literal["equal asymptote", "yes/no"] = "equal asymptote",
    overdispersion: bool = True,
    min_trials: int = 20,
    min_levels: int = 3,
    psignifit_options: Mapping[str, Any] | None = None,
) -> PsychometricFit:
    """Fit a psychometric function to one subject's responses on one device (thesis §3.6).

    Calls ``psignifit.psignifit`` on the pooled ``[comparison, n_stiffer, n]``
    rows (Bayesian fit on a parameter grid; MAP estimate) and derives PSE, LT,
    UT, JND (eq. 3.26) and WF (eq. 3.25) with posterior intervals (see the module
    docstring for the choice of experiment type and threshold definition).

    Args:
        comparison: (T,) comparison stiffness per trial [N/m].
        response: (T,) 1 if the comparison was judged stiffer, else 0.
        subject, device: labels carried into the result and error messages.
        confidence: level of the intervals, in (0, 1).
        lapse_corrected: read thresholds off the lapse-free sigmoid (default) or
            off the fitted curve with its lapses.
        sigmoid: psignifit sigmoid ("norm" = cumulative Gaussian, "logistic", ...).
        experiment_type: "equal asymptote" (γ = λ, default) or "yes/no" (γ, λ free).
        overdispersion: estimate psignifit's overdispersion η (psignifit 4's default);
            False fixes η = 0 (a pure binomial observer, about twice as fast).
        min_trials: fewest trials accepted.
        min_levels: fewest distinct comparison levels accepted.
        psignifit_options: further keyword options for ``psignifit.psignifit``
            (e.g. ``grid_steps``, ``stimulus_range``, ``priors``).

    Returns:
        `PsychometricFit`.

    Raises:
        InvalidInput: shapes, responses outside {0, 1}, fewer than ``min_trials``
            trials or ``min_levels`` levels (naming the subject/device), or bad options.
    """
    import psignifit
    from psignifit._utils import PsignifitException

    who = " ".join(x for x in (f"subject {subject!r}" if subject else "", f"device {device!r}" if device else "") if x)
    who = who or "data"
    c = float_array("comparison", comparison)
    r = float_array("response", response)
    if c.ndim != 1 or r.shape != c.shape:
        raise InvalidInput(f"comparison/response: expected two 1-D arrays of equal length, got {c.shape} and {r.shape}")
    if not (np.isfinite(c).all() and (c > 0).all()):
        raise InvalidInput(f"comparison: {who}: needs finite positive stiffnesses")
    try:
        rf = r.astype(float)
    except (TypeError, ValueError):
        raise InvalidInput(f"response: {who}: not numeric") from None
    if not np.isin(rf, (0.0, 1.0)).all():
        raise InvalidInput(f"response: {who}: values outside {{0, 1}}")
    if not (0 < scalar("confidence", confidence) < 1):
        raise InvalidInput(f"confidence: must lie in (0, 1), got {confidence!r}")
    if rf.size and np.all(rf == rf[0]):
        raise InvalidInput(f"response: {who}: every response is {int(rf[0])}; the threshold lies outside the tested "
                           "comparisons and no psychometric function can be fitted")
    if experiment_type not in ("equal asymptote", "yes/no"):
        raise InvalidInput(f"experiment_type: expected 'equal asymptote' or 'yes/no', got {experiment_type!r}")
    data = pool(c, rf)
    if c.size < min_trials or data.shape[0] < min_levels:
        raise InvalidInput(
            f"device: {who} has {c.size} trials at {data.shape[0]} comparison levels; "
            f"a psychometric fit needs at least {min_trials} trials at {min_levels} levels"
        )

    opts: dict[str, Any] = dict(psignifit_options or {})
    sigmoid_name = str(opts.pop("sigmoid", sigmoid))
    if sigmoid_name == "norm" and opts.get("thresh_PC", 0.5) == 0.5 and opts.get("width_alpha", 0.05) == 0.05:
        opts["sigmoid"] = _fast_gaussian_class()(PC=0.5, alpha=0.05)
    else:
        opts["sigmoid"] = sigmoid_name
    opts.setdefault("experiment_type", experiment_type)
    opts.setdefault("confP", (confidence,))
    if not overdispersion:
        fixed = dict(opts.get("fixed_parameters") or {})
        fixed.setdefault("eta", 0.0)
        opts["fixed_parameters"] = fixed
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            res = psignifit.psignifit(data, debug=True, **opts)
        except (PsignifitException, TypeError, ValueError) as exc:
            raise InvalidInput(f"psignifit_options: psignifit rejected the fit of {who}: {exc}") from None
    sig = res.configuration.make_sigmoid()
    est = res.parameter_estimate_MAP
    gamma_hat = float(est.get("gamma", est["lambda"]))
    point = _measures(sig, est["threshold"], est["width"], gamma_hat, est["lambda"], lapse_corrected)

    # Posterior over the grid -> intervals of the derived measures.
    post = np.asarray(res.debug["posteriors"])
    names = sorted(res.parameter_values)
    if "gamma" in names and post.ndim == len(names) - 1:
        names.remove("gamma")
    if post.ndim != len(names):
        raise RuntimeError(f"unexpected psignifit posterior shape {post.shape} for parameters {names}")
    keep = ["threshold", "width"] if lapse_corrected else ["threshold", "width", "lambda", "gamma"]
    marg = post.sum(axis=tuple(i for i, n in enumerate(names) if n not in keep))
    kept = [n for n in names if n in keep]
    axes = [np.asarray(res.parameter_values[n], dtype=float) for n in kept]
    mesh = dict(zip(kept, np.meshgrid(*axes, indexing="ij")))
    lam = mesh.get("lambda", 0.0)
    gam = mesh.get("gamma", lam)
    grid = _measures(sig, mesh["threshold"], mesh["width"], gam, lam, lapse_corrected)
    cis = {m: _weighted_interval(grid[m], marg, confidence) for m in MEASURES}

    return PsychometricFit(
        subject=str(subject),
        device=str(device),
        pse=float(point["pse"]),
        lt=float(point["lt"]),
        ut=float(point["ut"]),
        jnd=float(point["jnd"]),
        wf=float(point["wf"]),
        pse_ci=cis["pse"],
        lt_ci=cis["lt"],
        ut_ci=cis["ut"],
        jnd_ci=cis["jnd"],
        wf_ci=cis["wf"],
        confidence=float(confidence),
        lapse_corrected=bool(lapse_corrected),
        threshold=float(est["threshold"]),
        width=float(est["width"]),
        lapse=float(est["lambda"]),
        guess=gamma_hat,
        eta=float(est.get("eta", 0.0)),
        sigmoid=sigmoid_name,
        experiment_type=str(opts["experiment_type"]),
        n_trials=int(c.size),
        data=data,
        warnings=tuple(str(w.message) for w in caught),
        result=dataclasses.replace(res, debug={}),
    )


def fit_all(responses: Responses, **options: Any) -> list[PsychometricFit]:
    """Fit every (subject, device) of an experiment (thesis §3.6: per subject and device).

    Args:
        responses: the experiment's `Responses`.
        **options: keyword options of `fit_psychometric`.

    Returns:
        list of `PsychometricFit`, in order of first appearance of each (subject, device).

    Raises:
        InvalidInput: as `fit_psychometric`, naming the subject and device (and the
            first CSV line of that group when the responses came from a file).
    """
    fits = []
    for (subject, device), idx in responses.groups().items():
        try:
            fits.append(
                fit_psychometric(
                    responses.comparison[idx],
                    responses.response[idx],
                    subject=subject,
                    device=device,
                    **options,
                )
            )
        except InvalidInput as exc:
            line = int(responses.line[idx[0]])
            where = f" (rows from line {line})" if line >= 0 else ""
            raise InvalidInput(f"{exc}{where}") from None
    return fits


def results_table(fits: Iterable[PsychometricFit]) -> list[dict[str, Any]]:
    """Tidy per-subject table (one row per subject and device; see `PsychometricFit.row`)."""
    return [f.row() for f in fits]


def by_device(
    fits: Iterable[PsychometricFit],
    measure: str = "wf",
    *,
    devices: Sequence[str] | None = None,
) -> tuple[list[str], dict[str, np.ndarray]]:
    """One measure per device, aligned by subject, for the paired statistics of §3.6.

    Args:
        fits: fits of several subjects and devices.
        measure: "pse", "lt", "ut", "jnd" or "wf".
        devices: device order (default: order of first appearance).

    Returns:
        ``(subjects, values)``: the subjects (sorted) and ``{device: (n_subjects,) array}``.

    Raises:
        InvalidInput: unknown measure, duplicate (subject, device), or a subject
            missing on some device (paired tests need complete subjects).
    """
    if measure not in MEASURES:
        raise InvalidInput(f"measure: expected one of {MEASURES}, got {measure!r}")
    table: dict[tuple[str, str], float] = {}
    order: list[str] = []
    for f in fits:
        key = (f.subject, f.device)
        if key in table:
            raise InvalidInput(f"fits: two fits for subject {f.subject!r} on device {f.device!r}")
        table[key] = float(getattr(f, measure))
        if f.device not in order:
            order.append(f.device)
    devs = list(devices) if devices is not None else order
    subjects = sorted({s for s, _ in table})
    for d in devs:
        missing = [s for s in subjects if (s, d) not in table]
        if missing:
            raise InvalidInput(f"fits: device {d!r} has no fit for subject(s) {missing}")
    return subjects, {d: np.array([table[(s, d)] for s in subjects]) for d in devs}


# --------------------------------------------------------------------------- the study


@dataclasses.dataclass(frozen=True)
class StudyAnalysis:
    """The §3.6 analysis of a whole study: Table 3.3, the ANOVA and the paired tests.

    Attributes:
        fits: one `PsychometricFit` per subject and device.
        subjects: subjects present on every device (sorted).
        devices: devices in order.
        measure: the measure tested ("wf" in the thesis).
        summary: ``{measure: [Summary per device]}`` for "wf", "jnd" and "pse" (Table 3.3:
            mean (std); the medians of Fig. 3.10).
        values: ``{device: (n_subjects,) values of measure}`` aligned with ``subjects``.
        anova: between-subjects one-way ANOVA (what the thesis reports, F(2, 27)).
        anova_rm: repeated-measures ANOVA (the within-subject design, F(2, 18)).
        paired: paired t-tests between every pair of devices, adjusted (Holm in §3.6).
    """

    fits: list[PsychometricFit]
    subjects: list[str]
    devices: list[str]
    measure: str
    summary: dict[str, list[Summary]]
    values: dict[str, np.ndarray]
    anova: AnovaResult
    anova_rm: AnovaResult
    paired: list[PairedTest]


def analyse_fits(
    fits: Sequence[PsychometricFit],
    *,
    measure: str = "wf",
    devices: Sequence[str] | None = None,
    correction: str = "holm",
    alternative: str = "two-sided",
    alpha: float = 0.05,
) -> StudyAnalysis:
    """Table 3.3 and the §3.6 tests from per-subject fits.

    Args:
        fits: fits of every subject on every device.
        measure: measure for the ANOVA and t-tests (thesis: "wf").
        devices: device order (default: first appearance).
        correction: p-value adjustment of the paired tests ("holm" in §3.6, "fdr_bh" as Table 5.2).
        alternative: of the paired tests ("two-sided", "less", "greater").
        alpha: family-wise error rate (or FDR).

    Returns:
        `StudyAnalysis`.

    Raises:
        InvalidInput: a subject missing on a device, fewer than two devices or
            subjects, or bad test options.
    """
    fits = list(fits)
    subjects, values = by_device(fits, measure, devices=devices)
    devs = list(values)
    summary = {}
    for m in ("wf", "jnd", "pse"):
        summary[m] = describe(by_device(fits, m, devices=devs)[1])
    return StudyAnalysis(
        fits=fits,
        subjects=subjects,
        devices=devs,
        measure=measure,
        summary=summary,
        values=values,
        anova=one_way_anova(values),
        anova_rm=repeated_measures_anova(values),
        paired=paired_t_tests(values, correction=correction, alternative=alternative, alpha=alpha),
    )


def analyse(
    responses: Responses,
    *,
    measure: str = "wf",
    devices: Sequence[str] | None = None,
    correction: str = "holm",
    **fit_options: Any,
) -> StudyAnalysis:
    """Fit every subject and device, then `analyse_fits` (the whole §3.6 analysis of a study).

    ``rhi.analysis.psychophysics.analyse(from_csv("study.csv"))`` analyses a lab's own experiment.

    Args:
        responses: the study's responses.
        measure, devices, correction: see `analyse_fits`.
        **fit_options: keyword options of `fit_psychometric`.
    """
    return analyse_fits(fit_all(responses, **fit_options), measure=measure, devices=devices, correction=correction)
