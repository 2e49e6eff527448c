"""Beyond the thesis: is the rendered wall passive? Energy at the hand in the §6.4 palpation set-up.

Set-up: the simulated rhi4 (MuJoCo plant, device friction) at X₀ = [0.5, 0.1] m, a virtual
one-sided wall of K_e = 1000 N/m along u = [0, 1] rendered at 1 kHz by eq. 7.2
(`ForceRendering`, B^d = 0.01 N s/m, C_x ẋ compensated), actuator saturation handled by
ASCM (Algorithm 1), the null-space objectives of the §6.4 controller (FME matching to
M_Stiff^des with β = 20, the joint-limit barrier, K_d = 0.1; `rhi.experiments.ch6`),
started at the FME-matched configuration. The simulated hand (3000 N/m, 40 N s/m, at
most 60 N, the grip of `ch6.palpation`) palpates repeatedly: its reference moves from
2 mm outside the wall to 15 mm into it and back at 1 cm/s, for the whole run (60 s).
The hand's work W = ∫F_hᵀẋ dt (eq. 5.15) is the energy it put into the device; W < 0 is
energy the device gave the hand.

Cases: without and with the time-domain passivity controller (`rhi.control.passivity`,
Hannaford and Ryu 2002, at the motor port), with and without the null-space objectives,
the passivity controller at the handle port (H&R's virtual-environment port), and simple force
scaling in place of ASCM (no allocation torque in the null space), and the null-space energy tank
(`rhi.control.tank`: the objectives funded by the null-space damping, the allocation's deficit taken
out by its own damper) without and with the series damper, and the passive null space without a passivity
controller (issue 25 item 2: the joint-limit barrier in sampled-exact form, `JointLimitBarrier.hold`, and ASCM's
redistribution and the objectives on the tank's gate, `NullSpaceTank(allocation="gate")`), its tank full or empty
at the start.
A 5000 N/m wall, without and with the passivity controller, shows the chatter.

The energy is traced from the log (every term exact under the zero-order hold):
the motors' work Σ τ(k)ᵀ(q(k+1) − q(k)), split into the task part (J#ᵀτ)ᵀΔx at the
handle and the null-space rest; the energy the sampled wall generates
Σ F_e(k)ᵀΔx + ΔU_wall; the plant's joint friction losses Σ (b q̇² + f_c |q̇|) ΔT. The
notes state which of them makes the device active.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np

from rhi.control import (
    ControllerConfig,
    ForceRendering,
    JointLimitBarrier,
    NullSpaceController,
    NullSpaceTank,
    Passivity,
    WeightedSum,
)
from rhi.control.allocation import Saturation
from rhi.control.passivity import Method, Port
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.beyond import passivity_notes, sources
from rhi.experiments.beyond.wall_measures import STOP_MARGIN, energies, moving_average, wall_force
from rhi.experiments.ch6 import setup as ch6
from rhi.experiments.parts import Part, Plan, run_plan
from rhi.experiments.result import Result, Row, Table
from rhi.sim import Hand, HandPath, Plant, Probe, Wall, simulate

#: The rendered wall [N/m], the stiff wall [N/m] and B^d [N s/m] (thesis §6.4, §7.5).
K_E = 1000.0
K_STIFF = 5000.0
B_D = 0.01
#: The palpating hand: stiffness [N/m], damping [N s/m], largest force [N], stroke [m] out/in, speed [m/s].
HAND = (3000.0, 40.0, 60.0)
OUT, DEPTH, SPEED = 0.002, 0.015, 0.01
#: Target of the issue: the hand's work with the passivity controller [J].
TARGET_W = -1e-3
#: The passive null space's tank (`rhi.control.tank`, ``allocation="gate"``): full at the start (T(0) = capacity, the
#: explicit budget the redistribution and the objectives may spend before they have taken any energy in), and empty.
GATE_FULL = NullSpaceTank(initial=0.05, capacity=0.05, allocation="gate")
GATE_EMPTY = NullSpaceTank(initial=0.0, capacity=0.05, allocation="gate")
#: case key: (null-space objectives, passivity port or None, saturation handling, `Passivity.method`, the null-space
#: energy tank `rhi.control.tank` or None)
CASES: dict[str, tuple[bool, Port | None, Saturation, Method, NullSpaceTank | None]] = {
    "objectives": (True, None, "ascm", "damper_bounding", None),
    "objectives_pc": (True, "motors", "ascm", "damper_bounding", None),
    "objectives_damper": (True, "motors", "ascm", "damper", None),
    "objectives_bounding": (True, "motors", "ascm", "bounding", None),
    "objectives_tank": (True, None, "ascm", "damper", NullSpaceTank()),
    "objectives_tank_damper": (True, "motors", "ascm", "damper", NullSpaceTank()),
    "passive": (True, None, "ascm", "damper", GATE_FULL),
    "passive_empty": (True, None, "ascm", "damper", GATE_EMPTY),
    "bare": (False, None, "ascm", "damper_bounding", None),
    "bare_pc": (False, "motors", "ascm", "damper_bounding", None),
    "objectives_pc_handle": (True, "handle", "ascm", "damper_bounding", None),
    "scaling": (True, None, "scaling", "damper_bounding", None),
}
#: Cases whose joint-limit barrier is the sampled-exact form (`JointLimitBarrier.hold` = the 1 ms sample).
SAMPLED = ("passive", "passive_empty")
#: The sample period of the palpation [s] (`simulate`'s default rate).
DT = 1e-3
#: Cases whose energy is split by torque source (`rhi.experiments.beyond.sources`: a replay of every tick).
SPLIT_CASES = ("objectives", "objectives_damper", "objectives_tank", "objectives_tank_damper", "passive")
STIFF_CASES = ("objectives", "objectives_pc")
#: Window of the moving average that separates chatter from the palpation motion [s].
CHATTER_WINDOW = 0.02
DECIMATE = 10
#: Order of the per-case ``{case}_summary`` array.
SUMMARY = ("W", "motors", "task", "null", "wall_zoh", "friction", "force_rms_error", "chatter_velocity",
           "E_obs_min", "qdot_max", "force_peak", "objective_work", "null_work", "tank_end", "force_peak_wall",
           "contact_peak", "peak_at_stop")


#: `simulate`'s record hook (a `Probe`: the run stays on the compiled loop): the passivity scale λ, ASCM's held
#: joints and the tank's T_O + T_A, λ and μ.
PROBE = Probe(pc_scale="pc_scale", held="held", tank="tank", tank_scale="tank_scale", tank_damping="tank_damping")


def controller(dev: Device, *, objectives: bool, port: Port | None, saturation: Saturation = "ascm",
               method: Method = "damper_bounding", tank: NullSpaceTank | None = None, sampled: bool = False,
               implementation: Literal["fast", "reference"] = "fast") -> NullSpaceController:
    """The §6.4 rendering controller: eq. 7.2 with B^d = 0.01, ASCM (or `saturation`).

    With the ch. 6 null-space objectives if `objectives` (the barrier's sampled-exact form if `sampled`), the
    passivity controller (`method`) on `port` if given, and the null-space energy tank `tank` (`rhi.control.tank`).
    """
    u = np.array(ch6.U)
    _, _, _, Ms = ch6.desired_fmes(dev, u, ch6.Q_HOME)
    terms = ch6.controller_terms(Ms, dev.torque_max) if objectives else ()
    if sampled:
        terms = tuple(dataclasses.replace(t, objective=dataclasses.replace(t.objective, hold=DT))
                      if isinstance(t.objective, JointLimitBarrier) else t for t in terms)
    law = ForceRendering(damping=B_D, passivity=None if port is None else Passivity(port=port, method=method))
    return NullSpaceController(dev, ControllerConfig(
        primary=law, objectives=terms, damping=ch6.K_D, saturation=saturation,
        tank=tank, implementation=implementation))


def _run(dev: Device, q0: np.ndarray, case: str, *, stiffness: float, duration: float, depth: float, speed: float,
         progress) -> tuple[dict, dict]:
    u, x0 = np.array(ch6.U), np.array(ch6.X0)
    strokes = int(math.ceil(duration * speed / (OUT + depth))) + 1
    pts = [x0] + [x0 - OUT * u, x0 + depth * u] * strokes
    hand = Hand(HandPath(np.array(pts), speed=speed, start=0.2), stiffness=HAND[0], damping=HAND[1], max_force=HAND[2])
    plant = Plant(dev)
    plant.reset(q0)
    objectives, port, saturation, method, tank = CASES[case]
    ctrl = controller(dev, objectives=objectives, port=port, saturation=saturation, method=method, tank=tank,
                      sampled=case in SAMPLED)
    log = simulate(plant, ctrl, duration=duration, hand=hand, virtual=Wall(x0, u, stiffness), progress=progress,
                   record=PROBE)
    en = energies(dev, log, plant.friction, stiffness, x0=x0, u=u, damping=B_D)
    names, by_tick, replay = (sources.tick_work(dev, ctrl.config, log) if case in SPLIT_CASES
                              else ([], np.zeros((len(log.t) - 1, 0)), math.nan))
    work = dict(zip(names, by_tick.sum(axis=0).tolist()))
    pen = (log.x - x0) @ u
    F_des = stiffness * np.maximum(pen, 0.0)
    F = log.ft[:, :2] @ u  # the force the hand pushes along u = the force rendered to it [N]
    contact = F_des >= 0.5
    err = (F - F_des)[contact]
    w = max(1, int(round(CHATTER_WINDOW * 1000.0)))
    xd = log.xdot @ u
    hf_v = (xd - moving_average(xd, w))[contact]
    hf_F = (F - moving_average(F, w))[contact]
    stop = np.any((log.q < dev.q_min) | (log.q > dev.q_max), axis=1)
    held = log.extra["held"].astype(np.int64) @ (1 << np.arange(dev.n))  # the held set as a bit mask
    E, alpha_pc = log.E_obs, log.alpha_pc
    full = np.array([int(h).bit_count() >= dev.n - dev.m for h in held[:-1]])  # no redundancy left
    switch = np.convolve(np.diff(held, prepend=held[0]) != 0, np.ones(4), mode="full")[:len(held) - 1] > 0
    if E is None or alpha_pc is None:
        raise InvalidInput("log: no passivity columns (E_obs, alpha_pc); rhi.sim.simulate records them every tick")
    m = {
        **en,
        "W_min": float(np.min(log.work)),
        "force_rms_error": float(np.sqrt(np.mean(err**2))) if err.size else math.nan,
        "force_mean_error": float(np.mean(err)) if err.size else math.nan,
        "force_peak": float(np.max(F)),
        "penetration_max": float(np.max(pen)),
        "chatter_velocity": float(np.sqrt(np.mean(hf_v**2))) if hf_v.size else math.nan,
        "chatter_force": float(np.sqrt(np.mean(hf_F**2))) if hf_F.size else math.nan,
        "held": float(np.mean(held > 0)),
        "held_full": float(np.mean([int(h).bit_count() >= dev.n - dev.m for h in held])),
        "qdot_max": float(np.max(np.abs(log.dq))),
        "beyond_range": float(np.mean(stop)),
        **wall_force(F, contact, stop, float(log.t[1] - log.t[0])),
        "E_obs_min": float(np.nanmin(E)) if port is not None else math.nan,
        "pc_active": float(np.mean(alpha_pc > 0)) if port is not None else math.nan,
        "pc_scaled": float(np.mean(log.extra["pc_scale"] < 1)) if port is not None else math.nan,
        "alpha_scaling_min": float(np.nanmin(log.alpha)),
        "fault": log.fault,
        "sources": work,
        "when": {f"{name} {k}": float(np.sum(by_tick[sel, names.index(name)])) for name in ("allocation", "barrier")
                 if name in names for k, sel in (("held_full", full), ("switch", switch))},
        "replay_error": replay,
        "barrier": _barrier_energy(dev, ctrl, log) if case in SPLIT_CASES else {},
        "objective_work": sources.objective_work(work) if work else math.nan,
        "null_work": sources.null_work(work) if work else math.nan,
        "tank_end": float(log.extra["tank"][-1]),
        "tank_min": float(np.min(log.extra["tank"])),
        "tank_off": float(np.mean(log.extra["tank_scale"] < 1)),
        "tank_damped": float(np.mean(log.extra["tank_damping"] > 0)),
    }
    series = {"t": log.t, "W": log.work, "F": F, "F_des": F_des, "pen": pen, "E_obs": E,
              "alpha_pc": alpha_pc, "xdot": xd}
    out = {k: v[::DECIMATE] for k, v in series.items()}
    out["summary"] = np.array([m[k] for k in SUMMARY])
    return m, out


def _barrier_energy(dev: Device, ctrl: NullSpaceController, log) -> dict[str, float]:
    """The energy the barrier's held torque generates on the run's trajectory (`sources.barrier_generated`) [J].

    Both forms on the same encoder readings: "gradient" (sample-and-hold) and "sampled" (the discrete gradient).
    """
    out: dict[str, float] = {}
    for gain, bar in ctrl.barriers:
        if isinstance(bar, JointLimitBarrier):
            for form in ("gradient", "sampled"):
                out[form] = out.get(form, 0.0) + sources.barrier_generated(dev, bar, gain, log,
                                                                         sampled=form == "sampled")
    return out


def case(*, q0: tuple[float, ...], name: str, stiffness: float, duration: float, depth: float, speed: float,
         progress: Callable[[int, int], None] | None = None) -> tuple[dict, dict]:
    """One case of `passivity` (a `Part` of its plan): (numbers, decimated series) of the case `name` at `stiffness`."""
    return _run(device("rhi4"), np.array(q0), name, stiffness=stiffness, duration=duration, depth=depth,
                speed=speed, progress=progress)


@checked
def passivity_plan(
    *,
    duration: float = 60.0,
    stiff_duration: float = 20.0,
    stiffness: float = K_E,
    stiff: float | None = K_STIFF,
    depth: float = DEPTH,
    speed: float = SPEED,
    cases: Sequence[str] = tuple(CASES),
) -> Plan:
    """`passivity` as independent parts (one per case and wall), for running them side by side.

    Arguments as `passivity`; the parts are the cases at `stiffness`, then the `STIFF_CASES` at `stiff`.

    Raises:
        InvalidInput: non-positive durations or stiffnesses, unknown cases.
    """
    for name, v in (("duration", duration), ("stiff_duration", stiff_duration), ("stiffness", stiffness),
                    ("depth", depth), ("speed", speed)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
    if stiff is not None and not (isinstance(stiff, (int, float)) and math.isfinite(stiff) and stiff > 0):
        raise InvalidInput(f"stiff: must be finite and > 0 [N/m] or None, got {stiff!r}")
    cases = tuple(cases)
    for c in cases:
        if c not in CASES:
            raise InvalidInput(f"cases: unknown case {c!r}; available: {', '.join(CASES)}")
    if not cases:
        raise InvalidInput("cases: give at least one case")
    dev = device("rhi4")
    x0, u = np.array(ch6.X0), np.array(ch6.U)
    _, _, _, Ms = ch6.desired_fmes(dev, u, ch6.Q_HOME)
    q0 = ch6.best_match(dev, x0, WeightedSum(ch6.controller_terms(Ms, dev.torque_max)), starts=1)
    stiff_cases = STIFF_CASES if stiff is not None else ()
    n1, n2 = int(round(duration * 1000)), int(round(stiff_duration * 1000))
    q0t = tuple(q0.tolist())
    parts = [Part(c, functools.partial(case, q0=q0t, name=c, stiffness=stiffness, duration=duration, depth=depth,
                                       speed=speed), n1)
             for c in cases]
    parts += [Part(f"stiff_{c}", functools.partial(case, q0=q0t, name=c, stiffness=stiff, duration=stiff_duration,
                                                   depth=depth, speed=speed), n2)
              for c in stiff_cases if stiff is not None]
    return Plan(parts, functools.partial(_merge, q0=q0t, cases=cases, stiff_cases=stiff_cases, duration=duration,
                                         stiff_duration=stiff_duration, stiffness=stiffness, stiff=stiff, depth=depth,
                                         speed=speed))


def _merge(outputs: list[tuple[dict, dict]], *, q0, cases, stiff_cases, duration, stiff_duration, stiffness, stiff,
           depth, speed) -> Result:
    arrays: dict[str, np.ndarray] = {"q0": np.array(q0), "x0": np.array(ch6.X0), "u": np.array(ch6.U),
                                     "stiffness": np.array(stiffness)}
    res: dict[str, dict] = {}
    for c, (m, series) in zip(cases, outputs):
        res[c] = m
        arrays.update({f"{c}_{k}": v for k, v in series.items()})
    stiff_res: dict[str, dict] = {}
    for c, (m, series) in zip(stiff_cases, outputs[len(cases):]):
        stiff_res[c] = m
        arrays.update({f"stiff_{c}_{k}": v for k, v in series.items()})
    if stiff is not None:
        arrays["stiff"] = np.array(stiff)
    return Result("beyond.passivity", f"Beyond the thesis: energy at the hand palpating {stiffness:g} N/m on the "
                  "simulated rhi4, without and with time-domain passivity control",
                  _tables(res, stiff_res, duration, stiff_duration, stiffness, stiff), arrays,
                  _notes(res, stiff_res, duration, stiffness, depth, speed))


@checked
def passivity(
    *,
    duration: float = 60.0,
    stiff_duration: float = 20.0,
    stiffness: float = K_E,
    stiff: float | None = K_STIFF,
    depth: float = DEPTH,
    speed: float = SPEED,
    cases: Sequence[str] = tuple(CASES),
    progress: Callable[[int, int], None] | None = None,
) -> Result:
    """The energy the device gives the hand in the §6.4 palpation set-up, without and with passivity control.

    The cases are independent (`passivity_plan`: `rhi reproduce` runs them side by side).

    Args:
        duration: palpation time per case at `stiffness` [s] (issue 10: 60 s).
        stiff_duration: palpation time per case at the stiff wall [s].
        stiffness: the rendered wall K_e [N/m] (thesis: 1000).
        stiff: the stiff wall [N/m] (None: skip it).
        depth: how far the hand's reference goes into the wall each stroke [m].
        speed: the hand's reference speed [m/s].
        cases: keys of `CASES`.
        progress: callback(done, total) in control ticks.

    Returns:
        Result "beyond.passivity": energy and force tables; arrays ``{case}_{t, W, F, F_des, pen,
        E_obs, alpha_pc, xdot}`` (every 10 ms) and ``{case}_summary`` (the `SUMMARY` numbers, [J],
        [N], [m/s], [rad/s]) at K_e, and ``stiff_{case}_…`` at the stiff wall.

    Raises:
        InvalidInput: non-positive durations or stiffnesses, unknown cases.
    """
    return run_plan(passivity_plan(duration=duration, stiff_duration=stiff_duration, stiffness=stiffness, stiff=stiff,
                                   depth=depth, speed=speed, cases=cases), progress)


_LABEL = {
    "objectives": "null-space objectives, no PC",
    "objectives_pc": "null-space objectives, PC: damper + energy bounding (motor port)",
    "objectives_damper": "null-space objectives, series damper only, the law never scaled (motor port)",
    "objectives_bounding": "null-space objectives, energy bounding only (motor port)",
    "objectives_tank": "null-space objectives on the null-space energy tank, no PC",
    "objectives_tank_damper": "null-space objectives on the null-space energy tank, series damper (motor port)",
    "bare": "no null-space objectives, no PC",
    "bare_pc": "no null-space objectives, PC (motor port)",
    "objectives_pc_handle": "null-space objectives, PC at the handle port",
    "scaling": "null-space objectives, simple force scaling instead of ASCM, no PC",
    "passive": "passive null space (sampled-exact barrier, redistribution gated by a tank full at the start), no PC",
    "passive_empty": "passive null space (sampled-exact barrier, redistribution gated by an empty tank), no PC",
}


_WHEN = {"held_full": "while ASCM holds n − m joints", "switch": "on the ticks the held set switches and the 3 after"}


def _tables(res, stiff_res, duration, stiff_duration, stiffness, stiff) -> list[Table]:
    e_rows, f_rows, s_rows = [], [], []
    for c, m in res.items():
        lab = _LABEL[c]
        pc = CASES[c][1] is not None
        e_rows += [
            Row(f"hand's work W over {duration:g} s, {lab}", TARGET_W if pc else None, m["W"], "J",
                "target (issue 10): W ≥ −1 mJ with the passivity controller" if pc else ""),
            Row(f"lowest W during the run, {lab}", None, m["W_min"], "J"),
            Row(f"motors' work on the mechanism, {lab}", None, m["motors"], "J", "exact under the zero-order hold"),
            Row(f"  of which at the handle (J#ᵀτ)ᵀΔx, {lab}", None, m["task"], "J"),
            Row(f"  of which in the null space, {lab}", None, m["null"], "J"),
            Row(f"energy generated by the sampled wall Σ F_eᵀΔx + ΔU, {lab}", None, m["wall_zoh"], "J"),
            Row(f"joint friction losses of the plant, {lab}", None, m["friction"], "J"),
            Row(f"ticks with a joint held at its torque limit by ASCM, {lab}", None, 100.0 * m["held"], "%"),
            Row(f"fastest joint speed, {lab}", None, m["qdot_max"], "rad/s"),
            Row(f"ticks with a joint past its range limit (in the plant's stop), {lab}", None,
                100.0 * m["beyond_range"], "%"),
        ]
        if pc:
            e_rows += [Row(f"lowest E_obs of the observer, {lab}", 0.0, m["E_obs_min"], "J"),
                       Row(f"ticks with the PC damping / scaling the law, {lab}", None,
                           100.0 * m["pc_active"], "%", f"scaled: {100.0 * m['pc_scaled']:.1f} %")]
        f_rows += [
            Row(f"RMS force error F − K_e δX in contact, {lab}", None, m["force_rms_error"], "N",
                "includes the torque saturation every case shares"),
            Row(f"mean force error in contact, {lab}", None, m["force_mean_error"], "N"),
            Row(f"largest rendered force, {lab}", None, m["force_peak"], "N",
                f"a joint-stop impact at {m['peak_time']:.2f} s" if m["peak_at_stop"] else ""),
            Row(f"largest rendered force ≥ {STOP_MARGIN * 1e3:g} ms from a joint stop, {lab}", None,
                m["force_peak_wall"], "N", "the wall, not a stop impact"),
            Row(f"median over the contacts of each contact's largest force, {lab}", None, m["contact_peak"], "N"),
            Row(f"deepest penetration, {lab}", None, 1e3 * m["penetration_max"], "mm"),
        ]
    src_rows = []
    for c, m in res.items():
        lab = _LABEL[c]
        if m["sources"]:
            src_rows += sources.rows(m["sources"], lab)
            src_rows.append(Row(f"largest replay error of the twin, {lab}", None, m["replay_error"], "N m",
                                "the twin sends the logged torque"))
        if CASES[c][4] is not None:
            src_rows += [Row(f"tank energy T_O + T_A at the end (lowest), {lab}", None, m["tank_end"], "J",
                             f"lowest {m['tank_min']:.3g} J; objectives scaled (λ < 1) on "
                             f"{100 * m['tank_off']:.0f} % of the ticks, the allocation's damper on "
                             f"{100 * m['tank_damped']:.0f} %")]
        for form, e in m["barrier"].items():
            src_rows.append(Row(f"  energy the barrier's held torque generates, Σ τ_bᵀΔq + Δν ({form} form on this "
                                f"run's trajectory), {lab}", None, e, "J",
                                "the barrier's own port, before the projection; 0: a potential's exact sampled form"
                                + (" (the form this case sends)" if (form == "sampled") == (c in SAMPLED) else "")))
        if m["sources"]:
            src_rows.append(Row(f"ticks with no redundancy left (ASCM holds n − m joints), {lab}", None,
                                100.0 * m["held_full"], "%"))
            src_rows += [Row(f"  {k.split()[0]}'s work {_WHEN[k.split()[1]]}, {lab}", None, v, "J")
                         for k, v in m["when"].items()]
    for c, m in stiff_res.items():
        lab = _LABEL[c]
        s_rows += [
            Row(f"{stiff:g} N/m: chatter, RMS handle velocity above {1 / CHATTER_WINDOW:g} Hz in contact, {lab}",
                None, 1e3 * m["chatter_velocity"], "mm/s"),
            Row(f"{stiff:g} N/m: chatter, RMS force above {1 / CHATTER_WINDOW:g} Hz in contact, {lab}", None,
                m["chatter_force"], "N"),
            Row(f"{stiff:g} N/m: hand's work W over {stiff_duration:g} s, {lab}", None, m["W"], "J"),
            Row(f"{stiff:g} N/m: RMS force error in contact, {lab}", None, m["force_rms_error"], "N"),
            Row(f"{stiff:g} N/m: fastest joint speed, {lab}", None, m["qdot_max"], "rad/s"),
        ]
    for c, m in res.items():
        if c in ("objectives", "bare"):
            s_rows.append(Row(f"{stiffness:g} N/m: chatter, RMS handle velocity above {1 / CHATTER_WINDOW:g} Hz, "
                              f"{_LABEL[c]}", None, 1e3 * m["chatter_velocity"], "mm/s"))
    if "objectives" in res:
        m0 = res["objectives"]
        for c, m in res.items():
            if (CASES[c][1] is not None or c in SAMPLED) and CASES[c][0]:
                f_rows.append(Row(f"passive and the wall's largest force within 10 % of no PC's, {_LABEL[c]}", 1.0,
                                  float(m["W"] >= TARGET_W and m["W_min"] >= TARGET_W and abs(
                                      m["force_peak_wall"] / m0["force_peak_wall"] - 1.0) <= 0.1), "",
                                  f"W ≥ {TARGET_W * 1e3:g} mJ at every time; {m['force_peak_wall']:.2f} N vs "
                                  f"{m0['force_peak_wall']:.2f} N (away from the joint stops)", bound="min"))
    out = [Table(f"Energy at the hand palpating {stiffness:g} N/m for {duration:g} s (positive: into the device)",
                 e_rows),
           Table("What passivity costs in force", f_rows)]
    if src_rows:
        out.append(Table("Where the energy comes from: the motor-port work of each torque source, Σ part(k)ᵀΔq "
                         "(positive: into the mechanism)", src_rows))
    if s_rows:
        out.append(Table("Chatter", s_rows))
    return out


def _notes(res, stiff_res, duration, stiffness, depth, speed) -> list[str]:
    """The set-up, then `passivity_notes.notes`."""
    notes = [
        f"rhi4 in MuJoCo (device friction), 1 kHz, X₀ = {list(ch6.X0)} m, u = {list(ch6.U)}; wall {stiffness:g} N/m "
        f"rendered by eq. 7.2 with B^d = {B_D} N s/m and C_x ẋ; ASCM; objectives: FME matching to M_Stiff^des "
        f"(β = {ch6.BETA:g}) + joint-limit barrier, K_d = {ch6.K_D}; hand {HAND[0]:g} N/m, {HAND[1]:g} N s/m, "
        f"≤ {HAND[2]:g} N, reference {OUT * 1e3:g} mm out to {depth * 1e3:g} mm in at {speed * 1e2:g} cm/s, "
        f"{duration:g} s per case.",
        "Sign: W = ∫F_hᵀẋ dt is the energy the hand put into the device; W < 0 is energy the device gave the hand. "
        "The passivity observer's E_obs is the energy flowed from the mechanism into the controller (≥ 0: passive).",
    ]
    return notes + passivity_notes.notes(res, stiff_res, labels=_LABEL, window=CHATTER_WINDOW)
