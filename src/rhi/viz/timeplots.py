"""Plots over time in the view's panel (viser's uPlot): torques against limits, forces along u, V, α and β.

`History` keeps the last `window` seconds of what the view drew (live: a ring of snapshots; replay:
a slice of the log at the playback time, so seeking back works). `TimePlots` draws three charts
from it: each joint's torque as a fraction of its limit (±1 is the limit), the hand and environment
forces along the direction u the view measures along [N], and the ASO's V with the scalings α and β.
"""

from __future__ import annotations

import numpy as np

from rhi.sim.log import Log

_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf")


class History:
    """The last `window` seconds of the view's snapshots, as arrays.

    Args:
        n: motors.
        torque_min, torque_max: (n,) limits [N m] (the torques are stored as fractions of them).
        window: length of the history [s].
        capacity: most rows kept (the view draws at ≤ 60 frames per second).
    """

    def __init__(self, n: int, torque_min, torque_max, *, window: float = 5.0, capacity: int = 512) -> None:
        self.n, self.window = int(n), float(window)
        self.lo, self.hi = np.asarray(torque_min, dtype=float), np.asarray(torque_max, dtype=float)
        self._rows = np.full((capacity, 6 + n), np.nan)  # t, F_h·u, F_env·u, V, α, β, τ/limit (n)
        self._k = 0

    def ratio(self, tau: np.ndarray) -> np.ndarray:
        """τ: (..., n) [N m] as fractions of the limit on its side (−1 … 1 within the limits)."""
        tau = np.asarray(tau, dtype=float)
        return np.where(tau >= 0, tau / self.hi, tau / -self.lo)

    def add(self, snap, u: np.ndarray) -> None:
        """Append one snapshot (t, tau, F_hand, F_env, V, alpha, beta); a time going back starts afresh."""
        t = float(snap.t)
        if self._k and t < self._rows[(self._k - 1) % len(self._rows), 0]:
            self._rows[:] = np.nan
            self._k = 0
        g = lambda k: float(getattr(snap, k, np.nan))  # noqa: E731
        fu = [float(np.dot(np.asarray(getattr(snap, k, np.zeros_like(u)), dtype=float), u)) for k in ("F_hand", "F_env")]
        self._rows[self._k % len(self._rows)] = [t, *fu, g("V"), g("alpha"), g("beta"), *self.ratio(snap.tau)]
        self._k += 1

    def fill(self, log: Log, t: float, u: np.ndarray) -> None:
        """Replace the history by the log's last `window` seconds up to time t [s] (replay)."""
        i1 = int(np.searchsorted(log.t, t, side="right"))
        i0 = int(np.searchsorted(log.t, t - self.window, side="left"))
        idx = np.linspace(i0, max(i1 - 1, i0), min(len(self._rows), max(i1 - i0, 1))).astype(int)
        rows = np.column_stack([log.t[idx], log.F_hand[idx] @ u, log.F_env[idx] @ u, log.V[idx], log.alpha[idx],
                                log.beta[idx], self.ratio(log.tau[idx])])
        self._rows[:] = np.nan
        self._rows[: len(rows)] = rows
        self._k = len(rows)

    def arrays(self) -> dict[str, np.ndarray]:
        """The rows within `window` of the newest, in time order: t, F_hand_u, F_env_u, V, alpha, beta, (·, n) tau."""
        k, cap = self._k, len(self._rows)
        rows = self._rows[:k] if k <= cap else np.roll(self._rows, -(k % cap), axis=0)
        rows = rows[rows[:, 0] >= rows[-1, 0] - self.window] if len(rows) else rows
        names = ("t", "F_hand_u", "F_env_u", "V", "alpha", "beta")
        out = {name: rows[:, i] for i, name in enumerate(names)}
        out["tau"] = rows[:, 6:]
        return out


class TimePlots:
    """Three uPlot charts in the view's panel, redrawn from a `History`.

    Args:
        gui: the viser GUI API (inside the folder the charts go in).
        joint_names: names of the n motors.
    """

    def __init__(self, gui, joint_names: list[str]) -> None:
        self.n = len(joint_names)
        e = np.zeros(2)
        self.tau = gui.add_uplot(
            (e, *([e] * self.n)), ({"label": "t [s]"}, *({"label": nm, "stroke": _COLORS[i % 10]}
                                                         for i, nm in enumerate(joint_names))),
            title="τ / limit", scales={"y": {"auto": False, "range": (-1.05, 1.05)}}, axes=({}, {"label": "τ/limit"}),
            aspect=2.0)
        self.force = gui.add_uplot(
            (e, e, e), ({"label": "t [s]"}, {"label": "F_h·u [N]", "stroke": "#c81ea0"},
                        {"label": "F_env·u [N]", "stroke": "#c82828"}), title="forces along u", axes=({}, {"label": "N"}),
            # soft limits ±1 N: an all-zero series (no contact yet) must not give uPlot an empty range
            scales={"y": {"auto": True, "range": {"min": {"pad": 0.1, "soft": -1.0, "mode": 1},
                                                  "max": {"pad": 0.1, "soft": 1.0, "mode": 1}}}},
            aspect=2.0)
        self.scalars = gui.add_uplot(
            (e, e, e, e), ({"label": "t [s]"}, {"label": "V", "stroke": "#1f77b4"}, {"label": "α", "stroke": "#ff7f0e"},
                           {"label": "β", "stroke": "#2ca02c"}), title="ASO V, α, β (0 where undefined)",
            scales={"y": {"auto": False, "range": (-0.05, 1.05)}}, aspect=2.0)

    def update(self, history: History) -> None:
        """Redraw the charts from the history (nothing while it has fewer than two rows)."""
        a = history.arrays()
        t = a["t"]
        if len(t) < 2:
            return
        clean = lambda v: np.where(np.isfinite(v), v, 0.0)  # noqa: E731  # uPlot's autoscale cannot take NaN
        self.tau.data = (t, *(clean(a["tau"][:, i]) for i in range(self.n)))
        self.force.data = (t, clean(a["F_hand_u"]), clean(a["F_env_u"]))
        self.scalars.data = (t, clean(a["V"]), clean(a["alpha"]), clean(a["beta"]))
