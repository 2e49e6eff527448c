"""Chapter 6: dynamic reconfiguration of a redundant haptic interface for soft and hard contacts.

Thesis §6.3–6.4: the 3-DoF example (Figs 6.3–6.4), palpation of a 1000 N/m spring with
the configuration set by FME matching to M_Free^des vs M_Stiff^des (Fig. 6.9, Table 6.1),
the F_max ratio map (Fig. 6.10) and the ASO-driven transition between the desired FMEs
with and without the cosine blend (Fig. 6.11).

Set-up and the choices the thesis leaves open (each fixed before comparing with the thesis):

- **Desired FMEs** (eqs. 6.11–6.13): 𝒦 = μ λ_max(M̂₀), ζ = λ_min(M̂₀)/μ with μ = 5 from the
  torque-weighted FME at the home configuration (rhi4: q = 0 gives 𝒦 = 123.0, ζ = 3.34;
  the 3-DoF example: its initial configuration, 𝒦 = 5 × 5.79, ζ = 2.58/5). M_Free^des has
  its minor axis ζ along the motion u, M_Stiff^des its major axis 𝒦 along the contact force.
- **Configuration reached by FME matching** (`match_fme`): the minimiser of the
  controller's null-space cost on the self-motion manifold f(q) = x, reached from a start
  configuration (SLSQP, equality f(q) = x and the joint limits as constraints). For the
  3-DoF example the start is the thesis's initial configuration (the null-space controller
  converges from there with the end-effector held). On rhi4 the start is the IK solution
  from the home configuration q = 0 plus `starts − 1` seeded configurations, and the best
  match is kept, so every grid point of the map is computed independently.
- **Joint limits on rhi4** (§5.4 limits, `models/rhi4`): every unconstrained FME-matching
  optimum at X₀ lies outside them (M_Free^des: q4 > 80°; M_Stiff^des: q4 < −20° and
  q1 − q2 < −55°), so the matching is constrained. The thesis's controller (eq. 6.6) knows no
  limits; driven against the plant's limit stops its null-space torque no longer stays in
  the null space (the stop's reaction force is not in it) and pushes the handle with up to
  ~12 N in free space. The simulated controller therefore adds a joint-limit barrier to the
  null-space cost (`BARRIER`, a quadratic `rhi.control.JointLimitBarrier`: ½ Σ max(0, δ − d)² over the distances d to every box
  and linear limit, δ = 0.1 rad, gain 100 N m/rad), and the static optimum minimises the
  same sum ν_FME + (100/β) ν_lim, so simulation and statics describe one configuration.
- **Palpation** (§6.4, eq. 6.21, K_e = 1000 N/m from X₀ = [0.5, 0.1] m along u = [0, 1]):
  the MuJoCo plant (motor friction of `models/rhi4/device.toml [plant]`) starts at the
  FME-matched configuration; a hand holds X₀ while the null-space controller (β = 20,
  K_d = 0.1, dynamically consistent J#) keeps the match, then pushes in along u at constant
  speed. (Started from the IK configuration instead, the controller settles within 0.01 rad
  of the static optimum in about 1 s.) The primary law is the spring alone (eq. 6.21: no
  damping, no Coriolis/gravity terms); saturation is handled by simple force scaling
  (§6.3.1: "a scaling factor α ... as soon as one of the RHI's actuators is saturated"),
  not by ASCM (chapter 7). The rendered force is read on the
  handle's F/T sensor, as in Fig. 6.9.
- **Transition** (eqs. 6.14–6.19, ε₁ = 0.7, ε₂ = 0.95, ρ = 0.003, S = 50): the same palpation
  with `FMESchedule`, pushing in, holding, and releasing. "Without the method" is eq. 6.15
  as written: one threshold ε = ε₁ and an instantaneous switch of M_des (ρ = 0).

Why our numbers differ from the thesis's:

- Kinematics, torque limits and 𝒦, ζ are the thesis's, so FME shapes and static F_max
  depend only on which configuration the matching reaches. The thesis does not report its
  configurations; ours respect the §5.4 joint limits, which bind at X₀ for both FMEs.
- Table 6.1's F_max was measured on the hardware (with its friction, compliance, sensor
  filtering and a human hand); ours is a simulated hand on a plant whose inertias and
  friction are partly estimates (`models/rhi4/README.md`).
- Table 6.1's M_x and Φ come from a system-identification experiment on the hardware; we
  report our model's effective inertia Λ = (uᵀ J M⁻¹ Jᵀ u)⁻¹ (eq. 3.13) and the quasi-static
  viscous friction our plant reflects along u at the same configurations, beside them.
- Fig. 6.11: the thesis's β = 20 makes the null-space torque saturate the actuators during
  a reconfiguration, which bounds the applied null-space torque with or without the
  transition method (see `transition`).
- Fig. 6.10: the thesis shows the map without its configurations or numbers; where the
  joint limits leave little self-motion the two matched configurations nearly coincide and
  the ratio is close to 1 (our minimum is slightly below 1).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

import numpy as np
from scipy.optimize import LinearConstraint, NonlinearConstraint, minimize

from rhi import thesis as T
from rhi.control import (
    ControllerConfig,
    FMEMatching,
    FMESchedule,
    JointLimitBarrier,
    NullSpaceController,
    ObjectiveTerm,
    SpringPalpation,
    TransitionConfig,
    WeightedSum,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.control.saturation import allocate_scaling
from rhi.design.executors import parallel_map
from rhi.device import Device, device
from rhi.errors import InvalidInput, Unreachable
from rhi.experiments.result import Result, Row, Table
from rhi.metrics import (
    effective_inertia,
    force_ellipsoid,
    max_force,
    max_force_scaling,
    nullspace_projector,
    weighted_pinv,
)

Progress = Callable[[int, int], None]

#: §6.4 palpation set-up.
U = (0.0, 1.0)
X0 = (0.5, 0.1)
K_E = 1000.0
MU = 5.0
BETA = 20.0
K_D = 0.1
Q_HOME = (0.0, 0.0, 0.0, 0.0)
THESIS_K, THESIS_ZETA = T.K_ZETA_6_4
#: Table 6.1: (M_x [kg], Φ [N s/m], F_max [N]) along u at [0.5, 0.1] m.
THESIS_TABLE = T.TABLE_6_1
THESIS_GAIN = T.GAIN_6_4
#: Fig. 6.11 transition parameters and its stated duration ("performed in 0.5 second").
EPS1, EPS2, RHO, ASO_S = 0.7, 0.95, 0.003, 50.0
THESIS_TF = T.TRANSITION_TIME
#: §6.3.1 3-DoF example.
Q_3DOF = (np.pi / 6, -np.pi / 3, -3 * np.pi / 4)
F_3DOF = 3.5
U_3DOF = (1.0, 0.0)
THESIS_3DOF_EIG = T.EIG_3DOF
#: Joint-limit barrier of the simulated controller (our choice, see the module docstring).
LIMIT_MARGIN = 0.1
LIMIT_GAIN = 100.0
#: Grid of the F_max ratio map (the rhi4 region of Fig. 7.5's map) [m].
MAP_X = (0.25, 0.75)
MAP_Y = (-0.5, 0.3)

CASES = ("free", "stiff")


# --------------------------------------------------------------------------- objectives
#: The joint-limit barrier of the simulated controller: ½ Σ max(0, δ − d)², δ = `LIMIT_MARGIN`.
BARRIER = JointLimitBarrier(LIMIT_MARGIN)


def controller_terms(desired: np.ndarray, torque_max: np.ndarray, *, limits: bool = True,
                     beta: float = BETA) -> tuple[ObjectiveTerm, ...]:
    """The null-space terms of the rhi4 palpation controller: FME matching (β, thesis: 20) and the limit barrier."""
    terms = [ObjectiveTerm(FMEMatching(desired, torque_max), beta)]
    if limits:
        terms.append(ObjectiveTerm(BARRIER, LIMIT_GAIN))
    return tuple(terms)


# ------------------------------------------------------------------------ configurations
def match_fme(dev: Device, x, objective, q0, *, max_iter: int = 300) -> np.ndarray:
    """The configuration the null-space controller converges to from q0 with the end-effector at x.

    Minimises the objective's ν(q) on the self-motion manifold f(q) = x within the joint
    limits (SLSQP; the fixed point of gradient projection, eqs. 6.3 and 6.6, restricted to
    the limits), starting from q0 projected onto f(q) = x by Newton steps without any
    null-space motion. `rhi.control.configuration.optimal_configuration` would re-centre
    the result with `Device.ik`'s null-space term, moving it off the optimum; hence this
    local variant.

    Args:
        dev: the device.
        x: (m,) end-effector position [m].
        objective: `value(device, q)`, `gradient(device, q)` (e.g. `FMEMatching`, `WeightedSum`).
        q0: (n,) start configuration [rad].
        max_iter: SLSQP iterations.

    Returns:
        q: (n,) [rad] within the limits with f(q) = x (1e-9 m); never worse than the start.

    Raises:
        Unreachable: x cannot be reached within the limits from q0.
    """
    x = np.asarray(x, dtype=float)
    q_start = dev.ik(x, np.asarray(q0, dtype=float), k_null=0.0)
    cons = [NonlinearConstraint(lambda q: dev.fk(q) - x, 0.0, 0.0, jac=lambda q: dev.jacobian(q))]
    L = dev.linear_limits
    if L is not None:
        cons.append(LinearConstraint(L.C, L.lower, L.upper))
    res = minimize(
        lambda q: objective.value(dev, q),
        q_start,
        jac=lambda q: objective.gradient(dev, q),
        method="SLSQP",
        bounds=list(zip(dev.q_min, dev.q_max)),
        constraints=cons,
        options={"maxiter": max_iter, "ftol": 1e-12},
    )
    try:
        q = dev.ik(x, np.clip(res.x, dev.q_min, dev.q_max), k_null=0.0, restarts=0)
    except Unreachable:
        return q_start
    return q if objective.value(dev, q) <= objective.value(dev, q_start) else q_start


def start_configurations(dev: Device, x, count: int, seed: int = 6, *, restarts: int = 2) -> list[np.ndarray]:
    """Deterministic starts on f(q) = x: IK from the home configuration, then seeded ones.

    The first is `Device.ik` from q = 0 (joint-centring null-space term, `restarts` seeded
    restarts when that fails, as the Fig. 7.5 map does); the others are
    drawn uniformly in the joint box (NumPy generator `seed`) and projected onto f(q) = x by
    Newton steps without null-space motion; draws that do not reach x are skipped, so up
    to `count` starts come back.

    Raises:
        Unreachable: x is outside the workspace (the IK from home fails).
    """
    out = [np.asarray(dev.ik(x, np.zeros(dev.n), restarts=restarts))]
    rng = np.random.default_rng(seed)
    for q in rng.uniform(dev.q_min, dev.q_max, size=(max(count - 1, 0), dev.n)):
        try:
            out.append(dev.ik(x, q, k_null=0.0, restarts=0))
        except Unreachable:
            continue
    return out


def best_match(dev: Device, x, objective, *, starts: int | list[np.ndarray] = 3, seed: int = 6) -> np.ndarray:
    """`match_fme` from several deterministic starts; the lowest ν wins.

    Args:
        dev, x, objective: as `match_fme`.
        starts: a number of `start_configurations`, or the start configurations themselves.
        seed: seed of `start_configurations`.

    Raises:
        Unreachable: x is outside the workspace.
    """
    qs = start_configurations(dev, x, starts, seed) if isinstance(starts, int) else starts
    best, best_v = None, np.inf
    for s in qs:
        try:
            q = match_fme(dev, x, objective, s)
        except Unreachable:
            continue
        v = objective.value(dev, q)
        if v < best_v - 1e-12:
            best, best_v = q, v
    if best is None:
        where = np.round(np.asarray(x, dtype=float), 4).tolist()
        raise Unreachable(f"x: {where} m is outside the workspace of {dev.name}")
    return best


def desired_fmes(dev: Device, u, q_home, mu: float = MU) -> tuple[float, float, np.ndarray, np.ndarray]:
    """(𝒦, ζ, M_Free^des, M_Stiff^des) for motion/contact along u (eqs. 6.12–6.13, μ of §6.3.1)."""
    K, zeta = fme_shape(dev.jacobian(np.asarray(q_home, dtype=float)), dev.torque_max, mu)
    return K, zeta, desired_fme_free(u, K, zeta), desired_fme_stiff(u, K, zeta)


def reflected_damping(J: np.ndarray, M: np.ndarray, D: np.ndarray, u, k_d: float = K_D) -> float:
    """Quasi-static viscous friction felt along u [N s/m] with joint damping D and null-space damping k_D.

    With the null-space damping torque −N k_D q̇ (eq. 6.6, N = I − JᵀJ#ᵀ) and the motors'
    viscous friction −D q̇, a force F on the handle moves it at steady state with
    (D + k_D N) q̇ = JᵀF, ẋ = Jq̇; Φ = (uᵀ J (D + k_D N)⁻¹ Jᵀ u)⁻¹ is the F/ẋ of Table 6.1's
    model (eq. 6.22 at constant velocity). Coulomb friction is left out, as eq. 6.22 does.

    Args:
        J: (m, n) Jacobian [m/rad]; M: (n, n) inertia [kg m²]; D: (n,) joint damping [N m s/rad];
        u: (m,) direction; k_d: null-space damping [N m s/rad].
    """
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    N = nullspace_projector(J, M)
    Jt_u = J.T @ u
    return float(1.0 / (Jt_u @ np.linalg.solve(np.diag(D) + k_d * N, Jt_u)))


# ------------------------------------------------------------------------- 3-DoF example
def example_3dof(duration: float = 2.0, steps: int = 201, amplitude: float = F_3DOF, mu: float = MU) -> Result:
    """Figs 6.3–6.4: the 3-DoF planar RHI rendering F_e = [3.5 sin(πt/2), 0] N at three configurations.

    The end-effector is held at the position of the initial configuration
    q = [π/6, −π/3, −3π/4] rad (planar3r: L = 0.25 m, |T_i| <= 0.5 N m, W = diag(2, 2, 2)).
    The FMEs are matched from that configuration (`match_fme`, quasi-static: the fixed
    point the null-space controller reaches with the end-effector held) to M_Free^des
    (minor axis ζ along F_e) and M_Stiff^des (major axis 𝒦 along F_e). At each configuration
    τ = α Jᵀ F_e with the force scaling α of §6.3.1 (the largest α <= 1 keeping every joint
    within its limit), and the rendered force is J⁺ᵀ τ = α F_e.

    Args:
        duration: time span [s] (2 s: the positive half sine).
        steps: samples.
        amplitude: peak of F_e [N] (thesis: 3.5).
        mu: FME shape factor μ (thesis: 5).
    """
    dev = device("planar3r")
    lo, hi = dev.torque_limits
    q0 = np.array(Q_3DOF)
    x = dev.fk(q0)
    u = np.array(U_3DOF)
    K, zeta, Mf, Ms = desired_fmes(dev, u, q0, mu)
    configs = {
        "initial": q0,
        "free": match_fme(dev, x, FMEMatching(Mf, hi), q0),
        "stiff": match_fme(dev, x, FMEMatching(Ms, hi), q0),
    }
    t = np.linspace(0.0, duration, steps)
    Fe = np.stack([amplitude * np.sin(np.pi * t / 2), np.zeros_like(t)], axis=1)
    arrays: dict[str, np.ndarray] = {"t": t, "Fe": Fe, "x": x, "M_free_des": Mf, "M_stiff_des": Ms}
    rows: list[Row] = []
    lam0 = np.linalg.eigvalsh(force_ellipsoid(dev.jacobian(q0), hi))
    rows += [
        Row("λ_min of M̂ at the initial configuration", THESIS_3DOF_EIG[0], float(lam0[0]), "N²/(N m)²"),
        Row("λ_max of M̂ at the initial configuration", THESIS_3DOF_EIG[1], float(lam0[1]), "N²/(N m)²"),
        Row("𝒦 = μ λ_max", T.K_3DOF if mu == 5 else None, K, "N²/(N m)²"),
        Row("ζ = λ_min/μ", T.ZETA_3DOF if mu == 5 else None, zeta, "N²/(N m)²"),
    ]
    for name, q in configs.items():
        J = dev.jacobian(q)
        tau = np.empty((steps, dev.n))
        alpha = np.empty(steps)
        for k, F in enumerate(Fe):
            al = allocate_scaling(J.T @ F, np.zeros(dev.n), lo, hi)
            tau[k], alpha[k] = al.tau, al.alpha
        force = tau @ weighted_pinv(J)  # (J⁺ᵀ τ)ᵀ = τᵀ J⁺
        fs = float(max_force_scaling(J, u, torque_min=lo, torque_max=hi))
        flp = float(max_force(J, u, torque_min=lo, torque_max=hi, projector="pseudoinverse"))
        peak = float(np.max(np.abs(force[:, 0])))
        arrays.update({f"q_{name}": q, f"skeleton_{name}": dev.skeleton(q)[:, :2],
                       f"fme_{name}": force_ellipsoid(J, hi),
                       f"tau_{name}": tau, f"force_{name}": force, f"alpha_{name}": alpha})
        label = {"initial": "initial configuration", "free": "M_Free^des configuration",
                 "stiff": "M_Stiff^des configuration"}[name]
        rows += [
            Row(f"peak rendered |F_x|, {label}", T.F_E_3DOF if name == "stiff" and amplitude == T.F_E_3DOF else None,
                peak, "N",
                {"stiff": "thesis: rendered in full, without saturation, at the M_Stiff^des configuration",
                 "free": "thesis: capability decreased at the M_Free^des configuration (value not reported)",
                 "initial": "thesis: value not reported"}[name]),
            Row(f"F_max along x by force scaling, {label}", None, fs, "N"),
            Row(f"F_max along x with null-space torques (LP), {label}", None, flp, "N"),
        ]
        if name != "initial":
            D = Mf if name == "free" else Ms
            rows.append(Row(f"JBLD ν to M_{name.capitalize()}^des: initial → matched", None,
                            float(FMEMatching(D, hi).value(dev, q)), "",
                            f"initial: {FMEMatching(D, hi).value(dev, q0):.4f}"))
    return Result(
        "ch6.example_3dof",
        "Figs 6.3–6.4: 3-DoF RHI rendering F_e = [3.5 sin(πt/2), 0] N at the initial, M_Free and M_Stiff "
        "configurations",
        [Table("§6.3.1 example (end-effector held)", rows)],
        arrays,
        [
            "Quasi-static: the configurations are the fixed points of FME matching from the initial "
            "configuration (SLSQP on the self-motion manifold); force scaling as in §6.3.1.",
            "The thesis reports no numbers for this example besides M̂'s eigenvalues (2.6, 5.8) and the "
            "claim that only the M_Stiff^des configuration renders the full 3.5 N; both are checked.",
        ],
    )


# ----------------------------------------------------------------------- simulated palpation
def _palpation_controller(dev: Device, desired: np.ndarray | None, schedule: FMESchedule | None = None,
                          *, limits: bool = True, beta: float = BETA,
                          projector: str = "dynamic") -> NullSpaceController:
    """Spring palpation (eq. 6.21) with force scaling; FME matching to `desired` or by the ASO `schedule`.

    projector: "dynamic" (J#, eq. 6.6 as the thesis writes it) or "pseudoinverse" (J⁺).
    """
    law = SpringPalpation(K_E, X0, normal=U, damping=0.0, coriolis=False, gravity=False, passivity=None)
    if desired is not None:
        terms = controller_terms(desired, dev.torque_max, limits=limits, beta=beta)
    else:
        terms = (ObjectiveTerm(BARRIER, LIMIT_GAIN),) if limits else ()
    cfg = ControllerConfig(primary=law, objectives=terms, fme=schedule, damping=K_D, saturation="scaling",
                           projector=projector, aso_shape=ASO_S)
    return NullSpaceController(dev, cfg)


def _hand(points, speed: float, start: float, stiffness: float, damping: float):
    from rhi.sim import Hand, Path

    return Hand(Path(np.asarray(points, dtype=float), speed=speed, start=start), stiffness=stiffness,
                damping=damping, max_force=60.0)


def _run(dev: Device, controller, hand, q_start: np.ndarray, duration: float, progress: Progress | None,
         offset: int, total: int):
    from rhi.sim import Plant, simulate

    plant = Plant(dev)
    plant.reset(q_start)
    cb = None if progress is None else (lambda k, n: progress(offset + k, total))
    return simulate(plant, controller, duration=duration, hand=hand, progress=cb)


def _smooth(a: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average over `window` samples along axis 0 (edges: shorter windows)."""
    if window <= 1:
        return a
    k = np.ones(window) / window
    num = np.apply_along_axis(lambda v: np.convolve(v, k, mode="same"), 0, a)
    den = np.convolve(np.ones(len(a)), k, mode="same")
    return num / (den[:, None] if a.ndim > 1 else den)


def palpation(
    settle: float = 0.5,
    depth: float = 0.015,
    speed: float = 0.01,
    hold: float = 0.5,
    *,
    hand_stiffness: float = 3000.0,
    hand_damping: float = 40.0,
    starts: int = 3,
    limits: bool = True,
    filter_ms: float = 20.0,
    projectors: tuple[str, ...] = ("dynamic", "pseudoinverse"),
    progress: Progress | None = None,
) -> Result:
    """Fig. 6.9 and Table 6.1: palpating K_e = 1000 N/m from X₀ = [0.5, 0.1] m along u = [0, 1] on the simulated rhi4.

    For M_Free^des and M_Stiff^des: the plant starts at the FME-matched configuration of X₀
    (`best_match` of the controller's null-space cost); the hand holds X₀ for `settle`
    seconds while the null-space controller holds the match (the table reports how far it
    drifts), then pushes in along u by `depth` at `speed` and holds. The
    rendered force is the F/T sensor reading along u (moving average over `filter_ms`),
    signed like Table 6.1 (negative: the device pushes back along −u).

    Static numbers beside it, at the FME-matched configuration (`best_match`) and at the
    configuration the simulation settled to: F_max by force scaling (what the ch. 6
    controller can render), F_max with null-space torques (the LP of `rhi.metrics.max_force`,
    what ASCM of ch. 7 approaches), Λ along u, and the reflected viscous friction.

    Args:
        settle: time the hand holds X₀ before pushing [s].
        depth: how far the hand's reference moves into the environment [m] (past saturation for
            both FMEs: saturation starts near 5 and 9 mm).
        speed: pushing speed [m/s].
        hold: time held at the end [s].
        hand_stiffness, hand_damping: the hand's grip [N/m], [N s/m].
        starts: starts of the static matching (`best_match`).
        limits: add the joint-limit barrier to the controller (see the module docstring).
        filter_ms: moving-average window of the sensor force [ms].
        projectors: null-space projectors of the simulated controller, each run in turn:
            "dynamic" (J#, the thesis's text) and/or "pseudoinverse" (J⁺). The first one gives
            the main rows and arrays; the others add their simulated peaks and gain.
        progress: callback(done, total) in control ticks.
    """
    _check_motion(settle=settle, depth=depth, speed=speed, hold=hold)
    if not projectors or len(set(projectors)) != len(projectors) or any(
            p not in ("dynamic", "pseudoinverse") for p in projectors):
        raise InvalidInput(f"projectors: expected distinct 'dynamic'/'pseudoinverse' entries, got {projectors!r}")
    dev = device("rhi4")
    lo, hi = dev.torque_limits
    u, x0 = np.array(U), np.array(X0)
    K, zeta, Mf, Ms = desired_fmes(dev, u, Q_HOME)
    desired = {"free": Mf, "stiff": Ms}
    duration = settle + depth / speed + hold
    ticks = int(round(duration * 1000.0))
    arrays: dict[str, np.ndarray] = {"M_free_des": Mf, "M_stiff_des": Ms, "x0": x0, "u": u}
    D = _plant_damping(dev)
    stat: dict[str, dict[str, float]] = {}
    sim: dict[str, float] = {}
    total = 2 * ticks * len(projectors)
    q_opts = {case: best_match(dev, x0, WeightedSum(controller_terms(desired[case], hi, limits=limits)),
                               starts=starts) for case in CASES}
    for j, proj in enumerate(projectors[1:], start=1):  # the other projectors: simulated peaks only
        tag = "J#" if proj == "dynamic" else "J⁺"
        for i, case in enumerate(CASES):
            ctrl = _palpation_controller(dev, desired[case], limits=limits, projector=proj)
            hand = _hand([x0, x0 + depth * u], speed, settle, hand_stiffness, hand_damping)
            log = _run(dev, ctrl, hand, q_opts[case], duration, progress, (2 * j + i) * ticks, total)
            if log.fault is not None:
                raise InvalidInput(f"palpation: the controller stopped: {log.fault}")
            f_u = -_smooth(log.ft[:, :2], max(1, int(round(filter_ms)))) @ u
            sim[f"{case}_{tag}"] = float(np.min(np.where(log.t >= settle, f_u, np.inf)))
            arrays[f"force_{case}_{proj}"] = f_u
    for i, case in enumerate(CASES):
        q_opt = q_opts[case]
        ctrl = _palpation_controller(dev, desired[case], limits=limits, projector=projectors[0])
        hand = _hand([x0, x0 + depth * u], speed, settle, hand_stiffness, hand_damping)
        log = _run(dev, ctrl, hand, q_opt, duration, progress, i * ticks, total)
        if log.fault is not None:
            raise InvalidInput(f"palpation: the controller stopped: {log.fault}")
        k_set = int(round(settle * 1000.0)) - 1
        q_set = log.q[k_set]
        w = max(1, int(round(filter_ms)))
        f_u = -_smooth(log.ft[:, :2], w) @ u  # the device's force on the hand along u [N]
        desired_f = -K_E * np.maximum((log.x - x0) @ u, 0.0)
        push = log.t >= settle
        k_peak = int(np.argmin(np.where(push, f_u, np.inf)))
        sim[case] = float(f_u[k_peak])
        for tag, q in (("opt", q_opt), ("settled", q_set)):
            J, M = dev.jacobian(q), dev.mass_matrix(q)
            stat[f"{case}_{tag}"] = {
                "fs": float(max_force_scaling(J, u, torque_min=lo, torque_max=hi)),
                "lp": float(max_force(J, u, torque_min=lo, torque_max=hi, M=M)),
                "lp_pinv": float(max_force(J, u, torque_min=lo, torque_max=hi, projector="pseudoinverse")),
                "lam": float(effective_inertia(J, M, u)),
                "phi": reflected_damping(J, M, D, u),
                "nu": float(FMEMatching(desired[case], hi).value(dev, q)),
            }
        J_peak = dev.jacobian(log.q[k_peak])
        stat[f"{case}_peak"] = {"fs": float(max_force_scaling(J_peak, u, torque_min=lo, torque_max=hi))}
        arrays.update({
            f"t_{case}": log.t, f"force_{case}": f_u, f"desired_{case}": desired_f, f"tau_{case}": log.tau,
            f"x_{case}": log.x, f"q_{case}": log.q, f"alpha_{case}": log.alpha, f"q_opt_{case}": q_opt,
            f"q_settled_{case}": q_set, f"skeleton_{case}": dev.skeleton(q_set)[:, :2],
            f"fme_{case}": force_ellipsoid(dev.jacobian(q_set), hi),
            f"hand_{case}": log.F_hand @ u,
        })
    gain = lambda a, b: 100.0 * (a / b - 1.0)  # noqa: E731
    tf, ts = THESIS_TABLE["free"], THESIS_TABLE["stiff"]
    rows_tab = []
    for case, (mx, phi, fmax) in (("free", tf), ("stiff", ts)):
        lab = "M_Free^des" if case == "free" else "M_Stiff^des"
        s, o = stat[f"{case}_settled"], stat[f"{case}_opt"]
        rows_tab += [
            Row(f"F_max along u, {lab}: simulated F/T sensor peak", fmax, sim[case], "N",
                "simulated hand and plant; force scaling; negative: along −u"),
            Row(f"F_max along u, {lab}: force scaling at the settled configuration", fmax, -s["fs"], "N",
                "max_force_scaling: the ch. 6 controller's static capability"),
            Row(f"F_max along u, {lab}: LP with null-space torques, settled configuration", fmax, -s["lp"], "N",
                "rhi.metrics.max_force (dynamic J#): what ASCM (ch. 7) could reach"),
            Row(f"F_max along u, {lab}: force scaling at the static FME-matched optimum", fmax, -o["fs"], "N"),
            Row(f"M_x along u, {lab}: our model's Λ at the settled configuration", mx, s["lam"], "kg",
                "thesis: system identification on the hardware (eq. 6.22); ours: Λ = (uᵀJM⁻¹Jᵀu)⁻¹ (eq. 3.13), "
                "estimated inertias (models/rhi4/README.md)"),
            Row(f"Φ along u, {lab}: our plant's reflected viscous friction, settled configuration", phi, s["phi"],
                "N s/m", "thesis: system identification; ours: quasi-static (uᵀJ(D + k_D N)⁻¹Jᵀu)⁻¹ with the "
                "estimated motor damping D of device.toml [plant]; Coulomb friction not included"),
        ]
    rows_gain = [
        Row("force gain M_Stiff vs M_Free, simulated sensor peak", THESIS_GAIN, gain(sim["stiff"], sim["free"]), "%"),
        Row("force gain, force scaling at the settled configurations", THESIS_GAIN,
            gain(stat["stiff_settled"]["fs"], stat["free_settled"]["fs"]), "%"),
        Row("force gain, LP with null-space torques at the settled configurations", THESIS_GAIN,
            gain(stat["stiff_settled"]["lp"], stat["free_settled"]["lp"]), "%"),
        Row("force gain, LP with J⁺ null-space torques at the settled configurations", THESIS_GAIN,
            gain(stat["stiff_settled"]["lp_pinv"], stat["free_settled"]["lp_pinv"]), "%"),
        Row("force gain, force scaling at the static optima", THESIS_GAIN,
            gain(stat["stiff_opt"]["fs"], stat["free_opt"]["fs"]), "%"),
        *[Row(f"force gain M_Stiff vs M_Free, simulated sensor peak, controller with {tag}", THESIS_GAIN,
              gain(sim[f"stiff_{tag}"], sim[f"free_{tag}"]), "%") for tag in
          ("J#" if p == "dynamic" else "J⁺" for p in projectors[1:])],
        *[Row(f"F_max along u, M_{c.capitalize()}^des: simulated F/T sensor peak, controller with {tag}",
              THESIS_TABLE[c][2], sim[f"{c}_{tag}"], "N") for tag in
          ("J#" if p == "dynamic" else "J⁺" for p in projectors[1:]) for c in CASES],
        Row("inertia ratio Λ_Stiff/Λ_Free (thesis: M_x ratio)", T.MX_RATIO_6_1,
            stat["stiff_settled"]["lam"] / stat["free_settled"]["lam"], ""),
        Row("𝒦 (μ λ_max at q = 0)", THESIS_K, K, "N²/(N m)²"),
        Row("ζ (λ_min/μ at q = 0)", THESIS_ZETA, zeta, "N²/(N m)²"),
    ]
    rows_cfg = []
    for case in CASES:
        s, o = stat[f"{case}_settled"], stat[f"{case}_opt"]
        rows_cfg += [
            Row(f"JBLD ν to M_{case.capitalize()}^des, settled by the controller", None, s["nu"], "",
                f"static optimum: {o['nu']:.4f}"),
            Row(f"|q_settled − q_opt|, {case}", None, float(np.linalg.norm(arrays[f"q_settled_{case}"] -
                                                                           arrays[f"q_opt_{case}"])), "rad"),
            Row(f"force scaling F_max at the configuration of the simulated peak, {case}", None,
                -stat[f"{case}_peak"]["fs"], "N", "the null-space controller keeps reconfiguring during the push"),
        ]
    g_sim = gain(sim["stiff"], sim["free"])
    g_lp = gain(stat["stiff_settled"]["lp"], stat["free_settled"]["lp"])
    notes = [
        f"Simulated controller's projector: {projectors[0]} for the main rows; the gain rows marked J⁺/J# "
        "repeat the simulation with the other projector.",
        "Table 6.1's F_max is a hardware measurement; ours is the simulated F/T sensor (20 ms moving "
        "average) and the static capability at the configuration the controller settled to.",
        f"Gain M_Stiff over M_Free: {g_sim:.0f} % simulated vs the thesis's {THESIS_GAIN:.0f} %. The thesis does not "
        "report its configurations; ours are the FME-matched optima within the §5.4 joint limits, which bind "
        "for both FMEs, so F_max at each depends on where the limits cut the self-motion manifold. Simulated "
        f"F_max: M_Free^des {sim['free']:.2f} N (thesis {THESIS_TABLE['free'][2]} N), M_Stiff^des "
        f"{sim['stiff']:.2f} N (thesis {THESIS_TABLE['stiff'][2]} N). With null-space torques (the LP, ch. 7) "
        f"the gain would be {g_lp:.0f} %.",
        "M_x and Φ: the thesis identified them on the hardware; ours are model predictions at the same "
        "configurations (the system-identification reproduction is a separate experiment).",
        f"The joint limits bind at X₀ for both desired FMEs; the simulated controller has a joint-limit barrier "
        f"(δ = {LIMIT_MARGIN:g} rad, gain {LIMIT_GAIN:g} N m/rad) beside the thesis's FME term "
        f"(β = {BETA:g}, K_d = {K_D:g})."
        if limits else "Joint-limit barrier off: the controller is the thesis's eq. 6.6 alone.",
    ]
    return Result(
        "ch6.palpation",
        "Fig. 6.9 / Table 6.1: palpation of K_e = 1000 N/m at [0.5, 0.1] m with M_Free^des vs M_Stiff^des "
        "(simulated rhi4)",
        [Table("Table 6.1 along u = [0, 1] at [0.5, 0.1] m", rows_tab),
         Table("Force-feedback gain of M_Stiff^des over M_Free^des (thesis: 51 %)", rows_gain),
         Table("Configurations", rows_cfg)],
        arrays,
        notes,
    )


def _plant_damping(dev: Device) -> np.ndarray:
    """Motor viscous damping of the plant (device.toml [plant]): (n,) [N m s/rad]."""
    from rhi.sim import device_friction

    return np.asarray(device_friction(dev).damping, dtype=float)


# ---------------------------------------------------------------------------- transition
def transition(
    settle: float = 0.5,
    depth: float = 0.02,
    speed: float = 0.02,
    hold: float = 1.0,
    release: float = 1.5,
    *,
    hand_stiffness: float = 3000.0,
    hand_damping: float = 40.0,
    eps1: float = EPS1,
    eps2: float = EPS2,
    rho: float = RHO,
    beta: float = BETA,
    compare_beta: float | None = 2.0,
    starts: int = 3,
    limits: bool = True,
    progress: Progress | None = None,
) -> Result:
    """Fig. 6.11: the desired-FME transition driven by the ASO, with and without the cosine blend.

    The palpation of `palpation` with `FMESchedule(M_Free^des, M_Stiff^des, β)`, from the
    M_Free^des-matched configuration: the hand holds X₀ for `settle` seconds (V = 1, Ω = 1),
    pushes in by `depth` at `speed` (the ASO V of τ_m drains; below ε₁ the desired FME
    moves to M_Stiff^des), holds for `hold` seconds, returns to X₀ and stays there for
    `release` seconds (V refills; at ε₂ the desired FME moves back).

    "With the method": hysteresis ε₁, ε₂ and the cosine blend over t_f − t₀ = ρ ‖M_Free −
    M_Stiff‖_F (eqs. 6.16–6.19). "Without": eq. 6.15 with one threshold ε = ε₁ and an
    instantaneous switch. Reported per 1 ms tick, after `settle`:

    - the desired FME M_des(t) = Ω M_Free + (1 − Ω) M_Stiff (eq. 6.16) and ‖ΔM_des‖_F;
    - the null-space control signal τ_S = −β ∂ν/∂q (eq. 6.6) along the logged configuration,
      and its jump caused by the change of M_des alone, β‖∇ν(q_k; M_k+1) − ∇ν(q_k; M_k)‖;
    - the applied null-space torque τ_N = (I − JᵀJ#ᵀ)τ of the commanded torque (after the
      force scaling and the torque box);
    - the force disturbance at the handle, |F_sensor − F_commanded| along u.

    What we find, and why it differs from the thesis's Fig. 6.11: the method bounds the
    per-tick change of M_des (by π Δt/(2ρ)) and removes the jump of τ_S, as the thesis
    says. The thesis also shows less interference with the handle's motion and force. In
    our simulation that part is not reproduced: with the thesis's β = 20, −β∂ν/∂q exceeds
    the torque box for most of a reconfiguration, so the applied τ_N is bounded by the
    actuators in both variants (per-tick ‖Δτ_N‖ alike) and the reconfiguration from the
    M_Free^des to the M_Stiff^des optimum runs at saturated torque either way; the
    handle-force disturbance is then not smaller with the method (its largest value comes
    from q4 reaching its −20° limit at speed while the hand releases). `compare_beta`
    (default 2) repeats both variants at a gain whose null-space torque mostly stays inside
    the box: there the method lowers the applied τ_N jumps, but the largest handle
    disturbances of both variants occur in the saturated phase after the blend, not at the
    switch, so the handle-force comparison stays inconclusive. The thesis's hardware
    gradient scale is unknown; its β = 20 is the default.

    Args:
        settle, depth, speed, hold, release: the hand's motion ([s], [m], [m/s], [s], [s]).
        hand_stiffness, hand_damping: the hand's grip [N/m], [N s/m].
        eps1, eps2, rho: thresholds and duration factor [s] of eqs. 6.17–6.19.
        beta: FME gradient step β of eq. 6.6 (thesis: 20).
        compare_beta: a second β run for comparison (None: skip).
        starts: starts of the static M_Free^des matching (`best_match`).
        limits: add the joint-limit barrier to the controller.
        progress: callback(done, total) in control ticks.
    """
    _check_motion(settle=settle, depth=depth, speed=speed, hold=hold, release=release)
    for name, v in (("beta", beta), ("compare_beta", 1.0 if compare_beta is None else compare_beta)):
        if not np.isfinite(v) or v <= 0:
            raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
    dev = device("rhi4")
    u, x0 = np.array(U), np.array(X0)
    _, _, Mf, Ms = desired_fmes(dev, u, Q_HOME)
    duration = settle + 2 * depth / speed + hold + release
    ticks = int(round(duration * 1000.0))
    betas = [beta] + ([] if compare_beta is None else [compare_beta])
    total = 2 * ticks * len(betas)
    motion = dict(settle=settle, depth=depth, speed=speed, hold=hold, stiffness=hand_stiffness,
                  damping=hand_damping, duration=duration)
    variants = {
        "with": TransitionConfig(eps1=eps1, eps2=eps2, rho=rho, S=ASO_S),
        "without": TransitionConfig(eps1=eps1, eps2=eps1, rho=0.0, S=ASO_S),
    }
    arrays: dict[str, np.ndarray] = {"M_free_des": Mf, "M_stiff_des": Ms, "settle": np.array(settle)}
    out: dict[tuple[float, str], dict[str, float]] = {}
    for j, b in enumerate(betas):
        q_start = best_match(dev, x0, WeightedSum(controller_terms(Mf, dev.torque_max, limits=limits, beta=b)),
                             starts=starts)
        for i, (name, tc) in enumerate(variants.items()):
            offset = (2 * j + i) * ticks
            metrics, arr = _transition_run(dev, Mf, Ms, tc, b, q_start, motion, rho * float(np.linalg.norm(Mf - Ms)),
                                           limits, progress, offset, total)
            out[b, name] = metrics
            if j == 0:
                arrays.update({f"{k}_{name}": v for k, v in arr.items()})
                arrays["q_start"] = q_start
    dist = float(np.linalg.norm(Mf - Ms))
    bound = np.pi * 1e-3 / (2.0 * rho) if rho > 0 else np.inf
    w, wo = out[beta, "with"], out[beta, "without"]
    rows = [
        Row("full transition time t_f − t₀ = ρ‖M_Free − M_Stiff‖_F", THESIS_TF, rho * dist, "s",
            "thesis: ρ = 0.003 'so that the transition performed in 0.5 second'"),
        Row("max per-tick ‖ΔM_des‖_F, with the method", None, w["dM"], "N²/(N m)²",
            f"bound π Δt/(2ρ) = {bound:.3f} (Δt = 1 ms)"),
        Row("max per-tick ‖ΔM_des‖_F, without (eq. 6.15)", None, wo["dM"], "N²/(N m)²",
            f"‖M_Free − M_Stiff‖_F = {dist:.1f}: the whole change in one tick"),
        Row("max per-tick jump of τ_S = −β∂ν/∂q from the M_des change, with", None, w["jump"], "N m"),
        Row("max per-tick jump of τ_S from the M_des change, without", None, wo["jump"], "N m"),
        Row("desired-FME switches (Ω crossing ½), with", None, w["switches"], ""),
        Row("desired-FME switches (Ω crossing ½), without", None, wo["switches"], ""),
        Row("time Ω first leaves 1, with the method", None, w["first"], "s"),
        Row("time spent blending (0 < Ω < 1), with the method", None, w["blend"], "s"),
        Row("V min, with the method", None, w["V_min"], ""),
        Row("V max, with the method", None, w["V_max"], ""),
    ]
    for b in betas:
        tag = f" (β = {b:g})"
        bw, bwo = out[b, "with"], out[b, "without"]
        rows += [
            Row("max per-tick ‖Δτ_N‖ of the applied null-space torque, with" + tag, None, bw["dtau_n"], "N m",
                "after the force scaling and the torque box"),
            Row("max per-tick ‖Δτ_N‖ of the applied null-space torque, without" + tag, None, bwo["dtau_n"], "N m"),
            Row("max handle-force disturbance |F_sensor − F_commanded| along u, with" + tag, None,
                bw["disturbance"], "N", "over the whole run after settling"),
            Row("max handle-force disturbance, without" + tag, None, bwo["disturbance"], "N"),
            Row("RMS handle-force disturbance, with" + tag, None, bw["disturbance_rms"], "N"),
            Row("RMS handle-force disturbance, without" + tag, None, bwo["disturbance_rms"], "N"),
            Row("max disturbance within ρ‖ΔM‖_F after the first switch, with" + tag, None, bw["dist_w"], "N"),
            Row("max disturbance within ρ‖ΔM‖_F after the first switch, without" + tag, None, bwo["dist_w"], "N"),
            Row("peak sensor force along u, with" + tag, None, bw["peak"], "N"),
            Row("peak sensor force along u, without" + tag, None, bwo["peak"], "N"),
        ]
    notes = [
        "Without the method: eq. 6.15 with one threshold ε = ε₁ and an instantaneous switch (ρ = 0).",
        "τ_S is the FME term of eq. 6.6 along the logged configuration; its jump from the M_des change "
        "alone is evaluated at the frozen configuration of the tick. τ_N is the applied null-space torque "
        "(dynamically consistent J#), which the force scaling and the torque box bound in both variants.",
        f"With the thesis's β = {beta:g} the null-space torque saturates the actuators during a reconfiguration: "
        "the method removes the jump of τ_S and bounds ΔM_des per tick, but the applied τ_N is bounded by the "
        "torque box in both variants and the handle-force disturbance is not smaller with the method"
        + ("." if compare_beta is None else
           f"; at β = {compare_beta:g} (rows 'β = {compare_beta:g}') the applied τ_N jumps are smaller with it, while "
           "the largest handle disturbances of both variants occur in the saturated phase after the blend.")
        + " The thesis shows Fig. 6.11 as curves only.",
    ]
    return Result(
        "ch6.transition",
        "Fig. 6.11: switching the desired FME by the ASO with (cosine blend, hysteresis) and without the method",
        [Table("Fig. 6.11 transition (ε₁ = 0.7, ε₂ = 0.95, ρ = 0.003)", rows)],
        arrays,
        notes,
    )


def _transition_run(dev: Device, Mf: np.ndarray, Ms: np.ndarray, tc: TransitionConfig, beta: float,
                    q_start: np.ndarray, motion: dict, window: float, limits: bool, progress: Progress | None,
                    offset: int, total: int) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """One simulated push–hold–release with an ASO-switched desired FME: (metrics, arrays) of `transition`.

    `window` [s] is the span after the first tick with Ω < 1 over which the disturbance is
    also reported (the blend's duration, the same for both variants).
    """
    u, x0 = np.array(U), np.array(X0)
    schedule = FMESchedule(Mf, Ms, gain=beta, transition=tc)
    ctrl = _palpation_controller(dev, None, schedule, limits=limits)
    hand = _InOut(x0, u, motion["depth"], motion["speed"], motion["settle"], motion["hold"], motion["stiffness"],
                  motion["damping"])
    log = _run(dev, ctrl, hand, q_start, motion["duration"], progress, offset, total)
    if log.fault is not None:
        raise InvalidInput(f"transition: the controller stopped: {log.fault}")
    settle = motion["settle"]
    fme = FMEMatching(Mf, dev.torque_max)
    J, M, dJ = dev.jacobian(log.q), dev.mass_matrix(log.q), dev.jacobian_derivative(log.q)
    tau_n = np.einsum("kij,kj->ki", nullspace_projector(J, M), log.tau)
    om = log.omega
    Mdes = om[:, None, None] * Mf + (1.0 - om[:, None, None]) * Ms
    tau_s = np.array([-beta * fme.gradient_from(J[k], dJ[k], Mdes[k]) for k in range(len(om))])
    jump = np.zeros(len(om) - 1)
    for k in np.flatnonzero(np.diff(om) != 0):  # the part of Δτ_S caused by the new M_des alone
        jump[k] = beta * np.linalg.norm(fme.gradient_from(J[k], dJ[k], Mdes[k + 1]) -
                                        fme.gradient_from(J[k], dJ[k], Mdes[k]))
    after = log.t[1:] >= settle
    dM = np.linalg.norm(np.diff(Mdes, axis=0), axis=(1, 2))
    dtau_n = np.linalg.norm(np.diff(tau_n, axis=0), axis=1)
    f_u = -_smooth(log.ft[:, :2], 20) @ u
    f_cmd = -log.alpha * K_E * np.maximum((dev.fk(log.q) - x0) @ u, 0.0)
    err = np.abs(f_u - f_cmd)
    dist_f = err[log.t >= settle]
    moved = np.flatnonzero(om < 1.0)
    if moved.size:
        t0 = log.t[moved[0]]
        dist_w = err[(log.t >= t0) & (log.t <= t0 + window + 1e-9)]
    else:
        dist_w = np.zeros(1)
    metrics = {
        "dM": float(dM[after].max()), "jump": float(jump[after].max()), "dtau_n": float(dtau_n[after].max()),
        "V_min": float(np.nanmin(log.V)), "V_max": float(np.nanmax(log.V)),
        "switches": float(np.count_nonzero(np.diff((om < 0.5).astype(int)))), "peak": float(f_u.min()),
        "disturbance": float(dist_f.max()), "disturbance_rms": float(np.sqrt(np.mean(dist_f**2))),
        "dist_w": float(dist_w.max()),
        "first": float(log.t[moved[0]]) if moved.size else np.nan,
        "blend": float(np.count_nonzero((om > 1e-12) & (om < 1 - 1e-12))) * 1e-3,
    }
    arrays = {
        "t": log.t, "V": log.V, "omega": om, "tau": log.tau, "tau_null": tau_n, "tau_s": tau_s,
        "M_des": Mdes.reshape(len(om), -1)[:, [0, 1, 3]], "dM": dM, "jump": jump, "dtau_null": dtau_n,
        "force": f_u, "force_cmd": f_cmd, "x": log.x, "q": log.q, "alpha": log.alpha,
    }
    return metrics, arrays


def _check_motion(**kw: float) -> None:
    """Raise InvalidInput naming the first hand-motion parameter that is not finite and >= 0 (> 0 for depth, speed)."""
    for name, v in kw.items():
        strict = name in ("depth", "speed")
        if not np.isfinite(v) or v < 0 or (strict and v == 0):
            raise InvalidInput(f"{name}: must be finite and {'> 0' if strict else '>= 0'}, got {v!r}")


@dataclasses.dataclass(frozen=True)
class _InOut:
    """The transition's hand: hold X₀, push in by `depth`, hold, come back to X₀ (a `Hand` per phase)."""

    x0: np.ndarray
    u: np.ndarray
    depth: float
    speed: float
    settle: float
    hold: float
    stiffness: float
    damping: float

    def __post_init__(self) -> None:
        t_in = self.depth / self.speed
        tip = self.x0 + self.depth * self.u
        object.__setattr__(self, "_in", _hand([self.x0, tip], self.speed, self.settle, self.stiffness, self.damping))
        object.__setattr__(self, "_out", _hand([tip, self.x0], self.speed, self.settle + t_in + self.hold,
                                               self.stiffness, self.damping))
        object.__setattr__(self, "_switch", self.settle + t_in + self.hold)

    def force(self, t: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        return (self._in if t < self._switch else self._out).force(t, x, xdot)


# ------------------------------------------------------------------------ F_max ratio map
_DEV: dict[str, Device] = {}


def _rhi4() -> Device:
    if "rhi4" not in _DEV:
        _DEV["rhi4"] = device("rhi4")
    return _DEV["rhi4"]


def _ratio_row(y: float, xs: np.ndarray, starts: int, limits: bool) -> np.ndarray:
    """(6, len(xs)): F_max by scaling and LP and Λ (free, stiff) along the grid row at height y [m].

    Every point is matched independently from the same deterministic starts (`best_match`),
    so a row's values do not depend on which process computes it. NaN where unreachable.
    """
    dev = _rhi4()
    lo, hi = dev.torque_limits
    u = np.array(U)
    _, _, Mf, Ms = _desired_rhi4()
    objs = [WeightedSum(controller_terms(D, hi, limits=limits)) for D in (Mf, Ms)]
    out = np.full((6, len(xs)), np.nan)
    for i, x in enumerate(xs):
        try:
            qs = start_configurations(dev, (x, y), starts)
        except Unreachable:
            continue
        for c, obj in enumerate(objs):
            try:
                q = best_match(dev, (x, y), obj, starts=qs)
            except Unreachable:
                break
            J, M = dev.jacobian(q), dev.mass_matrix(q)
            if np.linalg.svd(J, compute_uv=False)[-1] < 1e-3:
                break
            out[c, i] = max_force_scaling(J, u, torque_min=lo, torque_max=hi)
            out[2 + c, i] = max_force(J, u, torque_min=lo, torque_max=hi, M=M)
            out[4 + c, i] = effective_inertia(J, M, u)
        else:
            continue
        out[:, i] = np.nan
    return out


@functools.lru_cache(maxsize=1)
def _desired_rhi4() -> tuple[float, float, np.ndarray, np.ndarray]:
    """`desired_fmes` of rhi4 for u = [0, 1] from the home configuration, once per process."""
    return desired_fmes(_rhi4(), np.array(U), Q_HOME)


def fmax_ratio_map(
    resolution: int = 25,
    progress: Progress | None = None,
    *,
    starts: int = 2,
    limits: bool = True,
    executor=None,
    workers: int | None = None,
) -> Result:
    """Fig. 6.10: F_max along u = [0, 1] with the M_Stiff^des configuration over that with the M_Free^des one.

    At each grid point of x ∈ [0.25, 0.75] m, y ∈ [−0.5, 0.3] m, rhi4's configuration is
    FME-matched (`best_match`, the palpation controller's cost) to M_Free^des and to
    M_Stiff^des, and F_max along u is evaluated at both by force scaling (the ch. 6
    controller) and by the LP with null-space torques. Rows go through
    `rhi.design.executors.parallel_map` (one row per task), so the map is bit-identical on
    every executor.

    Args:
        resolution: grid points per axis.
        progress: callback(done, total) in grid points, after each finished row.
        starts: starts per matching (`best_match`).
        limits: include the joint-limit barrier in the matched cost.
        executor, workers: where to run (`rhi.design.executors.using`).
    """
    if not isinstance(resolution, int) or resolution < 2:
        raise InvalidInput(f"resolution: must be an integer >= 2, got {resolution!r}")
    if not isinstance(starts, int) or starts < 1:
        raise InvalidInput(f"starts: must be an integer >= 1, got {starts!r}")
    xs = np.linspace(*MAP_X, resolution)
    ys = np.linspace(*MAP_Y, resolution)
    fn = functools.partial(_ratio_row, xs=xs, starts=starts, limits=limits)
    rows = parallel_map(fn, list(ys), executor=executor, workers=workers, progress=progress,
                        units=[resolution] * resolution)
    data = np.stack(rows, axis=1)  # (6, ny, nx)
    fs_free, fs_stiff, lp_free, lp_stiff, lam_free, lam_stiff = data
    ratio = fs_stiff / fs_free
    ratio_lp = lp_stiff / lp_free
    ok = np.isfinite(ratio)

    def stat(fn_, a):
        return float(fn_(a)) if a.size else np.nan

    r, rl = ratio[ok], ratio_lp[ok]
    rows_out = [
        Row("grid points reached", None, float(ok.sum())),
        Row("fraction of points with F_max(M_Stiff) > F_max(M_Free), force scaling", None,
            stat(np.mean, r > 1.0), "", "thesis: larger 'over the entire workspace'"),
        Row("min ratio F_Stiff/F_Free, force scaling", None, stat(np.min, r)),
        Row("median ratio, force scaling", None, stat(np.median, r)),
        Row("max ratio, force scaling", None, stat(np.max, r)),
        Row("fraction of points with ratio > 1, LP with null-space torques", None, stat(np.mean, rl > 1.0)),
        Row("median ratio, LP", None, stat(np.median, rl)),
        Row("median Λ ratio Λ_Stiff/Λ_Free", None, stat(np.median, (lam_stiff / lam_free)[ok])),
    ]
    return Result(
        "ch6.fmax_ratio_map",
        "Fig. 6.10: F_max ratio M_Stiff^des vs M_Free^des configurations over rhi4's workspace, u = [0, 1]",
        [Table("Fig. 6.10 F_max ratio", rows_out)],
        {"x": xs, "y": ys, "ratio": ratio, "ratio_lp": ratio_lp, "fs_free": fs_free, "fs_stiff": fs_stiff,
         "lp_free": lp_free, "lp_stiff": lp_stiff, "lam_free": lam_free, "lam_stiff": lam_stiff},
        ["The thesis shows Fig. 6.10 as a map only; we report its extremes and the fraction of points "
         "where M_Stiff^des gives more force.",
         f"Configurations: `best_match` with {starts} start(s) per point, joint limits respected"
         + (", joint-limit barrier in the cost." if limits else ".")],
    )
