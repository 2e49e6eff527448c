"""The §6.3–6.4 set-up: constants, desired FMEs, the FME-matching cost and configurations, the palpation controller.

See `rhi.experiments.ch6` for the choices the thesis leaves open.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from rhi import thesis as T
from rhi.control import (
    ControllerConfig,
    FMEMatching,
    FMESchedule,
    JointLimitBarrier,
    NullSpaceController,
    ObjectiveTerm,
    SpringPalpation,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.control.allocation import Saturation
from rhi.control.configuration import null_space_descent
from rhi.devices.model import Device
from rhi.errors import Unreachable
from rhi.metrics import nullspace_projector
from rhi.metrics.force import ProjectorKind
from rhi.sim import device_friction

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
#: Joint-limit barrier of the simulated controller (our choice, see `rhi.experiments.ch6`).
LIMIT_MARGIN = 0.1
LIMIT_GAIN = 100.0
#: Grid of the F_max ratio map (the rhi4 region of Fig. 7.5's map) [m].
MAP_X = (0.25, 0.75)
MAP_Y = (-0.5, 0.3)

CASES = ("free", "stiff")
NullSpace = Literal["scaled", "clipped"]


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
def match_fme(dev: Device, x, objective, q0, *, max_iter: int = 3000) -> np.ndarray:
    """The configuration the null-space controller converges to from q0 with the end-effector at x.

    Follows the gradient-projection flow of eqs. 6.3–6.6 down the objective's ν(q) along the
    self-motion manifold f(q) = x, sliding along the joint limits it meets, and settles it with
    SLSQP (ftol 1e-12): `rhi.control.configuration.null_space_descent`, from q0 projected onto
    f(q) = x without null-space motion. It ends in q0's basin: a minimiser over the whole manifold
    (what SLSQP alone from q0 may jump to) can lie in a basin the controller never reaches.

    Args:
        dev: the device.
        x: (m,) end-effector position [m].
        objective: `value(device, q)`, `gradient(device, q)` (e.g. `FMEMatching`, `WeightedSum`).
        q0: (n,) start configuration [rad].
        max_iter: flow steps at most.

    Returns:
        q: (n,) [rad] within the limits with f(q) = x (1e-9 m); never worse than the start.

    Raises:
        Unreachable: x cannot be reached within the limits from q0.
    """
    return null_space_descent(dev, x, objective, np.asarray(q0, dtype=float), tol=1e-12, max_iter=max_iter)


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
        dev: the device.
        x: (m,) end-effector position [m].
        objective: `value(device, q)`, `gradient(device, q)` (as `match_fme`).
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
        J: (m, n) Jacobian [m/rad].
        M: (n, n) inertia [kg m²].
        D: (n,) joint damping [N m s/rad].
        u: (m,) direction.
        k_d: null-space damping [N m s/rad].
    """
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    N = nullspace_projector(J, M)
    Jt_u = J.T @ u
    return float(1.0 / (Jt_u @ np.linalg.solve(np.diag(D) + k_d * N, Jt_u)))


# ----------------------------------------------------------------------- simulated palpation
def palpation_controller(dev: Device, desired: np.ndarray | None, schedule: FMESchedule | None = None,
                         *, limits: bool = True, beta: float = BETA, projector: ProjectorKind = "dynamic",
                         objectives: tuple[ObjectiveTerm, ...] = (), x0=X0, u=U, gravity: bool = False,
                         saturation: Saturation = "scaling", null_space: NullSpace | None = None) -> NullSpaceController:
    """Spring palpation (eq. 6.21) with force scaling; FME matching to `desired` or by the ASO `schedule`.

    Args:
        dev: rhi4 (or another RHI: the spatial srhi5 with a 3-D x0 and u).
        desired: (m, m) desired FME of the matching term (None: no FME-matching term).
        schedule: the ASO-driven `FMESchedule` (eqs. 6.14–6.19), or None.
        limits: add the joint-limit barrier (`BARRIER`, gain `LIMIT_GAIN`) after the other terms.
        beta: β of the FME-matching term (of the schedule's too).
        projector: "dynamic" (J#, eq. 6.6 as the thesis writes it) or "pseudoinverse" (J⁺).
        objectives: further null-space terms before the barrier (e.g. an intent-driven FME term).
        x0: (m,) the spring's rest point [m] (§6.4: X₀ = [0.5, 0.1] m).
        u: (m,) its direction (§6.4: u = [0, 1]).
        gravity: compensate G_x in the primary law (eq. 6.21 has none: rhi4 moves in a horizontal plane).
        saturation: allocation under the torque limits ("scaling", §6.3.1; or "ascm", ch. 7).
        null_space: "clipped" (eqs. 6.2–6.6 as written: τ_m + (I − JᵀJ#ᵀ)τ_S, each joint clipped at its
            programmed limit) or "scaled" (chapter 7's Algorithm 2 scales τ_S into the box); None: the law
            that goes with `saturation`, "clipped" with force scaling (chapter 6), "scaled" otherwise (ASCM's
            chapter 7).
    """
    if null_space is None:
        null_space = "clipped" if saturation == "scaling" else "scaled"
    law = SpringPalpation(K_E, tuple(x0), normal=tuple(u), damping=0.0, coriolis=False, gravity=gravity,
                          passivity=None)
    terms = list(objectives)
    if desired is not None:
        terms += controller_terms(desired, dev.torque_max, limits=False, beta=beta)
    if limits:
        terms.append(ObjectiveTerm(BARRIER, LIMIT_GAIN))
    if schedule is not None:
        terms.append(ObjectiveTerm(schedule, beta))
    cfg = ControllerConfig(primary=law, objectives=tuple(terms), damping=K_D, saturation=saturation,
                           projector=projector, aso_shape=ASO_S, null_space=null_space)
    return NullSpaceController(dev, cfg)


def plant_damping(dev: Device) -> np.ndarray:
    """Motor viscous damping of the plant (device.toml [plant]): (n,) [N m s/rad]."""
    return np.asarray(device_friction(dev).damping, dtype=float)
