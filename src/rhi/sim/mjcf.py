"""MuJoCo model (`MjSpec`) of a device's plant, generated from the same Pinocchio model the controller uses.

The kinematic tree is the device's serial chain in chain coordinates θ (one MuJoCo
hinge/slide per Pinocchio joint, the inertias Pinocchio merged from fixed links). Each
motor k is a *fixed tendon* whose length is the motor angle up to a constant,

    L = R θ = q + R b,   R A = I,

carrying the motor's rotor armature, viscous damping and Coulomb friction (frictionloss),
its range (the motor's joint limits) and a torque-limited motor actuator. R is the inverse
of A restricted to the joints on the path to the end effector when those rows span the motors
(`motor_inverse`), else A⁺. Tendon forces act on θ through Rᵀ, so the plant's inertia in motor
coordinates is Aᵀ M_θ A + diag(armature), exactly the device's `mass_matrix` (MuJoCo keeps the
armature term Rᵀ diag(a) R only between joints of one branch, which the path choice respects).
Chain joints that the motors do not span (side-branch parallelograms, `A` with more rows than
columns) are tied by tendon equalities G(θ − b) = 0 with G spanning the left null space of A. Linear joint limits become
tendon ranges. A body "handle" with a site carries the 6-axis force/torque sensor. Visual geometry
(massless, no contacts unless asked for) comes from `rhi.sim.geometry`.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pinocchio as pin

from rhi._validate import per_joint
from rhi.devices.model import Device
from rhi.errors import InvalidInput, ModelError
from rhi.sim.geometry import (
    GeomAdder,
    add_handle,
    add_scenery,
    add_skeleton,
    add_visuals,
    joint_axis,
    link_radius,
    quat_wxyz,
)

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
        """No friction for n motors."""
        return cls(np.zeros(n), np.zeros(n))

    def check(self, n: int) -> PlantFriction:
        """The friction as (n,) arrays (a scalar is broadcast); raise InvalidInput unless finite and >= 0."""
        return PlantFriction(per_joint("damping", self.damping, n), per_joint("frictionloss", self.frictionloss, n))


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
    fr = model.frames[device.ee_frame_id]
    j = fr.parentJoint if hasattr(fr, "parentJoint") else fr.parent
    path = set(model.supports[j])
    joint_of = {model.joints[k].idx_v: k for k in range(1, model.njoints)}
    rows = [r for r, i in enumerate(np.flatnonzero(moving)) if joint_of[i] in path]
    if len(rows) == A.shape[1] and np.linalg.matrix_rank(A[rows]) == A.shape[1]:
        R = np.zeros((A.shape[1], A.shape[0]))
        R[:, rows] = np.linalg.inv(A[rows])
        return R
    return np.linalg.pinv(A)


def plant_spec(device: Device, friction: PlantFriction | None = None, *, timestep: float = 5e-4,
               handle_mass: float = 1e-3, visual: bool = True, collision: bool = False) -> mujoco.MjSpec:
    """The device's plant as a MuJoCo `MjSpec` (compile it with `spec.compile()`).

    Args:
        device: the device (its Pinocchio model, actuation map, limits, armature).
        friction: motor friction; None: frictionless.
        timestep: physics step [s].
        handle_mass: mass of the sensorised handle body [kg] (between the F/T sensor and the hand).
        visual: add the device's visual geometry (`rhi.sim.geometry`); it has no mass and no contacts.
        collision: let that geometry collide (off by default: the plant's dynamics are the joints').

    Returns:
        The spec. Names: tendons "motor{k}" (k = 0..n−1), actuators "motor{k}", body and site
        "handle", sensors "ft_force" / "ft_torque" (handle frame, hand → device), "handle_pos" /
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

    spec = mujoco.MjSpec()
    spec.modelname = device.name
    spec.compiler.degree = False
    spec.compiler.autolimits = True
    spec.option.timestep = float(timestep)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = np.asarray(model.gravity.linear, dtype=float)
    spec.memory = 2 << 20
    bodies = {0: spec.worldbody}
    theta_names = []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nv != 1:
            raise ModelError(f"device: joint {model.names[j]} has {jm.nv} DoF; the plant supports 1-DoF joints")
        kind, axis = joint_axis(jm)
        M = model.jointPlacements[j]
        i = jm.idx_v
        if not moving[i]:  # locked: weld the body at θ_i = b_i
            motion = pin.SE3(pin.exp3(axis * device.b[i]), np.zeros(3)) if kind == "hinge" else \
                pin.SE3(np.eye(3), axis * device.b[i])
            M = M * motion
        body = bodies[model.parents[j]].add_body(name=f"b_{model.names[j]}", pos=M.translation,
                                                 quat=quat_wxyz(M.rotation))
        Y = model.inertias[j]
        Ic = np.asarray(Y.inertia) + _MIN_INERTIA * np.eye(3)
        body.mass = max(float(Y.mass), _MIN_MASS)
        body.ipos = np.asarray(Y.lever, dtype=float)
        body.fullinertia = [Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]]
        body.explicitinertial = True
        bodies[j] = body
        if moving[i]:
            body.add_joint(name=model.names[j], axis=axis, limited=mujoco.mjtLimited.mjLIMITED_FALSE,
                           type=mujoco.mjtJoint.mjJNT_HINGE if kind == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE)
            theta_names.append(model.names[j])

    # the sensorised handle, welded to the end-effector frame
    fr = model.frames[device.ee_frame_id]
    pj = fr.parentJoint if hasattr(fr, "parentJoint") else fr.parent
    handle = bodies[pj].add_body(name="handle", pos=fr.placement.translation, quat=quat_wxyz(fr.placement.rotation))
    hm = float(handle_mass)
    handle.mass, handle.ipos, handle.inertia = hm, [0, 0, 0], [hm * 1e-4] * 3
    handle.explicitinertial = True
    handle.add_site(name="handle", pos=[0, 0, 0], size=[0.005, 0, 0])
    if visual:
        add = GeomAdder(spec, collision=collision)
        add_scenery(spec)
        if not add_visuals(add, device, bodies):
            add_skeleton(add, device, bodies)
        add_handle(add, handle, link_radius(device))

    def fixed(name: str, coef: np.ndarray):
        t = spec.add_tendon(name=name)
        for c, jn in zip(coef, theta_names):
            if abs(c) > 1e-14:
                t.wrap_joint(jn, float(c))
        return t

    const = Ap @ b  # L = q + Ap b
    for k in range(n):
        t = fixed(f"motor{k}", Ap[k])
        t.armature, t.damping = float(device.armature[k]), [float(friction.damping[k]), 0.0, 0.0]
        t.frictionloss = float(friction.frictionloss[k])
        lo, hi = device.q_min[k], device.q_max[k]
        if np.isfinite(lo) and np.isfinite(hi):
            t.limited, t.range = mujoco.mjtLimited.mjLIMITED_TRUE, [lo + const[k], hi + const[k]]
    if device.linear_limits is not None:
        L = device.linear_limits
        for i, (c, lo, hi) in enumerate(zip(L.C, L.lower, L.upper)):
            off = c @ const
            t = fixed(f"linear{i}", c @ Ap)
            t.limited, t.range = mujoco.mjtLimited.mjLIMITED_TRUE, [lo + off, hi + off]
    for i, gi in enumerate(left_null_space(A)):
        fixed(f"closure{i}", gi)
        eq = spec.add_equality(type=mujoco.mjtEq.mjEQ_TENDON, name1=f"closure{i}", objtype=mujoco.mjtObj.mjOBJ_TENDON)
        data = np.array(eq.data)
        data[:5] = [gi @ b, 0, 0, 0, 0]  # polycoef
        eq.data = data
        eq.solref = [0.002, 1.0]

    for k in range(n):
        a = spec.add_actuator(name=f"motor{k}", target=f"motor{k}", trntype=mujoco.mjtTrn.mjTRN_TENDON)
        a.set_to_motor()
        lim = [device.torque_min[k], device.torque_max[k]]
        if np.all(np.isfinite(lim)):
            a.ctrllimited, a.ctrlrange = mujoco.mjtLimited.mjLIMITED_TRUE, lim
    S, O = mujoco.mjtSensor, mujoco.mjtObj
    for name, kind in (("ft_force", S.mjSENS_FORCE), ("ft_torque", S.mjSENS_TORQUE),
                       ("handle_pos", S.mjSENS_FRAMEPOS), ("handle_vel", S.mjSENS_FRAMELINVEL)):
        spec.add_sensor(name=name, type=kind, objtype=O.mjOBJ_SITE, objname="handle")
    return spec


def build_mjcf(device: Device, friction: PlantFriction | None = None, **kw) -> str:
    """MJCF text of the device's plant (`plant_spec(...).to_xml()`, e.g. to open it in MuJoCo's viewer)."""
    return plant_spec(device, friction, **kw).to_xml()
