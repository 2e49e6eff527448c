"""Identification on a device through the runtime: joint friction per motor and the apparent inertia M_x along u.

`identify_device` runs the programme of `rhi.analysis.sysid.excitation` with `rhi.runtime.run` (the
safety layer in force) over any link — the simulated plant, or a device process over UDP — and fits:

- **joint friction**, per motor i over its cruise windows (the other motors held): the model's
  rigid-body torque [M(q) q̈ + C(q, q̇) q̇ + g(q)]_i (q̈ from the encoders' q̇ by central differences)
  removes gravity and the coupling to the held motors from the commanded τ_i, and the rest is fitted
  by least squares as d_i q̇_i + f_i sign(q̇_i) + b_i: viscous friction d_i [N m s/rad], Coulomb
  friction f_i [N m] and a constant torque b_i the model misses (a gravity or offset error) [N m].
  Intervals are cluster-robust with one cluster per window (Student t, windows − 1 degrees of
  freedom); R² and the residual RMS over the windows' samples;
- **M_x along u** (thesis eq. 3.24 with a constant c, Tables 3.2 and 6.1): `rhi.analysis.sysid.identify`
  over the pushes (position along u from forward kinematics of the encoders, the rendered force F),
  beside the model's Λ (eq. 3.13) at each push's start.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from rhi.analysis.sysid.excitation import Excitation, Programme, Push, Window
from rhi.analysis.sysid.fit import SysidResult, identify
from rhi.analysis.sysid.records import Record
from rhi.errors import InvalidInput, RhiError


class IdentificationFailed(RhiError):
    """The identification run stopped before its programme ended (a safety fault, an e-stop, a lost link)."""


@dataclasses.dataclass(frozen=True)
class JointFriction:
    """Identified friction per motor: τ_f = d q̇ + f sign(q̇) + b.

    Attributes:
        damping, frictionloss, offset: (n,) d [N m s/rad], f [N m], b [N m].
        damping_ci, frictionloss_ci, offset_ci: (n, 2) 95 % intervals.
        r2, residual_rms: (n,) R² and the residual RMS [N m] over the windows' samples.
        samples, windows: (n,) samples and windows fitted per motor.
    """

    damping: np.ndarray
    frictionloss: np.ndarray
    offset: np.ndarray
    damping_ci: np.ndarray
    frictionloss_ci: np.ndarray
    offset_ci: np.ndarray
    r2: np.ndarray
    residual_rms: np.ndarray
    samples: np.ndarray
    windows: np.ndarray


@dataclasses.dataclass(frozen=True)
class Identification:
    """What `identify_device` found.

    Attributes:
        device: the device's name.
        q0: (n,) hold configuration [rad or m]; u: (m,) push direction.
        friction: the joint friction.
        inertia: the M_x fit (`SysidResult`: mass [kg], damping Φ [N s/m], offset c [N], intervals, R², RMS).
        lambda_model: the model's Λ (eq. 3.13) along u, mean over the pushes' start configurations [kg].
        windows, pushes: the programme as run.
        summary: the run's summary (`rhi.runtime.RunResult.summary`).
    """

    device: str
    q0: np.ndarray
    u: np.ndarray
    friction: JointFriction
    inertia: SysidResult
    lambda_model: float
    windows: list[Window]
    pushes: list[Push]
    summary: dict

    def to_dict(self) -> dict:
        """JSON-serialisable values, intervals and fit quality."""
        f, m = self.friction, self.inertia
        motors = [{"motor": i + 1, "damping": f.damping[i], "damping_ci": f.damping_ci[i].tolist(),
                   "frictionloss": f.frictionloss[i], "frictionloss_ci": f.frictionloss_ci[i].tolist(),
                   "offset": f.offset[i], "offset_ci": f.offset_ci[i].tolist(), "r2": f.r2[i],
                   "residual_rms": f.residual_rms[i], "samples": int(f.samples[i]), "windows": int(f.windows[i])}
                  for i in range(len(f.damping))]
        return {"device": self.device, "q0": self.q0.tolist(), "u": self.u.tolist(),
                "units": {"damping": "N m s/rad", "frictionloss": "N m", "offset": "N m", "residual_rms (motor)": "N m",
                          "M_x": "kg", "Phi": "N s/m", "c": "N", "residual_rms (M_x)": "N"},
                "joint_friction": motors,
                "apparent_inertia": {"M_x": m.mass, "M_x_ci": list(m.mass_ci), "Phi": m.damping,
                                     "Phi_ci": list(m.damping_ci), "c": m.offset, "c_ci": list(m.offset_ci or ()),
                                     "r2": m.r_squared, "residual_rms": m.residual_rms, "trials": m.n_trials,
                                     "samples": m.n_samples, "covariance": m.covariance,
                                     "Lambda_model": self.lambda_model},
                "pushes": [dataclasses.asdict(p) for p in self.pushes],
                "windows": [dataclasses.asdict(w) for w in self.windows],
                "run": {k: self.summary.get(k) for k in ("ticks", "rate_reached", "missed", "missed_pct", "clamped",
                                                          "fault")}}

    def friction_toml(self) -> str:
        """The ``[plant]`` table of a ``device.toml`` with the identified friction (negative estimates as 0)."""
        f = self.friction
        fmt = lambda v: ", ".join(f"{max(float(x), 0.0):.4g}" for x in v)  # noqa: E731
        return (f"[plant]  # identified by rhi identify on {self.device} (R² per motor: "
                f"{', '.join(f'{r:.3f}' for r in f.r2)})\n"
                f"damping = [{fmt(f.damping)}]          # viscous joint friction [N m s/rad]\n"
                f"frictionloss = [{fmt(f.frictionloss)}]     # Coulomb joint friction [N m]\n")


def _fresh(log, *names: str) -> list[np.ndarray]:
    """The log's columns `names` at the ticks that took a new reading (device time t increasing)."""
    t = np.asarray(log.t, dtype=float)
    keep = np.flatnonzero(np.diff(t, prepend=-np.inf) > 0)
    return [np.asarray(getattr(log, k), dtype=float)[keep] for k in names]


def joint_friction(device, log, windows: list[Window]) -> JointFriction:
    """Fit d, f, b per motor over its cruise windows of `log` (module docstring).

    Raises:
        InvalidInput: a motor without two windows of samples each way (the run ended early?).
    """
    from scipy import stats
    from statsmodels.regression.linear_model import OLS

    t, q, dq, tau = _fresh(log, "t", "q", "dq", "tau")
    n = q.shape[1]
    out: dict[str, list] = {k: [] for k in ("damping", "frictionloss", "offset", "damping_ci", "frictionloss_ci",
                                            "offset_ci", "r2", "residual_rms", "samples", "windows")}
    for i in range(n):
        rows, ys, groups = [], [], []
        for k, w in enumerate(x for x in windows if x.joint == i):
            sel = np.flatnonzero((t >= w.t0) & (t <= w.t1))
            sel = sel[np.abs(dq[sel, i]) > 0.2 * abs(w.speed)]  # the tracking has not let the speed fall
            if sel.size < 10:
                continue
            lo, hi = max(sel[0] - 1, 0), min(sel[-1] + 2, len(t))
            ddq = np.gradient(dq[lo:hi], t[lo:hi], axis=0)[sel - lo]
            rigid = np.array([device.mass_matrix(q[s])[i] @ a + device.coriolis(q[s], dq[s])[i] @ dq[s]
                              + device.gravity(q[s])[i] for s, a in zip(sel, ddq, strict=True)])
            v = dq[sel, i]
            rows.append(np.column_stack([v, np.sign(v), np.ones_like(v)]))
            ys.append(tau[sel, i] - rigid)
            groups.append(np.full(sel.size, k))
        signs = {float(np.sign(g[0, 1])) for g in rows}
        if len(rows) < 4 or signs != {-1.0, 1.0}:
            raise InvalidInput(f"log: motor {i + 1} has {len(rows)} friction windows with samples (need 4, both "
                               "ways; did the run end early?)")
        X, y, g = np.concatenate(rows), np.concatenate(ys), np.concatenate(groups)
        fit = OLS(y, X).fit(cov_type="cluster", cov_kwds={"groups": g}, use_t=True)
        beta, se = np.asarray(fit.params), np.sqrt(np.diag(np.asarray(fit.cov_params())))
        h = float(stats.t.ppf(0.975, len(rows) - 1)) * se
        resid = y - X @ beta
        ss = float(((y - y.mean()) ** 2).sum())
        for name, j in (("damping", 0), ("frictionloss", 1), ("offset", 2)):
            out[name].append(float(beta[j]))
            out[name + "_ci"].append([float(beta[j] - h[j]), float(beta[j] + h[j])])
        out["r2"].append(1.0 - float(resid @ resid) / ss if ss > 0 else math.nan)
        out["residual_rms"].append(float(np.sqrt(np.mean(resid**2))))
        out["samples"].append(len(y))
        out["windows"].append(len(rows))
    return JointFriction(**{k: np.asarray(v) for k, v in out.items()})


def apparent_inertia(device, log, pushes: list[Push], u, rate: float) -> tuple[SysidResult, float]:
    """(the eq. 3.24 fit with a constant c over the pushes, the model's Λ along u at their starts [kg]).

    Records sampled unevenly (readings skipped by a host that fell behind) are interpolated linearly onto a grid
    of `rate` [Hz] first.
    """
    t, q = _fresh(log, "t", "q")
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    records, lams = [], []
    for p in pushes:
        sel = (t >= p.t0) & (t <= p.t1)
        ts = t[sel]
        if ts.size < 8 or ts[-1] - ts[0] < 39.5 / rate:
            raise InvalidInput(f"log: push {p.trial + 1} lasted {1e3 * (p.t1 - p.t0):.0f} ms with {ts.size} readings "
                               f"(need {40 / rate * 1e3:.0f} ms and 8: a lighter push direction, a lower "
                               "Programme.accel or a larger push_speed)")
        x = device.fk(q[sel]) @ u
        if not np.allclose(np.diff(ts), 1.0 / rate, rtol=0.05):  # readings skipped: linear onto the rate's grid
            grid = np.arange(ts[0], ts[-1] + 0.5 / rate, 1.0 / rate)
            grid = grid[grid <= ts[-1]]
            x, ts = np.interp(grid, ts, x), grid
        records.append(Record(ts, x, np.full(ts.size, p.force), label=f"push {p.trial + 1}"))
        q0 = q[np.flatnonzero(sel)[0]]
        J, M = device.jacobian(q0), device.mass_matrix(q0)
        lams.append(1.0 / float(u @ J @ np.linalg.solve(M, J.T @ u)))
    if len(records) < 2:
        raise InvalidInput(f"log: {len(records)} pushes; need at least 2 (did the run end early?)")
    return identify(records, offset=True), float(np.mean(lams))


def identify_device(link, device, *, u=(0.0, 1.0), q0=None, programme: Programme | None = None, rate: float = 1000.0,
                    safety=None, realtime: bool = True, log: str | Path | None = None, progress=None,
                    cpu: int | None = None, priority: int | None = None, spin: bool = False,
                    cpu_latency: float | None = None) -> Identification:
    """Run the identification programme on `link` and fit joint friction and M_x (module docstring).

    Args:
        link: the device link, not yet opened (`SimLink`, `UDPLink`, a plugin's).
        device: the device model (its M, C, g, J and limits).
        u: (m,) push direction (thesis: [0, 1]).
        q0: (n,) hold configuration [rad or m]; None: the nearest one to the first reading that is the programme's
            margin inside every joint and linear limit.
        programme: the excitation's settings.
        rate: control rate [Hz].
        safety: the safety layer's limits (`rhi.runtime.run`).
        realtime: pace ticks on the wall clock; False: as fast as the link answers.
        log: a ``.rhilog`` path for the run, or None.
        progress: `rhi.runtime.run`'s status callback.
        cpu: pin the loop to this CPU (`rhi.runtime.run`).
        priority: SCHED_FIFO priority of the loop (`rhi.runtime.run`).
        spin: wait for each tick on a busy core (`rhi.runtime.run`).
        cpu_latency: the cores' wake-up bound [s] held for the run (`rhi.runtime.run`).

    Raises:
        IdentificationFailed: the run stopped on a fault before the programme ended (its reason; the log is kept).
        InvalidInput: bad arguments, or a motor without room to move at q0.
    """
    from rhi.runtime import run

    ex = Excitation(device, u, q0=q0, programme=programme)
    res = run(link, ex, rate=rate, safety=safety, log=log, realtime=realtime, progress=progress, cpu=cpu,
              priority=priority, spin=spin, cpu_latency=cpu_latency, until=ex.finished)
    if res.fault is not None or not ex.done:
        raise IdentificationFailed(f"the identification run stopped at t = {float(res.log.t[-1]) if len(res.log.t) else 0:.2f} s "
                                   f"before its programme ended: {res.fault or 'interrupted'}"
                                   + (f" (log: {log})" if log is not None else ""))
    friction = joint_friction(device, res.log, ex.windows)
    inertia, lam = apparent_inertia(device, res.log, ex.pushes, ex.u, rate)
    assert ex.q0 is not None
    return Identification(device=device.name, q0=ex.q0, u=ex.u, friction=friction, inertia=inertia,
                          lambda_model=lam, windows=ex.windows, pushes=ex.pushes, summary=res.summary)


__all__ = ["Identification", "IdentificationFailed", "JointFriction", "apparent_inertia", "identify_device",
           "joint_friction"]
