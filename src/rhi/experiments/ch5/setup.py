"""The §5.4 set-up: devices, constants, plant friction, the null-space impedance controller, the W reference.

See `rhi.experiments.ch5` for the choices the thesis leaves open.
"""

from __future__ import annotations

import numpy as np

from rhi import thesis as T
from rhi.control import ControllerConfig, ImpedanceControl, NullSpaceController, ObjectiveTerm
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput
from rhi.experiments.setups import positive
from rhi.metrics import tmi
from rhi.sim import HandPath, PlantFriction, Probe, w_path

D2 = 0.1405  #: rehab link 2 length in chapter 5 [m] (§5.4)
Q_FIXED = np.array([-0.63, 0.25, 0.28, 0.09])  #: initial HI configuration of §5.4.1 [rad]
X_FIXED = (0.48, -0.35)  #: end-effector position of §5.4.1 [m] (FK of Q_FIXED: (0.4815, −0.3503))
B_D = 0.3  #: desired damping B^d = diag(0.3, 0.3) [N s/m] (§5.4.1, §5.4.2)
GAMMA = 0.01  #: joint uncertainty Γ = diag(0.01) [N m s/rad] (eq. 5.13)
K_Q = 10.0  #: shape of the joint-limit penalty (eq. 4.20); our choice, see `rhi.experiments.ch5`
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


def devices() -> dict[str, Device]:
    """The chapter-5 devices: RHI (rhi4, d2 = 0.1405 m), the 2-DoF Rehab and the slave.

    The Rehab is rhi4 with the PHANToM locked at q3 = q4 = 0 (same d2); the slave is the
    rehabilitation robot 2.0.
    """
    return {"RHI": device("rhi4", d2=D2), "Rehab": device("rehab", d2=D2), "slave": device("rehab_slave")}


def plant_friction(kind: str, dev: Device):
    """The plant friction of `kind`: "thesis" (Γ of eq. 5.13 only) or "device" (device.toml [plant])."""
    if kind == "thesis":
        return PlantFriction(np.full(dev.n, GAMMA), np.zeros(dev.n))
    if kind == "device":
        return "device"
    raise InvalidInput(f"friction: expected 'thesis' or 'device', got {kind!r}")



def controller(dev: Device, objective, gain: float, damping: float, *,
               extra: tuple[ObjectiveTerm, ...] = ()) -> NullSpaceController:
    """Eq. 5.9 with the impedance law of eq. 5.6 plus the null-space objective (eq. 5.10).

    F_m = −B^d ẋ + C_x ẋ + G_x; friction is not compensated: the plant's friction is the
    residual of eq. 5.13. Eq. 5.9 as written: τ = τ_m + (I − JᵀJ#ᵀ)(τ_N − k_D q̇), each joint then
    clipped at its limit (``null_space="clipped"``, as chapter 6's law); chapter 7's scaling of the
    null-space torque into the torque box (Algorithm 2) is not part of chapter 5.

    Args:
        dev: the master device.
        objective: ν of eq. 5.10 (None: no objective).
        gain: its step α [N m per unit of ν].
        damping: null-space damping k_D [N m s/rad].
        extra: further null-space terms after it (e.g. a joint-limit barrier).
    """
    terms = ([ObjectiveTerm(objective, gain)] if objective is not None else []) + list(extra)
    cfg = ControllerConfig(primary=ImpedanceControl(damping=B_D * np.eye(dev.m)), objectives=terms, damping=damping,
                           saturation="none", null_space="clipped")
    return NullSpaceController(dev, cfg)


#: `simulate`'s record hook logging the slave's joint positions q_s (n_s,) [rad] each tick as "slave_q".
SLAVE_Q = Probe(slave_q="slave_q")


def tme_area(Jm: np.ndarray, Js: np.ndarray) -> np.ndarray:
    """TME 'area' as the thesis reports it: λ = σ₁σ₂ (eq. 4.17), broadcast over leading axes."""
    return tmi(Jm, Js)



def w_reference(center=W_CENTER, width: float = W_WIDTH, height: float = W_HEIGHT, speed: float = SPEED,
                start: float = 0.0) -> HandPath:
    """The W of Figs 5.4–5.5 (our dimensions, `rhi.experiments.ch5`): a `HandPath` of 5 points [m].

    It moves at `speed` [m/s] from `start` [s].
    """
    positive("width", width)
    positive("height", height)
    positive("speed", speed)
    positive("start", start, allow_zero=True)
    p = w_path(center, width=width, height=height, speed=speed)
    return HandPath(p.points, speed, start)


def distance_to_polyline(X: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Distance of each point X: (N, 2) to the polyline P: (k, 2) [m]."""
    a, b = P[:-1], P[1:]
    d = b - a
    t = np.clip(np.einsum("nkj,kj->nk", X[:, None, :] - a[None], d) / np.einsum("kj,kj->k", d, d), 0.0, 1.0)
    proj = a[None] + t[..., None] * d[None]
    return np.min(np.linalg.norm(X[:, None, :] - proj, axis=2), axis=1)

