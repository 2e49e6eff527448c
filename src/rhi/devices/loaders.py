"""Devices from user robot descriptions: URDF (and xacro), MJCF, installed description packages.

    dev = rhi.device_from_urdf("panda.urdf", ee_frame="panda_hand_tcp", task="xyz")
    dev = rhi.device_from_description("panda", ee_frame="panda_hand_tcp")   # example-robot-data
    dev = rhi.device_from_mjcf("arm.xml", ee_frame="tip", torque_max=10.0)

The motors are the movable joints on the path from the base to `ee_frame`. Joints off that
path (grippers, fingers) are locked, with a warning naming them; `lock={name: value}` locks
others. A `<mimic>` joint follows its primary through the device's actuation map
(θ_mimic = multiplier θ_primary + offset), so it is never a motor of its own. Continuous
joints have unbounded ranges (q_min = −inf, q_max = +inf).
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from rhi._validate import as_array, per_joint, scalar
from rhi.devices._description_checks import MAX_JOINTS, check_finite_numbers
from rhi.devices._urdf import UNBOUNDED, JointInfo, check_urdf, description_roots, read_description, stderr_captured
from rhi.devices.model import Device
from rhi.errors import InvalidInput, ModelError, UnknownDevice

__all__ = ["available_descriptions", "device_from_description", "device_from_mjcf", "device_from_urdf",
           "description_path"]

# robots of example-robot-data (PyPI) by short name; any other "<folder>/<file>" under the
# installed description roots works too (see `description_path`)
_DESCRIPTIONS = {
    "panda": "panda_description/urdf/panda.urdf",
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "kinova": "kinova_description/robots/kinova.urdf",
    "z1": "z1_description/urdf/z1.urdf",
}


def device_from_urdf(
    path,
    *,
    ee_frame: str,
    task: str = "xyz",
    ee_offset=None,
    lock: Mapping[str, float] | None = None,
    armature=None,
    torque_min=None,
    torque_max=None,
    friction: Mapping[str, object] | None = None,
    name: str | None = None,
    package_dirs: Sequence[str | Path] = (),
    inertia: str = "strict",
) -> Device:
    """A device from a URDF file, a xacro file or URDF XML text.

    Args:
        path: URDF or xacro file, or the XML text itself. xacro is expanded (`$(find pkg)`
            and `package://pkg/` are looked up in `package_dirs`, ROS_PACKAGE_PATH, the
            folders above the file and the installed description packages).
        ee_frame: name of the end-effector link (a URDF link or a fixed frame; joint names are refused).
        task: world axes of the position task ("xy", "xyz", ...), each at most once.
        ee_offset: (3,) tool point in `ee_frame` coordinates [m] (default: the frame origin).
        lock: {joint name: value [rad or m]} joints to hold fixed besides those off the path.
        armature: scalar or (n,) rotor inertia per motor [kg m²] (default 0).
        torque_min: scalar or (n,) lower actuator limits [N m or N] (default: − the URDF effort limits).
        torque_max: scalar or (n,) upper actuator limits [N m or N] (default: the URDF effort limits; a motor
            without one needs `torque_max`).
        friction: {"damping": (n,) [N m s/rad], "frictionloss": (n,) [N m]} for the plant
            (default: the URDF `<dynamics damping friction>` of each motor).
        name: device name (default: the file stem).
        package_dirs: extra folders to search for ROS packages.
        inertia: "strict" (default: a link with a mass and a zero inertia, a point mass, is refused) or "fill"
            (each point mass becomes a solid sphere of its mass at the density of water, `rhi.devices._urdf.fill_inertia`,
            with a warning listing them).

    Raises:
        ModelError: malformed or physically inconsistent description (the link/joint and attribute are named).
        InvalidInput: a bad argument (named).
    """
    text, near, stem = read_description(path, package_dirs)
    where = "path" if isinstance(path, str) and path.lstrip().startswith("<") else f"path: {path}"
    text, info = check_urdf(text, inertia=inertia, where=where, near=near)
    if info.filled:
        warnings.warn(f"{name or stem}: inertia='fill' gave point-mass links the inertia of a solid sphere of water "
                      "of their mass: " + ", ".join(f"{k} ({v:.3g} kg m²)" for k, v in info.filled.items()),
                      stacklevel=2)
    said: list[str] = []
    try:
        with stderr_captured(said):
            model = pin.buildModelFromXML(text)
    except Exception as exc:  # Pinocchio/urdfdom raise RuntimeError/ValueError; urdfdom's reason is on stderr
        reason = " ".join(ln.strip() for ln in said[0].splitlines() if ln.strip().startswith("Error:"))
        raise ModelError(f"{where}: malformed URDF: {reason or exc}") from None
    own = {
        "effort": {n: float(model.effortLimit[model.joints[model.getJointId(n)].idx_v]) for n in _movable(model)},
        "damping": {n: float(model.damping[model.joints[model.getJointId(n)].idx_v]) for n in _movable(model)},
        "frictionloss": {n: float(model.friction[model.joints[model.getJointId(n)].idx_v]) for n in _movable(model)},
        "armature": {},
    }
    for n in info.no_effort:
        own["effort"][n] = 0.0
    dev = _finish(model, info, own, name or stem, where, ee_frame=ee_frame, task=task, ee_offset=ee_offset, lock=lock,
                  armature=armature, torque_min=torque_min, torque_max=torque_max, friction=friction)
    dirs = ([str(near)] if near is not None else []) + [str(d) for d in package_dirs]
    dev.visual_description = ("urdf", text, tuple(dirs))
    return dev


def device_from_mjcf(
    path,
    *,
    ee_frame: str,
    task: str = "xyz",
    ee_offset=None,
    lock: Mapping[str, float] | None = None,
    armature=None,
    torque_min=None,
    torque_max=None,
    friction: Mapping[str, object] | None = None,
    name: str | None = None,
) -> Device:
    """A device from a MuJoCo MJCF file (same options as `device_from_urdf`).

    Torque limits default to the model's actuators (gear × ctrlrange, forcerange) or the joints'
    `actuatorfrcrange`; armature, damping and frictionloss default to the joints' own values.
    `ee_frame` is a body or site name. Equality constraints are not modelled. The file's visible geoms are the
    device's drawing (`rhi.sim.geometry.add_mjcf_visuals`).
    """
    import mujoco

    if not isinstance(path, (str, Path)):
        raise InvalidInput(f"path: expected an MJCF file path, got {type(path).__name__}")
    path = Path(path)
    where = f"path: {path}"
    if not path.is_file():
        raise ModelError(f"{where}: file does not exist")
    try:
        check_finite_numbers(ET.parse(path).getroot(), where)
    except ET.ParseError as exc:
        raise ModelError(f"{where}: malformed MJCF XML ({exc})") from None
    except OSError as exc:
        raise ModelError(f"{where}: cannot read ({exc})") from None
    try:
        mj = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ModelError(f"{where}: malformed MJCF: {' '.join(str(exc).split())}") from None
    if mj.njnt > MAX_JOINTS:
        raise ModelError(f"{where}: {mj.njnt} joints; at most {MAX_JOINTS} are supported "
                         "(rhi.devices._description_checks.MAX_JOINTS)")
    for j in range(mj.njnt):
        if mj.jnt_type[j] in (mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_BALL):
            raise ModelError(f"{where}: joint {mj.joint(j).name!r}: free/ball joints are not supported (hinge, slide)")
        if not np.linalg.norm(mj.jnt_axis[j]) >= 1e-9:
            raise ModelError(f"{where}: joint {mj.joint(j).name!r}: axis must be non-zero and finite")
    try:
        model = pin.buildModelFromMJCF(str(path))
    except Exception as exc:
        raise ModelError(f"{where}: Pinocchio cannot read the MJCF: {exc}") from None
    model.armature = np.zeros(model.nv)  # Device adds the motors' armature itself
    own: dict[str, dict[str, float]] = {"effort": {}, "damping": {}, "frictionloss": {}, "armature": {}}
    for j in range(mj.njnt):
        jn, dof = mj.joint(j).name, mj.jnt_dofadr[j]
        own["damping"][jn] = float(mj.dof_damping[dof])
        own["frictionloss"][jn] = float(mj.dof_frictionloss[dof])
        own["armature"][jn] = float(mj.dof_armature[dof])
        own["effort"][jn] = float(np.max(np.abs(mj.jnt_actfrcrange[j]))) if mj.jnt_actfrclimited[j] else 0.0
    for a in range(mj.nu):
        if mj.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        jn, gear = mj.joint(mj.actuator_trnid[a, 0]).name, abs(float(mj.actuator_gear[a, 0]))
        lim = []
        if mj.actuator_ctrllimited[a]:
            lim.append(gear * float(np.max(np.abs(mj.actuator_ctrlrange[a]))))
        if mj.actuator_forcelimited[a]:
            lim.append(float(np.max(np.abs(mj.actuator_forcerange[a]))))
        if lim:
            own["effort"][jn] = min(lim) if own["effort"][jn] == 0 else min(lim + [own["effort"][jn]])
    info = JointInfo(mimic={}, continuous=set(), no_effort=set())
    dev = _finish(model, info, own, name or path.stem, where, ee_frame=ee_frame, task=task, ee_offset=ee_offset,
                  lock=lock, armature=armature, torque_min=torque_min, torque_max=torque_max, friction=friction)
    dev.visual_description = ("mjcf", str(path.resolve()), ())
    return dev


def description_path(robot: str) -> Path:
    """The URDF of an installed description package (example-robot-data from PyPI).

    Args:
        robot: a short name ("panda", "ur5", "ur3", "ur10", "kinova", "z1") or a path
            relative to the package's robots folder, e.g. "ur_description/urdf/ur5_gripper.urdf".

    Raises:
        UnknownDevice: not installed or unknown (the known names are listed).
    """
    if not isinstance(robot, str) or not robot:
        raise InvalidInput(f"robot: expected a robot name, got {robot!r}")
    rel = _DESCRIPTIONS.get(robot, robot)
    for root in description_roots():
        if (root / rel).is_file():
            return root / rel
    roots = description_roots()
    hint = "" if roots else " (install example-robot-data: pip install example-robot-data)"
    raise UnknownDevice(f"robot: no installed description {robot!r}{hint}; short names: {', '.join(sorted(_DESCRIPTIONS))}")


def available_descriptions() -> dict[str, Path]:
    """{name: URDF} of the robots of the installed description packages (example-robot-data, rtb-data).

    The short names (`description_path`) first, then every URDF by its path under its package root
    (e.g. "so_arm_description/urdf/so101.urdf"); each works as `device_from_description`'s `robot`.
    """
    out: dict[str, Path] = {}
    for short, rel in _DESCRIPTIONS.items():
        for root in description_roots():
            if (root / rel).is_file():
                out.setdefault(short, root / rel)
    for root in description_roots():
        for f in sorted(root.rglob("*.urdf")):
            out.setdefault(str(f.relative_to(root)), f)
    return out


def device_from_description(robot: str, *, ee_frame: str, **kw) -> Device:
    """`device_from_urdf` on an installed description package's URDF (see `description_path`).

    Example: ``rhi.device_from_description("panda", ee_frame="panda_hand_tcp")`` gives the
    7-joint arm (fingers locked); ``rhi.device_from_description("ur5", ee_frame="tool0")``.
    """
    kw.setdefault("name", robot.split("/")[-1].split(".")[0])
    return device_from_urdf(description_path(robot), ee_frame=ee_frame, **kw)


# ------------------------------------------------------------------- shared
def _movable(model: pin.Model) -> list[str]:
    return [model.names[j] for j in range(1, model.njoints) if model.joints[j].nv > 0]


def _finish(model: pin.Model, info: JointInfo, own: dict, name: str, where: str, *, ee_frame, task, ee_offset, lock,
            armature, torque_min, torque_max, friction) -> Device:
    """Lock, reduce, build the actuation map and limits, and check the dynamics of a loaded model."""
    if model.nq != model.nv:
        raise ModelError(f"{where}: {name} has a joint with nq != nv (free, spherical, planar); not supported")
    _check_ee(model, ee_frame)
    movable = _movable(model)
    mimic = info.mimic
    fid = model.getFrameId(ee_frame)
    path_ids = set(model.supports[model.frames[fid].parentJoint])
    on_path = [n for n in movable if model.getJointId(n) in path_ids]
    values = _lock_values(model, lock, movable, mimic)
    off = [n for n in movable if n not in on_path and n not in values and n not in mimic]
    for jn in off:
        jid = model.getJointId(jn)
        lo, hi = model.lowerPositionLimit[model.joints[jid].idx_q], model.upperPositionLimit[model.joints[jid].idx_q]
        values[jn] = float(np.clip(0.0, lo, hi))
    if off:
        warnings.warn(f"{name}: joints off the path to {ee_frame!r} locked: "
                      + ", ".join(f"{n}={values[n]:g}" for n in off), stacklevel=3)
    # mimic joints follow their primary; locked when the primary is locked or off the path
    for jn, (p, mult, offs) in mimic.items():
        if p in values or p not in on_path:
            values.setdefault(p, 0.0)
            values[jn] = mult * values[p] + offs
    motors = [n for n in on_path if n not in values and n not in mimic]
    if not motors:
        raise ModelError(f"ee_frame: no movable joint left between the base and {ee_frame!r}")
    q_ref = pin.neutral(model)
    for jn, v in values.items():
        q_ref[model.joints[model.getJointId(jn)].idx_q] = v
    locked_ids = sorted(model.getJointId(n) for n in values)
    reduced = pin.buildReducedModel(model, locked_ids, q_ref) if locked_ids else model
    fid_r = reduced.getFrameId(ee_frame)
    ee = ee_frame
    if ee_offset is not None:
        off3 = as_array("ee_offset", ee_offset, shape_tail=(3,))
        if off3.ndim != 1:
            raise InvalidInput(f"ee_offset: expected shape (3,), got {off3.shape}")
        fr = reduced.frames[fid_r]
        ee = f"{ee_frame}_tool"
        reduced.addFrame(pin.Frame(ee, fr.parentJoint, fid_r, fr.placement * pin.SE3(np.eye(3), off3),
                                   pin.FrameType.OP_FRAME))
    idx = {reduced.names[j]: reduced.joints[j].idx_v for j in range(1, reduced.njoints)}
    n = len(motors)
    A, b = np.zeros((reduced.nv, n)), np.zeros(reduced.nv)
    for k, mname in enumerate(motors):
        A[idx[mname], k] = 1.0
    for mname, (p, mult, offs) in mimic.items():
        if mname in idx and mname not in values:
            A[idx[mname], motors.index(p)] = mult
            b[idx[mname]] = offs
    q_min = np.array([reduced.lowerPositionLimit[idx[m]] for m in motors])
    q_max = np.array([reduced.upperPositionLimit[idx[m]] for m in motors])
    q_min = np.where(q_min <= -UNBOUNDED / 10, -np.inf, q_min)
    q_max = np.where(q_max >= UNBOUNDED / 10, np.inf, q_max)
    tmin, tmax = _torque_limits(motors, own["effort"], torque_min, torque_max)
    arm = _per_motor("armature", armature, motors, own["armature"])
    fr = friction or {}
    if not isinstance(fr, Mapping) or set(fr) - {"damping", "frictionloss"}:
        raise InvalidInput(f"friction: expected a dict with keys 'damping' and/or 'frictionloss', got {friction!r}")
    damping = _per_motor("friction['damping']", fr.get("damping"), motors, own["damping"])
    floss = _per_motor("friction['frictionloss']", fr.get("frictionloss"), motors, own["frictionloss"])
    dev = Device(reduced, name=name, ee_frame=ee, task_axes=task, actuation=A, offset=b, q_min=q_min, q_max=q_max,
                 torque_min=tmin, torque_max=tmax, joint_names=motors, armature=arm,
                 damping=damping, frictionloss=floss)
    dev.locked_joints = dict(values)
    _check_inertia(dev, where)
    return dev


def _check_ee(model: pin.Model, ee_frame) -> None:
    if not isinstance(ee_frame, str):
        raise InvalidInput(f"ee_frame: expected a frame name, got {type(ee_frame).__name__}")
    bodies = [f.name for f in model.frames if f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)]
    if not model.existFrame(ee_frame):
        raise ModelError(f"ee_frame: no link or frame named {ee_frame!r}; valid frames: {', '.join(bodies)}")
    same = [str(f.type).split(".")[-1].lower() for f in model.frames if f.name == ee_frame]
    if len(same) > 1:
        raise ModelError(f"ee_frame: {ee_frame!r} names {len(same)} frames ({', '.join(same)}): a link and a joint "
                         "share the name; rename one in the description")
    f = model.frames[model.getFrameId(ee_frame)]
    if f.type == pin.FrameType.JOINT:
        child = [g.name for g in model.frames if g.type == pin.FrameType.BODY and g.parentJoint == f.parentJoint]
        raise ModelError(f"ee_frame: {ee_frame!r} is a joint, not a link; its child link is {child[0]!r}"
                         if child else f"ee_frame: {ee_frame!r} is a joint, not a link")


def _lock_values(model: pin.Model, lock, movable: list[str], mimic: dict) -> dict[str, float]:
    if lock is None:
        return {}
    if not isinstance(lock, Mapping):
        raise InvalidInput(f"lock: expected a dict {{joint name: value}}, got {type(lock).__name__}")
    out = {}
    for jn, v in lock.items():
        if jn not in movable:
            raise InvalidInput(f"lock: unknown joint {jn!r}; movable joints: {', '.join(movable)}")
        if jn in mimic:
            raise InvalidInput(f"lock: {jn!r} mimics {mimic[jn][0]!r}; lock {mimic[jn][0]!r} instead")
        val = scalar(f"lock[{jn!r}]", v)
        i = model.joints[model.getJointId(jn)].idx_q
        if not model.lowerPositionLimit[i] - 1e-12 <= val <= model.upperPositionLimit[i] + 1e-12:
            raise InvalidInput(f"lock[{jn!r}]: {val} outside the joint range "
                               f"[{model.lowerPositionLimit[i]:g}, {model.upperPositionLimit[i]:g}]")
        out[jn] = val
    return out


def _per_motor(arg: str, value, motors: list[str], own: Mapping[str, float]) -> np.ndarray:
    n = len(motors)
    if value is None:
        return np.array([own.get(m, 0.0) for m in motors], dtype=float)
    return per_joint(arg, value, n)


def _torque_limits(motors: list[str], effort: Mapping[str, float], torque_min, torque_max):
    n = len(motors)
    if torque_max is None:
        missing = [m for m in motors if not 0 < effort.get(m, 0.0) < math.inf]
        if missing:
            raise ModelError(f"torque_max: joint(s) {', '.join(map(repr, missing))} have no effort limit in the "
                             "description; pass torque_max= (scalar or one value per motor) [N m]")
        hi = np.array([effort[m] for m in motors])
    else:
        hi = as_array("torque_max", torque_max)
        hi = np.full(n, float(hi)) if hi.ndim == 0 else hi
        if hi.shape != (n,):
            raise InvalidInput(f"torque_max: expected a scalar or {n} values (motors {motors}), got shape {hi.shape}")
    if torque_min is None:
        lo = -hi
    else:
        lo = as_array("torque_min", torque_min)
        lo = np.full(n, float(lo)) if lo.ndim == 0 else lo
        if lo.shape != (n,):
            raise InvalidInput(f"torque_min: expected a scalar or {n} values (motors {motors}), got shape {lo.shape}")
    return lo, hi


def _check_inertia(dev: Device, where: str) -> None:
    """The mass matrix must be positive definite: every motor moves some mass or armature."""
    finite = np.isfinite(dev.q_min) & np.isfinite(dev.q_max)
    mid = 0.5 * (np.where(finite, dev.q_min, 0.0) + np.where(finite, dev.q_max, 0.0))
    q = np.where(finite, mid, np.clip(0.0, dev.q_min, dev.q_max))
    M = dev.mass_matrix(q)
    weak = [dev.joint_names[i] for i in range(dev.n) if not M[i, i] > 1e-12]
    if weak or np.linalg.eigvalsh(M)[0] <= 0:
        raise ModelError(f"{where}: the mass matrix of {dev.name} is not positive definite"
                         + (f": joint(s) {', '.join(weak)} move no mass" if weak else "")
                         + "; give the links <inertial> masses and inertias (or pass armature=)")
