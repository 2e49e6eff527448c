"""The least-squares fit of eq. 3.24/6.22 (M_x ẍ + Φ ẋ [+ c] = F) over trials, with cluster-robust intervals."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Literal

import numpy as np

from rhi.analysis.sysid.records import Record
from rhi.analysis.sysid.signals import default_window, derivatives, lowpass
from rhi.errors import InvalidInput

FloatArray = np.ndarray


@dataclasses.dataclass(frozen=True)
class SysidResult:
    """Identified ``M_x ẍ + Φ ẋ (+ c) = F`` along ``u`` (thesis eqs. 3.24, 6.22).

    Attributes:
        mass: M_x [kg].
        damping: Φ [N s/m].
        offset: c [N], or None when not fitted.
        mass_se, damping_se: standard errors [kg], [N s/m].
        offset_se: standard error of c [N], or None.
        mass_ci, damping_ci: (low, high) confidence intervals at ``confidence``.
        offset_ci: (low, high) for c, or None.
        confidence: level of the intervals (e.g. 0.95).
        covariance: "cluster" (by trial), "hac" (Newey-West) or "ols".
        dof: degrees of freedom of the Student t used for the intervals.
        residual_rms: RMS of ``F − M ẍ − Φ ẋ − c`` over the fitted samples [N].
        r_squared: coefficient of determination of the fit.
        n_samples: samples used in the regression (all trials).
        n_trials: number of trials pooled.
        cutoff_hz: low-pass cut-off used [Hz].
        params: (p,) [M_x, Φ(, c)]; cov: (p, p) their covariance.
    """

    mass: float
    damping: float
    offset: float | None
    mass_se: float
    damping_se: float
    offset_se: float | None
    mass_ci: tuple[float, float]
    damping_ci: tuple[float, float]
    offset_ci: tuple[float, float] | None
    confidence: float
    covariance: str
    dof: float
    residual_rms: float
    r_squared: float
    n_samples: int
    n_trials: int
    cutoff_hz: float
    params: FloatArray = dataclasses.field(repr=False)
    cov: FloatArray = dataclasses.field(repr=False)




def regressors(
    record: Record,
    *,
    cutoff_hz: float = 20.0,
    order: int = 5,
    derivative: Literal["savgol", "central"] = "savgol",
    window: int | None = None,
) -> dict[str, FloatArray]:
    """Filtered signals of one record: position, velocity, acceleration and force.

    Derivatives first (second-order differentiator), then the same zero-phase
    Butterworth low-pass on all four signals (thesis §3.5, §6.4). The samples
    where the differentiator is one-sided (half a window at each end; one sample
    for "central") are dropped before filtering, so the filter's padding starts
    from accurate values.

    Args:
        record: one trial (uniformly sampled).
        cutoff_hz: low-pass cut-off [Hz] (see `lowpass`).
        order: low-pass order (see `lowpass`).
        derivative: differentiator (see `derivatives`).
        window: its window (see `derivatives`); the default window is
            `default_window(sample_rate, cutoff_hz)`.

    Returns:
        dict with "time" [s], "position" [m], "velocity" [m/s], "acceleration" [m/s²],
        "force" [N], each (N − 2·edge,).

    Raises:
        InvalidInput: non-uniform sampling (name the record) or bad filter settings.
    """
    if not record.is_uniform():
        raise InvalidInput(
            f"record {record.label!r}: time is not uniformly sampled; use Record.resampled(rate) first"
        )
    fs = record.sample_rate
    if window is None and derivative == "savgol":
        window = default_window(fs, cutoff_hz)
    v, a = derivatives(record.time, record.position, method=derivative, window=window)
    # One-sided (edge) derivative estimates are much less accurate than centred ones, and the
    # filter's odd padding would spread their error over ~1/cutoff: drop them before filtering.
    edge = int(window) // 2 if derivative == "savgol" and window is not None else 1
    sl = slice(edge, record.time.size - edge)
    stacked = np.stack([record.position[sl], v[sl], a[sl], record.force[sl]])
    try:
        xf, vf, af, ff = lowpass(stacked, sample_rate=fs, cutoff_hz=cutoff_hz, order=order)
    except InvalidInput as exc:
        raise InvalidInput(
            f"record {record.label!r}: {record.time.size} samples at {fs:.4g} Hz are too few for a "
            f"{derivative} differentiator (drops {edge} at each end) and this filter ({exc})"
        ) from None
    return {"time": record.time[sl], "position": xf, "velocity": vf, "acceleration": af, "force": ff}


def identify(
    records: Record | Iterable[Record],
    *,
    cutoff_hz: float = 20.0,
    order: int = 5,
    derivative: Literal["savgol", "central"] = "savgol",
    window: int | None = None,
    offset: bool = False,
    position_range: tuple[float, float] | None = None,
    trim_s: float | None = None,
    covariance: Literal["auto", "cluster", "hac", "ols"] = "auto",
    confidence: float = 0.95,
) -> SysidResult:
    """Identify ``M_x`` and viscous ``Φ`` in ``M_x ẍ + Φ ẋ (+ c) = F`` (thesis eqs. 3.24, 6.22).

    Each record is differentiated and low-passed on its own (`regressors`), the
    selected samples of all records are pooled, and ``[M_x, Φ(, c)]`` solves the
    linear least-squares problem ``min Σ (F − M_x ẍ − Φ ẋ − c)²``.

    Args:
        records: one `Record` or several trials (the thesis pools ten).
        cutoff_hz: low-pass cut-off [Hz] (default 20 Hz; see the module docstring).
        order: Butterworth order (thesis: 5).
        derivative: "savgol" (default) or "central" (see `derivatives`).
        window: Savitzky-Golay window [samples] (default `default_window`: a quarter
            of the cut-off period, 13 samples at 1 kHz and 20 Hz).
        offset: also fit a constant force ``c`` [N].
        position_range: (low, high) [m]: use only samples whose filtered position
            along ``u`` lies in this interval (e.g. around the point of interest,
            as the thesis measures "at" the point after starting 1 or 5 cm before).
        trim_s: drop this many seconds at both ends of every record [s], where the
            differentiator's one-sided fits and the filter's padding act. Default:
            one derivative window (13 ms at 1 kHz and 20 Hz); 0 keeps everything.
        covariance: "cluster" (by trial), "hac" (Newey-West), "ols", or "auto"
            (cluster with ≥ 5 trials, HAC otherwise).
        confidence: level of the reported intervals, in (0, 1).

    Returns:
        `SysidResult` with estimates, standard errors, intervals and fit quality.

    Raises:
        InvalidInput: no records, bad settings, too few selected samples, or
            regressors without excitation (e.g. no motion).
    """
    from statsmodels.regression.linear_model import OLS

    recs = [records] if isinstance(records, Record) else list(records)
    if not recs:
        raise InvalidInput("records: no trials given")
    for i, r in enumerate(recs):
        if not isinstance(r, Record):
            raise InvalidInput(f"records[{i}]: expected a Record, got {type(r).__name__}")
    if not (0 < confidence < 1):
        raise InvalidInput(f"confidence: must lie in (0, 1), got {confidence!r}")
    if trim_s is not None and not (math.isfinite(trim_s) and trim_s >= 0):
        raise InvalidInput(f"trim_s: must be a non-negative number of seconds, got {trim_s!r}")
    if position_range is not None:
        lo, hi = (float(v) for v in position_range)
        if not (lo < hi):
            raise InvalidInput(f"position_range: low must be below high, got {position_range!r}")
    if covariance not in ("auto", "cluster", "hac", "ols"):
        raise InvalidInput(f"covariance: expected 'auto', 'cluster', 'hac' or 'ols', got {covariance!r}")

    rows, ys, groups = [], [], []
    max_rate = 0.0
    for k, r in enumerate(recs):
        s = regressors(r, cutoff_hz=cutoff_hz, order=order, derivative=derivative, window=window)
        if trim_s is None:
            w = window if window is not None else default_window(r.sample_rate, cutoff_hz)
            trim = w / r.sample_rate
        else:
            trim = trim_s
        keep = (s["time"] >= s["time"][0] + trim) & (s["time"] <= s["time"][-1] - trim)
        if position_range is not None:
            keep &= (s["position"] >= lo) & (s["position"] <= hi)
        cols = [s["acceleration"][keep], s["velocity"][keep]]
        if offset:
            cols.append(np.ones(int(keep.sum())))
        rows.append(np.stack(cols, axis=-1))
        ys.append(s["force"][keep])
        groups.append(np.full(int(keep.sum()), k))
        max_rate = max(max_rate, r.sample_rate)
    X = np.concatenate(rows)
    y = np.concatenate(ys)
    g = np.concatenate(groups)
    p = X.shape[1]
    if X.shape[0] < 3 * p + 2:
        raise InvalidInput(
            f"records: only {X.shape[0]} samples selected (trim_s/position_range); need at least {3 * p + 2}"
        )
    scale = np.sqrt((X * X).sum(axis=0))
    if (scale == 0).any() or np.linalg.cond(X / np.where(scale == 0, 1, scale)) > 1e8:
        raise InvalidInput("records: acceleration and velocity are not independently excited (no or constant motion)")

    n_trials = len(set(g.tolist()))
    method = covariance
    if method == "auto":
        method = "cluster" if n_trials >= 5 else "hac"
    if method == "cluster" and n_trials < 2:
        raise InvalidInput("covariance: 'cluster' needs at least 2 trials with selected samples")
    model = OLS(y, X)
    if method == "cluster":
        fit = model.fit(cov_type="cluster", cov_kwds={"groups": g}, use_t=True)
        dof = float(n_trials - 1)
    elif method == "hac":
        maxlags = int(math.ceil(2 * max_rate / cutoff_hz))
        fit = model.fit(cov_type="HAC", cov_kwds={"maxlags": maxlags}, use_t=True)
        dof = float(X.shape[0] - p)
    else:
        fit = model.fit(use_t=True)
        dof = float(X.shape[0] - p)
    params = np.asarray(fit.params, dtype=float)
    cov = np.asarray(fit.cov_params(), dtype=float)
    se = np.sqrt(np.diag(cov))
    from scipy import stats

    q = float(stats.t.ppf(0.5 + confidence / 2, dof))
    ci = [(float(params[i] - q * se[i]), float(params[i] + q * se[i])) for i in range(p)]
    resid = y - X @ params
    ss_tot = float(((y - y.mean()) ** 2).sum())
    if not ss_tot > 1e-12 * float((y * y).sum()):
        raise InvalidInput("records: the force is constant over the selected samples, so the fit's R² is undefined; "
                           "record a varying force (a push, a release)")
    return SysidResult(
        mass=float(params[0]),
        damping=float(params[1]),
        offset=float(params[2]) if offset else None,
        mass_se=float(se[0]),
        damping_se=float(se[1]),
        offset_se=float(se[2]) if offset else None,
        mass_ci=ci[0],
        damping_ci=ci[1],
        offset_ci=ci[2] if offset else None,
        confidence=float(confidence),
        covariance=method,
        dof=dof,
        residual_rms=float(np.sqrt(np.mean(resid**2))),
        r_squared=1.0 - float((resid**2).sum()) / ss_tot,
        n_samples=int(X.shape[0]),
        n_trials=n_trials,
        cutoff_hz=float(cutoff_hz),
        params=params,
        cov=cov,
    )


