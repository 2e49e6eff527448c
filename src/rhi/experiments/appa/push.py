"""§A.4.3, Fig. A.8: the 26 kg box pushed by the WMM on the MuJoCo plant, with and without DM enhancement.

Each case runs the App. A controller on `rhi.sim.box_push.BoxPushPlant` (the wmm plant with a box that slides
on the floor with friction, pushed by a tip at the end effector) and reads the arm's joint torques from the
plant. With DM enhancement the push starts from the configuration that the Cartesian (0–5 s) and null-space
(5–20 s) phases reach (`rhi.experiments.appa.kinematic.dm_run`, kinematic as in `appa.dm_enhancement`).

**Readings** (`READINGS`). The thesis gives the box's mass (26 kg), the push's start (≈ 20 s) and goal
(≈ 0.2 m), the torque limits and the controllers' gains. Everything else is a reading. Each reading below
names the sentence that allows it, and all were fixed before the first run. The headline uses them as they
stand. `ALTERNATIVES` are the other readings, and the friction sweep (`frictions`) shows how the outcome
depends on μ (no thesis value).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Literal

import numpy as np

from rhi import thesis as T
from rhi.control.mobile import W_TAU_LIMITS, DMConfig, WeightedConfig, WeightedDistributionController
from rhi.devices.model import device
from rhi.experiments.appa.kinematic import PUSH_LIMITS, Q0, dm_run
from rhi.experiments.arguments import checked
from rhi.experiments.parts import Part, Plan, run_plan
from rhi.experiments.result import Result, Row, Table
from rhi.sim.box_push import PUSH_BASE_KV, Box, BoxPushPlant, push_trajectory
from rhi.sim.mobile import simulate_mobile

G = 9.81
#: Reading "friction": μ from Fig. A.9(b)'s ≈ 30 N m at the thesis's DM 5.88. For a pure x force F,
#: ‖W_τ J_mᵀ F u‖ = F / DM, so F = 30 × 5.88 = 176.4 N slides the box: μ = F / (26 kg · g).
FRICTION = 30.0 * 5.88 / (26.0 * G)
#: Alternative reading: a handbook value for a loaded wooden or cardboard box on a hard floor.
FRICTION_HANDBOOK = 0.4
#: A joint saturates when |τ_i| reaches this fraction of its limit.
SATURATED = 0.999
#: The cases: controller distribution, null-space projector, whether DM is enhanced, label of its rows.
CASES: dict[str, tuple[Literal["weighted", "pinv_generalized"], Literal["weighted", "generalized"], bool, str]] = {
    "without": ("pinv_generalized", "weighted", False, "without DM (traditional J⁺)"),
    "with": ("weighted", "weighted", True, "with DM (eq. A.19 as printed)"),
    "with_ortho": ("weighted", "generalized", True, "with DM (orthogonal projector)"),
    "without_weighted": ("weighted", "weighted", False, "without DM (weighted distribution)"),
}

READINGS: dict[str, tuple[str, str]] = {
    "without": ("without DM enhancement: the traditional controller J⁺ = Jᵀ(JJᵀ)⁻¹ of §A.4.2 (the generalized "
                "Jacobian, as appa.tracking's traditional row), no null-space term, holding x0 until the push",
                "line 2198: 'compared with the traditional method expressed in the trajectory tracking experiment "
                "(no null-space control is used) in a box pushing task'"),
    "with": ("with DM enhancement: eq. A.19 as printed (weighted J† of A.11–A.14, K_x = 10 I, ε = 0.2) with A.20's "
             "DM term along u = x (k_N = 0.2, W_τ = diag(1, 1, 1, 1, 2.5, 2.5, 2.5)) during the push too, after the "
             "Cartesian phase (0–5 s, A.17–A.18, k_C = 0.01, z ∈ [0.36, 0.56] m) and the null-space phase (5–20 s)",
             "line 2212: 'during time 5-20 s, the DM was enhanced using the null-space controller from 3.905 to 5.88, "
             "and then the push task started'"),
    "friction": (f"the box slides on the floor with Coulomb friction μ = 30 × 5.88 / (26 · 9.81) = {FRICTION:.3f}: the "
                 "force at which a pure x force gives ‖W_τ τ‖ = 30 N m at DM = 5.88 (‖W_τ J_mᵀ F u‖ = F / DM)",
                 "line 2212: 'the DM was enhanced ... to 5.88, and then the push task started ... the norm of the "
                 "weighted joint torque stayed at about 30 Nm'"),
    "push": ("the end effector's reference is held until 20 s, then moves 0.2 m along world x in 10 s with a "
             "minimum-jerk profile (the usual model of a person's point-to-point motion), then is held for 5 s",
             "line 2204: 'the goal is to push it about 0.2 m forward'; line 2210: 'The push task started at about "
             "20 s' (the person's profile through the haptic interface is not given)"),
    "contact": ("a frictionless sphere (radius 2 cm) at the end effector touches the box's vertical face, 5 mm from "
                "it at the start, on the box's centre line: the push force is normal to the face, along world x",
                "line 2202: 'u = J_I⁻¹[1, 0, 0]ᵀ ... to enhance the force exertion capability only along the x axis "
                "of the world frame'"),
    "box": ("the box is 0.5 × 0.5 m and 10 cm taller than the contact point. It stands on the floor under the drawn "
            "base's wheels and slides without tipping (pitch and roll held)",
            "line 2212: 'The box was pushed about 0.25 m with the proposed method'"),
    "torque": (f"the joint torque is MuJoCo's actuator torque of each arm joint (its position and velocity servo "
               f"together, clipped to 32/13 N m: one motor per joint). The plant compensates the arm's gravity, so "
               f"this is the torque with gravity subtracted. It is sampled every control period, and a joint "
               f"saturates when |τ_i| ≥ {SATURATED:.1%} of its limit",
               "line 2210: 'the joint torque is obtained via joint torque sensors, the gravity of the system has "
               "been subtracted, and the torque limits of the manipulator are 32 Nm for the first four joints and "
               "13 Nm for the last three joints'"),
    "base": (f"the base rolls without slip and holds against the push's reaction (velocity servo {PUSH_BASE_KV:g} "
             "N s/m)", "line 2004: 'Assuming a pure rolling contact between the wheels of the mobile base and the "
             "ground (i.e., no slippage)'"),
}
#: Readings beside the literal ones (name → (what, sentence)); their rows carry the same thesis values.
ALTERNATIVES: dict[str, tuple[str, str]] = {
    "with_ortho": ("with DM enhancement through the orthogonal projector of J_q (the base moves with the self-motion)",
                   "line 2030: 'J_q† = Q⁻¹J_qᵀ(J_qQ⁻¹J_qᵀ)⁻¹ is the weighted pseudoinverse of J_q'"),
    "without_weighted": ("without DM enhancement: the proposed weighted distribution (A.11–A.14) with the DM off",
                         "Fig. A.8's caption '(a) Without DM enhancement' names no other controller"),
    "handbook": (f"μ = {FRICTION_HANDBOOK} (a loaded wooden or cardboard box on a hard floor)",
                 "line 2204 names the box's mass only, neither its material nor the floor's"),
}


def push_case(case: str, friction: float, *, dt: float, t_cartesian: float, t_null: float, distance: float,
              duration: float, hold: float, settle: float,
              progress: Callable[[int, int], None] | None = None) -> dict[str, np.ndarray]:
    """One box push (a `Part` of `box_push_plan`): the DM phases where the case has them, then the push on the plant.

    Args:
        case: a key of `CASES`.
        friction: the box's friction μ on the floor.
        dt: control period [s].
        t_cartesian: Cartesian DM phase [s].
        t_null: null-space DM phase [s].
        distance: push length [m].
        duration: push time [s].
        hold: time held after the push [s].
        settle: time on the plant before the push starts [s].
        progress: callback(done, total) in control steps of the push.

    Returns:
        t (K,) thesis time [s] (the push starts at t_cartesian + t_null), tau (K, 7) [N m], box (K, 3) [m],
        force (K, 3) tip on box [N], x, x_des (K, 3) [m], q (K, 10), dm (K,) [N], q_start (10,).
    """
    dist, null_space, dm, _ = CASES[case]
    dev = device("wmm")
    cfg = DMConfig(u=(1.0, 0.0, 0.0), k_c=0.01, k_n=0.2) if dm else None
    q_start = dm_run((1.0, 0.0, 0.0), null_space, t_null, dt=dt, t_cartesian=t_cartesian)["q_end"] if dm else Q0.copy()
    ctl = WeightedDistributionController(dev, WeightedConfig(dt=dt, k_x=10.0, epsilon=0.2, distribution=dist,
                                                             null_space=null_space, dm=cfg))
    x_start = dev.fk(q_start)
    plant = BoxPushPlant(x_start, box=Box(friction=friction), device=dev)
    traj = push_trajectory(x_start, distance, start=settle, duration=duration, hold=hold, dt=dt)
    log = simulate_mobile(ctl, traj, q_start, plant=plant, stage="dm_null" if dm else "track", progress=progress)
    return {"t": log.t + (t_cartesian + t_null - settle), "tau": np.array(plant.torques), "box": np.array(plant.box_x),
            "force": np.array(plant.tip_force), "x": log.x, "x_des": log.x_des, "q": log.q_true, "dm": log.dm,
            "q_start": q_start}


def push_measures(t: np.ndarray, tau: np.ndarray, start: float) -> dict[str, float]:
    """What Fig. A.8 shows of a run, from the push's start on.

    Args:
        t: (K,) time [s].
        tau: (K, 7) arm joint torques [N m].
        start: the push's start [s].

    Returns:
        joint: the first joint (1–7) to saturate (NaN if none); t_sat: when [s] (NaN if none); max: the largest
        |τ_i| [N m]; max_joint: its joint; tau4: the largest |τ_4| [N m]; w_norm: the largest ‖W_τ τ‖ [N m].
    """
    on = t >= start - 1e-9
    a = np.abs(tau[on])
    sat = a >= SATURATED * PUSH_LIMITS
    k = np.flatnonzero(sat.any(axis=1))
    first = int(k[0]) if k.size else -1
    peak = a.max(axis=0)
    w = np.linalg.norm(tau[on] / np.asarray(W_TAU_LIMITS), axis=1)
    return {"joint": float(np.argmax(sat[first]) + 1) if first >= 0 else float("nan"),
            "t_sat": float(t[on][first]) if first >= 0 else float("nan"), "max": float(peak.max()),
            "max_joint": float(np.argmax(peak) + 1), "tau4": float(peak[3]), "w_norm": float(w.max())}


@checked
def box_push(dt: float = 0.01, t_cartesian: float = 5.0, t_null: float = 15.0, distance: float = 0.2,
             duration: float = 10.0, hold: float = 5.0, settle: float = 1.0, alternatives: bool = True,
             frictions: tuple[float, ...] = (0.3, 0.5), progress: Callable[[int, int], None] | None = None) -> Result:
    """§A.4.3, Fig. A.8: the box push with and without DM enhancement, joint torques from the plant.

    Args:
        dt: control period [s].
        t_cartesian: Cartesian DM phase [s] (thesis 0–5 s).
        t_null: null-space DM phase [s] (thesis 5–20 s; the push starts at its end).
        distance: push length [m] (thesis goal ≈ 0.2 m).
        duration: push time [s] (not in the thesis).
        hold: time held after the push [s].
        settle: time on the plant before the push [s].
        alternatives: run the readings of `ALTERNATIVES` too.
        frictions: more friction coefficients μ to run both literal cases at (a sensitivity, no thesis value).
        progress: callback(done, total) in control steps.

    Returns:
        Fig. A.8's claims beside the thesis, each case's torques, and the arrays for the figure.
    """
    return run_plan(box_push_plan(dt, t_cartesian, t_null, distance, duration, hold, settle, alternatives, frictions),
                    progress)


@checked
def box_push_plan(dt: float = 0.01, t_cartesian: float = 5.0, t_null: float = 15.0, distance: float = 0.2,
                  duration: float = 10.0, hold: float = 5.0, settle: float = 1.0, alternatives: bool = True,
                  frictions: tuple[float, ...] = (0.3, 0.5)) -> Plan:
    """`box_push` as independent parts, one per run (arguments as `box_push`)."""
    for mu in frictions:
        Box(friction=mu)  # the friction's own check, before any run
    runs = [("without", FRICTION), ("with", FRICTION)]
    if alternatives:
        runs += [("with_ortho", FRICTION), ("without_weighted", FRICTION), ("without", FRICTION_HANDBOOK),
                 ("with", FRICTION_HANDBOOK)]
    runs += [(c, float(mu)) for mu in frictions for c in ("without", "with")]
    work = int(round((settle + duration + hold) / dt)) + 1
    return Plan([Part(c if mu == FRICTION else f"{c}, μ = {mu:.2f}",
                      functools.partial(push_case, c, mu, dt=dt, t_cartesian=t_cartesian, t_null=t_null,
                                        distance=distance, duration=duration, hold=hold, settle=settle), work)
                 for c, mu in runs],
                functools.partial(_merge, runs=tuple(runs), start=t_cartesian + t_null, distance=distance))


def _label(case: str, mu: float) -> str:
    """The rows' label of a run: the case's, with μ where it is not the literal reading's."""
    return CASES[case][3] + ("" if mu == FRICTION else f", μ = {mu:.2f}")


def _merge(outputs: list[dict[str, np.ndarray]], *, runs: tuple[tuple[str, float], ...], start: float,
           distance: float) -> Result:
    rows: list[Row] = []
    sweep: list[Row] = []
    arrays: dict[str, np.ndarray] = {}
    meas = {}
    for (case, mu), out in zip(runs, outputs):
        m = push_measures(out["t"], out["tau"], start)
        meas[case, mu] = m
        label, literal = _label(case, mu), mu == FRICTION
        pushed = float(out["box"][-1, 0] - out["box"][0, 0])
        sat = "never" if np.isnan(m["joint"]) else f"joint {m['joint']:.0f} at {m['t_sat']:.2f} s"
        where = f"largest at joint {m['max_joint']:.0f}; first saturation: {sat}"
        dm = [Row(f"{label}: DM along x at the push's start", None, float(out["dm"][0]), "N")] if CASES[case][2] else []
        new = [Row(f"{label}: first arm joint to saturate", T.PUSH_JOINT if case == "without" and literal else None,
                   m["joint"], "", "no joint reached its limit" if np.isnan(m["joint"]) else ""),
               Row(f"{label}: time the first joint saturates", T.PUSH_SATURATION_T if case == "without" and literal
                   else None, m["t_sat"], "s", "depends on the push profile, which the thesis does not give"),
               Row(f"{label}: largest arm joint torque during the push", T.PUSH_MAX_TORQUE
                   if case.startswith("with") and not case.startswith("without") else None, m["max"], "N m", where,
                   bound="max" if case.startswith("with") and not case.startswith("without") else None),
               Row(f"{label}: largest |τ_4| during the push", None, m["tau4"], "N m"),
               Row(f"{label}: largest ‖W_τ τ‖ during the push", None, m["w_norm"], "N m"),
               Row(f"{label}: box pushed", None, pushed, "m", f"the end effector's reference moves {distance:g} m"),
               *dm]
        (rows if literal or mu == FRICTION_HANDBOOK else sweep).extend(new)
        key = case if literal else f"{case}_mu{mu:.2f}"
        for name in ("t", "tau", "box", "force", "x", "x_des", "dm"):
            arrays[f"{key}_{name}"] = out[name]
    w, wo = meas["with", FRICTION], meas["without", FRICTION]
    rows.insert(0, Row("box–floor friction μ (reading 'friction': Fig. A.9(b)'s 30 N m at DM 5.88)", None, FRICTION, ""))
    rows.append(Row("largest ‖W_τ τ‖ during the push, without / with DM enhancement", T.TAU_RATIO_PUSH,
                    wo["w_norm"] / w["w_norm"], "", "thesis: 'almost 40' / 'about 30' N m (Fig. A.9(b))"))
    arrays["limits"] = PUSH_LIMITS
    arrays["push_start"] = np.array(start)
    tables = [Table("Fig. A.8: joint torques in the box push", rows)]
    if sweep:
        tables.append(Table("Fig. A.8: sensitivity to the floor's friction μ (no thesis value)", sweep))
    return Result(
        "appa.box_push", "§A.4.3 / Fig. A.8: the 26 kg box push on the MuJoCo plant, with and without DM enhancement",
        tables, arrays,
        [f"Reading '{k}' (fixed before the first run): {what} ({why})." for k, (what, why) in READINGS.items()]
        + [f"Alternative reading '{k}': {what} ({why})." for k, (what, why) in ALTERNATIVES.items()]
        + [_over_friction(meas), _levers()],
    )


def _over_friction(meas: dict[tuple[str, float], dict[str, float]]) -> str:
    """The note on both Fig. A.8 claims at every μ of this run (the traditional J⁺ and eq. A.19 as printed)."""
    parts = []
    for mu in sorted({mu for case, mu in meas if case == "without" and ("with", mu) in meas}):
        wo, w = meas["without", mu], meas["with", mu]
        sat = "no joint saturates" if np.isnan(wo["joint"]) else f"joint {wo['joint']:.0f} saturates first"
        parts.append(f"μ = {mu:.3f}: without DM {sat}, with DM the largest torque is {w['max']:.1f} N m")
    return "Both claims at each friction of this run: " + "; ".join(parts) + "."


def _levers() -> str:
    """The note on which joint a pure x force at the end effector loads most, relative to its limit, at q0."""
    per_n = np.abs(device("wmm").jacobian(Q0)[:, 3:].T @ np.array([1.0, 0.0, 0.0]))  # [N m per N]
    order = np.argsort(-per_n / PUSH_LIMITS)
    return (f"At q0 a pure x force at the end effector loads joint {order[0] + 1} most relative to its limit "
            f"({per_n[order[0]]:.3f} N m per N) and joint 4 with {per_n[3]:.3f} N m per N; joint 4 saturates first "
            "only where the force or the configuration differs from q0's pure push.")
