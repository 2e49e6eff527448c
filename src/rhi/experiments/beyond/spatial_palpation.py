"""Beyond the thesis (§8.2): 3-D palpation on the spatial RHI srhi5 — the controllers of chs 3, 6 and 7 with m = 3.

The ch. 6 palpation (eq. 6.21, K_e = 1000 N/m) in 3-D: the hand presses the srhi5 handle
down (u = [0, 0, −1] by default) into a virtual spring from X₀. The desired FMEs are eqs.
6.11–6.13 generalised to m = 3: M_Free^des has its minor axis ζ along u and 𝒦 on the two
axes across it, M_Stiff^des its major axis 𝒦 along u and ζ across; 𝒦, ζ from the
torque-weighted FME at q = 0 with μ = 5 (§6.3.1). Cases, each on the MuJoCo plant from the
FME-matched configuration (`rhi.experiments.ch6.setup.best_match`, joint-limit barrier as ch. 6):

- ``free`` / ``stiff``: FME matching to M_Free^des / M_Stiff^des with force scaling (ch. 6);
- ``schedule``: the ASO (eq. 6.14) with hysteresis and the cosine transition (eqs. 6.15–6.19)
  switching M_des from M_Free^des to M_Stiff^des as the actuators saturate;
- ``stiff_ascm``: M_Stiff^des with ASCM (Algorithm 1) and the tertiary objective (eq. 7.16,
  Algorithm 2) instead of scaling (ch. 7).

Gravity acts on the PHANToM's shoulder and forearm (srhi5 stands upright), so the primary
law compensates G_x and the controller the null-space part of g(q); the thesis's planar
rhi4 had none. Also reported: VME matching along a 3-D direction (ch. 3/5) as a run in which
the hand holds the handle while the null-space controller reconfigures from the sub-chain
configuration (q1 = q2 = 0) towards the eq.-3.22 optimum.
"""

from __future__ import annotations

import numpy as np

from rhi.control import (
    ControllerConfig,
    FMESchedule,
    ImpedanceControl,
    NullSpaceController,
    ObjectiveTerm,
    TransitionConfig,
    VMEMatching,
    WeightedSum,
)
from rhi.control.configuration import optimal_configuration
from rhi.devices.model import device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.beyond.spatial import chain_points
from rhi.experiments.ch6 import setup as ch6
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress, check_motion, path_hand, run, smooth
from rhi.metrics import effective_inertia, effective_manipulability, force_ellipsoid, max_force, max_force_scaling
from rhi.sim import Hand, HandPath

U = (0.0, 0.7071067811865476, -0.7071067811865476)  # down and sideways: where the FMEs differ most (static F_max)
#: the PHANToM sub-chain configuration whose handle position is X₀ (shoulder 0.4 rad, forearm 0.5 rad)
Q_SUB_X0 = (0.0, 0.4, 0.5)
CASES = ("free", "stiff", "schedule", "stiff_ascm")


def _controller(dev, x0, u, case: str, Mf, Ms) -> NullSpaceController:
    """The ch. 6 palpation controller in 3-D (gravity compensated) for `case` (see `CASES`)."""
    if case == "schedule":
        sched = FMESchedule(Mf, Ms, transition=TransitionConfig(ch6.EPS1, ch6.EPS2, ch6.RHO, ch6.ASO_S))
        return ch6.palpation_controller(dev, None, sched, x0=x0, u=u, gravity=True)
    return ch6.palpation_controller(dev, Mf if case == "free" else Ms, x0=x0, u=u, gravity=True,
                                    saturation="ascm" if case == "stiff_ascm" else "scaling")


@checked
def spatial_palpation(
    settle: float = 0.3,
    depth: float = 0.02,
    speed: float = 0.02,
    hold: float = 0.3,
    u: tuple[float, float, float] = U,
    *,
    cases: tuple[str, ...] = CASES,
    starts: int = 3,
    hand_stiffness: float = 3000.0,
    hand_damping: float = 40.0,
    filter_ms: float = 20.0,
    progress: Progress | None = None,
) -> Result:
    """3-D palpation of K_e = 1000 N/m along u with M_Free^des, M_Stiff^des, the ASO transition and ASCM.

    Args:
        settle: time the hand holds X₀ [s].
        depth: push depth along u [m].
        speed: push speed [m/s].
        hold: time held at depth [s].
        u: (3,) direction into the environment (normalised).
        cases: any of "free", "stiff", "schedule", "stiff_ascm".
        starts: starts of the static FME matching (`ch6.best_match`).
        hand_stiffness: the hand's grip stiffness [N/m].
        hand_damping: the hand's grip damping [N s/m].
        filter_ms: moving-average window of the F/T force [ms].
        progress: callback(done, total) in control ticks.
    """
    check_motion(settle=settle, depth=depth, speed=speed, hold=hold)
    uu = np.asarray(u, dtype=float)
    if uu.shape != (3,) or not np.all(np.isfinite(uu)) or np.linalg.norm(uu) == 0:
        raise InvalidInput(f"u: expected a non-zero finite (3,) direction, got {u!r}")
    uu = uu / np.linalg.norm(uu)
    for c in cases:
        if c not in CASES:
            raise InvalidInput(f"cases: unknown {c!r}; expected a subset of {CASES}")
    dev = device("srhi5")
    lo, hi = dev.torque_limits
    x0 = device("srhi5_phantom").fk(np.array(Q_SUB_X0))
    K, zeta, Mf, Ms = ch6.desired_fmes(dev, uu, np.zeros(dev.n))
    duration = settle + depth / speed + hold
    ticks = int(round(duration * 1000.0))
    arrays: dict[str, np.ndarray] = {"M_free_des": Mf, "M_stiff_des": Ms, "x0": x0, "u": uu}
    rows: list[Row] = [Row("𝒦 (μ λ_max at q = 0)", None, K, "N²/(N m)²"), Row("ζ (λ_min/μ at q = 0)", None, zeta,
                                                                              "N²/(N m)²")]
    q_match = {}
    for i, case in enumerate(cases):
        start_case = "free" if case in ("free", "schedule") else "stiff"
        if start_case not in q_match:
            obj = WeightedSum(ch6.controller_terms(Mf if start_case == "free" else Ms, hi))
            q_match[start_case] = ch6.best_match(dev, x0, obj, starts=starts)
        ctrl = _controller(dev, x0, uu, case, Mf, Ms)
        hand = path_hand([x0, x0 + depth * uu], speed, settle, hand_stiffness, hand_damping)
        log = run(dev, ctrl, hand, q_match[start_case], duration, progress, i * ticks, len(cases) * ticks)
        if log.fault is not None:
            raise InvalidInput(f"spatial_palpation: the controller stopped in case {case!r}: {log.fault}")
        f_u = -smooth(log.ft[:, :3], max(1, int(round(filter_ms)))) @ uu
        push = log.t >= settle
        k_peak = int(np.argmin(np.where(push, f_u, np.inf)))
        q_end = log.q[-1]
        J, M = dev.jacobian(q_end), dev.mass_matrix(q_end)
        k_set = max(int(round(settle * 1000.0)) - 1, 0)
        drift = float(np.linalg.norm(log.x[k_set] - x0))
        lab = {"free": "M_Free^des", "stiff": "M_Stiff^des", "schedule": "ASO schedule M_Free → M_Stiff",
               "stiff_ascm": "M_Stiff^des + ASCM"}[case]
        rows += [
            Row(f"peak force along u (F/T sensor), {lab}", None, float(f_u[k_peak]), "N", "negative: along −u"),
            Row(f"F_max along u by scaling at the final configuration, {lab}", None,
                -float(max_force_scaling(J, uu, torque_min=lo, torque_max=hi)), "N"),
            Row(f"F_max along u, LP with null-space torques, final configuration, {lab}", None,
                -float(max_force(J, uu, torque_min=lo, torque_max=hi, M=M)), "N"),
            Row(f"Λ along u at the final configuration, {lab}", None, float(effective_inertia(J, M, uu)), "kg"),
            Row(f"handle drift from X₀ while settling, {lab}", None, drift, "m"),
            Row(f"min ASO V during the push, {lab}", None, float(np.min(log.V[push])), ""),
            Row(f"final Ω (1: M_Free, 0: M_Stiff), {lab}", None, float(log.omega[-1]), ""),
            Row(f"torque-limit excess, {lab}", None, float(np.max(np.maximum(log.tau - hi, lo - log.tau))), "N m",
                "≤ 0: within the box"),
        ]
        arrays.update({f"t_{case}": log.t, f"force_{case}": f_u, f"x_{case}": log.x, f"q_{case}": log.q,
                       f"tau_{case}": log.tau, f"alpha_{case}": log.alpha, f"omega_{case}": log.omega,
                       f"V_{case}": log.V, f"desired_{case}": -ch6.K_E * np.maximum((log.x - x0) @ uu, 0.0),
                       f"skeleton_{case}": chain_points(dev, q_end), f"fme_{case}": force_ellipsoid(J, hi)})
    notes = [
        "Not in the thesis (§8.2 future work): srhi5 (models/srhi5) with the ch. 6/7 controllers at m = 3. "
        f"X₀ = {np.round(x0, 4).tolist()} m (the PHANToM sub-chain at q = {list(Q_SUB_X0)} rad), u = "
        f"{np.round(uu, 3).tolist()}.",
        "Forces are the simulated F/T sensor (20 ms moving average) on the MuJoCo plant with the estimated "
        "motor friction of device.toml [plant]; β = 20, K_d = 0.1, joint-limit barrier as ch. 6.",
    ]
    return Result("beyond.spatial_palpation",
                  "Beyond the thesis: spatial RHIs — 3-D palpation with M_Free, M_Stiff, the ASO transition and ASCM",
                  [Table("3-D palpation of K_e = 1000 N/m on srhi5", rows)], arrays, notes)


@checked
def spatial_vme(duration: float = 2.0, u: tuple[float, float, float] = (0.0, 1.0, 0.0),
                        gain: float = 10.0, progress: Progress | None = None) -> Result:
    """VME matching along a 3-D u (eqs. 3.20–3.23) on the srhi5 plant while the hand holds the handle.

    Starts at the sub-chain configuration of X₀ (q1 = q2 = 0, the PHANToM alone) and runs the
    null-space controller with ImpedanceControl (eq. 5.6, gravity compensated) and
    VMEMatching(u, β = 0.01) with step `gain`; the hand holds X₀ (3000 N/m).
    """
    check_motion(duration=duration, gain=gain)
    uu = np.asarray(u, dtype=float)
    if uu.shape != (3,) or not np.all(np.isfinite(uu)) or np.linalg.norm(uu) == 0:
        raise InvalidInput(f"u: expected a non-zero finite (3,) direction, got {u!r}")
    uu = uu / np.linalg.norm(uu)
    dev = device("srhi5")
    q0 = np.r_[0.0, 0.0, Q_SUB_X0]
    x0 = dev.fk(q0)
    obj = VMEMatching(tuple(uu), 0.01)
    cfg = ControllerConfig(primary=ImpedanceControl(damping=1.0),
                           objectives=(ObjectiveTerm(obj, gain), ObjectiveTerm(ch6.BARRIER, ch6.LIMIT_GAIN)),
                           damping=ch6.K_D, saturation="ascm")
    hand = Hand(HandPath(np.array([x0, x0]), speed=0.01), stiffness=3000.0, damping=40.0, max_force=60.0)
    log = run(dev, NullSpaceController(dev, cfg), hand, q0, duration, progress, 0,
                   int(round(duration * 1000.0)))
    if log.fault is not None:
        raise InvalidInput(f"spatial_vme: the controller stopped: {log.fault}")
    nu = np.array([obj.value(dev, q) for q in log.q[::10]])
    q_opt = optimal_configuration(dev, x0, obj, q0)
    rho = lambda q: float(effective_manipulability(dev.jacobian(q), uu))  # noqa: E731
    rows = [
        Row("ν (eq. 3.22) at the start (sub-chain configuration)", None, float(nu[0])),
        Row("ν at the end of the run", None, float(nu[-1])),
        Row("ν at the static optimum (SLSQP)", None, float(obj.value(dev, q_opt))),
        Row("ρ along u at the start", None, rho(q0), "m/s"),
        Row("ρ along u at the end", None, rho(log.q[-1]), "m/s"),
        Row("ρ along u at the static optimum", None, rho(q_opt), "m/s"),
        Row("max handle drift from X₀", None, float(np.max(np.linalg.norm(log.x - x0, axis=1))), "m"),
    ]
    return Result("beyond.spatial_vme", "Beyond the thesis: spatial RHIs — VME matching along a 3-D u on srhi5",
                  [Table(f"Null-space VME matching along u = {np.round(uu, 3).tolist()}", rows)],
                  {"t": log.t[::10], "nu": nu, "q": log.q[::10], "x": log.x[::10], "q_opt": q_opt},
                  ["The hand holds the handle; the null-space torque reconfigures srhi5 from the PHANToM-only "
                   "configuration towards the eq.-3.22 optimum (the ch. 3 controller, eqs. 3.20–3.21, with m = 3)."])
