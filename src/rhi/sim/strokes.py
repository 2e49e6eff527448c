"""Synthetic strokes of a hand moving a haptic device: labelled force/velocity streams for intent estimation.

A stroke is a straight minimum-jerk movement of length L along a random axis u with peak
speed v_peak, followed by a pause; the hand force is what an impedance-type device with
apparent mass M [kg], damping B [N s/m] and Coulomb friction f_c [N] asks for,
F = M ẍ + B ẋ + f_c sign(ẋ) u, plus seeded Gaussian noise on the force (σ_F [N]) and on the
velocity (σ_v [m/s]). The label u_true is the current stroke's axis (held through the
following pause). Used to train (`rhi.control.intent.HMMIntent.fit`) and to test the
estimators of `rhi.control.intent`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rhi.errors import InvalidInput


@dataclasses.dataclass(frozen=True)
class Strokes:
    """Labelled streams sampled every dt.

    Attributes:
        t: (N,) time [s]; force: (N, m) hand force [N]; xdot: (N, m) velocity [m/s];
        u_true: (N, m) stroke axis (unit); onset: (k,) stroke start times [s]; moving: (N,) bool.
    """

    t: np.ndarray
    force: np.ndarray
    xdot: np.ndarray
    u_true: np.ndarray
    onset: np.ndarray
    moving: np.ndarray


def synthetic_strokes(count: int, *, m: int = 2, seed: int = 0, dt: float = 1e-3, length=(0.03, 0.10),
                      peak_speed=(0.015, 0.05), pause=(0.1, 0.4), mass: float = 0.1, damping: float = 0.3,
                      coulomb: float = 0.05, force_noise: float = 0.1, speed_noise: float = 0.001,
                      turn_min: float = np.radians(30.0)) -> Strokes:
    """`count` seeded strokes in m = 2 or 3 dimensions (module docstring); consecutive axes differ by ≥ `turn_min`.

    Args:
        count: number of strokes (>= 1).
        m: task dimensions.
        seed: NumPy generator seed.
        dt: sample period [s].
        length: (min, max) of the uniform draw of a stroke's length [m].
        peak_speed: (min, max) of the uniform draw of a stroke's peak speed [m/s].
        pause: (min, max) of the uniform draw of the pause after a stroke [s].
        mass: mass of the device the hand moves [kg].
        damping: viscous damping of the device [N s/m].
        coulomb: Coulomb friction of the device [N].
        force_noise: Gaussian noise σ of the force reading [N].
        speed_noise: Gaussian noise σ of the speed reading [m/s].
        turn_min: smallest axial angle between consecutive strokes [rad].
    """
    if not isinstance(count, (int, np.integer)) or count < 1:
        raise InvalidInput(f"count: expected an integer >= 1, got {count!r}")
    if m not in (2, 3):
        raise InvalidInput(f"m: expected 2 or 3, got {m!r}")
    for name, v in (("dt", dt), ("mass", mass), ("damping", damping), ("coulomb", coulomb),
                    ("force_noise", force_noise), ("speed_noise", speed_noise)):
        if not np.isfinite(v) or v < 0 or (name == "dt" and v == 0):
            raise InvalidInput(f"{name}: must be finite and {'> 0' if name == 'dt' else '>= 0'}, got {v!r}")
    for name, v in (("length", length), ("peak_speed", peak_speed), ("pause", pause)):
        if len(v) != 2 or not 0 <= v[0] <= v[1] or (name != "pause" and v[0] == 0):
            raise InvalidInput(f"{name}: expected (min, max) with 0 < min <= max, got {v!r}")
    rng = np.random.default_rng(seed)
    Fs: list[np.ndarray] = []
    Vs: list[np.ndarray] = []
    Us: list[np.ndarray] = []
    onset: list[float] = []
    mov: list[np.ndarray] = []
    u_prev, t0 = None, 0.0
    for _ in range(count):
        while True:
            u = rng.normal(size=m)
            u /= np.linalg.norm(u)
            if u_prev is None or np.arccos(min(1.0, abs(float(u @ u_prev)))) >= turn_min:
                break
        L, vp, rest = rng.uniform(*length), rng.uniform(*peak_speed), rng.uniform(*pause)
        T = 1.875 * L / vp  # minimum jerk: v_peak = 1.875 L / T
        s = np.arange(0.0, T, dt) / T
        v = L / T * (30 * s**2 - 60 * s**3 + 30 * s**4)
        a = L / T**2 * (60 * s - 180 * s**2 + 120 * s**3)
        f = mass * a + damping * v + coulomb * np.sign(v)
        k_rest = int(round(rest / dt))
        v = np.r_[v, np.zeros(k_rest)]
        f = np.r_[f, np.zeros(k_rest)]
        onset.append(t0)
        t0 += len(v) * dt
        Vs.append(v[:, None] * u)
        Fs.append(f[:, None] * u)
        Us.append(np.tile(u, (len(v), 1)))
        mov.append(np.r_[np.ones(len(s), bool), np.zeros(k_rest, bool)])
        u_prev = u
    V, F, U = np.vstack(Vs), np.vstack(Fs), np.vstack(Us)
    F = F + rng.normal(scale=force_noise, size=F.shape)
    V = V + rng.normal(scale=speed_noise, size=V.shape)
    return Strokes(np.arange(len(V)) * dt, F, V, U, np.array(onset), np.concatenate(mov))
