"""Appendix A, kinematic control of the WMM: motion distribution by a weighting matrix and DM enhancement.

* `tracking` (§A.4.2, Table A.1, Figs. A.5–A.6): the 0.25 m circle beyond the arm's
  workspace, tracked on the MuJoCo plant (slipping base, servoed arm) by the proposed
  weighted distribution (γ of eqs. A.11–A.15, ε = 0.2, K_x = 10) and by the traditional
  plain pseudoinverse.
* `dm_enhancement` (§A.4.3, Figs. A.7, A.9): directional manipulability enhanced first in
  Cartesian space (0–5 s, eqs. A.17–A.18, z ∈ [0.36, 0.56] m) then in the null space
  (5–20 s, eqs. A.19–A.20), along z (the thesis's simulation) and along x (the box push),
  k_C = 0.01, k_N = 0.2, W_τ = diag(1, 1, 1, 1, 2.5, 2.5, 2.5). Kinematic simulation.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Literal

import numpy as np
from scipy.optimize import minimize

from rhi import thesis as T
from rhi.control.mobile import W_TAU_LIMITS, DMConfig, WeightedConfig, WeightedDistributionController
from rhi.devices.mobile_base import wheel_geometry
from rhi.devices.model import device
from rhi.experiments.arguments import checked
from rhi.experiments.parts import Part, Plan, run_plan
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import ProgressChain
from rhi.sim.mobile import MobileLog, MobilePlant, SlipModel, circle, hold, simulate_mobile

PI = math.pi
#: Thesis start configuration q0 = [0, 0, 0, 0, π/6, 0, π/2, 0, −π/6, 0] (§A.4.1, §B.4.1).
Q0 = np.array([0.0, 0.0, 0.0, 0.0, PI / 6, 0.0, PI / 2, 0.0, -PI / 6, 0.0])
CM, DEG = 100.0, 180.0 / PI
#: Fig. A.8: the arm's torque limits [N m], "32 Nm for the first four joints and 13 Nm for the last three" (line 2210).
PUSH_LIMITS = np.array([32.0] * 4 + [13.0] * 3)
#: Fig. A.9(b): ‖W_τ τ‖ rose to "almost 40" N m without DM enhancement and stopped the push [N m].
PUSH_NORM = 40.0


def slip_note(slip: SlipModel) -> str:
    """The result note that describes the base slip model `slip` (appendices A and B)."""
    return (f"Base slip model (ours; the thesis measures rather than models it): twist efficiency "
            f"1 − s = [{1 - slip.longitudinal:.2f}, {1 - slip.lateral:.2f}, {1 - slip.yaw:.2f}] (x_b, y_b, θ_b), "
            f"coloured noise {100 * slip.noise:.0f} % (τ = {slip.noise_tau} s, seed {slip.seed}). The controllers "
            "see odometry, not the true base pose; errors are measured on MuJoCo's true end-effector "
            "(the motion-capture role). Tracking errors scale with this model, not with the thesis's robot.")


@checked
def tracking(
    duration: float = 40.0,
    dt: float = 0.01,
    radius: float = 0.25,
    slip: SlipModel | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Result:
    """§A.4.2: circle beyond the arm's workspace, proposed weighted distribution vs plain pseudoinverse.

    Args:
        duration: run length [s] (one turn of the circle: 40 s).
        dt: control period T [s].
        radius: circle radius R [m] (thesis 0.25).
        slip: base ground model (default `SlipModel()`).
        progress: callback(done, total) in control steps.

    Returns:
        Table A.1 beside ours, maximum tracking errors, base motion interval; arrays for Figs. A.5–A.6.
    """
    slip = slip if slip is not None else SlipModel()
    dev = device("wmm")
    traj = circle(dev.fk(Q0), radius, duration=duration, dt=dt)
    methods: dict[str, tuple[Literal["weighted", "pinv", "pinv_generalized"], Literal["wheel", "generalized"]]] = {
        "proposed": ("weighted", "wheel"), "traditional": ("pinv_generalized", "wheel"),
        "traditional_wheel_speeds": ("pinv", "wheel"), "proposed_generalized": ("weighted", "generalized")}
    prog = ProgressChain(progress, traj.t.size * len(methods))
    logs: dict[str, MobileLog] = {}
    for name, (dist, weighting) in methods.items():
        ctl = WeightedDistributionController(dev, WeightedConfig(dt=dt, k_x=10.0, epsilon=0.2, distribution=dist,
                                                                 weighting=weighting))
        logs[name] = simulate_mobile(ctl, traj, Q0, plant=MobilePlant(dev, slip=slip),
                                     progress=prog.run(traj.t.size))
    thesis = {m: {**T.TABLE_A_1[m], "err": T.ERROR_A[m]} for m in ("proposed", "traditional")}
    thesis["proposed_generalized"] = thesis["proposed"]
    notes_m = {"traditional_wheel_speeds": "J⁺ of the wheel-speed Jacobian [J_b P, J_m] (wheel speeds in rad/s): "
                                          "not in the thesis",
               "proposed_generalized": "reading: W_x = diag(γI₃, (1−γ)I₇) on J_q = [J_b, J_m] (§B.2: for a "
                                       "holonomic base both Jacobians 'can be utilized'); A.12 as printed weights "
                                       "the 4 wheel speeds"}
    comps = (("v_xb", CM, "cm/s"), ("v_yb", CM, "cm/s"), ("ω_b", DEG, "°/s"))
    rows, err_rows = [], []
    arrays: dict[str, np.ndarray] = {"t": traj.t, "x_des": traj.x}
    stats = {}
    for name, log in logs.items():
        st = log.base_stats()
        stats[name] = st
        th = thesis.get(name)
        label = name.replace("_", " ")
        note = notes_m.get(name, "")
        for i, (c, scale, unit) in enumerate(comps):
            rows.append(Row(f"{label}: max |{c}|", th["max"][i] if th else None, float(st["max"][i] * scale), unit, note))
            rows.append(Row(f"{label}: RMS {c}", th["rms"][i] if th else None, float(st["rms"][i] * scale), unit, note))
        if th and name.startswith("proposed"):
            moving = np.any(np.abs(log.base_velocity) > 1e-9, axis=1)
            rms_m = np.sqrt(np.mean(log.base_velocity[moving] ** 2, axis=0)) if moving.any() else np.full(3, np.nan)
            for i, (c, scale, unit) in enumerate(comps):
                rows.append(Row(f"{label}: RMS {c} over the base's motion only", th["rms"][i], float(rms_m[i] * scale),
                                unit, "reading: Table A.1's RMS over the samples where the base is commanded"))
        emax = np.abs(log.error).max(axis=0) * CM
        for i, ax in enumerate("xy"):
            err_rows.append(Row(f"{label}: max tracking error {ax}", th["err"][i] if th else None, float(emax[i]), "cm",
                                "true end-effector (MuJoCo) vs x_d; depends on the slip model"))
        err_rows.append(Row(f"{label}: base commanded for", None, float(st["duration"].max()), "s"))
        for key in ("x", "x_est", "q", "q_true", "dq", "gamma", "eta"):
            arrays[f"{name}_{key}"] = getattr(log, key)
    p, tr = stats["proposed"], stats["traditional"]
    ratio = [Row(f"RMS {c} proposed / traditional", th, float(100 * p["rms"][i] / tr["rms"][i]), "%")
             for i, ((c, _, _), th) in enumerate(zip(comps, T.RMS_RATIO_A))]
    interval = [Row("proposed: base first commanded", T.BASE_INTERVAL_A[0], float(p["first"]), "s"),
                Row("proposed: base last commanded", T.BASE_INTERVAL_A[1], float(p["last"]), "s")]
    bounds_ok = all(log.bounds_ok for log in logs.values())
    return Result(
        "appa.tracking",
        f"§A.4.2 / Table A.1: {radius} m circle beyond the arm's workspace, weighted distribution vs pseudoinverse",
        [Table("Table A.1: commanded base velocity", rows + ratio + _geometry_sensitivity(dev, traj, dt)),
         Table("§A.4.2: tracking and base motion", err_rows + interval)],
        arrays,
        [
            slip_note(slip),
            f"Control period {dt} s, K_x = 10, ε = 0.2, velocity bounds of eq. A.13 from Table B.1; every "
            f"commanded position and velocity stayed within its bounds: {bounds_ok}.",
            "γ is computed from the arm-only solution (γ = 0) each step, then the weighted J† of eq. A.11 is "
            "applied; at γ = 1 the base alone cannot move the end-effector vertically and J† = W^½(JW^½)⁺ drops "
            "that component in the least-squares sense.",
            "Traditional = J⁺ = Jᵀ(JJᵀ)⁻¹ of the generalized Jacobian [J_b, J_m] (base velocities in m/s and "
            "rad/s, sent to the wheels by P⁺): for a holonomic base it and the wheel-speed Jacobian describe the "
            "same motions (§B.2); compare its rows with the thesis's traditional row. J⁺ of the wheel-speed "
            "Jacobian [J_b P, J_m] with wheel speeds in rad/s ('traditional wheel speeds') weights the base "
            "columns by R/4 ≈ 0.02 m/rad and already favours the arm: a plain pseudoinverse's split depends on "
            "the base's units, which is what W_x makes explicit.",
            "Mecanum geometry (R, l1, l2) and the base inertia are flagged estimates (models/wmm/README.md).",
            _table_a1_bound(),
            _omega_peak(logs["proposed"]),
        ],
    )


def _geometry_sensitivity(dev, traj, dt: float) -> list[Row]:
    """Rows: the proposed run's ω_b (kinematic) for wheel-base sizes l1 + l2 around rhi's estimate (the thesis gives none).

    Under eq. A.12 as printed W_x weights wheel speeds, so the base's rotation costs ∝ (l1 + l2) per rad/s: ω_b
    depends on a number the thesis does not publish (Fig. A.4 names R, l1, l2 only). Not a reading: no thesis value.
    """
    geo = wheel_geometry(dev)
    base = geo["half_length"] + geo["half_width"]
    rows = []
    for size in (0.30, base, 0.65):
        g = dict(geo, half_length=geo["half_length"] * size / base, half_width=geo["half_width"] * size / base)
        ctl = WeightedDistributionController(dev, WeightedConfig(dt=dt, k_x=10.0, epsilon=0.2, geometry=g))
        st = simulate_mobile(ctl, traj, Q0).base_stats()
        note = "sensitivity (kinematic run): l1 + l2 is not given in the thesis" + (" (rhi's estimate)" if size == base
                                                                                     else "")
        rows += [Row(f"proposed, l1 + l2 = {size:.2f} m: max |ω_b|", None, float(st["max"][2] * DEG), "°/s", note),
                 Row(f"proposed, l1 + l2 = {size:.2f} m: RMS ω_b", None, float(st["rms"][2] * DEG), "°/s", note)]
    return rows


def _omega_peak(log: MobileLog) -> str:
    """The note on where the proposed run's largest |ω_b| is commanded and what γ (A.14) does there."""
    w = np.abs(log.base_velocity[:, 2]) * DEG
    k = int(np.argmax(w))
    below = log.gamma < 1.0
    rest = float(w[below].max()) if below.any() else math.nan
    return (f"The proposed run's largest |ω_b| ({w[k]:.3f} °/s) is commanded at t = {log.t[k]:.2f} s, where γ goes "
            f"{log.gamma[max(k - 1, 0)]:.2f} → {log.gamma[k]:.2f} (η of the arm-only solution {log.eta[k]:.2f}): at γ = 1 "
            f"the base alone takes the motion (A.14). Over the {int(below.sum())} samples with γ < 1 the largest is "
            f"{rest:.3f} °/s; γ = 1 on {int((~below).sum())} samples.")


def _table_a1_bound() -> str:
    """The note on Table A.1's own consistency: the largest RMS its max and the base's motion interval allow.

    The run is taken as one turn of the §A.4.2 circle (x_d has period 2π/(π/20) = 40 s).
    """
    duration = 40.0
    on = float(T.BASE_INTERVAL_A[1]) - float(T.BASE_INTERVAL_A[0])
    mx, rms = float(T.TABLE_A_1["proposed"]["max"][0]), float(T.TABLE_A_1["proposed"]["rms"][0])
    return (f"Thesis arithmetic: with max |v_xb| = {mx} cm/s and the base moving only {on:.2f} s (7.15–20.35 s), the RMS "
            f"over a {duration:g} s run is at most {mx} × √({on:.2f}/{duration:g}) = {mx * math.sqrt(on / duration):.2f} "
            f"cm/s < the printed {rms} (a run of one turn of the circle): Table A.1's proposed RMS is over a run "
            f"≤ {on * (mx / rms) ** 2:.1f} s or over another window (the 'over the base's motion only' rows), while "
            "the traditional RMS (base always moving) is over the run.")


def _dm_phase(ctl: WeightedDistributionController, q0: np.ndarray, t_cart: float, t_null: float, dt: float,
              tick: Callable[[], None]) -> dict[str, np.ndarray]:
    """Cartesian phase then null-space phase, kinematic; returns time series and configurations."""
    dev = ctl.device
    x0 = dev.fk(q0)
    log1 = simulate_mobile(ctl, hold(x0, duration=t_cart, dt=dt), q0, stage="dm_cartesian")
    tick()
    q1 = log1.q[-1] + log1.dq[-1] * dt
    x1 = dev.fk(q1)
    log2 = simulate_mobile(ctl, hold(x1, duration=t_null, dt=dt), q1, stage="dm_null")
    tick()
    q2 = log2.q[-1] + log2.dq[-1] * dt
    t = np.concatenate([log1.t, t_cart + dt + log2.t])
    return {
        "t": t,
        "dm": np.concatenate([log1.dm, log2.dm]),
        "x": np.concatenate([log1.x, log2.x]),
        "q": np.concatenate([log1.q, log2.q]),
        "q_cart": q1,
        "q_end": q2,
        "dm_cart": ctl.dm(q1),
        "dm_end": ctl.dm(q2),
        "bounds_ok": log1.bounds_ok and log2.bounds_ok,
    }


@checked(skip_at_zero=("t_long",))
def dm_enhancement(
    dt: float = 0.01,
    t_cartesian: float = 5.0,
    t_null: float = 15.0,
    t_long: float = 100.0,
    progress: Callable[[int, int], None] | None = None,
) -> Result:
    """§A.4.3: DM enhancement along z (simulation) and along x (box push), Cartesian then null space.

    Args:
        dt: control period [s].
        t_cartesian: Cartesian phase (A.17–A.18) [s] (thesis 0–5 s).
        t_null: null-space phase (A.19–A.20) [s] (thesis 5–20 s).
        t_long: a longer null-space phase for z, whose end time the thesis does not give [s] (0: skip;
            the default 100 s lets the ascent settle).
        progress: callback(done, total) in simulation phases.

    Returns:
        DM values and weighted joint-torque norms beside the thesis's; DM histories for Fig. A.9.
    """
    return run_plan(dm_enhancement_plan(dt, t_cartesian, t_null, t_long), progress)


@checked(skip_at_zero=("t_long",))
def dm_enhancement_plan(dt: float = 0.01, t_cartesian: float = 5.0, t_null: float = 15.0,
                        t_long: float = 100.0) -> Plan:
    """`dm_enhancement` as independent parts, one per run (arguments as `dm_enhancement`)."""
    X, Z = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
    runs: list[tuple[str, tuple[float, float, float], Literal["generalized", "weighted"], float,
                     Literal["exact", "printed"]]] = [
        ("z", Z, "generalized", t_null, "exact"), ("x", X, "generalized", t_null, "exact"),
        ("x_weighted", X, "weighted", t_null, "exact"), ("z_weighted", Z, "weighted", t_null, "exact"),
        ("x_printed", X, "weighted", t_null, "printed")]
    if t_long > 0:
        runs.append(("z_long", Z, "generalized", t_long, "exact"))
    return Plan([Part(name, functools.partial(dm_run, u, ns, tn, dt=dt, t_cartesian=t_cartesian, gradient=g), 2)
                 for name, u, ns, tn, g in runs],
                functools.partial(_dm_merge, names=tuple(r[0] for r in runs), dt=dt, t_cartesian=t_cartesian,
                                  t_null=t_null, t_long=t_long))


def dm_run(u: tuple[float, float, float], null_space: Literal["generalized", "weighted"], t_null: float, *,
           dt: float, t_cartesian: float, gradient: Literal["exact", "printed"] = "exact",
           progress: Callable[[int, int], None] | None = None) -> dict[str, np.ndarray]:
    """One run of `dm_enhancement` (a `Part` of its plan): DM enhancement along u, Cartesian then null-space phase.

    Args:
        u: (3,) DM direction.
        null_space: the controller's null-space projector.
        t_null: null-space phase [s].
        dt: control period [s].
        t_cartesian: Cartesian phase [s].
        gradient: eq. A.9's factor (`DMConfig.gradient`).
        progress: callback(done, 2) after each phase.
    """
    dev = device("wmm")
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], 2)

    ctl = WeightedDistributionController(
        dev, WeightedConfig(dt=dt, k_x=10.0, epsilon=0.2, null_space=null_space,
                            dm=DMConfig(u=u, k_c=0.01, k_n=0.2, gradient=gradient)))
    return _dm_phase(ctl, Q0, t_cartesian, t_null, dt, tick)


def dm_supremum(q_start: np.ndarray, u, *, base_free: bool, starts: int = 3, seed: int = 0) -> float:
    """Largest DM along u (A.8) over the configurations that keep the end effector at fk(q_start), within the joint limits.

    What the null-space phase (A.19–A.20) can reach at most, however long it runs: with the base
    fixed (the weighted J† of A.19 at γ = 0) or free. SLSQP from q_start and `starts` − 1 seeded
    perturbations of its arm angles; the best local maximum (a lower bound of the supremum).

    Args:
        q_start: (10,) configuration [x_b, y_b, θ_b, q_m].
        u: (3,) world direction.
        base_free: let x_b, y_b (±1 m) and θ_b (±π) move.
        starts: number of SLSQP starts.
        seed: seed of the perturbations.
    """
    dev = device("wmm")
    w2 = 1.0 / np.asarray(W_TAU_LIMITS) ** 2
    uu = np.asarray(u, dtype=float) / np.linalg.norm(u)
    x_held = dev.fk(q_start)
    lo = np.where(np.isfinite(dev.q_min), dev.q_min, -2 * PI)
    hi = np.where(np.isfinite(dev.q_max), dev.q_max, 2 * PI)
    lo[:3], hi[:3] = (q_start[:3] - [1.0, 1.0, PI], q_start[:3] + [1.0, 1.0, PI]) if base_free else (q_start[:3],) * 2

    def neg_dm(q: np.ndarray) -> float:
        v = dev.jacobian(q)[:, 3:].T @ uu
        return -min(float((v * w2) @ v) ** -0.5, 1e3)

    cons = {"type": "eq", "fun": lambda q: dev.fk(q) - x_held, "jac": lambda q: dev.jacobian(q)}
    rng = np.random.default_rng(seed)
    best = -neg_dm(q_start)
    for k in range(starts):
        q0 = q_start + (0.0 if k == 0 else np.r_[np.zeros(3), rng.normal(scale=0.4, size=dev.n - 3)])
        res = minimize(neg_dm, np.clip(q0, lo, hi), method="SLSQP", bounds=list(zip(lo, hi)), constraints=[cons],
                       options={"maxiter": 300})
        if np.linalg.norm(dev.fk(res.x) - x_held) < 1e-6 and np.all(res.x >= lo - 1e-9) and np.all(res.x <= hi + 1e-9):
            best = max(best, -float(res.fun))
    return best


def _suprema(dev, q_cart: np.ndarray, u, thesis) -> list[Row]:
    ax = "xyz"[int(np.argmax(np.abs(u)))]
    at = f"end effector held at z = {dev.fk(q_cart)[2]:.4f} m (after the Cartesian phase)"
    return [Row(f"largest DM along {ax} the arm's self-motion can reach (base fixed: eq. A.19 as printed)", thesis,
                dm_supremum(q_cart, u, base_free=False), "N", f"best of 3 SLSQP starts, joint limits; {at}"),
            Row(f"largest DM along {ax} with the base free", thesis, dm_supremum(q_cart, u, base_free=True), "N",
                f"best of 3 SLSQP starts, joint limits; {at}")]


def _push_rows(dev, w_tau: np.ndarray, runs) -> list[Row]:
    """Fig. A.8 read statically: a push force F along world x at the end effector, arm torques τ = J_mᵀ F.

    F is the force at which ‖W_τ τ‖ reaches the thesis's "almost 40" N m at q0 (no DM enhancement); the
    torques are compared at that force after each DM enhancement (`runs`: (label, run)). Gravity is left out,
    as the thesis subtracts it from its torque sensors.
    """
    ex = np.array([1.0, 0.0, 0.0])
    t0 = dev.jacobian(Q0)[:, 3:].T @ ex  # [N m per N]
    F = PUSH_NORM / float(np.linalg.norm(w_tau @ t0))
    why = ("static reading: a pure x force at the handle; the thesis measured the torques while a person pushed a "
           "26 kg box (contact force direction, floor friction and push profile unpublished)")
    rows = [Row("box push, static: push force at which ‖W_τ τ‖ reaches 40 N m at q0", None, F, "N"),
            Row("box push, static: first arm joint to reach its limit (32/13 N m) at q0", T.PUSH_JOINT,
                float(np.argmax(np.abs(t0) / PUSH_LIMITS) + 1), "", why)]
    for label, r in runs:
        t = dev.jacobian(r["q_end"])[:, 3:].T @ ex
        rows.append(Row(f"box push, static: largest arm joint torque at that force after the DM enhancement ({label})",
                        T.PUSH_MAX_TORQUE, float(np.abs(t).max() * F), "N m", why, bound="max"))
    return rows


def _dm_merge(outputs: list[dict[str, np.ndarray]], *, names: tuple[str, ...], dt: float, t_cartesian: float,
              t_null: float, t_long: float) -> Result:
    dev = device("wmm")
    w_tau = np.diag(1.0 / np.asarray(W_TAU_LIMITS))
    out = dict(zip(names, outputs))

    def tau_norm(q, u, F=10.0):
        return float(np.linalg.norm(w_tau @ dev.jacobian(q)[:, 3:].T @ (F * np.asarray(u))))

    z, x, xw, zw, xp = out["z"], out["x"], out["x_weighted"], out["z_weighted"], out["x_printed"]
    t_end = t_cartesian + t_null
    rows_z = [
        Row("DM along z at q0", T.DM_Z[0], float(z["dm"][0]), "N"),
        Row(f"DM along z after enhancement (t = {t_end:g} s)", T.DM_Z[1], float(z["dm_end"]), "N",
            "the thesis does not give the simulation's length; null-space gradient ascent is slow along z"),
        Row("‖W_τ τ‖ for a 10 N z force at q0", T.TAU_Z[0], tau_norm(Q0, (0, 0, 1)), "N m"),
        Row(f"‖W_τ τ‖ for a 10 N z force after (t = {t_end:g} s)", T.TAU_Z[1], tau_norm(z["q_end"], (0, 0, 1)), "N m"),
        Row(f"DM along z after enhancement, eq. A.19 as printed (weighted J†, t = {t_end:g} s)", T.DM_Z[1],
            float(zw["dm_end"]), "N", "at γ = 0 the weighted J† locks the base: only the arm's own self-motion is left"),
        *_suprema(dev, z["q_cart"], (0.0, 0.0, 1.0), T.DM_Z[1]),
    ]
    if "z_long" in out:
        zl = out["z_long"]
        k = int(np.nanargmax(zl["dm"]))
        qk = zl["q"][k]
        at = [dev.joint_names[i] for i in range(dev.n)
              if min(abs(qk[i] - dev.q_min[i]), abs(dev.q_max[i] - qk[i])) < 1e-2]
        where = f"; joints at a position bound: {', '.join(at)}" if at else ""
        drift = float(np.linalg.norm(zl["x"][int(round(t_cartesian / dt)) + 1:] - dev.fk(zl["q_cart"]), axis=1).max())
        where += f"; end effector within {drift * 1e3:.3f} mm of the held position"
        last = zl["t"] >= zl["t"][-1] - 10.0
        settle = float(np.ptp(zl["dm"][last]))
        rows_z += [
            Row(f"largest DM along z within {t_cartesian + t_long:g} s", T.DM_Z[1], float(zl["dm"][k]), "N",
                f"reading: orthogonal projector, joints at a bound left out of the self-motion, a null-space phase "
                f"of {t_long:g} s (the thesis gives none for z); reached at t = {zl['t'][k]:.1f} s{where}; DM changed "
                f"by {settle:.1e} over the last 10 s"),
            Row("‖W_τ τ‖ for a 10 N z force at that configuration", T.TAU_Z[1], tau_norm(zl["q"][k], (0, 0, 1)), "N m"),
        ]
    rows_x = [
        Row("DM along x at q0", T.DM_X[0], float(x["dm"][0]), "N"),
        Row(f"DM along x after the Cartesian phase (t = {t_cartesian:g} s)", T.DM_X[1], float(x["dm_cart"]), "N"),
        Row("end-effector z after the Cartesian phase", T.Z_AFTER_CARTESIAN, float(dev.fk(x["q_cart"])[2]), "m"),
        Row(f"DM along x after the null-space phase (t = {t_end:g} s)", T.DM_X[2], float(x["dm_end"]), "N",
            "projector of the generalized Jacobian (eq. A.7, Q = I): the base moves with the self-motion"),
        Row(f"DM along x after the null-space phase, eq. A.19 as printed (weighted J†, t = {t_end:g} s)", T.DM_X[2],
            float(xw["dm_end"]), "N", "at γ = 0 the weighted J† locks the base: only the arm's own self-motion is left"),
        Row(f"DM along x after the Cartesian phase, eq. A.9's factor as printed (t = {t_cartesian:g} s)", T.DM_X[1],
            float(xp["dm_cart"]), "N", "−½H₂^(−3/2) instead of the derivative's −½H₂³: a step H₂^4.5 ≈ 400× shorter"),
        Row("end-effector z after the Cartesian phase, eq. A.9's factor as printed", T.Z_AFTER_CARTESIAN,
            float(dev.fk(xp["q_cart"])[2]), "m", "the printed factor contradicts the thesis's own 0.456 m and 3.905"),
        Row(f"DM along x after the null-space phase, eq. A.9's factor as printed (weighted J†, t = {t_end:g} s)",
            T.DM_X[2], float(xp["dm_end"]), "N", "reading: eqs. A.9 and A.19 both as printed"),
        *_suprema(dev, x["q_cart"], (1.0, 0.0, 0.0), T.DM_X[2]),
        Row("‖W_τ τ‖ ratio without / with DM enhancement (push along x)", T.TAU_RATIO_PUSH,
            float(x["dm_end"]) / float(x["dm"][0]), "",
            "thesis: measured torques while pushing a 26 kg box (≈ 40 vs ≈ 30 N m); ours: DM_after/DM_before, static"),
        Row("base displacement during the x enhancement", None,
            float(np.linalg.norm(x["q_end"][:2] - Q0[:2])), "m"),
        *_push_rows(dev, w_tau, (("orthogonal projector", x), ("eq. A.19 as printed", xw))),
    ]
    arrays = {}
    for name, r in out.items():
        for key in ("t", "dm", "x", "q"):
            arrays[f"{name}_{key}"] = r[key]
        arrays[f"{name}_skeleton_start"] = dev.skeleton(Q0)
        arrays[f"{name}_skeleton_end"] = dev.skeleton(r["q_end"])
    ok = all(r["bounds_ok"] for r in out.values())
    return Result(
        "appa.dm_enhancement",
        "§A.4.3: directional manipulability enhancement in Cartesian space then in the null space",
        [Table("§A.4.3 DM along z (simulation)", rows_z), Table("§A.4.3 / Fig. A.9 DM along x (box push)", rows_x)],
        arrays,
        [
            f"Kinematic simulation (the robot follows the command exactly), control period {dt} s; Cartesian "
            f"phase 0–{t_cartesian:g} s (A.17–A.18, only z optimised, z ∈ [0.36, 0.56] m), then the null-space "
            f"phase holding the reached position (A.19–A.20). Bounds respected in every run: {ok}.",
            "∇H₂ (A.9) uses the factor −½ s^(−3/2) = −½ H₂³ (s = uᵀJW²Jᵀu); eq. A.9 prints H₂^(−3/2). ∇_x H₂ = "
            "∇_{q_m}H₂ J_m⁺ (A.10).",
            "The box push itself (a 26 kg box, measured joint torques, Fig. A.8) is simulated on the MuJoCo plant by "
            "appa.box_push. Here the torque-norm row compares the DM ratio with the thesis's measured torque ratio, "
            "and the 'box push, static' rows read Fig. A.8 with a pure x force at the handle (a reading beside it).",
            "J_m and u are in world axes (u = [1, 0, 0] or [0, 0, 1]); the thesis's u = J_I⁻¹[1, 0, 0] with J_m "
            "in base axes is the same DM.",
            "The thesis's law has no position-bound handling: a joint at a position bound the DM gradient pushes "
            "against is left out of the (generalized) self-motion, which the other joints carry on (saturation in "
            "the null space, [51]), and the self-motion is scaled down where it would exceed a velocity bound "
            "(A.13), so that the held position is kept (the z run's elbow reaches 2.5 rad after ≈ 27 s).",
            "Readings (findings of the independent transcription, tests/test_transcription_wmm.py): eq. A.19 as "
            "printed (weighted J†) and eq. A.9's factor as printed are the literal rows; the headline rows use "
            "the orthogonal projector of J_q and the exact derivative of H₂.",
        ],
    )
