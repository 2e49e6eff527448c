"""MJCF of a device's plant, generated from the same Pinocchio model the controller uses.

The kinematic tree is the device's serial chain in chain coordinates θ (one MuJoCo
hinge/slide per Pinocchio joint, the inertias Pinocchio merged from fixed links). Each
motor k is a *fixed tendon* whose length is the motor angle up to a constant,

    L = R θ = q + R b,   R A = I,

carrying the motor's rotor armature, viscous damping and Coulomb friction (frictionloss),
its range (the motor's joint limits) and a torque-limited motor actuator. R is the inverse
of A restricted to the joints on the path to the end effector when those rows span the motors
(`motor_inverse`), else A⁺. Tendon forces act on θ through Rᵀ, so the plant's inertia in motor
coordinates is Aᵀ M_θ A + diag(armature), exactly the device's `mass_matrix` (MuJoCo keeps the
armature term Rᵀ diag(a) R only between joints of one branch, which the path choice respects). Chain joints that the motors do not span (side-branch
parallelograms, `A` with more rows than columns) are tied by tendon equalities
G(θ − b) = 0 with G spanning the left null space of A. Linear joint limits become
tendon ranges. A body "handle" with a site carries the 6-axis force/torque sensor.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from rhi.device import Device
from rhi.errors import InvalidInput, ModelError

_MIN_MASS = 1e-6  # [kg] MuJoCo needs mass on bodies with joints; used where Pinocchio has none
_MIN_INERTIA = 1e-9  # [kg m²]


@dataclasses.dataclass(frozen=True)
class PlantFriction:
    """Joint friction of the motors (motor coordinates).

    Attributes:
        damping: (n,) viscous friction [N m s/rad].
        frictionloss: (n,) Coulomb friction [N m].
    """

    damping: np.ndarray
    frictionloss: np.ndarray

    @classmethod
    def zero(cls, n: int) -> PlantFriction:
        return cls(np.zeros(n), np.zeros(n))

    def check(self, n: int) -> PlantFriction:
        out = {}
        for f in ("damping", "frictionloss"):
            v = np.asarray(getattr(self, f), dtype=float)
            v = np.full(n, float(v)) if v.ndim == 0 else v
            if v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v < 0):
                raise InvalidInput(f"{f}: expected {n} finite values >= 0, got {np.asarray(getattr(self, f)).tolist()}")
            out[f] = v
        return PlantFriction(**out)


def _fmt(v) -> str:
    return " ".join(f"{float(x):.12g}" for x in np.atleast_1d(v))


def _joint_axis(jm) -> tuple[str, np.ndarray]:
    name = jm.shortname()
    fixed = {"JointModelRX": ("hinge", 0), "JointModelRY": ("hinge", 1), "JointModelRZ": ("hinge", 2),
             "JointModelPX": ("slide", 0), "JointModelPY": ("slide", 1), "JointModelPZ": ("slide", 2)}
    if name in fixed:
        kind, i = fixed[name]
        return kind, np.eye(3)[i]
    if name == "JointModelRevoluteUnaligned":
        return "hinge", np.asarray(jm.extract().axis, dtype=float)
    if name == "JointModelPrismaticUnaligned":
        return "slide", np.asarray(jm.extract().axis, dtype=float)
    raise ModelError(f"device: joint type {name} has no MuJoCo plant equivalent (revolute/prismatic only)")


def left_null_space(A: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    """Rows G spanning {g : gᵀ A = 0}: (nθ − rank A, nθ)."""
    U, s, _ = np.linalg.svd(A)
    rank = int(np.sum(s > tol * max(1.0, s.max(initial=0.0))))
    return U[:, rank:].T


def motor_inverse(device: Device, A: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """Right inverse R (n, nθ) of the moving rows A (nθ, n), R A = I, supported on the end effector's path.

    MuJoCo's sparse inertia has no entries between joints of different branches, so tendon
    armature spread over a side branch (A⁺ on a parallelogram) would lose its cross terms.
    When the rows of A of the joints that support the end-effector frame are invertible, R
    uses only those; otherwise R = A⁺.
    """
    model = device.model
    fr = model.frames[device._fid]
    j = fr.parentJoint if hasattr(fr, "parentJoint") else fr.parent
    path = set(model.supports[j])
    joint_of = {model.joints[k].idx_v: k for k in range(1, model.njoints)}
    rows = [r for r, i in enumerate(np.flatnonzero(moving)) if joint_of[i] in path]
    if len(rows) == A.shape[1] and np.linalg.matrix_rank(A[rows]) == A.shape[1]:
        R = np.zeros((A.shape[1], A.shape[0]))
        R[:, rows] = np.linalg.inv(A[rows])
        return R
    return np.linalg.pinv(A)


def build_mjcf(device: Device, friction: PlantFriction | None = None, *, timestep: float = 5e-4,
               handle_mass: float = 1e-3) -> str:
    """MJCF text of the device's plant.

    Args:
        device: the device (its Pinocchio model, actuation map, limits, armature).
        friction: motor friction; None: frictionless.
        timestep: physics step [s].
        handle_mass: mass of the sensorised handle body [kg] (between the F/T sensor and the hand).

    Returns:
        The MJCF document. Names: tendons "motor{k}" (k = 0..n−1), actuators "motor{k}",
        site "handle", sensors "ft_force" / "ft_torque" (handle frame, hand → device), "handle_pos" /
        "handle_vel" (world frame).
    """
    if not np.isfinite(timestep) or timestep <= 0:
        raise InvalidInput(f"timestep: must be > 0 [s], got {timestep!r}")
    n, model = device.n, device.model
    friction = (friction or PlantFriction.zero(n)).check(n)
    moving = np.any(device.A != 0, axis=1)
    A, b = device.A[moving], device.b[moving]  # chain joints the motors move; the others are welded at b
    if np.linalg.matrix_rank(A) < n:
        raise ModelError(f"device: actuation map of {device.name} has rank < {n}; motors are not independent")
    Ap = motor_inverse(device, A, moving)  # (n, nθ): L = Ap θ

    root = ET.Element("mujoco", model=device.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    g = model.gravity.linear
    ET.SubElement(root, "option", timestep=f"{timestep:.9g}", integrator="implicitfast", gravity=_fmt(g))
    ET.SubElement(root, "size", memory="2M")
    world = ET.SubElement(root, "worldbody")
    bodies = {0: world}
    theta_names = []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nv != 1:
            raise ModelError(f"device: joint {model.names[j]} has {jm.nv} DoF; the plant supports 1-DoF joints")
        kind, axis = _joint_axis(jm)
        M = model.jointPlacements[j]
        i = jm.idx_v
        if not moving[i]:  # locked: weld the body at θ_i = b_i
            motion = pin.SE3(pin.exp3(axis * device.b[i]), np.zeros(3)) if kind == "hinge" else \
                pin.SE3(np.eye(3), axis * device.b[i])
            M = M * motion
        quat = pin.Quaternion(M.rotation)
        body = ET.SubElement(bodies[model.parents[j]], "body", name=f"b_{model.names[j]}",
                             pos=_fmt(M.translation), quat=_fmt([quat.w, quat.x, quat.y, quat.z]))
        Y = model.inertias[j]
        mass = max(float(Y.mass), _MIN_MASS)
        Ic = np.asarray(Y.inertia) + _MIN_INERTIA * np.eye(3)
        ET.SubElement(body, "inertial", pos=_fmt(Y.lever), mass=f"{mass:.12g}",
                      fullinertia=_fmt([Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]]))
        bodies[j] = body
        if moving[i]:
            ET.SubElement(body, "joint", name=model.names[j], type=kind, axis=_fmt(axis), limited="false")
            theta_names.append(model.names[j])

    # the sensorised handle, welded to the end-effector frame
    fr = model.frames[device._fid]
    pj = fr.parentJoint if hasattr(fr, "parentJoint") else fr.parent
    quat = pin.Quaternion(fr.placement.rotation)
    handle = ET.SubElement(bodies[pj], "body", name="handle", pos=_fmt(fr.placement.translation),
                           quat=_fmt([quat.w, quat.x, quat.y, quat.z]))
    hm = float(handle_mass)
    ET.SubElement(handle, "inertial", pos="0 0 0", mass=f"{hm:.9g}", diaginertia=_fmt([hm * 1e-4] * 3))
    ET.SubElement(handle, "site", name="handle", pos="0 0 0", size="0.005")

    tendons = ET.SubElement(root, "tendon")

    def fixed(name: str, coef: np.ndarray, **attrs) -> None:
        t = ET.SubElement(tendons, "fixed", name=name, **attrs)
        for c, jn in zip(coef, theta_names):
            if abs(c) > 1e-14:
                ET.SubElement(t, "joint", joint=jn, coef=f"{c:.15g}")

    const = Ap @ b  # L = q + Ap b
    for k in range(n):
        attrs = {"armature": f"{device.armature[k]:.12g}", "damping": f"{friction.damping[k]:.12g}",
                 "frictionloss": f"{friction.frictionloss[k]:.12g}"}
        lo, hi = device.q_min[k], device.q_max[k]
        if np.isfinite(lo) and np.isfinite(hi):
            attrs.update(limited="true", range=_fmt([lo + const[k], hi + const[k]]))
        fixed(f"motor{k}", Ap[k], **attrs)
    if device.linear_limits is not None:
        L = device.linear_limits
        for i, (c, lo, hi) in enumerate(zip(L.C, L.lower, L.upper)):
            off = c @ const
            fixed(f"linear{i}", c @ Ap, limited="true", range=_fmt([lo + off, hi + off]))
    G = left_null_space(A)
    equality = ET.SubElement(root, "equality") if len(G) else None
    for i, gi in enumerate(G):
        fixed(f"closure{i}", gi)
        ET.SubElement(equality, "tendon", tendon1=f"closure{i}", polycoef=_fmt([gi @ b, 0, 0, 0, 0]),
                      solref="0.002 1")

    act = ET.SubElement(root, "actuator")
    for k in range(n):
        lim = [device.torque_min[k], device.torque_max[k]]
        rng = {"ctrllimited": "true", "ctrlrange": _fmt(lim)} if np.all(np.isfinite(lim)) else {}
        ET.SubElement(act, "motor", name=f"motor{k}", tendon=f"motor{k}", **rng)
    sensors = ET.SubElement(root, "sensor")
    ET.SubElement(sensors, "force", name="ft_force", site="handle")
    ET.SubElement(sensors, "torque", name="ft_torque", site="handle")
    ET.SubElement(sensors, "framepos", name="handle_pos", objtype="site", objname="handle")
    ET.SubElement(sensors, "framelinvel", name="handle_vel", objtype="site", objname="handle")
    ET.indent(root)
    return ET.tostring(root, encoding="unicode")
