"""A second, independent transcription of eq. 3.24's identification (§3.5, Table 3.2; issue 23).

Plain NumPy from the thesis text (line 662): the end-effector position from the encoders, "the first
and the second derivative of the position ... using a second order filter" (a local quadratic
least-squares fit, written out here as its own convolution weights), "a 5th-order lowpass filter"
(SciPy's Butterworth in transfer-function form, run forwards and backwards: zero phase), and "linear
least-squares" of Λ ẍ + B ẋ = F_ext (eq. 3.24, F_r = B ẋ) by `numpy.linalg.lstsq`. It imports nothing of
`rhi.analysis`. rhi's own choices it takes as data: the derivative window (13 samples at 1 kHz), the
20 Hz cut-off, dropping the half-window edges and one window more at each end, and the samples whose
filtered position lies within ±3 mm of the point.
"""

from __future__ import annotations

import numpy as np
from scipy import signal


def quadratic_derivatives(x: np.ndarray, h: float, window: int) -> tuple[np.ndarray, np.ndarray]:
    """ẋ, ẍ at every sample with a full window: x ≈ a + bτ + cτ² fitted over `window` samples, ẋ = b, ẍ = 2c.

    Returns (N − window + 1,) each, for samples window//2 … N − window//2 − 1.
    """
    k = window // 2
    tau = np.arange(-k, k + 1) * h
    V = np.stack([np.ones_like(tau), tau, tau**2], axis=1)
    P = np.linalg.pinv(V)  # (3, window): [a, b, c] = P @ x_window
    xs = np.lib.stride_tricks.sliding_window_view(x, window)
    coef = xs @ P.T
    return coef[:, 1], 2.0 * coef[:, 2]


def butterworth_zero_phase(x: np.ndarray, fs: float, cutoff: float, order: int = 5) -> np.ndarray:
    """The 5th-order Butterworth low-pass run forwards and backwards (transfer-function form)."""
    b, a = signal.butter(order, cutoff, btype="low", fs=fs)
    return signal.filtfilt(b, a, x)


def fit_eq_3_24(records, *, point: float, half_width: float = 0.003, cutoff: float = 20.0, window: int = 13,
                lowpass: bool = True) -> tuple[float, float]:
    """(Λ [kg], B [N s/m]) of eq. 3.24 pooled over the trials; each record has .time, .position, .force."""
    A, y = [], []
    for r in records:
        t, x, f = np.asarray(r.time), np.asarray(r.position), np.asarray(r.force)
        h = float(np.median(np.diff(t)))
        v, acc = quadratic_derivatives(x, h, window)
        k = window // 2
        sl = slice(k, len(t) - k)
        sig = np.stack([x[sl], v, acc, f[sl]])
        if lowpass:
            sig = np.stack([butterworth_zero_phase(s, 1.0 / h, cutoff) for s in sig])
        ts = t[sl]
        trim = window * h
        keep = (ts >= ts[0] + trim) & (ts <= ts[-1] - trim)
        keep &= (sig[0] >= point - half_width) & (sig[0] <= point + half_width)
        A.append(np.stack([sig[2][keep], sig[1][keep]], axis=1))
        y.append(sig[3][keep])
    sol, *_ = np.linalg.lstsq(np.concatenate(A), np.concatenate(y), rcond=None)
    return float(sol[0]), float(sol[1])
