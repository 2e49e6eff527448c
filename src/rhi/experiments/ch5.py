"""Chapter 5: null-space control of the redundant HI for teleoperation manipulability (thesis §5.3–5.4.1).

Set-up (thesis §5.4): master rhi4 with d = [0.254, 0.1405, 0.21, 0.181] m and the §5.4
joint limits; slave `rehab_slave` (l = [0.34, 0.375] m, eq. 5.12b); both in one planar
frame (the thesis starts both end-effectors at the same (X, Y), so H = I, no scaling).
Unilateral teleoperation (Fig. 5.2): the slave PD-tracks the master's position
(`rhi.sim.Teleoperation`); the master is an impedance-type device,
F_m = −B^d ẋ + C_x ẋ + G_x with B^d = diag(0.3, 0.3) N s/m (eq. 5.6 with M_x^d = M_x,
`rhi.control.ImpedanceControl`; G_x = 0 in the horizontal plane),
τ = Jᵀ F_m + (I − Jᵀ J#ᵀ)(τ_N − k_D q̇) (eq. 5.9) with τ_N = −α ∂ν/∂q (eq. 5.10).

Plant (MuJoCo): the thesis's simulation leaves, after model-based compensation, only the
uncertainty 𝓕 = J#ᵀ Γ q̇ with Γ = diag(0.01) (eq. 5.13) acting on the user; our plant has
exactly this joint viscous friction Γ and no Coulomb friction (``friction="thesis"``), and
no friction compensation in the controller (what eq. 5.6's F_x leaves uncompensated).
``friction="device"`` uses the rhi4 estimates of models/rhi4/device.toml instead
(uncompensated viscous + Coulomb friction, as in the thesis's experiments, eq. 5.16).

Choices the thesis leaves open (each is ours, fixed before comparing with the thesis):

- **Objective ν (eq. 5.11)** ``TMIMatching``: the JBLD between the slave ME
  ˢM = J_s J_sᵀ and the HI ME ᵐM = J^q J^qᵀ built from the joint-limit-penalised Jacobian
  J^q (eqs. 4.19–4.20), as §5.3 says ("by using the index penalized Jacobian, we will
  prevent the HI from approaching limits"). The slave's ME is not penalised (eq. 5.11
  names it "the ME of the slave robot"; its limits are estimates). The linear
  (parallelogram) limits are not penalised (eq. 4.20 is per joint).
- **k_q = 10** in eq. 4.20 (the thesis gives no value). The stated purpose is a guard
  that keeps the HI off its limits "in addition to enhancing the teleoperation
  manipulability": with k_q = 10, P_i ≥ 0.97 on the central 80 % of every range and
  falls to 0 only near a limit. ch. 4 uses k_q = 1 for its design indices; with k_q = 1,
  P_i ≥ 0.9 only on the central 40 % of a range, the penalty dominates ν and the controller
  barely moves (see `fixed_point`'s variants table: the result depends strongly on k_q).
- **Gains**: α = 1 N m per unit of ν, null-space damping k_D = 0.05 N m s/rad (the
  thesis gives neither; the fixed-point controller settles in a few seconds with them).
- **Yoshikawa scenario (eq. 5.14)**: τ_N = −α ∂ν/∂q with ν = −log μ(J^q)
  (`rhi.control.Manipulability(log=True, k_q=K_Q)`): the same joint-limit guard J^q (same k_q) as scenario 1, which
  §4.3.2 also substitutes into the manipulability (eq. 4.7), so that scenarios 1 and 2 differ
  only in what they optimise; and log μ instead of μ (same maximiser; −log μ is a log-det like
  ν, so one α serves both; the literal α ∂μ/∂q is the same direction scaled by μ ≈ 0.1). The
  literal eq. 5.14 (plain J) is a `fixed_point` variant: it drives q3 into its −55° limit
  within 1.5 s, where the limit turns null-space torque into end-effector force.
- **Simulated user**: a hand holding the handle (fixed point: K = 3000 N/m, B = 40 N s/m)
  or tracking the reference at constant speed (W: K = 300 N/m, B = 10 N s/m, `rhi.sim.Hand`),
  the "internal PD controller" of §5.4.1.
- **W trajectory** (Figs 5.4–5.5, only drawn in the thesis): the letter W, four strokes,
  centred at (0.50, 0.00) m, 0.16 m wide (x) and 0.25 m high (y): path length 1.01 m,
  50.6 s at 2 cm/s (Table 5.1's experimental completion times are 49–62 s). It lies in
  the 2-DoF Rehab's workspace (the narrowest of the three, checked by IK along the path)
  and spans the Rehab's crescent across y ∈ [−0.125, 0.125] m (criteria 1 and 2 of §5.4.1).
  Criterion 3, strokes along the slave ME's major axis, cannot hold along a whole W with our
  slave model: across the crescent that axis turns from radial (inner side) to tangential
  (outer side) and the ME is nearly round in between. We report the alignment (mean |cos|
  between the path and the major axis, weighted by the anisotropy): ≈ 0.62, about what
  random directions give (0.64); a W rotated by 90° does no better (0.57).
- **Start**: each scenario starts from IK at the W's first point (seeded from the §5.4
  configuration), holds there for `settle` seconds so the null-space controller converges,
  then follows the W. Effort and mean TME area are taken over the motion only.
- **"Area" of the TME**: we read the thesis's mean "area" 0.1034 as the TMI λ = σ₁σ₂
  (eq. 4.17): it and the implied 0.122 of scenario 1 have the size of λ for these robots
  (λ ≤ l₁l₂ = 0.1275; ours 0.09–0.12), while π σ₁σ₂ would be 0.27–0.39. We report λ of
  the plain (unpenalised) Jacobians, the ellipses Fig. 5.3 draws; percentages do not
  depend on the factor π.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rhi import thesis as T
from rhi.control import (
    ControllerConfig,
    ImpedanceControl,
    Manipulability,
    NullSpaceController,
    ObjectiveTerm,
    TMIMatching,
)
from rhi.device import Device, device
from rhi.errors import InvalidInput, Unreachable
from rhi.experiments.result import Result, Row, Table
from rhi.metrics import (
    ellipsoid_axes,
    penalized_jacobian,
    teleoperation_ellipsoid,
    tmi,
    velocity_ellipsoid,
)
from rhi.sim import Hand, Path, Plant, PlantFriction, Teleoperation, check_path_in_workspace, simulate, w_path

D2 = 0.1405  #: rehab link 2 length in chapter 5 [m] (§5.4)
Q_FIXED = np.array([-0.63, 0.25, 0.28, 0.09])  #: initial HI configuration of §5.4.1 [rad]
X_FIXED = (0.48, -0.35)  #: end-effector position of §5.4.1 [m] (FK of Q_FIXED: (0.4815, −0.3503))
B_D = 0.3  #: desired damping B^d = diag(0.3, 0.3) [N s/m] (§5.4.1, §5.4.2)
GAMMA = 0.01  #: joint uncertainty Γ = diag(0.01) [N m s/rad] (eq. 5.13)
K_Q = 10.0  #: shape of the joint-limit penalty (eq. 4.20); our choice, see the module docstring
GAIN = 1.0  #: step size α of eq. 5.10 [N m per unit of ν]
NULL_DAMPING = 0.05  #: null-space damping k_D of eq. 5.9 [N m s/rad]
SPEED = 0.02  #: W-trajectory speed [m/s] (§5.4.1)
W_CENTER = (0.50, 0.0)  #: W centre [m] (our choice)
W_WIDTH = 0.16  #: W width along x [m] (our choice)
W_HEIGHT = 0.25  #: W height along y [m] (our choice)
SLAVE_SEED = np.array([0.3, 0.6])  #: IK seed on the slave's elbow branch [rad]
REHAB_SEED = np.array([0.3, 0.9])  #: IK seed of the 2-DoF Rehab [rad]
HOLD = {"stiffness": 3000.0, "damping": 40.0}  #: hand holding the handle still (fixed point)
TRACK = {"stiffness": 300.0, "damping": 10.0}  #: hand following the W

THESIS_TME_INCREASE = T.TME_INCREASE  #: % increase of the TME area at the fixed point (§5.4.1)
THESIS_MEAN_TME_S2 = T.MEAN_TME_S2  #: mean TME area, RHI + Yoshikawa (§5.4.1)
THESIS_S2_BELOW_S1 = T.S2_BELOW_S1  #: % by which scenario 2's mean TME area is below scenario 1's (§5.4.1)
#: Table 5.1 (experiments, 8 users): scenario means
TABLE_5_1 = T.TABLE_5_1

SCENARIOS = {
    "s1": "RHI + TMI objective (eq. 5.11)",
    "s2": "RHI + Yoshikawa μ (eq. 5.14)",
    "s3": "2-DoF Rehab",
}

Progress = Callable[[int, int], None] | None


def devices() -> dict[str, Device]:
    """The chapter-5 devices: RHI (rhi4, d2 = 0.1405 m), the 2-DoF Rehab (rhi4 with the PHANToM
    locked at q3 = q4 = 0, same d2), and the slave (rehabilitation robot 2.0)."""
    return {"RHI": device("rhi4", d2=D2), "Rehab": device("rehab", d2=D2), "slave": device("rehab_slave")}


# --------------------------------------------------------------------------- objective
# --------------------------------------------------------------------------- helpers
def _friction(kind: str, dev: Device):
    if kind == "thesis":
        return PlantFriction(np.full(dev.n, GAMMA), np.zeros(dev.n))
    if kind == "device":
        return "device"
    raise InvalidInput(f"friction: expected 'thesis' or 'device', got {kind!r}")


def _positive(name: str, v: float, *, allow_zero: bool = False) -> float:
    v = float(v)
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise InvalidInput(f"{name}: must be finite and {'>=' if allow_zero else '>'} 0, got {v!r}")
    return v


def _controller(dev: Device, objective, gain: float, damping: float) -> NullSpaceController:
    """Eq. 5.9 with the impedance law of eq. 5.6 (F_m = −B^d ẋ + C_x ẋ + G_x; friction not compensated:
    the plant's friction is the residual of eq. 5.13) plus the null-space objective (eq. 5.10)."""
    terms = [ObjectiveTerm(objective, gain)] if objective is not None else []
    cfg = ControllerConfig(primary=ImpedanceControl(damping=B_D * np.eye(dev.m)), objectives=terms, damping=damping,
                           saturation="none")
    return NullSpaceController(dev, cfg)


class _Chain:
    """Progress over several runs: run i reports (offset + done, total)."""

    def __init__(self, progress: Progress, total: int) -> None:
        self.progress, self.total, self.offset = progress, total, 0

    def run(self, n: int):
        off = self.offset
        self.offset += n
        if self.progress is None:
            return None
        return lambda k, _n: self.progress(off + k, self.total)


def _ticks(duration: float, rate: float = 1000.0) -> int:
    return int(round(duration * rate))


def _tme_area(Jm: np.ndarray, Js: np.ndarray) -> np.ndarray:
    """TME 'area' as the thesis reports it: λ = σ₁σ₂ (eq. 4.17), broadcast over leading axes."""
    return tmi(Jm, Js)


# --------------------------------------------------------------------------- fixed point
def fixed_point(
    duration: float = 10.0,
    *,
    variants: bool = True,
    k_q: float | None = K_Q,
    gain: float = GAIN,
    damping: float = NULL_DAMPING,
    friction: str = "thesis",
    frames: int = 12,
    progress: Progress = None,
) -> Result:
    """Fig. 5.3: TME area before and after the TMI null-space controller converges, end-effector held.

    The simulated hand holds the handle at FK(Q_FIXED) = (0.4815, −0.3503) m (the thesis's
    (0.48, −0.35) m to its rounding); the slave sits at the same point. The controller of
    eq. 5.9 with ν of eq. 5.11 runs for `duration` seconds; we report the TME area λ = σ₁σ₂
    (eq. 4.17, plain Jacobians) at the start and the end (thesis: +18.1 %).

    Because the thesis gives no k_q, no gains, and does not say whether the slave's ME is
    penalised, `variants` also runs the same controller with other readings of eq. 5.11
    (no penalty; k_q = 1 as in ch. 4; penalised slave) and with Yoshikawa's μ (eq. 5.14).
    The final configuration is a local minimum of ν reached by gradient flow from the
    thesis's start, so it depends on these choices; the variants table shows how much.

    Args:
        duration: simulated time per run [s] (the default controller settles in ≈ 5 s).
        variants: also run the alternative objectives (6 more runs).
        k_q: penalty shape of the main objective (None: no penalty).
        gain: step size α of eq. 5.10 [N m].
        damping: null-space damping k_D [N m s/rad].
        friction: "thesis" (Γ = 0.01 viscous only, eq. 5.13) or "device" (rhi4 estimates).
        frames: configurations kept for the evolution drawing.
        progress: optional callback(done, total) over all runs.

    Returns:
        Result "ch5.fixed_point" with arrays for Fig. 5.3: `q0`, `qT`, `q_frames` (frames, 4),
        skeletons `skel_master_0`, `skel_master_T`, `skel_frames` (frames, k, 2), `skel_slave`,
        ellipses `ell_master_0/T`, `ell_slave`, `tme_0/T` (2, 2), series `t`, `tmi`, `nu`.

    Raises:
        InvalidInput: non-positive duration, gain or frames, negative damping, unknown friction.
    """
    duration = _positive("duration", duration)
    gain = _positive("gain", gain)
    damping = _positive("damping", damping, allow_zero=True)
    if int(frames) < 2:
        raise InvalidInput(f"frames: must be >= 2, got {frames!r}")
    devs = devices()
    rhi, slave = devs["RHI"], devs["slave"]
    _friction(friction, rhi)
    x0 = rhi.fk(Q_FIXED)
    qs = slave.ik(x0, SLAVE_SEED)
    Js = slave.jacobian(qs)
    runs: dict[str, object] = {"main": TMIMatching(slave, qs, k_q=k_q)}
    if variants:
        runs["plain eq. 5.11 (ᵐM = JJᵀ, no penalty)"] = TMIMatching(slave, qs, k_q=None)
        runs["k_q = 1 (ch. 4 value), HI penalised"] = TMIMatching(slave, qs, k_q=1.0)
        runs["k_q = 1, HI and slave penalised"] = TMIMatching(slave, qs, k_q=1.0, penalize_slave=True)
        runs[f"k_q = {K_Q:g}, HI and slave penalised"] = TMIMatching(slave, qs, k_q=K_Q, penalize_slave=True)
        runs[f"Yoshikawa μ of J^q (k_q = {K_Q:g}), scenario 2's objective"] = Manipulability(log=True, k_q=K_Q)
        runs["Yoshikawa μ of J, literal eq. 5.14"] = Manipulability(log=True)
    N = _ticks(duration)
    chain = _Chain(progress, N * len(runs))
    hand = Hand(Path([x0]), **HOLD)
    out = {}
    for name, obj in runs.items():
        plant = Plant(rhi, friction=_friction(friction, rhi))
        plant.reset(Q_FIXED)
        log = simulate(plant, _controller(rhi, obj, gain, damping), duration=duration, hand=hand,
                       progress=chain.run(N))
        out[name] = log
    log = out["main"]
    q0, qT = log.q[0], log.q[-1]
    J0, JT = rhi.jacobian(q0), rhi.jacobian(qT)
    a0, aT = float(_tme_area(J0, Js)), float(_tme_area(JT, Js))
    main = runs["main"]
    stride = max(1, len(log.t) // 200)
    Jt = rhi.jacobian(log.q[::stride])
    tmi_t = _tme_area(Jt, Js)
    nu_t = np.array([main.value(rhi, q) for q in log.q[::stride]])
    last = log.t >= log.t[-1] - 1.0
    drift = float(np.max(np.linalg.norm(log.x - x0, axis=1)))
    kq_str = "none" if k_q is None else f"{k_q:g}"
    Jp0 = penalized_jacobian(J0, q0, rhi.q_min, rhi.q_max, K_Q)
    JpT = penalized_jacobian(JT, qT, rhi.q_min, rhi.q_max, K_Q)
    Jsp = penalized_jacobian(Js, qs, slave.q_min, slave.q_max, K_Q)
    p0, pT = float(tmi(Jp0, Jsp)), float(tmi(JpT, Jsp))
    rows = [
        Row("TME area increase by the TMI null-space controller", THESIS_TME_INCREASE, 100.0 * (aT / a0 - 1.0), "%",
            f"ν of eq. 5.11 with k_q = {kq_str}; the thesis's k_q, gains and penalisation are not given "
            "(variants table); the thesis's model of the HI dynamics [23, 45] is not published"),
        Row("TME area λ = σ₁σ₂ before", None, a0, "m²/s² per (rad/s)²"),
        Row("TME area λ = σ₁σ₂ after", None, aT, "m²/s² per (rad/s)²"),
        Row("upper bound of λ: the slave's own σ₁σ₂", None, float(np.prod(ellipsoid_axes(Js @ Js.T)[0])),
            "m²/s² per (rad/s)²", "the TME lies inside the slave ME"),
        Row(f"penalised TMI (eq. 4.17 with J^q, k_q = {K_Q:g}) increase", None, 100.0 * (pT / p0 - 1.0), "%"),
        Row("ν before", None, float(main.value(rhi, q0))),
        Row("ν after", None, float(main.value(rhi, qT))),
        Row("max end-effector drift while held", None, 1e3 * drift, "mm", "hand K = 3000 N/m holds the handle"),
        Row("max |q̇| over the last second (convergence)", None, float(np.max(np.linalg.norm(log.dq[last], axis=1))),
            "rad/s"),
        Row("user work while held", None, float(log.work[-1]), "J"),
    ]
    rows += [Row(f"final q{i + 1}", None, float(qT[i]), "rad") for i in range(rhi.n)]
    tables = [Table("Fig. 5.3: TME area at the fixed point (0.48, −0.35) m", rows)]
    if variants:
        vrows = []
        for name, lg in out.items():
            if name == "main":
                continue
            qv = lg.q[-1]
            inc = 100.0 * (float(_tme_area(rhi.jacobian(qv), Js)) / a0 - 1.0)
            lim = float(np.min(np.minimum(qv - rhi.q_min, rhi.q_max - qv)))
            vrows.append(Row(f"TME area increase, {name}", THESIS_TME_INCREASE, inc, "%",
                             f"final q = {np.round(qv, 3).tolist()} rad, "
                             f"{np.degrees(lim):.1f}° from the nearest limit"))
        tables.append(Table("Fig. 5.3 sensitivity: other readings of eq. 5.11 (same gains and plant)", vrows))
    idx = np.linspace(0, len(log.t) - 1, int(frames)).astype(int)
    arrays = {
        "x0": x0, "q0": q0, "qT": qT, "q_slave": qs,
        "q_frames": log.q[idx], "t_frames": log.t[idx],
        "skel_master_0": rhi.skeleton(q0)[:, :2], "skel_master_T": rhi.skeleton(qT)[:, :2],
        "skel_frames": np.array([rhi.skeleton(q)[:, :2] for q in log.q[idx]]),
        "skel_slave": slave.skeleton(qs)[:, :2],
        "ell_master_0": velocity_ellipsoid(J0), "ell_master_T": velocity_ellipsoid(JT),
        "ell_slave": velocity_ellipsoid(Js),
        "tme_0": teleoperation_ellipsoid(J0, Js), "tme_T": teleoperation_ellipsoid(JT, Js),
        "t": log.t[::stride], "tmi": tmi_t, "nu": nu_t,
    }
    notes = [
        f"Controller: eq. 5.9 with F_m = −B^d ẋ + C_x ẋ (eq. 5.6), B^d = {B_D} N s/m, α = {gain} N m, k_D = {damping} N m s/rad, "
        f"{duration} s at 1 kHz on the MuJoCo plant ({friction} friction).",
        "TME area = λ = σ₁σ₂ of eq. 4.17 with the plain Jacobians (multiply by π for the geometric area; the "
        "percentage is the same).",
        "The thesis gives no k_q, gains or penalisation of the slave: its 18.1 % is one point of the range the "
        "variants table spans. With k_q = 1 the penalty dominates ν and the controller stops near the start; "
        "without a penalty the HI runs into its q4 limit (held there by the plant's limit).",
    ]
    return Result("ch5.fixed_point", "Fig. 5.3: TME before/after the TMI null-space controller, end-effector held",
                  tables, arrays, notes)


# --------------------------------------------------------------------------- W trajectory
def w_reference(center=W_CENTER, width: float = W_WIDTH, height: float = W_HEIGHT, speed: float = SPEED,
                start: float = 0.0) -> Path:
    """The W of Figs 5.4–5.5 (our dimensions, module docstring): a `Path` of 5 points [m] at `speed` [m/s]
    starting at `start` [s]."""
    _positive("width", width)
    _positive("height", height)
    _positive("speed", speed)
    _positive("start", start, allow_zero=True)
    p = w_path(center, width=width, height=height, speed=speed)
    return Path(p.points, speed, start)


def _distance_to_polyline(X: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Distance of each point X: (N, 2) to the polyline P: (k, 2) [m]."""
    a, b = P[:-1], P[1:]
    d = b - a
    t = np.clip(np.einsum("nkj,kj->nk", X[:, None, :] - a[None], d) / np.einsum("kj,kj->k", d, d), 0.0, 1.0)
    proj = a[None] + t[..., None] * d[None]
    return np.min(np.linalg.norm(X[:, None, :] - proj, axis=2), axis=1)


def w_trajectory(
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
    progress: Progress = None,
) -> Result:
    """Figs 5.5–5.6: the W trajectory at 2 cm/s with three scenarios, the slave following by teleoperation.

    Scenario 1: RHI with the TMI objective (eq. 5.11, `TMIMatching` on the slave's encoders);
    scenario 2: RHI with Yoshikawa's μ (eq. 5.14); scenario 3: the 2-DoF Rehab (the RHI with
    q3 = q4 = 0 locked). The simulated hand drives the master along the W (the thesis's
    "internal PD controller"); the slave PD-tracks the master (`rhi.sim.Teleoperation`).

    Reported: mean TME area λ = σ₁σ₂ over the motion (thesis: scenario 2 = 0.1034, 15.3 %
    below scenario 1), the user's work W(t) = ∫F_hᵀẋ dt (eq. 5.15; Fig. 5.6, thesis order
    1 < 2 < 3), the slave's tracking errors, and the alignment of the W with the slave ME.

    Args:
        scale: scales the W's width and height (quick runs: < 1; the speed stays).
        speed: path speed [m/s] (thesis: 0.02).
        settle: hold at the W's first point before moving [s] (null-space convergence).
        center, width, height: the W (module docstring) [m].
        k_q: penalty shape of eq. 4.20 in the objectives of scenarios 1 and 2 (None: plain Jacobians,
            i.e. the literal eqs. 5.11 and 5.14).
        gain, damping: null-space step size α [N m] and damping k_D [N m s/rad] (as `fixed_point`).
        friction: "thesis" (Γ = 0.01, eq. 5.13) or "device".
        ellipses: points along the W where Fig. 5.5's ellipses are kept.
        progress: optional callback(done, total).

    Raises:
        Unreachable: the W leaves the workspace of the RHI, the Rehab or the slave (IK along it).
        InvalidInput: non-positive scale/speed/sizes, negative settle, unknown friction.
    """
    scale = _positive("scale", scale)
    settle = _positive("settle", settle, allow_zero=True)
    gain = _positive("gain", gain)
    damping = _positive("damping", damping, allow_zero=True)
    path = w_reference(center, width * scale, height * scale, speed, settle)
    devs = devices()
    for dev in devs.values():
        _friction(friction, dev)  # validate before the IK checks
    rhi, reh, slave = devs["RHI"], devs["Rehab"], devs["slave"]
    p0 = path.points[0]
    seeds = {"RHI": Q_FIXED, "Rehab": REHAB_SEED, "slave": SLAVE_SEED}
    start = {}
    for name, dev in devs.items():
        try:
            start[name] = dev.ik(p0, seeds[name])
        except Unreachable:
            raise Unreachable(f"path: the W's first point {np.round(p0, 4).tolist()} m is outside the workspace of "
                              f"{name} ({dev.name})") from None
        check_path_in_workspace(dev, path, q0=start[name])
    duration = settle + path.duration + 0.5
    N = _ticks(duration)
    chain = _Chain(progress, 3 * N)
    arrays: dict[str, np.ndarray] = {"path": path.points, "settle": np.array(settle)}
    stats: dict[str, dict[str, float]] = {}
    for key in SCENARIOS:
        dev = reh if key == "s3" else rhi
        sp = Plant(slave, friction=_friction(friction, slave))
        sp.reset(start["slave"])
        tele = Teleoperation(sp)
        if key == "s1":
            obj = TMIMatching(slave, lambda tele=tele: tele.slave.q, k_q=k_q)
        elif key == "s2":
            obj = Manipulability(log=True, k_q=k_q)
        else:
            obj = None
        plant = Plant(dev, friction=_friction(friction, dev))
        plant.reset(start["Rehab" if key == "s3" else "RHI"])
        log = simulate(plant, _controller(dev, obj, gain, damping), duration=duration, hand=Hand(path, **TRACK),
                       teleop=tele, progress=chain.run(N), record=lambda sp=sp: {"slave_q": sp.q})
        qs = log.extra["slave_q"]
        moving = (log.t >= settle - 1e-9) & (log.t <= settle + path.duration + 1e-9)
        Jm, Js = dev.jacobian(log.q), slave.jacobian(qs)
        area = _tme_area(Jm, Js)
        ref = np.array([path(t)[0] for t in log.t])
        err_ref = np.linalg.norm(log.slave_x - ref, axis=1)[moving]
        err_path = _distance_to_polyline(log.slave_x[moving], path.points)
        W0 = log.work[np.argmax(moving)]
        work = log.work - W0
        Jsp = penalized_jacobian(Js, qs, slave.q_min, slave.q_max, K_Q)
        Jmp = penalized_jacobian(Jm, log.q, dev.q_min, dev.q_max, K_Q)
        lim = np.min(np.minimum(log.q - dev.q_min, dev.q_max - log.q), axis=1)
        dt = np.diff(log.t, append=log.t[-1] + (log.t[1] - log.t[0]))[moving]
        dq = log.dq[moving]
        fr = plant.friction
        iw = np.flatnonzero(moving)[[0, -1]]
        ke = [0.5 * log.dq[i] @ dev.mass_matrix(log.q[i]) @ log.dq[i] for i in iw]
        stats[key] = {
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
    s1, s2, s3 = (stats[k] for k in SCENARIOS)
    below = 100.0 * (1.0 - s2["area"] / s1["area"])
    order = float(s1["work"] < s2["work"] < s3["work"])
    # alignment of the W's strokes with the slave ME's major axis, weighted by its anisotropy
    qs_path = check_path_in_workspace(slave, path, q0=start["slave"], step=0.01)
    tangent = np.diff(path.sample(0.01), axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    s_ax, U_ax = ellipsoid_axes(velocity_ellipsoid(slave.jacobian(qs_path[:-1])))
    weight = 1.0 - s_ax[:, 1] / s_ax[:, 0]
    align = float(np.sum(weight * np.abs(np.einsum("kj,kj->k", tangent, U_ax[:, :, 0]))) / np.sum(weight))
    names = {k: f"scenario {i + 1} ({v})" for i, (k, v) in enumerate(SCENARIOS.items())}
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
    effort = [
        Row(f"user work over the W, {names[k]}", None, stats[k]["work"], "J", "eq. 5.15, simulated hand")
        for k in SCENARIOS
    ]
    effort += [
        Row(f"energy dissipated by joint friction over the W, {names[k]}", None, stats[k]["e_friction"], "J",
            "∫ q̇ᵀΓq̇ dt: the part of the effort that depends on the HI's kinematics (cf. eq. 4.21)")
        for k in SCENARIOS
    ]
    effort += [
        Row(f"energy dissipated by the rendered damping B^d over the W, {names[k]}", None, stats[k]["e_damping"],
            "J", "∫ ẋᵀB^dẋ dt, the same path and speed for every scenario")
        for k in SCENARIOS
    ]
    effort += [
        Row(f"actuator work over the W, {names[k]}", None, stats[k]["e_actuator"], "J",
            "∫ τᵀq̇ dt: damping removes energy (< 0); null-space motion adds or removes it")
        for k in SCENARIOS
    ]
    effort += [
        Row(f"energy balance residual over the W, {names[k]}", None,
            stats[k]["work"] + stats[k]["e_actuator"] - stats[k]["e_friction"] - stats[k]["d_kinetic"], "J",
            "user + actuator work − friction losses − Δ kinetic energy: ≈ 0 up to the 1 kHz sampling "
            "of τᵀq̇")
        for k in SCENARIOS
    ]
    excess = {k: stats[k]["work"] - stats[k]["e_damping"] for k in SCENARIOS}
    effort += [
        Row(f"user work beyond the rendered damping, {names[k]}", None, excess[k], "J",
            "W − ∫ẋᵀB^dẋ dt: the kinematics-dependent part of the effort (friction, inertia, "
            "null-space coupling)")
        for k in SCENARIOS
    ]
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


# --------------------------------------------------------------------------- workspaces
def workspaces(samples: int = 20000, seed: int = 0, cell: float = 0.02, area_samples: int = 300000) -> Result:
    """Fig. 5.4: workspaces of the RHI, the 2-DoF Rehab and the slave, and the W.

    Uniform samples of each device's joint box, kept where the linear (parallelogram)
    limits hold (`rhi.experiments.ch3.workspaces`). Areas are estimated by counting the
    `cell` × `cell` squares that `area_samples` samples occupy: a lower bound that grows
    with the sample count, slowly for the 4-DoF RHI whose edges are sparsely sampled
    (0.57 / 0.64 / 0.68 m² at 3·10⁴ / 10⁵ / 3·10⁵ samples; the 2-DoF devices converge).

    Args:
        samples: joint-space samples per device kept for the figure.
        seed: random seed.
        cell: grid cell for the area estimate [m].
        area_samples: joint-space samples per device for the area estimate (≥ samples).

    Returns:
        Result "ch5.workspaces" with arrays `workspaces` (3, samples, 2) [m] for RHI, Rehab, slave
        (NaN: rejected sample), `path` (the W's corners) and the table of areas.
    """
    from rhi.experiments.ch3 import workspaces as sample

    if int(samples) < 1:
        raise InvalidInput(f"samples: must be >= 1, got {samples!r}")
    if int(area_samples) < int(samples):
        raise InvalidInput(f"area_samples: must be >= samples ({samples}), got {area_samples!r}")
    cell = _positive("cell", cell)
    devs = devices()
    dense = sample(devs, int(area_samples), seed)
    pts = dense[:, : int(samples)]
    occupied = []
    for P in dense:
        P = P[np.all(np.isfinite(P), axis=1)]
        occupied.append({tuple(c) for c in np.floor(P / cell).astype(int).tolist()})
    area = [len(o) * cell**2 for o in occupied]
    inside = len(occupied[1] & occupied[0]) / max(1, len(occupied[1]))
    path = w_reference()
    reach = {}
    for name, dev in devs.items():
        try:
            check_path_in_workspace(dev, path, q0=dev.ik(path.points[0], {"RHI": Q_FIXED, "Rehab": REHAB_SEED,
                                                                          "slave": SLAVE_SEED}[name]), step=0.01)
            reach[name] = 1.0
        except Unreachable:
            reach[name] = 0.0
    rows = [Row(f"workspace area, {nm}", None, a, "m²",
                f"{cell * 100:g} cm cells occupied by {area_samples} samples (a lower bound)")
            for nm, a in zip(devs, area)]
    rows += [
        Row("RHI workspace larger than the Rehab's (1 = yes)", T.WORKSPACE_LARGER, float(area[0] > area[1]), "", "§5.4.1, Fig. 5.4"),
        Row("fraction of the Rehab's cells inside the RHI's", None, inside, "",
            "1 in exact arithmetic: the Rehab is the RHI with q3 = q4 = 0, inside its limits"),
    ]
    rows += [Row(f"W inside the workspace of the {nm} (1 = yes)", T.W_INSIDE, reach[nm], "") for nm in devs]
    return Result("ch5.workspaces", "Fig. 5.4: workspaces of the RHI, the 2-DoF Rehab and the slave",
                  [Table("Fig. 5.4 workspaces", rows)],
                  {"workspaces": pts, "path": path.points},
                  ["The thesis shows Fig. 5.4 as a figure only; the areas are ours.",
                   "workspaces[0], [1], [2]: " + ", ".join(devs) + "."])
