"""Weighted motion distribution with directional-manipulability (DM) enhancement, at the velocity level (thesis App. A).

The weighted pseudoinverse J† = W_x Jᵀ(J W_x Jᵀ)⁻¹ of the wheel-velocity Jacobian
J = [J_b P, J_m] (eqs. A.5, A.11) with the motion-distribution weight γ (A.12–A.15) driven
by the arm's local velocity limits (A.13); the directional manipulability H₂ (A.8) of the
arm enhanced in Cartesian space (A.17–A.18) or in the null space (A.19–A.20). The
"traditional" baseline is the plain pseudoinverse J⁺ (§A.4.2, ``distribution="pinv"``).

Frames: J_m is the position Jacobian of the arm columns expressed in the world frame (as
``Device.jacobian`` returns it), so a world direction u needs no rotation J_I⁻¹ (§A.4.3
writes u = J_I⁻¹[1, 0, 0]ᵀ for J_m in the base frame; the two are the same DM).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np

from rhi._validate import as_array, unit_vector
from rhi.control.mobile.bounds import (
    EPS,
    JointBounds,
    check_dt,
    joint_bounds,
    scale_factor,
    velocity_bounds_unchecked,
)
from rhi.control.mobile.kinematics import check_base, check_vector, gram_inverse
from rhi.control.mobile.measures import dm_cartesian_gradient, dm_gradient, dm_value
from rhi.control.mobile.protocol import MobileStep
from rhi.devices.mobile_base import mecanum_map, wheel_geometry, wheel_jacobian
from rhi.devices.model import Device, DeviceTerms
from rhi.errors import InfeasibleLimits, InvalidInput

#: An arm joint whose local velocity bound (A.13) toward its position bound is below this [rad/s] is at that bound.
HELD = 1e-6
#: App. A.4.3: W_τ = diag(1, 1, 1, 1, 2.5, 2.5, 2.5) = diag(1/τ_lim) with τ_lim below.
W_TAU_LIMITS = (1.0, 1.0, 1.0, 1.0, 0.4, 0.4, 0.4)


def motion_weights(gamma: float, n_base: int, n_arm: int) -> np.ndarray:
    """Diagonal of the motion-distribution weight W_x = diag(γ I_b, (1 − γ) I_m) (thesis eq. A.12).

    Args:
        gamma: γ ∈ [0, 1]: 0 gives all motion to the arm, 1 all to the base.
        n_base: b, number of base inputs (4 wheels for the Mecanum base).
        n_arm: m, number of arm joints.

    Returns:
        (b + m,) diagonal of W_x.
    """
    g = float(gamma)
    if not 0.0 <= g <= 1.0:
        raise InvalidInput(f"gamma: must lie in [0, 1], got {gamma!r}")
    return np.concatenate([np.full(n_base, g), np.full(n_arm, 1.0 - g)])


def weighted_pinv_psd(J, w) -> np.ndarray:
    """Weighted pseudoinverse J† = W Jᵀ(J W Jᵀ)⁻¹ with a diagonal W ⪰ 0 (thesis eq. A.11).

    Computed as W^½ (J W^½)⁺, which equals the thesis's formula wherever J W Jᵀ is
    invertible and stays defined where it is not (γ = 1 leaves only the base, which cannot
    move the end-effector vertically: that component is then dropped in the least-squares
    sense instead of dividing by zero).

    Args:
        J: (..., r, n) Jacobian.
        w: (..., n) diagonal of W, entries ≥ 0.

    Returns:
        (..., n, r) J†, with J J† = I where J W Jᵀ has full rank.
    """
    J = as_array("J", J, ndim_min=2)
    w = as_array("w", w, shape_tail=(J.shape[-1],))
    if (w < 0).any():
        raise InvalidInput("w: weights must be >= 0")
    s = np.sqrt(w)
    return s[..., :, None] * np.linalg.pinv(J * s[..., None, :], rcond=1e-10)


def distribution_ratio(dq_m, dq_min, dq_max) -> np.ndarray:
    """η = max_i |q̇_m,i| / |Q̇_bound,i|, the arm's use of its velocity limits (thesis eq. A.15).

    Each joint is compared with the bound in the direction it moves (the thesis's formula
    takes both bounds; with symmetric limits away from a position bound they agree, and
    near one the side the joint moves away from must not count). A joint moving toward a
    zero bound gives η = inf.

    Args:
        dq_m: (..., m) arm joint velocities [rad/s].
        dq_min: (..., m) local lower bounds of eq. A.13 [rad/s].
        dq_max: (..., m) local upper bounds of eq. A.13 [rad/s].

    Returns:
        (...,) η ≥ 0.
    """
    dq_m = np.asarray(dq_m, dtype=float)
    bound = np.where(dq_m >= 0, dq_max, -np.asarray(dq_min, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(np.abs(dq_m) > 0, np.abs(dq_m) / np.abs(bound), 0.0)
    return np.max(r, axis=-1)


def distribution_gamma(eta, epsilon: float) -> np.ndarray:
    """γ = 0 if η ≤ ε, η if ε < η ≤ 1, 1 if η > 1 (thesis eq. A.14).

    Args:
        eta: (...,) η of eq. A.15.
        epsilon: ε ∈ [0, 1), largest η the arm handles alone.
    """
    eps = float(epsilon)
    if not 0.0 <= eps < 1.0:
        raise InvalidInput(f"epsilon: must lie in [0, 1), got {epsilon!r}")
    eta = np.asarray(eta, dtype=float)
    return np.where(eta <= eps, 0.0, np.minimum(eta, 1.0))


@dataclasses.dataclass(frozen=True)
class DMConfig:
    """Directional manipulability enhancement (thesis §A.3.1, §A.3.3, §A.4.3).

    Attributes:
        u: (3,) world direction of the force to enhance (normalised).
        torque_limits: (m,) τ_lim of W_τ = diag(1/τ_lim) [N m] (thesis: W_τ = diag(1,1,1,1,2.5,2.5,2.5)).
        k_c: Cartesian gain k_C of eq. A.18 (thesis 0.01).
        k_n: null-space gain k_N of eq. A.20 (thesis k_H = 0.2).
        axes: Cartesian components optimised by eq. A.18 (thesis: "z" only); the others get 0.
        x_min, x_max: (len(axes),) position bounds of those components [m] (thesis z ∈ [0.36, 0.56]).
        gradient: eq. A.9's factor: "exact" (−½ s^(−3/2) = −½ H₂³, the derivative of H₂) or
            "printed" (−½ H₂^(−3/2) as eq. A.9 prints it: the exact gradient times H₂^(−4.5)).
    """

    u: tuple[float, ...] = (0.0, 0.0, 1.0)
    torque_limits: tuple[float, ...] = W_TAU_LIMITS
    k_c: float = 0.01
    k_n: float = 0.2
    axes: str = "z"
    x_min: tuple[float, ...] = (0.36,)
    x_max: tuple[float, ...] = (0.56,)
    gradient: Literal["exact", "printed"] = "exact"

    def __post_init__(self) -> None:
        if self.gradient not in ("exact", "printed"):
            raise InvalidInput(f"gradient: expected 'exact' or 'printed', got {self.gradient!r}")
        object.__setattr__(self, "u", tuple(unit_vector("u", self.u, 3)))
        t = as_array("torque_limits", self.torque_limits, ndim_min=1)
        if (t <= 0).any():
            raise InvalidInput("torque_limits: every entry must be > 0")
        if not self.axes or any(a not in "xyz" for a in self.axes) or len(set(self.axes)) != len(self.axes):
            raise InvalidInput(f"axes: expected distinct axes from 'xyz', got {self.axes!r}")
        lo = as_array("x_min", self.x_min, shape_tail=(len(self.axes),))
        hi = as_array("x_max", self.x_max, shape_tail=(len(self.axes),))
        if (lo > hi).any():
            raise InfeasibleLimits(f"x_min > x_max: {lo.tolist()} > {hi.tolist()}")
        for name in ("k_c", "k_n"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0:
                raise InvalidInput(f"{name}: must be finite and >= 0, got {v!r}")


def _factor(d: DMConfig, h: float) -> float:
    """1 for the exact A.9 gradient, H₂^(−4.5) for the factor as printed (see `DMConfig.gradient`)."""
    return 1.0 if d.gradient == "exact" else h**-4.5


@dataclasses.dataclass(frozen=True)
class WeightedConfig:
    """Parameters of the App. A velocity-level controller.

    Attributes:
        dt: sampling time T of eq. A.13 [s].
        k_x: K_x of eq. A.19 [1/s] (thesis 10).
        epsilon: ε of eq. A.14 (thesis 0.2).
        distribution: "weighted" (W_x with adaptive γ, eqs. A.11–A.15), "pinv" (the
            traditional plain pseudoinverse J⁺ of the wheel-speed Jacobian, §A.4.2) or
            "pinv_generalized" (J_q⁺ of the generalized Jacobian [J_b, J_m], base in m/s and
            rad/s, mapped to the wheels by P⁺: the pseudoinverse's split depends on the base's units).
        null_space: projector of the DM null-space stage (see
            `WeightedDistributionController._null_motion`): "generalized" (default; reproduces
            the thesis's §A.4.3 numbers) or "weighted" (eq. A.19 as printed).
        weighting: the Jacobian W_x weights (``distribution="weighted"``): "wheel" (eqs. A.11–A.12
            as printed: J = [J_b P, J_m], b = 4 wheel speeds) or "generalized" (J_q = [J_b, J_m],
            n_b = 3 base velocities; §B.2: for a holonomic base both Jacobians "can be utilized").
        dm: directional manipulability enhancement, or None.
        bounds: joint bounds of the generalized coordinates [x_b, y_b, θ_b, q_m]; None: the device's.
        geometry: Mecanum geometry {wheel_radius, half_length, half_width} [m]; None: the device's.
    """

    dt: float = 0.01
    k_x: float = 10.0
    epsilon: float = 0.2
    distribution: Literal["weighted", "pinv", "pinv_generalized"] = "weighted"
    null_space: Literal["generalized", "weighted"] = "generalized"
    weighting: Literal["wheel", "generalized"] = "wheel"
    dm: DMConfig | None = None
    bounds: JointBounds | None = None
    geometry: dict | None = None

    def __post_init__(self) -> None:
        check_dt(self.dt)
        if self.distribution not in ("weighted", "pinv", "pinv_generalized"):
            raise InvalidInput(
                f"distribution: expected 'weighted', 'pinv' or 'pinv_generalized', got {self.distribution!r}")
        if self.weighting not in ("wheel", "generalized"):
            raise InvalidInput(f"weighting: expected 'wheel' or 'generalized', got {self.weighting!r}")
        if self.null_space not in ("generalized", "weighted"):
            raise InvalidInput(f"null_space: expected 'generalized' or 'weighted', got {self.null_space!r}")
        if not math.isfinite(self.k_x) or self.k_x < 0:
            raise InvalidInput(f"k_x: must be finite and >= 0, got {self.k_x!r}")
        distribution_gamma(0.0, self.epsilon)  # validates epsilon


@dataclasses.dataclass(frozen=True)
class VelocityCommand:
    """One velocity-level command of the App. A controller.

    Attributes:
        v: (b + m,) [wheel speeds (4) [rad/s]; arm joint rates [rad/s]] (eq. A.5).
        dq: (n,) generalized velocities (ẋ_b, ẏ_b, θ̇_b, q̇_m) = (P v_b; v_m) [m/s, rad/s].
        x: (3,) end-effector position from the kinematics [m].
        gamma: motion-distribution weight γ (A.14).
        eta: η of eq. A.15 (arm-only demand).
        dm: directional manipulability H₂ of the arm (NaN without a DMConfig) [N].
        clipped: whether a velocity bound had to be enforced on the command (the self-motion
            scaled down, or the command clipped).
    """

    v: np.ndarray
    dq: np.ndarray
    x: np.ndarray
    gamma: float
    eta: float
    dm: float
    clipped: bool


class WeightedDistributionController:
    """Weighted-pseudoinverse motion distribution with DM enhancement (thesis §A.3, eqs. A.11–A.20).

    Tracking (A.19 with v_n = 0): v = J†(ẋ_d + K_x(x_d − x)). γ comes from the arm-only
    solution (γ = 0): η (A.15) compares its arm rates with the local bounds of A.13, and
    γ (A.14) then weights the distribution (A.12). Stages:

    * ``"track"``: trajectory tracking only;
    * ``"dm_cartesian"``: v = J† v_c with v_c,i = k_C [∇_x H₂]_i inside the position bounds
      of the optimised axes, 0 otherwise (A.17–A.18);
    * ``"dm_null"``: tracking plus (I − J†J) v_n, v_n = k_N [0; ∇_{q_m}H₂ᵀ] (A.19–A.20).

    The command is kept within the arm's local velocity bounds (A.13) and the base's
    velocity bounds (Table B.1), which the thesis's law does not enforce: the self-motion
    of "dm_null" leaves out the joints at a position bound it pushes against (with the
    ``"generalized"`` projector), is scaled by the largest s ∈ [0, 1] that fits the bounds
    (the task stays exact), and what still exceeds a bound is clipped;
    `VelocityCommand.clipped` reports scaling or clipping.

    Args:
        device: the mobile manipulator (``rhi.device("wmm")``).
        config: parameters.
    """

    def __init__(self, device: Device, config: WeightedConfig | None = None) -> None:
        check_base(device, 3)
        self.device = device
        self.config = config or WeightedConfig()
        self.bounds = self.config.bounds if self.config.bounds is not None else joint_bounds(device)
        if self.bounds.n != device.n:
            raise InvalidInput(f"bounds: expected {device.n} joints, got {self.bounds.n}")
        self.geometry = dict(self.config.geometry or wheel_geometry(device))
        mecanum_map(0.0, **self.geometry)  # validates the geometry
        self.n_wheels = 4
        self.m = device.n - 3
        dm = self.config.dm
        if dm is not None and len(dm.torque_limits) != self.m:
            raise InvalidInput(f"dm.torque_limits: expected {self.m} entries, got {len(dm.torque_limits)}")

    def reset(self) -> None:
        """Nothing to reset: the controller keeps no state between samples."""

    def jacobian(self, q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, J, P): position (3,) [m], WMM Jacobian J = [J_b P, J_m] (3, 4 + m) (eq. A.5), P (3, 4) (eq. A.21)."""
        q = check_vector("q", q, self.device.n)
        terms = self.device.terms(q, check=False)
        P = mecanum_map(q[2], **self.geometry)
        return terms.x, wheel_jacobian(terms.J, P), P

    def dm(self, q) -> float:
        """H₂ of the arm at q (A.8) for the configured direction [N]."""
        return self._dm_terms(self.device.terms(check_vector("q", q, self.device.n), check=False))[1]

    def _dm_terms(self, terms: DeviceTerms) -> tuple[DMConfig, float, np.ndarray, np.ndarray]:
        """(config.dm, H₂, J_m, ∂J_m/∂q_m) of the arm from a terms snapshot (∂J/∂q from `Device.terms`)."""
        d = self.config.dm
        if d is None:
            raise InvalidInput("config.dm: no DMConfig given")
        Jm = terms.J[:, 3:]
        return d, float(dm_value(Jm, d.u, d.torque_limits)), Jm, terms.dJ[:, 3:, 3:]

    def advance(self, t: float, q, dq, x_des, dx_des, ddx_des, *, stage: str = "track") -> MobileStep:
        """One sample for `rhi.sim.mobile.simulate_mobile`: the velocity `step` commands (dq, ddx_des unused)."""
        cmd = self.step(t, q, x_des, dx_des, stage=stage)
        return MobileStep(cmd.dq, None, cmd.x, {"gamma": cmd.gamma, "eta": cmd.eta, "dm": cmd.dm})

    def _null_motion(self, J, Jq, P, Jp, grad_arm, held) -> np.ndarray:
        """(I − J†J) v_n, v_n = [0; k_N ∇_{q_m}H₂ᵀ] (eqs. A.19–A.20), as [wheel speeds; arm rates].

        ``null_space="weighted"``: the projector of the distribution's own J† (eq. A.19 as
        printed; at γ = 0 that J† has no base rows and the base cannot move).
        ``"generalized"``: the orthogonal projector of the generalized Jacobian
        J_q = [J_b, J_m] (eq. A.7 with Q = I), whose base motion is sent to the wheels as
        P⁺ q̇_b; the base then moves with the arm's self-motion. The arm joints `held` (at a
        position bound the gradient pushes against) take no part: their columns and entries
        are removed, so the other joints carry on the self-motion (saturation in the null
        space, Flacco et al. [51], which eq. A.13 cites).
        """
        if self.config.null_space == "weighted":
            v = np.concatenate([np.zeros(self.n_wheels), grad_arm])
            return v - Jp @ (J @ v)
        vq = np.concatenate([np.zeros(3), np.where(held, 0.0, grad_arm)])
        if held.any():
            Jq = Jq.copy()
            Jq[:, 3:][:, held] = 0.0
        Gi = gram_inverse(Jq, 0.0)
        vq = vq - Jq.T @ (Gi @ (Jq @ vq)) if Gi is not None else vq - np.linalg.pinv(Jq) @ (Jq @ vq)
        return np.concatenate([np.linalg.pinv(P) @ vq[:3], vq[3:]])

    def _weighted_pinv(self, gamma: float, J, Jq, P) -> np.ndarray:
        """J† of eq. A.11 at γ as a map to [wheel speeds; arm rates] (11, 3), for ``config.weighting``.

        "wheel": W_x = diag(γ I_4, (1 − γ) I_m) on J = [J_b P, J_m] (eqs. A.11–A.12 as printed);
        "generalized": W_x = diag(γ I_3, (1 − γ) I_m) on J_q = [J_b, J_m], the base part sent
        to the wheels as P⁺ q̇_b.
        """
        m = self.m
        if self.config.weighting == "wheel":
            return weighted_pinv_psd(J, motion_weights(gamma, self.n_wheels, m))
        Jg = weighted_pinv_psd(Jq, motion_weights(gamma, 3, m))
        return np.vstack([np.linalg.pinv(P) @ Jg[:3], Jg[3:]])

    def step(self, t: float, q, x_des=None, dx_des=None, *, stage: str = "track") -> VelocityCommand:
        """One control step.

        Args:
            t: time [s] (unused by the law; kept for a uniform controller interface).
            q: (n,) configuration [x_b, y_b, θ_b, q_m].
            x_des: (3,) desired position [m] (not used by "dm_cartesian").
            dx_des: (3,) desired velocity [m/s] (not used by "dm_cartesian").
            stage: "track", "dm_cartesian" or "dm_null".

        Returns:
            `VelocityCommand`.
        """
        c = self.config
        if stage not in ("track", "dm_cartesian", "dm_null"):
            raise InvalidInput(f"stage: expected 'track', 'dm_cartesian' or 'dm_null', got {stage!r}")
        if stage != "track" and c.dm is None:
            raise InvalidInput(f"stage: {stage!r} needs config.dm")
        q = check_vector("q", q, self.device.n)
        terms = self.device.terms(q, check=False)
        x, Jq = terms.x, terms.J  # generalized Jacobian [J_b, J_m] (3, n)
        P = mecanum_map(q[2], **self.geometry)
        J = wheel_jacobian(Jq, P)  # A.5
        nw = self.n_wheels
        h = math.nan
        grad = None
        if stage == "dm_cartesian":
            d, h, Jm, dJm = self._dm_terms(terms)
            gx = dm_cartesian_gradient(Jm, dJm, d.u, d.torque_limits) * _factor(d, h)  # A.10
            dx = np.zeros(3)
            for i, ax in enumerate(d.axes):
                k = "xyz".index(ax)
                if d.x_min[i] <= x[k] <= d.x_max[i]:
                    dx[k] = d.k_c * gx[k]  # A.18
        else:
            x_des = check_vector("x_des", x_des, 3)
            dx_des = check_vector("dx_des", dx_des, 3)
            dx = dx_des + c.k_x * (x_des - x)
            if stage == "dm_null":
                d, h, Jm, dJm = self._dm_terms(terms)
                grad = d.k_n * dm_gradient(Jm, dJm, d.u, d.torque_limits) * _factor(d, h)  # v_n of A.20, A.9
            elif c.dm is not None:
                h = float(dm_value(Jq[:, 3:], c.dm.u, c.dm.torque_limits))
        vlo, vhi = velocity_bounds_unchecked(q, self.bounds, c.dt)
        held = None if grad is None else (grad > 0) & (vhi[3:] <= HELD) | (grad < 0) & (vlo[3:] >= -HELD)
        gamma, eta = math.nan, math.nan
        if c.distribution == "pinv":
            Jp = np.linalg.pinv(J)
        elif c.distribution == "pinv_generalized":
            Jp = np.vstack([np.linalg.pinv(P) @ np.eye(3, self.device.n), np.eye(self.device.n)[3:]]) @ np.linalg.pinv(Jq)
        else:
            J0 = self._weighted_pinv(0.0, J, Jq, P)
            v0 = J0 @ dx
            if grad is not None:
                v0 = v0 + self._null_motion(J, Jq, P, J0, grad, held)
            eta = float(distribution_ratio(v0[nw:], vlo[3:], vhi[3:]))
            gamma = float(distribution_gamma(eta, c.epsilon))
            Jp = J0 if gamma == 0.0 else self._weighted_pinv(gamma, J, Jq, P)
        v = Jp @ dx
        null_scale = 1.0
        if grad is not None:
            vn = self._null_motion(J, Jq, P, Jp, grad, held)  # A.19
            # the self-motion is scaled down (as App. B's β, Fig. B.4) where it would drive a joint past
            # its bounds (A.13): clipping it instead would break the task (J v ≠ ẋ)
            null_scale, _ = scale_factor(np.r_[P @ vn[:nw], vn[nw:]], np.r_[P @ v[:nw], v[nw:]], lo=vlo, hi=vhi)
            v = v + null_scale * vn
        # enforce the bounds: arm rates (A.13), base generalized velocity (Table B.1)
        v_arm = np.clip(v[nw:], vlo[3:], vhi[3:])
        dqb = P @ v[:nw]
        ratio = np.max(np.abs(dqb) / np.maximum(np.abs(np.where(dqb >= 0, vhi[:3], vlo[:3])), EPS))
        clipped = bool(np.any(v_arm != v[nw:]) or ratio > 1.0 or null_scale < 1.0)
        if ratio > 1.0:
            v[:nw] /= ratio
            dqb = dqb / ratio
        v[nw:] = v_arm
        return VelocityCommand(v, np.concatenate([dqb, v_arm]), x, gamma, eta, h, clipped)
