"""Psychometric fits with psignifit per subject and device: PSE, LT, UT, JND (eq. 3.26), WF (eq. 3.25)."""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import float_array, scalar
from rhi.analysis.psychophysics.trials import MEASURES, Responses, pool
from rhi.errors import InvalidInput


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
    """Psignifit's cumulative-Gaussian sigmoid evaluated through ``scipy.special`` (same values).

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
        subject: subject label carried into the result and error messages.
        device: device label carried into the result and error messages.
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

