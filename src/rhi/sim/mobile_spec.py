"""MuJoCo model (`MjSpec`) of the wheeled mobile manipulator's plant (thesis App. A and B).

Bodies, joint placements and inertias are the device's Pinocchio model (inertias of fixed
links merged by Pinocchio); massless slider links get 1 g so that MuJoCo accepts them. The
arm bodies are gravity compensated (the Gen3's own controller does it) and every arm joint
has a position servo (kp) and a velocity servo (kv) whose torques are limited to the
device's torque limits (32/13 N m); the base joints have velocity servos. Visual geometry:
the arm's links as capsules, the Mecanum chassis with its four wheels and a floor.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from rhi.devices.mobile_base import BASE_JOINTS, wheel_geometry
from rhi.devices.model import Device
from rhi.errors import InvalidInput, ModelError
from rhi.sim.geometry import GeomAdder, add_floor, add_handle, add_mecanum_base, add_scenery, add_skeleton, link_radius, quat_wxyz

#: Reflected rotor inertia of each Gen3 joint in the plant [kg m²] (ESTIMATE: harmonic-drive
#: actuators; the value only sets how hard the servos work, not the kinematics).
ARM_ARMATURE = 0.1

_AXIS = {"JointModelRX": (mujoco.mjtJoint.mjJNT_HINGE, 0), "JointModelRY": (mujoco.mjtJoint.mjJNT_HINGE, 1),
         "JointModelRZ": (mujoco.mjtJoint.mjJNT_HINGE, 2), "JointModelPX": (mujoco.mjtJoint.mjJNT_SLIDE, 0),
         "JointModelPY": (mujoco.mjtJoint.mjJNT_SLIDE, 1), "JointModelPZ": (mujoco.mjtJoint.mjJNT_SLIDE, 2)}


def wmm_spec(device: Device, *, timestep: float = 1e-3, arm_kp: float = 4000.0, arm_kv: float = 150.0,
             base_kv: float = 5000.0, armature: float = ARM_ARMATURE, geometry: dict | None = None,
             visual: bool = True) -> mujoco.MjSpec:
    """The mobile manipulator plant as an `MjSpec`.

    Args:
        device: a device whose first three coordinates are [x_b, y_b, θ_b] (``wmm``).
        timestep: physics step [s].
        arm_kp: arm position gain [N m/rad].
        arm_kv: arm velocity gain [N m s/rad].
        base_kv: base velocity gain [N s/m, N m s/rad].
        armature: reflected rotor inertia of each arm joint [kg m²].
        geometry: Mecanum geometry {wheel_radius, half_length, half_width} [m] for the drawn wheels;
            None: the device's (or the bundled wmm's).
        visual: add the visual geometry (massless, no contacts).

    Returns:
        The spec; joints are named as the device's, the end-effector site "ee",
        actuators "pos_<joint>", "vel_<joint>" (arm) and "vel_<base joint>".
    """
    if tuple(device.joint_names[:3]) != BASE_JOINTS:
        raise InvalidInput(f"device: expected coordinates starting with {list(BASE_JOINTS)}, got {device.joint_names}")
    for name, v in (("timestep", timestep), ("arm_kp", arm_kp), ("arm_kv", arm_kv), ("base_kv", base_kv)):
        if not math.isfinite(v) or v <= 0:
            raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
    model = device.model
    if model.nq != device.n or not np.allclose(device.A, np.eye(device.n)):
        raise ModelError(f"device: {device.name} must be driven in chain coordinates (A = I)")
    spec = mujoco.MjSpec()
    spec.modelname = f"{device.name}_plant"
    spec.compiler.degree = False
    spec.compiler.autolimits = True
    spec.option.timestep = float(timestep)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = np.asarray(model.gravity.linear, dtype=float)
    bodies = {0: spec.worldbody}
    names = device.joint_names
    for j in range(1, model.njoints):
        jm = model.joints[j]
        kind_axis = _AXIS.get(jm.shortname())
        if kind_axis is None:
            raise ModelError(f"device: joint type {jm.shortname()} is not supported by the mobile plant")
        kind, ax = kind_axis
        M = model.jointPlacements[j]
        arm = jm.idx_v >= 3
        body = bodies[model.parents[j]].add_body(name=f"b_{names[jm.idx_v]}", pos=M.translation,
                                                 quat=quat_wxyz(M.rotation))
        if arm:
            body.gravcomp = 1.0
        Y = model.inertias[j]
        Ic = np.asarray(Y.inertia) + 1e-7 * np.eye(3)
        body.mass = max(float(Y.mass), 1e-3)
        body.ipos = np.asarray(Y.lever, dtype=float)
        body.fullinertia = [Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]]
        body.explicitinertial = True
        jnt = body.add_joint(name=names[jm.idx_v], type=kind, axis=np.eye(3)[ax])
        lo, hi = device.q_min[jm.idx_v], device.q_max[jm.idx_v]
        if np.isfinite(lo) and np.isfinite(hi):
            jnt.limited, jnt.range = mujoco.mjtLimited.mjLIMITED_TRUE, [lo, hi]
        else:
            jnt.limited = mujoco.mjtLimited.mjLIMITED_FALSE
        if arm:
            jnt.armature = float(armature)
        bodies[j] = body
    fr = model.frames[model.getFrameId(device.ee_frame)]
    ee = bodies[fr.parentJoint]
    ee.add_site(name="ee", pos=fr.placement.translation, quat=quat_wxyz(fr.placement.rotation), size=[0.01, 0, 0])
    if visual:
        add = GeomAdder(spec)
        add_scenery(spec)
        add_skeleton(add, device, bodies, skip={1, 2, 3}, base=False)  # the base joints x_b, y_b, θ_b
        floor = add_mecanum_base(add, bodies[3], **(geometry or wheel_geometry(device)))
        add_floor(add, spec, floor)
        hb = ee.add_body(name="handle", pos=fr.placement.translation, quat=quat_wxyz(fr.placement.rotation))
        add_handle(add, hb, link_radius(device))
    for i, name in enumerate(names):
        if i < 3:
            a = spec.add_actuator(name=f"vel_{name}", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            a.set_to_velocity(kv=float(base_kv))
            continue
        lim = [device.torque_min[i], device.torque_max[i]]
        a = spec.add_actuator(name=f"pos_{name}", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        a.set_to_position(kp=float(arm_kp))
        a.forcelimited, a.forcerange = mujoco.mjtLimited.mjLIMITED_TRUE, lim
        a = spec.add_actuator(name=f"vel_{name}", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        a.set_to_velocity(kv=float(arm_kv))
        a.forcelimited, a.forcerange = mujoco.mjtLimited.mjLIMITED_TRUE, lim
    return spec
