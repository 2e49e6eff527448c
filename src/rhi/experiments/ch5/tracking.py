"""Figs 5.5–5.6, Table 5.1: the W trajectory in the slave workspace, three scenarios (§5.4.1)."""

from __future__ import annotations

import functools

import numpy as np

from rhi import thesis as T
from rhi.control import Manipulability, TMIMatching
from rhi.errors import Unreachable
from rhi.experiments.arguments import checked
from rhi.experiments.ch5.setup import (
    B_D,
    GAIN,
    K_Q,
    NULL_DAMPING,
    Q_FIXED,
    REHAB_SEED,
    SCENARIOS,
    SLAVE_Q,
    SLAVE_SEED,
    SPEED,
    TABLE_5_1,
    THESIS_MEAN_TME_S2,
    THESIS_S2_BELOW_S1,
    TRACK,
    W_CENTER,
    W_HEIGHT,
    W_WIDTH,
    controller,
    devices,
    distance_to_polyline,
    plant_friction,
    tme_area,
    w_reference,
)
from rhi.experiments.parts import Part, Plan, run_plan
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress, positive, ticks
from rhi.metrics import ellipsoid_axes, penalized_jacobian, teleoperation_ellipsoid, tmi, velocity_ellipsoid
from rhi.sim import Hand, HandPath, Plant, Teleoperation, check_path_in_workspace, simulate

#: Alternative readings of scenarios 1–2 run beside the headline: (tag, scenario, changed setting).
READINGS = (("plain", "s1", {"k_q": None}), ("plain", "s2", {"k_q": None}),
            ("literal", "s2", {"k_q": None, "literal": True}))


@checked
def w_trajectory(*, progress: Progress | None = None, **settings) -> Result:
    """Figs 5.5–5.6: the W trajectory at 2 cm/s with three scenarios, the slave following by teleoperation.

    Scenario 1: RHI with the TMI objective (eq. 5.11, `TMIMatching` on the slave's encoders);
    scenario 2: RHI with Yoshikawa's μ (eq. 5.14); scenario 3: the 2-DoF Rehab (the RHI with
    q3 = q4 = 0 locked). The simulated hand drives the master along the W (the thesis's
    "internal PD controller"); the slave PD-tracks the master (`rhi.sim.Teleoperation`).

    Reported: mean TME area λ = σ₁σ₂ over the motion (thesis: scenario 2 = 0.1034, 15.3 %
    below scenario 1), the user's work W(t) = ∫F_hᵀẋ dt (eq. 5.15; Fig. 5.6, thesis order
    1 < 2 < 3), the slave's tracking errors, and the alignment of the W with the slave ME.

    The scenarios are independent (`w_trajectory_plan`: `rhi reproduce` runs them side by side).

    Args:
        progress: optional callback(done, total).
        **settings: scale, speed, settle, center, width, height, k_q, gain, damping, friction, ellipses, readings
            (`w_trajectory_plan`).

    Raises:
        Unreachable: the W leaves the workspace of the RHI, the Rehab or the slave (IK along it).
        InvalidInput: non-positive scale/speed/sizes, negative settle, unknown friction, an unknown setting.
    """
    return run_plan(w_trajectory_plan(**settings), progress)


@checked
def w_trajectory_plan(
    *,
    scale: float = 1.0,
    speed: float = SPEED,
    settle: float = 2.0,
    center=W_CENTER,
    width: float = W_WIDTH,
    height: float = W_HEIGHT,
    k_q: float | None = K_Q,
    gain: float = GAIN,
    damping: float = NULL_DAMPING,
    friction: str = "thesis",
    ellipses: int = 13,
    readings: bool = True,
) -> Plan:
    """`w_trajectory` as independent parts, one per scenario.

    Args:
        scale: scales the W's width and height (quick runs: < 1; the speed stays).
        speed: path speed [m/s] (thesis: 0.02).
        settle: hold at the W's first point before moving [s] (null-space convergence).
        center: centre of the W (`rhi.experiments.ch5`) [m].
        width: its width [m].
        height: its height [m].
        k_q: penalty shape of eq. 4.20 in the objectives of scenarios 1 and 2 (None: plain Jacobians,
            i.e. the literal eqs. 5.11 and 5.14).
        gain: null-space step size α [N m] (as `fixed_point`).
        damping: null-space damping k_D [N m s/rad].
        friction: "thesis" (Γ = 0.01, eq. 5.13) or "device".
        ellipses: points along the W where Fig. 5.5's ellipses are kept.
        readings: also run the alternative readings of scenarios 1–2 and report them beside (issue 23):
            "plain J" (k_q = None in both objectives) and "literal eq. 5.14" (scenario 2 with
            τ_N = α ∂μ/∂q of the plain Jacobian, not −α ∂(−log μ(J^q))/∂q).

    Raises:
        Unreachable: the W leaves the workspace of the RHI, the Rehab or the slave (IK along it).
        InvalidInput: non-positive scale/speed/sizes, negative settle, unknown friction.
    """
    scale = positive("scale", scale)
    settle = positive("settle", settle, allow_zero=True)
    gain = positive("gain", gain)
    damping = positive("damping", damping, allow_zero=True)
    path = w_reference(center, width * scale, height * scale, speed, settle)
    devs = devices()
    for dev in devs.values():
        plant_friction(friction, dev)  # validate before the IK checks
    duration = settle + path.duration + 0.5
    common = {"scale": scale, "speed": speed, "settle": settle, "center": center, "width": width, "height": height,
              "k_q": k_q, "gain": gain, "damping": damping, "friction": friction, "ellipses": ellipses,
              "start": w_start(path)}
    parts = [Part(key, functools.partial(w_scenario, key, **common), ticks(duration)) for key in SCENARIOS]
    if readings:  # the alternative readings of scenarios 1–2, after the three scenarios (`READINGS`)
        parts += [Part(f"{key}_{tag}", functools.partial(w_scenario, key, **{**common, **change}), ticks(duration))
                  for tag, key, change in READINGS]
    return Plan(parts, functools.partial(_w_merge, readings=readings, **common))


def w_start(path: HandPath) -> dict[str, tuple[float, ...]]:
    """{"RHI", "Rehab", "slave": start configuration (n,) [rad]} at the W's first point (IK from the §5.4 seeds).

    Raises:
        Unreachable: the W leaves the workspace of the RHI, the Rehab or the slave (IK along it).
    """
    p0 = path.points[0]
    seeds = {"RHI": Q_FIXED, "Rehab": REHAB_SEED, "slave": SLAVE_SEED}
    start = {}
    for name, dev in devices().items():
        try:
            start[name] = dev.ik(p0, seeds[name])
        except Unreachable:
            raise Unreachable(f"path: the W's first point {np.round(p0, 4).tolist()} m is outside the workspace of "
                              f"{name} ({dev.name})") from None
        check_path_in_workspace(dev, path, q0=start[name])
    return {k: tuple(v.tolist()) for k, v in start.items()}


def w_scenario(key: str, *, start: dict[str, tuple[float, ...]], progress: Progress | None = None,
               **setting) -> tuple[dict, dict]:
    """One scenario of `w_trajectory` (a `Part` of its plan): (its numbers, its arrays) from the start configurations.

    Args:
        key: "s1", "s2" or "s3" (`SCENARIOS`).
        start: {"RHI", "Rehab", "slave": start configuration (n,) [rad]} at the W's first point.
        progress: callback(done, total) in ticks.
        **setting: scale, speed, settle, center, width, height, k_q, gain, damping, friction, ellipses as
            `w_trajectory_plan` takes them.
    """
    scale, speed, settle, friction = setting["scale"], setting["speed"], setting["settle"], setting["friction"]
    k_q, gain, damping, ellipses = setting["k_q"], setting["gain"], setting["damping"], setting["ellipses"]
    path = w_reference(setting["center"], setting["width"] * scale, setting["height"] * scale, speed, settle)
    devs = devices()
    rhi, reh, slave = devs["RHI"], devs["Rehab"], devs["slave"]
    duration = settle + path.duration + 0.5
    N = ticks(duration)
    arrays: dict[str, np.ndarray] = {}
    dev = reh if key == "s3" else rhi
    sp = Plant(slave, friction=plant_friction(friction, slave))
    sp.reset(np.array(start["slave"]))
    tele = Teleoperation(sp)
    obj: TMIMatching | Manipulability | None
    if key == "s1":
        obj = TMIMatching(slave, sp, k_q=k_q)  # the slave's encoders at each tick
    elif key == "s2":
        obj = Manipulability(log=not setting.get("literal", False), k_q=k_q)
    else:
        obj = None
    plant = Plant(dev, friction=plant_friction(friction, dev))
    plant.reset(np.array(start["Rehab" if key == "s3" else "RHI"]))
    log = simulate(plant, controller(dev, obj, gain, damping), duration=duration, hand=Hand(path, **TRACK),
                   teleop=tele, progress=progress, record=SLAVE_Q)
    qs = log.extra["slave_q"]
    moving = (log.t >= settle - 1e-9) & (log.t <= settle + path.duration + 1e-9)
    Jm, Js = dev.jacobian(log.q), slave.jacobian(qs)
    area = tme_area(Jm, Js)
    ref = np.array([path(t)[0] for t in log.t])
    err_ref = np.linalg.norm(log.slave_x - ref, axis=1)[moving]
    err_path = distance_to_polyline(log.slave_x[moving], path.points)
    W0 = log.work[np.argmax(moving)]
    work = log.work - W0
    Jsp = penalized_jacobian(Js, qs, q_min=slave.q_min, q_max=slave.q_max, k_q=K_Q)
    Jmp = penalized_jacobian(Jm, log.q, q_min=dev.q_min, q_max=dev.q_max, k_q=K_Q)
    lim = np.min(np.minimum(log.q - dev.q_min, dev.q_max - log.q), axis=1)
    dt = np.diff(log.t, append=log.t[-1] + (log.t[1] - log.t[0]))[moving]
    dq = log.dq[moving]
    fr = plant.friction
    iw = np.flatnonzero(moving)[[0, -1]]
    ke = [0.5 * log.dq[i] @ dev.mass_matrix(log.q[i]) @ log.dq[i] for i in iw]
    stats = {
        "d_kinetic": float(ke[1] - ke[0]),
        "e_friction": float(np.sum((np.einsum("kj,kj->k", dq * fr.damping, dq)
                                    + np.abs(dq) @ fr.frictionloss) * dt)),
        "e_damping": float(np.sum(B_D * np.einsum("kj,kj->k", log.xdot[moving], log.xdot[moving]) * dt)),
        "e_actuator": float(np.sum(np.einsum("kj,kj->k", log.tau[moving], dq) * dt)),
        "area": float(np.mean(area[moving])),
        "area_pen": float(np.mean(tmi(Jmp, Jsp)[moving])),
        "bound": float(np.mean(np.abs(np.linalg.det(Js))[moving])),
        "mu": float(np.mean(np.sqrt(np.linalg.det(Jm @ np.swapaxes(Jm, -1, -2)))[moving])),
        "work": float(work[moving][-1]),
        "work_settle": float(W0),
        "err_rms": float(np.sqrt(np.mean(err_ref**2))),
        "err_max": float(np.max(err_ref)),
        "path_rms": float(np.sqrt(np.mean(err_path**2))),
        "master_rms": float(np.sqrt(np.mean(np.linalg.norm(log.x - ref, axis=1)[moving] ** 2))),
        "limit": float(np.degrees(np.min(lim[moving]))),
        "fault": 0.0 if log.fault is None else 1.0,
    }
    sel = slice(None, None, max(10, N // 1000))  # about 1000 samples per scenario for the figures
    arrays[f"{key}_t"] = log.t[sel] - settle
    arrays[f"{key}_work"] = work[sel]
    arrays[f"{key}_area"] = area[sel]
    arrays[f"{key}_x"] = log.x[sel]
    arrays[f"{key}_slave_x"] = log.slave_x[sel]
    arrays[f"{key}_q"] = log.q[sel]
    k = np.flatnonzero(moving)[np.linspace(0, int(moving.sum()) - 1, int(ellipses)).astype(int)]
    arrays[f"{key}_ell_points"] = log.slave_x[k]
    arrays[f"{key}_ell_master"] = velocity_ellipsoid(Jm[k])
    arrays[f"{key}_ell_slave"] = velocity_ellipsoid(Js[k])
    arrays[f"{key}_ell_tme"] = teleoperation_ellipsoid(Jm[k], Js[k])
    return stats, arrays


def _w_merge(outputs: list[tuple[dict, dict]], *, scale, speed, settle, center, width, height, k_q, gain, damping,
             friction, ellipses, start, readings) -> Result:
    path = w_reference(center, width * scale, height * scale, speed, settle)
    slave = devices()["slave"]
    arrays: dict[str, np.ndarray] = {"path": path.points, "settle": np.array(settle)}
    stats: dict[str, dict[str, float]] = {}
    for key, (st, arr) in zip(SCENARIOS, outputs):
        stats[key] = st
        arrays.update(arr)
    s1, s2, s3 = (stats[k] for k in SCENARIOS)
    below = 100.0 * (1.0 - s2["area"] / s1["area"])
    order = float(s1["work"] < s2["work"] < s3["work"])
    # alignment of the W's strokes with the slave ME's major axis, weighted by its anisotropy
    qs_path = check_path_in_workspace(slave, path, q0=np.array(start["slave"]), step=0.01)
    tangent = np.diff(path.sample(0.01), axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    s_ax, U_ax = ellipsoid_axes(velocity_ellipsoid(slave.jacobian(qs_path[:-1])))
    weight = 1.0 - s_ax[:, 1] / s_ax[:, 0]
    align = float(np.sum(weight * np.abs(np.einsum("kj,kj->k", tangent, U_ax[:, :, 0]))) / np.sum(weight))
    names = {k: f"scenario {i + 1} ({v})" for i, (k, v) in enumerate(SCENARIOS.items())}
    alt = {f"{key}_{tag}": st for (tag, key, _), (st, _arr) in zip(READINGS, outputs[len(SCENARIOS):])}
    rows = [
        Row(f"mean TME area, {names['s1']}", T.MEAN_TME_S1, s1["area"],
            "m²/s² per (rad/s)²",
            "thesis value implied: 0.1034 / (1 − 0.153); our W is not the thesis's (only drawn)"),
        Row(f"mean TME area, {names['s2']}", THESIS_MEAN_TME_S2, s2["area"], "m²/s² per (rad/s)²",
            "depends on where the W lies in the slave workspace (ours: module docstring)"),
        Row(f"mean TME area, {names['s3']}", None, s3["area"], "m²/s² per (rad/s)²"),
        Row("mean of the slave's own σ₁σ₂ along the W (upper bound of the TME area)", None, s1["bound"],
            "m²/s² per (rad/s)²", "the TME lies inside the slave ME; scenarios 1 and 2 come close to it"),
        Row("scenario 2's mean TME area below scenario 1's", THESIS_S2_BELOW_S1, below, "%"),
        Row(f"mean penalised TMI (k_q = {K_Q:g}, both robots), scenario 1", None, s1["area_pen"]),
        Row(f"mean penalised TMI (k_q = {K_Q:g}, both robots), scenario 2", None, s2["area_pen"]),
        Row(f"mean penalised TMI (k_q = {K_Q:g}, both robots), scenario 3", None, s3["area_pen"]),
        Row("mean Yoshikawa μ of the HI, scenario 1", None, s1["mu"], "m²/rad²"),
        Row("mean Yoshikawa μ of the HI, scenario 2 (maximised)", None, s2["mu"], "m²/rad²"),
        Row("mean Yoshikawa μ of the HI, scenario 3", None, s3["mu"], "m²/rad²"),
        Row("W's alignment with the slave ME major axis (mean |cos|, anisotropy-weighted)", None, align, "",
            "1: strokes along the major axis; 0.64: random directions"),
    ]
    if alt:  # the alternative readings (issue 23), each beside the headline's scenario 2 gap
        rows += [
            Row("reading 'plain J' (k_q = None in eqs. 5.11, 5.14): mean TME area, scenario 1", None,
                alt["s1_plain"]["area"], "m²/s² per (rad/s)²"),
            Row("reading 'plain J': mean TME area, scenario 2", None, alt["s2_plain"]["area"], "m²/s² per (rad/s)²"),
            Row("reading 'plain J': scenario 2's mean TME area below scenario 1's", THESIS_S2_BELOW_S1,
                100.0 * (1.0 - alt["s2_plain"]["area"] / alt["s1_plain"]["area"]), "%"),
            Row("reading 'literal eq. 5.14' (τ_N = α ∂μ/∂q, plain J): mean TME area, scenario 2", None,
                alt["s2_literal"]["area"], "m²/s² per (rad/s)²", "scenario 1 as the headline"),
            Row("reading 'literal eq. 5.14': scenario 2's mean TME area below scenario 1's", THESIS_S2_BELOW_S1,
                100.0 * (1.0 - alt["s2_literal"]["area"] / s1["area"]), "%"),
        ]
    excess = {k: stats[k]["work"] - stats[k]["e_damping"] for k in SCENARIOS}
    energies = (  # (quantity, {scenario: value [J]}, note): a row per scenario each
        ("user work over the W", {k: stats[k]["work"] for k in SCENARIOS}, "eq. 5.15, simulated hand"),
        ("energy dissipated by joint friction over the W", {k: stats[k]["e_friction"] for k in SCENARIOS},
         "∫ q̇ᵀΓq̇ dt: the part of the effort that depends on the HI's kinematics (cf. eq. 4.21)"),
        ("energy dissipated by the rendered damping B^d over the W", {k: stats[k]["e_damping"] for k in SCENARIOS},
         "∫ ẋᵀB^dẋ dt, the same path and speed for every scenario"),
        ("actuator work over the W", {k: stats[k]["e_actuator"] for k in SCENARIOS},
         "∫ τᵀq̇ dt: damping removes energy (< 0); null-space motion adds or removes it"),
        ("energy balance residual over the W",
         {k: stats[k]["work"] + stats[k]["e_actuator"] - stats[k]["e_friction"] - stats[k]["d_kinetic"]
          for k in SCENARIOS},
         "user + actuator work − friction losses − Δ kinetic energy: ≈ 0 up to the 1 kHz sampling of τᵀq̇"),
        ("user work beyond the rendered damping", excess,
         "W − ∫ẋᵀB^dẋ dt: the kinematics-dependent part of the effort (friction, inertia, null-space coupling)"),
    )
    effort = [Row(f"{what}, {names[k]}", None, value[k], "J", note) for what, value, note in energies for k in SCENARIOS]
    effort += [
        Row("effort order 1 < 2 < 3 holds (1 = yes)", T.EFFORT_ORDER, order, "", "Fig. 5.6"),
        Row("work ratio scenario 2 / scenario 1", T.EFFORT_RATIO_5_1[0],
            s2["work"] / s1["work"], "", "thesis: Table 5.1 experiments (8 users, uncompensated real friction)"),
        Row("work ratio scenario 3 / scenario 1", T.EFFORT_RATIO_5_1[1],
            s3["work"] / s1["work"], "", "thesis: Table 5.1 experiments"),
        Row("ratio of the work beyond damping, scenario 2 / scenario 1",
            T.EFFORT_RATIO_5_1[0], excess["s2"] / excess["s1"], "",
            "thesis: Table 5.1 experiments, where real friction dominates the damping"),
        Row("ratio of the work beyond damping, scenario 3 / scenario 1",
            T.EFFORT_RATIO_5_1[1], excess["s3"] / excess["s1"], "",
            "thesis: Table 5.1 experiments"),
    ]
    effort += [Row(f"user work while settling, {names[k]}", None, stats[k]["work_settle"], "J") for k in SCENARIOS]
    track = []
    for i, k in enumerate(SCENARIOS):
        st = stats[k]
        track += [
            Row(f"slave error to the reference point, RMS, {names[k]}", None, 1e3 * st["err_rms"], "mm",
                "simulated hand: a PD on the reference"),
            Row(f"slave error to the reference point, max, {names[k]}", TABLE_5_1["error"][i], 1e3 * st["err_max"],
                "mm", "thesis: Table 5.1 mean error of human users (experiments)"),
            Row(f"slave distance to the W polyline, RMS, {names[k]}", None, 1e3 * st["path_rms"], "mm"),
            Row(f"master error to the reference point, RMS, {names[k]}", None, 1e3 * st["master_rms"], "mm"),
            Row(f"closest approach to a joint limit, {names[k]}", None, st["limit"], "deg"),
        ]
    track.append(Row("task completion time (prescribed by the path speed)", None, path.duration, "s",
                     f"Table 5.1's experimental means: {TABLE_5_1['time']} s (humans choose their speed)"))
    notes = [
        f"W: centre {np.round(np.asarray(center, float), 3).tolist()} m, "
        f"{width * scale:.3f} m × {height * scale:.3f} m, "
        f"length {path.length:.3f} m at {speed} m/s after {settle} s of settling; means over the motion only.",
        "Effort differences come from the joint friction Γ q̇ (eq. 5.13) and from how the null-space motion "
        "couples into the handle; B^d ẋ is the same for all scenarios. Table 5.1 is from experiments with people and real "
        "(uncompensated) friction, so only the order and rough ratios are comparable.",
        "The slave's configuration for the TME comes from its simulated encoders (it lags the master by the PD's "
        "tracking error).",
        "Scenario 1's controller keeps reshaping the HI as the slave ME turns along the W; the actuators supply "
        "the friction losses of that self-motion (compare the actuator work with the rendered damping) and part of "
        "its energy reaches the hand through friction and Coriolis coupling (dips of W(t)), so a lower effort in "
        "scenario 1 is partly energy from the actuators, not only better-matched kinematics.",
        "Both RHI objectives bring the TME close to its upper bound, the slave's own ME (the μ-optimal HI ME is "
        "large enough to contain most of the slave's): scenario 2's TME is not clearly below scenario 1's, unlike "
        "the thesis's 15.3 %.",
    ]
    for k in SCENARIOS:
        if stats[k]["fault"]:
            notes.append(f"{names[k]}: the controller stopped (fault); see the log.")
    return Result("ch5.w_trajectory", "Figs 5.5–5.6: W trajectory in the slave workspace, three scenarios",
                  [Table("Fig. 5.5: teleoperation manipulability along the W", rows),
                   Table("Fig. 5.6 and Table 5.1: user effort (eq. 5.15)", effort),
                   Table("Tracking (Table 5.1's error and time are experimental)", track)],
                  arrays, notes)


