"""Chapter 3 on the simulated rhi4: the null-space VME-matching controller converging at the Table 3.1 points.

Set-up (thesis §3.4–3.5): the 4-DoF RHI (`rhi.device("rhi4")`) in MuJoCo (`rhi.sim.Plant`,
with the device's estimated joint friction), the user's hand holding the handle at one
of the two Table 3.1 points (0.49, −0.22) and (0.49, −0.14) m (`rhi.sim.Hand`, a
3000 N/m grip), and the controller of eq. 3.20,

    τ = Jᵀ F + (I − Jᵀ J#ᵀ)(τ_N − k_D q̇),   τ_N = −α ∂ν/∂q   (eq. 3.21),

with F the free-space primary force (F = −B^d ẋ + C_x ẋ, B^d = 0: nothing rendered) and
ν the JBLD distance of the velocity ellipsoid JJᵀ to M_des = u uᵀ + β(I − u uᵀ),
u = [0, 1], β = 0.01 (eqs. 3.22–3.23). The controller reconfigures the RHI through its
self-motion while the hand keeps the handle still; the converged configuration's
effective manipulability ρ (eq. 3.6) and effective apparent inertia Λ (eq. 3.13) along u
are reported beside Table 3.1 and beside the static optimum of eq. 3.22 (SLSQP, as in
`rhi.experiments.ch3.measures.table_3_1`).

What the thesis leaves open and we chose (every value is an argument):

- the start configuration: "rehab" — the RHI folded as the thesis's Rehab NHI
  (q3 = q4 = 0, §3.5) — and "thesis" — the optimised configuration printed in §3.5,
  projected onto the point by IK (it is 0.7–0.9 mm off the point as printed);
- α = 10 and k_D = 1 N m s/rad (not given in the thesis): fast enough to converge within
  a few seconds and, with the plant's Coulomb friction (0.02 N m on the rehab motors),
  large enough that the self-motion does not stall far from the optimum;
- joint limits. The minima of eq. 3.22 on the self-motion manifold lie on the joint
  limits of §5.4 (q2 = 0° together with q4 = 80° or q4 = −20°). The controller of
  eqs. 3.20–3.21 alone then pushes the motors into their stops; a stop's reaction torque
  is not in the null space, so the hand is pushed by a few newtons and the handle
  drifts by about a millimetre. The main runs therefore add `BARRIER` (a `rhi.control.JointLimitBarrier`,
  an inverse barrier that is zero more than 5° away from every limit) as a second null-space
  objective, and the runs "eq. 3.21 alone" show what the stops do. The static optimum is
  computed for both objectives.

Why our numbers differ from the thesis's:

- The objective is not convex in q. JBLD is geodesically convex on SPD matrices (the
  thesis's argument, [132]), but ν(q) on the self-motion manifold has several local
  minima (at (0.49, −0.22) the controller settles at ν ≈ 0.92, q ≈ (−0.10, 0.36, 0.24,
  −0.27) rad from the Rehab-like start and at ν ≈ 0.72, q ≈ (−0.86, 0.05, 0.78, 1.30) rad
  from the thesis's configuration), so the converged configuration depends on the
  start — the result reports each start.
- The thesis's printed optimum is not a stationary point of eq. 3.22: with the thesis's
  own kinematics (ρ at that configuration matches Table 3.1 to its rounding) the
  projected gradient (I − JᵀJ#ᵀ)∂ν/∂q there is ≈ 0.4 on q1, and the controller moves
  away from it. A hardware controller whose self-motion stalls on joint friction
  before the optimum would explain it; the thesis gives neither α nor k_D.
- Λ depends on the inertial model, which the thesis does not publish (see
  `models/rhi4/README.md`); ρ is kinematic and comparable.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from rhi._validate import as_array
from rhi.control import (
    ControllerConfig,
    ForceRendering,
    JointLimitBarrier,
    NullSpaceController,
    ObjectiveTerm,
    VMEMatching,
    WeightedSum,
)
from rhi.control.configuration import optimal_configuration
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.ch3.measures import BETA, POINTS, THESIS_LAMBDA, THESIS_Q, THESIS_RHO, U, measures
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import vme_values
from rhi.metrics import nullspace_projector
from rhi.sim import Hand, HandPath, Log, Plant, simulate

#: Gradient step α of eq. 3.21 (not given in the thesis).
GAIN = 10.0
#: Null-space joint damping k_D of eq. 3.20 [N m s/rad] (not given in the thesis).
NULL_DAMPING = 1.0
#: The simulated hand's grip: stiffness [N/m] and damping [N s/m] holding the handle still.
HAND_STIFFNESS = 3000.0
HAND_DAMPING = 40.0
#: Joint-limit barrier: active within this distance of a limit [rad], and its weight.
LIMIT_MARGIN = math.radians(5.0)
LIMIT_WEIGHT = 0.01
#: Handle drift allowed while the null space moves (issue 3 acceptance) [m].
DRIFT_LIMIT = 5e-4
#: Log decimation for the stored time series (every k-th control tick).
DECIMATE = 10
STARTS = ("rehab", "thesis")


#: The joint-limit barrier of the main runs (an inverse barrier, δ = 5°, w = 0.01).
BARRIER = JointLimitBarrier(LIMIT_MARGIN, LIMIT_WEIGHT, kind="inverse")


def with_barrier(objective) -> WeightedSum:
    """ν + ν_lim with `BARRIER`: the cost the limit-aware controller minimises (equal steps α), for its static optimum."""
    return WeightedSum((ObjectiveTerm(objective, 1.0), ObjectiveTerm(BARRIER, 1.0)))


def start_configuration(dev: Device, x, which: str) -> np.ndarray:
    """Start configuration at the point x: (2,) [m].

    Args:
        dev: rhi4.
        x: end-effector point [m].
        which: "rehab" (q3 = q4 = 0, q1, q2 from the Rehab NHI's IK) or "thesis" (the §3.5 optimum
            nearest to x, projected onto x by IK).

    Returns:
        q: (4,) [rad], within the joint limits, fk(q) = x.
    """
    x = as_array("x", x, shape_tail=(2,))
    if which == "rehab":
        q12 = device("rehab").ik(x, np.full(2, 0.3))
        q = np.array([q12[0], q12[1], 0.0, 0.0])
        return dev.ik(x, q, k_null=0.0)  # exact already; IK confirms reachability within the limits
    if which == "thesis":
        i = int(np.argmin([np.linalg.norm(np.subtract(p, x)) for p in POINTS]))
        return dev.ik(x, np.array(THESIS_Q[i]), k_null=0.0)  # nearest point of the self-motion manifold
    raise InvalidInput(f"which: expected one of {STARTS}, got {which!r}")


def controller(dev: Device, *, gain: float = GAIN, damping: float = NULL_DAMPING, limits: bool = True,
               beta: float = BETA) -> NullSpaceController:
    """The controller of eqs. 3.20–3.21: free-space primary law, VME matching (eq. 3.22), optional limit barrier.

    Args:
        dev: the device model.
        gain: α of eq. 3.21.
        damping: k_D of eq. 3.20 [N m s/rad].
        limits: add `BARRIER` with the same step α.
        beta: β of eq. 3.23.
    """
    terms = [ObjectiveTerm(VMEMatching(tuple(U), beta), gain)]
    if limits:
        terms.append(ObjectiveTerm(BARRIER, gain))
    cfg = ControllerConfig(primary=ForceRendering(damping=0.0, passivity=None), objectives=terms, damping=damping,
                           saturation="none")
    return NullSpaceController(dev, cfg)


def hold_run(dev: Device, x, q0, ctrl: NullSpaceController, *, duration: float,
             progress: Callable[[int, int], None] | None = None) -> Log:
    """Simulate the hand holding the handle at x from q0 while `ctrl` runs (the null space moves)."""
    plant = Plant(dev)
    plant.reset(q0)
    hand = Hand(HandPath(np.asarray([x], dtype=float)), stiffness=HAND_STIFFNESS, damping=HAND_DAMPING, max_force=None)
    return simulate(plant, ctrl, duration=duration, hand=hand, progress=progress)  # free space: F_env = 0


def settling_time(t: np.ndarray, v: np.ndarray, tol: float = 1e-3) -> float:
    """First time after which |v − v_end| stays below tol (t: (N,) [s], v: (N,))."""
    out = np.abs(v - v[-1]) > tol
    if not out.any():
        return float(t[0])
    k = int(np.flatnonzero(out)[-1]) + 1
    return float(t[min(k, len(t) - 1)])


def _run_summary(dev: Device, x, log: Log, vme: VMEMatching, objective, gain: float) -> dict:
    x = np.asarray(x, dtype=float)
    q_end = log.q[-1]
    drift = np.linalg.norm(log.x - x, axis=1)
    nu = vme_values(dev, vme, log.q[::DECIMATE])
    t = log.t[::DECIMATE]
    J, M = dev.jacobian(q_end), dev.mass_matrix(q_end)
    grad_torque = gain * nullspace_projector(J, M) @ objective.gradient(dev, q_end)
    rho, lam = measures(dev, q_end)
    return {
        "q": q_end, "rho": rho, "lam": lam, "nu_start": float(vme.value(dev, log.q[0])), "nu_end": float(nu[-1]),
        "drift_max": float(drift.max()), "t_settle": settling_time(t, nu), "dq_end": float(np.linalg.norm(log.dq[-1])),
        "null_torque_end": float(np.linalg.norm(grad_torque)), "fault": log.fault,
        "series": {"t": t, "nu": nu, "drift": drift[::DECIMATE], "q": log.q[::DECIMATE]},
    }


@checked
def nullspace_configurations(
    duration: float = 12.0,
    *,
    points: Sequence[Sequence[float]] = POINTS,
    starts: Sequence[str] = STARTS,
    hard_stops: bool = True,
    gain: float = GAIN,
    damping: float = NULL_DAMPING,
    progress: Callable[[int, int], None] | None = None,
) -> Result:
    """The null-space VME-matching controller (eqs. 3.20–3.23) converging on the simulated rhi4 (Table 3.1).

    For every point and start configuration, the hand holds the handle at the point for
    `duration` seconds while the controller (with the joint-limit barrier) reconfigures
    the RHI; the converged q, its ρ and Λ along u = [0, 1] are reported beside Table 3.1's
    RHI column, beside the thesis's printed configuration and beside the static optimum
    (SLSQP) of the same objective, polished from the converged q. With `hard_stops`, the
    controller of eqs. 3.20–3.21 alone also runs from the first start (the joint limits
    are then the plant's stops).

    Args:
        duration: simulated time per run [s] (1 kHz control).
        points: end-effector points [m] (default: the two of Table 3.1).
        starts: start configurations, each "rehab" or "thesis" (see `start_configuration`).
        hard_stops: also run eq. 3.21 alone (no barrier) from ``starts[0]``.
        gain: α of eq. 3.21.
        damping: k_D of eq. 3.20 [N m s/rad].
        progress: callback(done, total) over all simulated control ticks.

    Returns:
        Result "ch3.nullspace_configurations" with tables (converged configuration, ρ, Λ,
        drift, settling time per run) and arrays ``{run}_t``, ``{run}_nu`` (JBLD ν of
        eq. 3.22), ``{run}_drift`` [m], ``{run}_q`` [rad] sampled every 10 ms, ``{run}_q_end``,
        ``{run}_q_start`` and ``{run}_point``, for run keys ``p{i}_{start}_barrier`` / ``p{i}_{start}_stops``.

    Raises:
        InvalidInput: bad duration, point, start name or gains.
    """
    if not (math.isfinite(duration) and duration > 0):
        raise InvalidInput(f"duration: must be > 0 [s], got {duration!r}")
    for name, v in (("gain", gain), ("damping", damping)):
        if not (math.isfinite(v) and v >= 0):
            raise InvalidInput(f"{name}: must be finite and >= 0, got {v!r}")
    starts = tuple(starts)
    if not starts:
        raise InvalidInput("starts: give at least one start configuration")
    for s in starts:
        if s not in STARTS:
            raise InvalidInput(f"starts: expected names from {STARTS}, got {s!r}")
    pts = [as_array("points", p, shape_tail=(2,)) for p in points]
    if not pts:
        raise InvalidInput("points: give at least one point")
    dev = device("rhi4")
    vme = VMEMatching(tuple(U), BETA)
    plan = [(i, s, True) for i in range(len(pts)) for s in starts]
    if hard_stops:
        plan += [(i, starts[0], False) for i in range(len(pts))]
    ticks = int(round(duration * 1000.0))
    total = ticks * len(plan)
    arrays: dict[str, np.ndarray] = {}
    summaries: dict[tuple[int, str, bool], dict] = {}
    for r, (i, s, lim) in enumerate(plan):
        x = pts[i]
        q0 = start_configuration(dev, x, s)
        ctrl = controller(dev, gain=gain, damping=damping, limits=lim)
        cb = None if progress is None else (lambda k, n, off=r * ticks: progress(off + k, total))
        log = hold_run(dev, x, q0, ctrl, duration=duration, progress=cb)
        obj = with_barrier(vme) if lim else vme
        summ = _run_summary(dev, x, log, vme, obj, gain)
        summ["q0"] = q0
        summaries[i, s, lim] = summ
        key = f"p{i}_{s}_{'barrier' if lim else 'stops'}"
        for k, v in summ["series"].items():
            arrays[f"{key}_{k}"] = v
        arrays[f"{key}_q_start"], arrays[f"{key}_q_end"], arrays[f"{key}_point"] = q0, summ["q"], x

    # references: the thesis's printed configuration and the static optimum (SLSQP)
    ref_rows, conv_rows, stop_rows, q_rows = [], [], [], []
    slsqp: dict[int, np.ndarray] = {}
    for i, x in enumerate(pts):
        where = f"({x[0]:g}, {x[1]:g})"
        j = int(np.argmin([np.linalg.norm(np.subtract(p, x)) for p in POINTS]))
        on_table = bool(np.allclose(POINTS[j], x))
        th_rho = THESIS_RHO["RHI"][j] if on_table else None
        th_lam = THESIS_LAMBDA["RHI"][j] if on_table else None
        q_th = np.array(THESIS_Q[j])
        r_th, l_th = measures(dev, q_th)
        ref_rows += [
            Row(f"ρ at {where}, thesis's printed configuration", th_rho, r_th, "m/s"),
            Row(f"Λ at {where}, thesis's printed configuration", th_lam, l_th, "kg",
                "inertial model differs (models/rhi4/README.md)"),
            Row(f"ν (eq. 3.22) at {where}, thesis's printed configuration", None, vme.value(dev, q_th)),
            Row(f"|(I − JᵀJ#ᵀ) ∂ν/∂q| at {where}, thesis's printed configuration (0 at an optimum)", 0.0,
                float(np.linalg.norm(nullspace_projector(dev.jacobian(q_th), dev.mass_matrix(q_th))
                                     @ vme.gradient(dev, q_th))), "1/rad",
                "the printed configuration is not a stationary point of eq. 3.22", bound="max"),
        ]
        q_s = optimal_configuration(dev, x, vme, q_th)
        slsqp[i] = q_s
        arrays[f"p{i}_q_slsqp"] = q_s
        r_s, l_s = measures(dev, q_s)
        ref_rows += [
            Row(f"ρ at {where}, static optimum of eq. 3.22 from the thesis's configuration (SLSQP)", th_rho, r_s,
                "m/s"),
            Row(f"Λ at {where}, static optimum (SLSQP)", th_lam, l_s, "kg"),
            Row(f"ν at {where}, static optimum (SLSQP)", None, vme.value(dev, q_s)),
        ]
        for s in starts:
            sm = summaries[i, s, True]
            q_p = optimal_configuration(dev, x, with_barrier(vme), sm["q"], tol=1e-10, max_iter=300, exact_start=True)
            arrays[f"p{i}_{s}_barrier_q_polished"] = q_p
            lbl = f"at {where} from the {s} start"
            conv_rows += [
                Row(f"ρ {lbl}", th_rho, sm["rho"], "m/s",
                    "" if th_rho is None else "local minimum reached from this start (ν is not convex in q)"),
                Row(f"Λ {lbl}", th_lam, sm["lam"], "kg", "inertial model differs (models/rhi4/README.md)"),
                Row(f"ν (eq. 3.22) start → converged {lbl}", None, sm["nu_end"], "",
                    f"start ν = {sm['nu_start']:.4f}"),
                Row(f"max handle drift {lbl}", DRIFT_LIMIT * 1e3, sm["drift_max"] * 1e3, "mm",
                    "rhi's acceptance bound, not a thesis number", bound="max"),
                Row(f"settling time of ν (±1e-3) {lbl}", None, sm["t_settle"], "s"),
                Row(f"|q̇| at the end {lbl}", None, sm["dq_end"], "rad/s"),
                Row(f"|α (I − JᵀJ#ᵀ) ∂ν/∂q| at the end {lbl} (stalled on friction if > 0)", None,
                    sm["null_torque_end"], "N m"),
                Row(f"|q_converged − q_static optimum polished from it| {lbl}", 0.0,
                    float(np.linalg.norm(sm["q"] - q_p)), "rad",
                    "local static optimum of the same objective (VME + barrier), SLSQP started at the converged q",
                    tolerance=5e-3, bound="max"),
            ]
            for k in range(dev.n):
                q_rows.append(Row(f"q{k + 1} {lbl}", THESIS_Q[j][k] if on_table else None, float(sm["q"][k]), "rad",
                                  "thesis: the configuration printed in §3.5"))
        if hard_stops:
            sm = summaries[i, starts[0], False]
            lbl = f"at {where} from the {starts[0]} start, eq. 3.21 alone (joint stops)"
            stop_rows += [
                Row(f"ρ {lbl}", th_rho, sm["rho"], "m/s"),
                Row(f"Λ {lbl}", th_lam, sm["lam"], "kg"),
                Row(f"ν converged {lbl}", None, sm["nu_end"]),
                Row(f"max handle drift {lbl}", DRIFT_LIMIT * 1e3, sm["drift_max"] * 1e3, "mm",
                    "stops' reaction torques leave the null space and push the hand"),
                Row(f"limits within 0.5° of (or beyond) at the end {lbl}", None,
                    float(np.sum(BARRIER.distances(dev, sm["q"]) < math.radians(0.5))), ""),
            ]
            for k in range(dev.n):
                stop_rows.append(Row(f"q{k + 1} {lbl}", None, float(sm["q"][k]), "rad"))

    worst = max(sm["drift_max"] for (i, s, lim), sm in summaries.items() if lim)
    faults = [f"{k}: {sm['fault']}" for k, sm in summaries.items() if sm["fault"]]
    tables = [Table("Null-space controller (eqs. 3.20–3.23 + limit barrier), converged on the simulated rhi4",
                    conv_rows),
              Table("Converged configurations beside the thesis's (§3.5)", q_rows),
              Table("References: the thesis's configuration and the static optimum of eq. 3.22", ref_rows)]
    if stop_rows:
        tables.append(Table("Eq. 3.21 alone: the joint stops hold the optimum", stop_rows))
    notes = [
        f"rhi4 in MuJoCo (device friction), 1 kHz, hand K = {HAND_STIFFNESS:g} N/m holding the point; "
        f"α = {gain:g}, k_D = {damping:g} N m s/rad, β = {BETA}, u = [0, 1]; {duration:g} s per run.",
        f"Worst handle drift with the limit barrier: {worst * 1e3:.3f} mm (bound {DRIFT_LIMIT * 1e3:g} mm).",
        "ν(q) has several local minima on the self-motion manifold; the converged configuration depends on the "
        "start (the thesis argues global convergence from the convexity of the JBLD, which holds on SPD matrices, "
        "not in q).",
        "The minima of eq. 3.22 lie on joint limits (q2 = 0° with q4 = 80° or −20°); the barrier keeps the joints "
        "≥ a few degrees inside them (5° margin), eq. 3.21 alone drives the motors into their stops.",
        "The thesis's printed optimum is not stationary for eq. 3.22 in the thesis's own kinematics; ρ and Λ at it "
        "are reported as a reference.",
    ]
    if faults:
        notes.append("Controller faults: " + "; ".join(faults))
    return Result("ch3.nullspace_configurations",
                  "§3.4–3.5: the null-space VME-matching controller converging at the Table 3.1 points "
                  "(simulated rhi4)",
                  tables, arrays, notes)
