"""Beyond the thesis (§8.2): the user's intent as the task direction u of the VME and FME objectives.

Three ways to set u (`rhi.control.intent`, `rhi.control.intent_control`):

- **known**: the true direction (the W's stroke direction at the hand's reference; the
  palpation's push direction), the thesis's assumption;
- **estimated**: online from the handle's F/T reading and velocity, by the baseline
  (`FilteredIntent`: filtered structure tensor, confidence, hysteresis) and by the learned
  model (`HMMIntent`: an HMM over motion primitives whose emission concentration and
  switching rate are fitted on synthetic strokes, `rhi.sim.strokes`, seed 101);
- **fixed**: a constant chosen without the task (W: u = [0, 1], ch. 3's; palpation:
  u = [1, 0], across the push).

Experiments: the estimators on seeded synthetic strokes (axial error, lag); the ch. 5 W
trajectory on rhi4 (d2 = 0.1405 m) teleoperating the rehab slave, with VME matching along u
(eq. 3.22, β = 0.01, gain 1, the ch. 6 joint-limit barrier) instead of ch. 5's TMI objective —
user effort (eq. 5.15), mean TME area λ = σ₁σ₂, peak hand force, estimator error and lag;
and the ch. 6 palpation (1000 N/m at [0.5, 0.1] m) with FME matching to M_Stiff^des(u) —
peak rendered force along the true u, estimator error and lag.
"""

from __future__ import annotations

import functools

import numpy as np

from rhi.control import (
    ObjectiveTerm,
    WeightedSum,
)
from rhi.control.compiled import CompiledIntent
from rhi.control.intent import FilteredIntent, HMMIntent, KnownIntent, axial_error
from rhi.control.intent_control import IntentController, IntentFME, IntentVME
from rhi.devices.model import device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.ch5 import setup as ch5
from rhi.experiments.ch6 import setup as ch6
from rhi.experiments.parts import Part, Plan, run_plan
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress, check_motion, path_hand, positive, run, smooth, ticks
from rhi.metrics import tmi
from rhi.sim import Hand, Plant, Teleoperation, simulate
from rhi.sim.strokes import synthetic_strokes

TRAIN_SEED, TEST_SEED = 101, 202
LAG_DEG = 20.0  #: lag: time after a change of the true direction until the axial error is below this [deg]
VME_GAIN = 1.0


def trained_hmm(m: int = 2, strokes: int = 80, seed: int = TRAIN_SEED, **kw) -> HMMIntent:
    """`HMMIntent.fit` on `strokes` synthetic strokes (seeded)."""
    s = synthetic_strokes(strokes, m=m, seed=seed)
    return HMMIntent.fit(s.force, s.xdot, s.u_true, **kw)


def estimators(m: int, u0) -> dict[str, object]:
    """The two estimators, fresh, with output u0 before any evidence."""
    h = trained_hmm(m)
    return {"filtered": FilteredIntent(m=m, u0=u0), "hmm": HMMIntent(m=m, u0=u0, kappa=h.kappa, switch=h.switch)}


def error_and_lag(t: np.ndarray, u_est: np.ndarray, u_true: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    """Axial error statistics over `mask` [deg] and the median lag after each change of u_true [s]."""
    err = np.degrees(axial_error(u_est, u_true))
    changes = np.flatnonzero(axial_error(u_true[1:], u_true[:-1]) > 1e-6) + 1
    lags = []
    for k in changes:
        ok = np.flatnonzero(err[k:] < LAG_DEG)
        if len(ok):
            lags.append(t[k + ok[0]] - t[k])
    e = err[mask]
    return {"mean": float(np.mean(e)), "median": float(np.median(e)), "p95": float(np.percentile(e, 95)),
            "lag": float(np.median(lags)) if lags else float("nan")}


@checked
def intent_strokes(train: int = 80, test: int = 40, progress: Progress | None = None) -> Result:
    """The estimators on seeded synthetic strokes in 2-D and 3-D (trained on seed 101, tested on seed 202)."""
    for nm, v in (("train", train), ("test", test)):
        if not isinstance(v, (int, np.integer)) or v < 2:
            raise InvalidInput(f"{nm}: expected an integer >= 2, got {v!r}")
    rows, arrays = [], {}
    for i, m in enumerate((2, 3)):
        s = synthetic_strokes(test, m=m, seed=TEST_SEED)
        h = trained_hmm(m, train)
        ests: dict[str, FilteredIntent | HMMIntent] = {"filtered": FilteredIntent(m=m, u0=np.eye(m)[0]),
                "hmm": HMMIntent(m=m, u0=np.eye(m)[0], kappa=h.kappa, switch=h.switch)}
        rows += [Row(f"{m}-D HMM: learned Watson concentration κ", None, h.kappa),
                 Row(f"{m}-D HMM: learned switching rate per tick", None, h.switch)]
        for name, est in ests.items():
            U = np.array([est.update(f, v) for f, v in zip(s.force, s.xdot)])
            st = error_and_lag(s.t, U, s.u_true, s.moving)
            rows += [Row(f"{m}-D {name}: mean axial error while moving", None, st["mean"], "deg"),
                     Row(f"{m}-D {name}: 95th percentile axial error while moving", None, st["p95"], "deg"),
                     Row(f"{m}-D {name}: median lag to < {LAG_DEG:g}° after a new stroke", None, st["lag"], "s")]
            arrays[f"err_{m}d_{name}"] = np.degrees(axial_error(U, s.u_true))
        arrays[f"t_{m}d"], arrays[f"moving_{m}d"] = s.t, s.moving
        if progress is not None:
            progress(i + 1, 2)
    return Result("beyond.intent_strokes", "Beyond the thesis: intent estimation — estimators on synthetic strokes",
                  [Table(f"{test} test strokes (seed {TEST_SEED}); HMM trained on {train} strokes (seed {TRAIN_SEED})",
                         rows)], arrays,
                  ["Strokes: minimum-jerk segments along random axes (≥ 30° apart) with pauses, the hand force of an "
                   "impedance device (0.1 kg, 0.3 N s/m, 0.05 N Coulomb) plus noise (0.1 N, 1 mm/s), rhi.sim.strokes.",
                   "Axial error arccos|û·u|: the VME and FME objectives depend on u uᵀ only."])


class PathIntent:
    """The known intent along a `rhi.sim.HandPath`: the reference's direction of motion at time t (held when at rest)."""

    def __init__(self, path, u0) -> None:
        self.path, self.u0 = path, np.asarray(u0, dtype=float)
        self.reset()

    def reset(self) -> None:
        """Back to u0 with full confidence."""
        self.u, self.confidence = self.u0.copy(), 1.0

    def update_at(self, t: float, force=None, xdot=None) -> np.ndarray:
        """The direction u at time t [s]: the reference's unit velocity (kept while the reference rests); (m,)."""
        v = self.path(t)[1]
        n = float(np.linalg.norm(v))
        if n > 0:
            self.u = v / n
        return self.u

    def update(self, force=None, xdot=None) -> np.ndarray:
        """The current u: (m,) (the known intent needs no evidence)."""
        return self.u

    def compiled(self) -> CompiledIntent:
        """Its tick in compiled code: the path's segment velocities and arc lengths."""
        p = self.path
        step = np.diff(p.points, axis=0)
        seg = np.linalg.norm(step, axis=1)  # as `HandPath` computes its segments
        v = p.speed * (step / np.where(seg > 0, seg, 1.0)[:, None])
        return CompiledIntent("path", {"start": p.start, "speed": p.speed}, table=v.reshape(-1, p.points.shape[1]),
                              knots=np.concatenate([[0.0], np.cumsum(seg)]))


def _true_w(path, t: np.ndarray, u0: np.ndarray) -> np.ndarray:
    est = PathIntent(path, u0)
    return np.array([est.update_at(tk).copy() for tk in t])


#: The sources of u in `intent_w_trajectory`, in order.
W_SOURCES = ("known", "filtered", "hmm", "fixed")


@checked
def intent_w_trajectory(scale: float = 1.0, speed: float = ch5.SPEED, settle: float = 2.0,
                        progress: Progress | None = None) -> Result:
    """The ch. 5 W trajectory with VME matching along u known / estimated (filtered, HMM) / fixed.

    The sources are independent (`intent_w_trajectory_plan`: `rhi reproduce` runs them side by side).

    Args:
        scale: scales the W (quick runs < 1).
        speed: hand speed [m/s].
        settle: hold before moving [s].
        progress: callback(done, total) in ticks.
    """
    return run_plan(intent_w_trajectory_plan(scale, speed, settle), progress)


@checked
def intent_w_trajectory_plan(scale: float = 1.0, speed: float = ch5.SPEED, settle: float = 2.0) -> Plan:
    """`intent_w_trajectory` as independent parts, one per source of u (arguments as `intent_w_trajectory`)."""
    scale = positive("scale", scale)
    settle = positive("settle", settle, allow_zero=True)
    path = ch5.w_reference(ch5.W_CENTER, ch5.W_WIDTH * scale, ch5.W_HEIGHT * scale, speed, settle)
    N = ticks(settle + path.duration + 0.5)
    return Plan([Part(key, functools.partial(intent_w_source, key, scale=scale, speed=speed, settle=settle), N)
                 for key in W_SOURCES],
                functools.partial(_intent_w_merge, scale=scale, speed=speed, settle=settle))


def intent_w_source(key: str, *, scale: float, speed: float, settle: float,
                    progress: Progress | None = None) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """One source of u in `intent_w_trajectory` (a `Part` of its plan): (its numbers, its arrays).

    Args:
        key: one of `W_SOURCES`.
        scale: as `intent_w_trajectory`.
        speed: as `intent_w_trajectory` [m/s].
        settle: as `intent_w_trajectory` [s].
        progress: callback(done, total) in ticks.
    """
    path = ch5.w_reference(ch5.W_CENTER, ch5.W_WIDTH * scale, ch5.W_HEIGHT * scale, speed, settle)
    devs = ch5.devices()
    dev, slave = devs["RHI"], devs["slave"]
    p0 = path.points[0]
    q_m, q_s = dev.ik(p0, ch5.Q_FIXED), slave.ik(p0, ch5.SLAVE_SEED)
    u_fixed = np.array([0.0, 1.0])
    first = path.points[1] - path.points[0]
    u_first = first / np.linalg.norm(first)
    src: PathIntent | FilteredIntent | HMMIntent | KnownIntent
    if key == "known":
        src = PathIntent(path, u_first)
    elif key == "filtered":
        src = FilteredIntent(m=2, u0=u_fixed)
    elif key == "hmm":
        h = trained_hmm(2)
        src = HMMIntent(m=2, u0=u_fixed, kappa=h.kappa, switch=h.switch)
    else:
        src = KnownIntent(u_fixed)
    duration = settle + path.duration + 0.5
    sp = Plant(slave, friction=ch5.plant_friction("thesis", slave))
    sp.reset(q_s)
    inner = ch5.controller(dev, IntentVME(src, 0.01), VME_GAIN, ch5.NULL_DAMPING,
                           extra=(ObjectiveTerm(ch6.BARRIER, ch6.LIMIT_GAIN),))
    ctrl = IntentController(inner, src)
    plant = Plant(dev, friction=ch5.plant_friction("thesis", dev))
    plant.reset(q_m)
    log = simulate(plant, ctrl, duration=duration, hand=Hand(path, **ch5.TRACK), teleop=Teleoperation(sp),
                   progress=progress, record=ch5.SLAVE_Q)
    if log.fault is not None:
        raise InvalidInput(f"intent_w_trajectory: the controller stopped in scenario {key!r}: {log.fault}")
    moving = (log.t >= settle - 1e-9) & (log.t <= settle + path.duration + 1e-9)
    U = np.array([h[1] for h in ctrl.history])
    Ut = _true_w(path, log.t, u_first)
    area = tmi(dev.jacobian(log.q), slave.jacobian(log.extra["slave_q"]))
    W0 = log.work[np.argmax(moving)]
    st = error_and_lag(log.t, U, Ut, moving)
    stats = {"work": float(log.work[moving][-1] - W0), "area": float(np.mean(area[moving])),
             "peak": float(np.max(np.linalg.norm(log.F_hand[moving], axis=1))), **st}
    arrays = {f"{key}_t": log.t[::10] - settle, f"{key}_err": np.degrees(axial_error(U, Ut))[::10],
              f"{key}_work": (log.work - W0)[::10], f"{key}_area": area[::10]}
    return stats, arrays


def _intent_w_merge(outputs: list[tuple[dict, dict]], *, scale: float, speed: float, settle: float) -> Result:
    path = ch5.w_reference(ch5.W_CENTER, ch5.W_WIDTH * scale, ch5.W_HEIGHT * scale, speed, settle)
    u_fixed = np.array([0.0, 1.0])
    rows, arrays, stats = [], {"path": path.points}, {}
    for key, (st, arr) in zip(W_SOURCES, outputs):
        stats[key] = st
        arrays.update(arr)
    names = {"known": "u known", "filtered": "u estimated (filtered)", "hmm": "u estimated (HMM)",
             "fixed": "u fixed [0, 1]"}
    for key, s in stats.items():
        rows += [Row(f"user work over the W (eq. 5.15), {names[key]}", None, s["work"], "J"),
                 Row(f"mean TME area λ = σ₁σ₂, {names[key]}", None, s["area"], "m²/s² per (rad/s)²"),
                 Row(f"peak hand force, {names[key]}", None, s["peak"], "N")]
        if key in ("filtered", "hmm", "fixed"):
            rows += [Row(f"mean axial error of u while moving, {names[key]}", None, s["mean"], "deg"),
                     Row(f"median lag to < {LAG_DEG:g}° after a stroke change, {names[key]}", None, s["lag"], "s")]
    seg = np.diff(path.points, axis=0)
    rows.append(Row("largest axial angle between a stroke of the W and u fixed", None,
                    float(np.degrees(axial_error(seg, u_fixed).max())), "deg",
                    "the W's strokes are steep: a fixed [0, 1] is never far from the true direction"))
    gap = stats["fixed"]["work"] - stats["known"]["work"]
    for key in ("filtered", "hmm"):
        rec = (stats["fixed"]["work"] - stats[key]["work"]) / gap if abs(gap) > 1e-12 else float("nan")
        rows.append(Row(f"share of the known-u effort benefit recovered, {names[key]}", None, rec, "",
                        "(W_fixed − W_est)/(W_fixed − W_known); 1: all of it"))
    return Result("beyond.intent_w_trajectory",
                  "Beyond the thesis: intent estimation — ch. 5 W trajectory with VME matching along u",
                  [Table("W trajectory (rhi4 teleoperating the rehab slave)", rows)], arrays,
                  ["VME matching along u (eq. 3.22) replaces ch. 5's TMI objective; same hand, plant friction "
                   "(Γ = 0.01), B^d = 0.3 N s/m and slave as ch5.w_trajectory.",
                   "Known u: the reference's stroke direction at each instant; fixed u: [0, 1] (ch. 3)."])


@checked
def intent_palpation(settle: float = 0.5, depth: float = 0.015, speed: float = 0.01, hold: float = 0.3,
                     *, starts: int = 3, progress: Progress | None = None) -> Result:
    """The ch. 6 palpation with FME matching to M_Stiff^des(u): u known [0, 1] / estimated / fixed [1, 0].

    Known starts at the M_Stiff^des([0, 1]) match (as ch. 6); the others at the M_Stiff^des([1, 0])
    match (a device that does not know the push direction); the estimators start from u = [1, 0].
    """
    check_motion(settle=settle, depth=depth, speed=speed, hold=hold)
    dev = device("rhi4")
    hi = dev.torque_max
    u_true, u_fixed, x0 = np.array(ch6.U), np.array([1.0, 0.0]), np.array(ch6.X0)
    K, zeta, _, _ = ch6.desired_fmes(dev, u_true, ch6.Q_HOME)
    sources = {"known": KnownIntent(u_true), **estimators(2, u_fixed), "fixed": KnownIntent(u_fixed)}
    starts_q = {}
    for u_key, u in (("true", u_true), ("fixed", u_fixed)):
        obj = IntentFME(KnownIntent(u), K, zeta, hi, "stiff")
        starts_q[u_key] = ch6.best_match(dev, x0, WeightedSum((ObjectiveTerm(obj, ch6.BETA),
                                                              ObjectiveTerm(ch6.BARRIER, ch6.LIMIT_GAIN))),
                                         starts=starts)
    duration = settle + depth / speed + hold
    N = int(round(duration * 1000.0))
    rows, arrays = [], {}
    for i, (key, src) in enumerate(sources.items()):
        fme = ObjectiveTerm(IntentFME(src, K, zeta, hi, "stiff"), ch6.BETA)
        ctrl = IntentController(ch6.palpation_controller(dev, None, objectives=(fme,)), src)
        hand = path_hand([x0, x0 + depth * u_true], speed, settle, 3000.0, 40.0)
        log = run(dev, ctrl, hand, starts_q["true" if key == "known" else "fixed"], duration, progress, i * N,
                       len(sources) * N)
        if log.fault is not None:
            raise InvalidInput(f"intent_palpation: the controller stopped in scenario {key!r}: {log.fault}")
        f_u = -smooth(log.ft[:, :2], 20) @ u_true
        push = log.t >= settle
        U = np.array([h[1] for h in ctrl.history])
        err = np.degrees(axial_error(U, u_true))
        k_ok = np.flatnonzero(push & (err < LAG_DEG))
        rows += [Row(f"peak force along u, u {key}", None, float(np.min(f_u[push])), "N", "negative: along −u"),
                 Row(f"final axial error of u, u {key}", None, float(err[-1]), "deg"),
                 Row(f"lag from push onset to < {LAG_DEG:g}° error, u {key}", None,
                     float(log.t[k_ok[0]] - settle) if len(k_ok) else float("nan"), "s")]
        arrays.update({f"{key}_t": log.t, f"{key}_force": f_u, f"{key}_err": err})
    peak = {r.quantity.split("u ")[-1]: r.ours for r in rows if r.quantity.startswith("peak")}
    gap = peak["known"] - peak["fixed"]
    for key in ("filtered", "hmm"):
        rows.append(Row(f"share of the known-u force benefit recovered, u {key}", None,
                        (peak[key] - peak["fixed"]) / gap if abs(gap) > 1e-12 else float("nan"), "",
                        "(F_est − F_fixed)/(F_known − F_fixed); 1: all of it"))
    return Result("beyond.intent_palpation",
                  "Beyond the thesis: intent estimation — ch. 6 palpation with M_Stiff^des along u",
                  [Table("Palpation of 1000 N/m at [0.5, 0.1] m along [0, 1] (rhi4, force scaling)", rows)], arrays,
                  ["The estimators see the hand holding still while settling (no evidence: u stays [1, 0]) and the "
                   "push (force and motion along [0, 1]); the null-space FME matching reconfigures during the push."])
