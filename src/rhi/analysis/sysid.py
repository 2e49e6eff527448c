"""System identification of the apparent mass and viscous friction along a direction.

The end-effector of a haptic interface pushed by a constant external force along
a direction ``u`` is modelled as the scalar system

    M_x ẍ + Φ ẋ (+ c) = F_ext                      (thesis eqs. 3.24 and 6.22)

with ``x`` the position along ``u`` [m], ``M_x`` the effective apparent inertia
[kg] (Λ of eq. 3.13 in chapter 3), ``Φ`` the viscous (back-drive) friction
[N s/m] and ``c`` an optional constant force [N] (force-sensor bias, or the
Coulomb friction of a motion in one direction). The thesis's procedure (§3.5,
§6.4): velocity and acceleration from the measured position by a second-order
differentiating filter, every signal through a zero-phase 5th-order Butterworth
low-pass, then linear least squares over ten pooled trials.

Why filtering does not bias the fit: the zero-phase filter (``sosfiltfilt`` with
odd padding) is a *linear* operator on a record, and the same operator is applied
to the regressand ``F`` and to the regressors ``ẍ``, ``ẋ`` and the constant, so
an exact relation ``F = M ẍ + Φ ẋ + c`` before filtering holds exactly after it.
What can break it is the differentiator at a record's ends, where its fits are
one-sided: those samples are dropped before filtering and a further derivative
window is trimmed after it (`regressors`, `identify`). The cut-off then trades
noise against nothing in the model; it need only stay above the dynamics.

Default cut-off, 20 Hz: the free response has a single pole at ``Φ/(2π M)``,
0.4-1.3 Hz for the devices of Tables 3.2 and 6.1 (``M`` 0.04-0.57 kg, ``Φ``
0.3-0.6 N s/m), and voluntary hand motion stays below ~10 Hz; 20 Hz keeps both
with margin while removing encoder and force-sensor noise, whose second
derivative grows as ``f²``. Raise it for short records of a light device.

Uncertainty: filtered, densely sampled residuals are strongly autocorrelated, so
ordinary least-squares standard errors would be far too small. The default
(``covariance="auto"``) uses cluster-robust standard errors with one cluster per
trial (independent trials, arbitrary correlation within a trial; Student t with
``n_trials − 1`` degrees of freedom) when there are at least 5 trials, and
Newey-West (HAC) standard errors with a lag of two cut-off periods otherwise.
Trials must have independent noise for the cluster errors to hold.

Measured on simulated trials (`simulate_record`: ten trials of 0.12-0.3 s at
1 kHz under 0.5-1.5 N; M 0.036-0.5 kg, Φ 0.3-2 N s/m): noiseless relative error
below 2·10⁻⁴; with 10 µm position and 0.02 N force noise the 95 % intervals
covered the truth in 92-99 % of 100 data sets per plant, with 50 µm and 0.05 N
in 89-95 % for M <= 0.125 kg. Position noise also enters the regressors (errors
in variables) and biases ``M_x`` towards zero: with 50 µm on the 0.5 kg device
(acceleration only ~2 m/s²) the bias was -2 % against a standard error of 1.3 %
(coverage 80-85 %); lower the cut-off for heavy, slow devices.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import as_array, scalar, unit_vector
from rhi.analysis._csv import read_rows
from rhi.errors import InvalidInput

#: fewest samples a record may have (filter padding, derivative window, 3 parameters).
MIN_SAMPLES = 32
#: largest relative deviation of a sampling interval from the median interval.
UNIFORM_TOLERANCE = 0.05

FloatArray = np.ndarray


@dataclasses.dataclass(frozen=True)
class Record:
    """One identification trial: position and force along ``u`` sampled in time.

    Attributes:
        time: (N,) strictly increasing, uniformly sampled time [s].
        position: (N,) end-effector position along ``u`` [m] (any origin).
        force: (N,) external force along ``u`` [N].
        label: trial name used in error messages and results.
    """

    time: FloatArray
    position: FloatArray
    force: FloatArray
    label: str = ""

    def __post_init__(self) -> None:
        name = f"record {self.label!r}" if self.label else "record"
        t = as_array(f"{name}.time", self.time, shape_tail=(None,))
        x = as_array(f"{name}.position", self.position, shape_tail=(None,))
        f = as_array(f"{name}.force", self.force, shape_tail=(None,))
        if t.ndim != 1 or x.shape != t.shape or f.shape != t.shape:
            raise InvalidInput(
                f"{name}: time, position and force must be 1-D of equal length, "
                f"got shapes {t.shape}, {x.shape}, {f.shape}"
            )
        if t.size < MIN_SAMPLES:
            raise InvalidInput(f"{name}: {t.size} samples; need at least {MIN_SAMPLES}")
        dt = np.diff(t)
        if (dt <= 0).any():
            i = int(np.flatnonzero(dt <= 0)[0]) + 1
            raise InvalidInput(
                f"{name}.time: not strictly increasing at sample {i} ({float(t[i - 1])!r} then {float(t[i])!r})"
            )
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "position", x)
        object.__setattr__(self, "force", f)

    @property
    def sample_rate(self) -> float:
        """Sampling rate [Hz] from the median interval."""
        return 1.0 / float(np.median(np.diff(self.time)))

    def is_uniform(self, tolerance: float = UNIFORM_TOLERANCE) -> bool:
        """Whether every sampling interval is within ``tolerance`` (relative) of the median."""
        dt = np.diff(self.time)
        med = np.median(dt)
        return bool(np.all(np.abs(dt - med) <= tolerance * med))

    def resampled(self, rate: float) -> Record:
        """The record linearly interpolated onto a uniform grid of ``rate`` [Hz]."""
        if not (math.isfinite(rate) and rate > 0):
            raise InvalidInput(f"rate: must be a positive sampling rate in Hz, got {rate!r}")
        t = np.arange(self.time[0], self.time[-1] + 0.5 / rate, 1.0 / rate)
        t = t[t <= self.time[-1]]
        return Record(t, np.interp(t, self.time, self.position), np.interp(t, self.time, self.force), self.label)


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


def project(positions: ArrayLike, forces: ArrayLike, u: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Project Cartesian trajectories and forces onto a direction: ``x = p·û``, ``F = f·û``.

    Args:
        positions: (..., N, m) end-effector positions [m] (e.g. from forward kinematics).
        forces: (..., N, m) external forces [N] in the same frame, or (..., N) already along ``u``.
        u: (m,) direction (normalised internally, must be non-zero).

    Returns:
        ``(x, F)``: (..., N) position along ``û`` [m] and (..., N) force along ``û`` [N].

    Raises:
        InvalidInput: mismatched shapes, non-finite entries or zero-length ``u``.
    """
    p = as_array("positions", positions, ndim_min=2)
    u = unit_vector("u", u, p.shape[-1])
    if u.ndim != 1:
        raise InvalidInput(f"u: expected shape ({p.shape[-1]},), got {u.shape}")
    f = as_array("forces", forces, ndim_min=1)
    x = p @ u
    if f.shape == p.shape:
        F = f @ u
    elif f.shape == x.shape:
        F = f
    else:
        raise InvalidInput(f"forces: expected shape {p.shape} or {x.shape} to match positions, got {f.shape}")
    return x, F


def lowpass(signal: ArrayLike, *, sample_rate: float, cutoff_hz: float = 20.0, order: int = 5) -> FloatArray:
    """Zero-phase Butterworth low-pass along the last axis (thesis §3.5, §6.4: 5th order).

    ``scipy.signal.butter`` in second-order sections run forwards and backwards
    (``sosfiltfilt``): no phase lag, squared magnitude response, and a linear
    operator on the record (odd padding), so relations that are linear in the
    filtered signals survive the filtering exactly.

    Args:
        signal: (..., N) uniformly sampled signal.
        sample_rate: sampling rate [Hz].
        cutoff_hz: -3 dB frequency of the one-way filter [Hz], below ``sample_rate / 2``.
        order: filter order (the response is applied twice).

    Returns:
        (..., N) filtered signal.

    Raises:
        InvalidInput: non-finite signal, cut-off not in (0, Nyquist), or a record
            shorter than the filter's padding.
    """
    from scipy import signal as sps

    x = as_array("signal", signal, ndim_min=1)
    sample_rate = scalar("sample_rate", sample_rate, positive=True)
    cutoff_hz = scalar("cutoff_hz", cutoff_hz, positive=True)
    if not (math.isfinite(sample_rate) and sample_rate > 0):
        raise InvalidInput(f"sample_rate: must be positive, got {sample_rate!r}")
    if not (0 < cutoff_hz < sample_rate / 2):
        raise InvalidInput(f"cutoff_hz: must lie in (0, {sample_rate / 2:g}) Hz (Nyquist), got {cutoff_hz!r}")
    if int(order) != order or order < 1:
        raise InvalidInput(f"order: must be a positive integer, got {order!r}")
    sos = sps.butter(int(order), cutoff_hz, btype="low", fs=sample_rate, output="sos")
    padlen = 3 * (2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum()))
    if x.shape[-1] <= padlen:
        raise InvalidInput(f"signal: {x.shape[-1]} samples; a zero-phase order-{order} filter needs more than {padlen}")
    return sps.sosfiltfilt(sos, x, axis=-1)


def default_window(sample_rate: float, cutoff_hz: float) -> int:
    """Default Savitzky-Golay window: the odd number of samples nearest a quarter of the cut-off period.

    Short enough that its own low-pass (≈ 3.5 cut-off frequencies for a quadratic
    fit) leaves the Butterworth in charge, long enough that the per-sample noise of
    the second derivative (∝ window^-2.5) stays small at the record's edges, where
    the filter's padding amplifies it. Measured on simulated trials (see
    tests/test_analysis.py): 7 samples at 1 kHz biases a 0.5 kg mass by -10 % through
    acceleration noise (errors in variables); 11-15 samples keep the bias below 0.3 %.

    Args:
        sample_rate: [Hz].
        cutoff_hz: low-pass cut-off [Hz].

    Returns:
        odd window length >= 5 [samples].
    """
    w = int(round(sample_rate / (4.0 * cutoff_hz)))
    return max(5, w + 1 - w % 2)


def derivatives(
    time: ArrayLike,
    position: ArrayLike,
    *,
    method: Literal["savgol", "central"] = "savgol",
    window: int | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Velocity and acceleration of a sampled position by a second-order differentiator.

    ``"savgol"``: Savitzky-Golay, a local quadratic (second-order) least-squares fit
    over ``window`` samples differentiated once and twice (uniform sampling).
    ``"central"``: second-order-accurate central differences (``numpy.gradient``,
    applied twice; also valid on non-uniform time).

    Args:
        time: (N,) strictly increasing time [s].
        position: (..., N) position [m].
        method: "savgol" or "central".
        window: odd Savitzky-Golay window in samples (default: `default_window` at a
            20 Hz cut-off, i.e. about 12.5 ms of samples).

    Returns:
        ``(velocity, acceleration)``: (..., N) [m/s] and (..., N) [m/s²].

    Raises:
        InvalidInput: bad shapes, non-increasing time, non-uniform time for "savgol",
            a window that is even, below 3 or longer than the record.
    """
    t = as_array("time", time, shape_tail=(None,))
    x = as_array("position", position, ndim_min=1)
    if t.ndim != 1 or x.shape[-1] != t.shape[0]:
        raise InvalidInput(f"position: last axis must match time's {t.shape}, got {x.shape}")
    if t.size < 5:
        raise InvalidInput(f"time: {t.size} samples; need at least 5")
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.flatnonzero(dt <= 0)[0]) + 1
        raise InvalidInput(f"time: not strictly increasing at sample {i}")
    if method == "central":
        v = np.gradient(x, t, axis=-1, edge_order=2)
        return v, np.gradient(v, t, axis=-1, edge_order=2)
    if method != "savgol":
        raise InvalidInput(f"method: expected 'savgol' or 'central', got {method!r}")
    from scipy.signal import savgol_filter

    h = float(np.median(dt))
    if np.any(np.abs(dt - h) > UNIFORM_TOLERANCE * h):
        i = int(np.flatnonzero(np.abs(dt - h) > UNIFORM_TOLERANCE * h)[0]) + 1
        raise InvalidInput(
            f"time: sampling is not uniform at sample {i} (interval {dt[i - 1]:.3g} s, median {h:.3g} s); "
            "use method='central' or Record.resampled()"
        )
    if window is None:
        window = default_window(1.0 / h, 20.0)
    if int(window) != window or window < 3 or window % 2 == 0:
        raise InvalidInput(f"window: must be an odd integer >= 3, got {window!r}")
    if window > t.size:
        raise InvalidInput(f"window: {window} samples exceeds the record length {t.size}")
    v = savgol_filter(x, int(window), 2, deriv=1, delta=h, axis=-1)
    a = savgol_filter(x, int(window), 2, deriv=2, delta=h, axis=-1)
    return v, a


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
        cutoff_hz, order: low-pass cut-off [Hz] and order (see `lowpass`).
        derivative, window: differentiator (see `derivatives`); the default window is
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
    edge = int(window) // 2 if derivative == "savgol" else 1
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


def simulate_record(
    mass: float,
    damping: float,
    force: float,
    *,
    duration: float,
    rate: float = 1000.0,
    offset: float = 0.0,
    position_noise: float = 0.0,
    force_noise: float = 0.0,
    seed: int | Sequence[int] | None = None,
    label: str = "",
) -> Record:
    """A synthetic trial: ``M ẍ + Φ ẋ + c = F`` from rest, integrated by ``scipy.integrate.solve_ivp``.

    A test and teaching aid, not the physics simulation (that is `rhi.sim`): the
    true parameters are known, so `identify` can be checked against them.

    Args:
        mass: M [kg] > 0.
        damping: Φ [N s/m] >= 0.
        force: constant external force F [N] applied from t = 0.
        duration: record length [s].
        rate: sampling rate [Hz].
        offset: constant opposing force c [N].
        position_noise: standard deviation of white noise added to the position [m].
        force_noise: standard deviation of white noise added to the force [N].
        seed: seed of the noise generator (required when any noise is non-zero); give
            every trial its own seed, e.g. ``(seed, trial)``: trials with identical
            noise are not independent, and the cluster-robust errors of `identify`
            assume independent trials.
        label: trial name.

    Returns:
        `Record` sampled at ``rate`` on [0, duration].
    """
    from scipy.integrate import solve_ivp

    for name, val, ok in (
        ("mass", mass, mass > 0),
        ("damping", damping, damping >= 0),
        ("duration", duration, duration > 0),
        ("rate", rate, rate > 0),
        ("position_noise", position_noise, position_noise >= 0),
        ("force_noise", force_noise, force_noise >= 0),
    ):
        if not (math.isfinite(val) and ok):
            raise InvalidInput(f"{name}: invalid value {val!r}")
    if (position_noise > 0 or force_noise > 0) and seed is None:
        raise InvalidInput("seed: required when noise is added (reproducible runs)")
    t = np.arange(0.0, duration + 0.5 / rate, 1.0 / rate)

    def rhs(_t, s):
        return [s[1], (force - offset - damping * s[1]) / mass]

    sol = solve_ivp(rhs, (0.0, t[-1]), [0.0, 0.0], t_eval=t, method="DOP853", rtol=1e-10, atol=1e-13)
    x = sol.y[0]
    f = np.full_like(t, force)
    if position_noise > 0 or force_noise > 0:
        rng = np.random.default_rng(seed)
        x = x + position_noise * rng.standard_normal(t.size)
        f = f + force_noise * rng.standard_normal(t.size)
    return Record(t, x, f, label)


_POSITION_AXES = ("x", "y", "z")
_FORCE_AXES = ("fx", "fy", "fz")


def from_csv(path: str | Path, *, u: ArrayLike | None = None) -> list[Record]:
    """Read a user's recorded identification trials from a CSV file.

    The header names the columns (case and surrounding spaces ignored):

    - ``time`` [s], strictly increasing within a trial;
    - the position: ``position`` (already along ``u``) [m], or Cartesian
      ``x, y(, z)`` [m] projected onto ``u``;
    - the force: ``force`` (along ``u``) [N], or ``fx, fy(, fz)`` [N] projected onto ``u``;
    - optionally ``trial``: a label; rows with the same label form one record
      (in file order), so ten trials may share one file.

    Args:
        path: CSV file.
        u: (m,) direction, required when positions or forces are Cartesian.

    Returns:
        list of `Record`, one per trial, in order of first appearance.

    Raises:
        InvalidInput: unreadable file, missing column, a non-numeric or non-finite
            value (naming the line and column), time not increasing (naming the
            line), or a trial with fewer than `MIN_SAMPLES` rows.
    """
    path, cols, index, body = read_rows(path)
    if "time" not in index:
        raise InvalidInput(f"{path.name}: missing column 'time' (found {cols})")

    def cartesian(axes: Sequence[str]) -> list[str]:
        present = [a for a in axes if a in index]
        return present if present[:2] == list(axes[:2]) else []

    if "position" in index:
        pos_cols = ["position"]
    else:
        pos_cols = cartesian(_POSITION_AXES)
        if not pos_cols:
            raise InvalidInput(f"{path.name}: missing column 'position' (or Cartesian 'x', 'y'[, 'z']); found {cols}")
    if "force" in index:
        force_cols = ["force"]
    else:
        force_cols = cartesian(_FORCE_AXES)
        if not force_cols:
            raise InvalidInput(f"{path.name}: missing column 'force' (or Cartesian 'fx', 'fy'[, 'fz']); found {cols}")
    m = max(len(pos_cols), len(force_cols))
    if m > 1:
        if u is None:
            raise InvalidInput(f"u: required to project the Cartesian columns {pos_cols + force_cols} of {path.name}")
        u_vec = unit_vector("u", u)
        if u_vec.shape != (m,):
            raise InvalidInput(
                f"u: expected {m} components for columns {pos_cols + force_cols}, got shape {u_vec.shape}"
            )
        if 1 < len(pos_cols) != m or 1 < len(force_cols) != m:
            raise InvalidInput(
                f"{path.name}: position columns {pos_cols} and force columns {force_cols} differ in dimension"
            )
    numeric = ["time", *pos_cols, *force_cols]
    trial_i = index.get("trial")

    groups: dict[str, list[tuple[int, list[float]]]] = {}
    for line, row in body:
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) < len(cols):
            raise InvalidInput(f"{path.name}, line {line}: {len(row)} fields; the header has {len(cols)}")
        vals = []
        for c in numeric:
            text = row[index[c]].strip()
            try:
                v = float(text)
            except ValueError:
                raise InvalidInput(f"{path.name}, line {line}, column '{c}': {text!r} is not a number") from None
            if not math.isfinite(v):
                raise InvalidInput(f"{path.name}, line {line}, column '{c}': non-finite value {text!r}")
            vals.append(v)
        label = row[trial_i].strip() if trial_i is not None else ""
        groups.setdefault(label, []).append((line, vals))
    if not groups:
        raise InvalidInput(f"{path.name}: no data rows")

    records = []
    for label, items in groups.items():
        name = f"trial {label!r}" if label else "the file"
        if len(items) < MIN_SAMPLES:
            raise InvalidInput(f"{path.name}: {name} has {len(items)} rows; need at least {MIN_SAMPLES}")
        lines = [ln for ln, _ in items]
        data = np.array([v for _, v in items])
        t = data[:, 0]
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            j = int(bad[0]) + 1
            raise InvalidInput(
                f"{path.name}, line {lines[j]}, column 'time': {float(t[j])!r} does not increase "
                f"(previous row of {name}: {float(t[j - 1])!r})"
            )
        pos = data[:, 1 : 1 + len(pos_cols)]
        frc = data[:, 1 + len(pos_cols) :]
        x = pos[:, 0] if len(pos_cols) == 1 else pos @ u_vec
        f = frc[:, 0] if len(force_cols) == 1 else frc @ u_vec
        records.append(Record(t, x, f, label))
    return records
