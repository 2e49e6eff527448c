"""User robot descriptions.

Real arms from example-robot-data and rtb-data against Pinocchio and MuJoCo, mimic/continuous joints, locking, tool
offsets, friction carried by the device, and refused descriptions.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import rhi
from rhi import metrics
from rhi.errors import InvalidInput, ModelError, UnknownDevice
from rhi.sim import Plant, device_friction

XACRO = Path(__import__("rtbdata").__file__).parent / "xacro/qut_frankie_description/robots/panda_arm_hand.urdf.xacro"


def _load(robot: str, ee: str) -> rhi.Device:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rhi.device_from_description(robot, ee_frame=ee)


@pytest.fixture(scope="module")
def panda():
    return _load("panda", "panda_hand_tcp")


@pytest.fixture(scope="module")
def ur5():
    return _load("ur5", "tool0")


def _mujoco_from_urdf(path: Path) -> mujoco.MjModel:
    txt = re.sub(r"<visual>.*?</visual>|<collision>.*?</collision>", "", path.read_text(), flags=re.S)
    txt = re.sub(r"(<robot[^>]*>)", r'\1<mujoco><compiler fusestatic="false"/></mujoco>', txt, count=1)
    return mujoco.MjModel.from_xml_string(txt)


@pytest.mark.parametrize("robot, ee, n", [("panda", "panda_hand_tcp", 7), ("ur5", "tool0", 6)])
def test_real_arms_match_pinocchio_and_mujoco(robot, ee, n):
    dev = _load(robot, ee)
    assert dev.n == n
    path = rhi.description_path(robot)
    raw = pin.buildModelFromUrdf(str(path))  # every joint independent (fingers too)
    data = raw.createData()
    mj = _mujoco_from_urdf(path)
    md = mujoco.MjData(mj)
    fid = raw.getFrameId(ee)
    iv = [raw.joints[raw.getJointId(j)].idx_v for j in dev.joint_names]
    imj = [mj.joint(j).qposadr[0] for j in dev.joint_names]
    rng = np.random.default_rng(3)
    lo, hi = np.maximum(dev.q_min, -np.pi), np.minimum(dev.q_max, np.pi)
    for q in rng.uniform(lo, hi, size=(5, n)):
        th = pin.neutral(raw)
        th[iv] = q
        J = pin.computeFrameJacobian(raw, data, th, fid, pin.LOCAL_WORLD_ALIGNED)[:3, iv]
        M = pin.crba(raw, data, th)
        M = np.triu(M) + np.triu(M, 1).T
        g = pin.computeGeneralizedGravity(raw, data, th)[iv]
        np.testing.assert_allclose(dev.jacobian(q), J, atol=1e-9)
        np.testing.assert_allclose(dev.mass_matrix(q), M[np.ix_(iv, iv)], atol=1e-9)
        np.testing.assert_allclose(dev.gravity(q), g, atol=1e-9)
        md.qpos[:] = 0.0
        md.qpos[imj] = q
        mujoco.mj_forward(mj, md)
        Mm = np.zeros((mj.nv, mj.nv))
        mujoco.mj_fullM(mj, md, Mm)
        jp = np.zeros((3, mj.nv))
        mujoco.mj_jacBody(mj, md, jp, None, mj.body(ee).id)
        np.testing.assert_allclose(dev.mass_matrix(q), Mm[np.ix_(imj, imj)], atol=1e-9)
        np.testing.assert_allclose(dev.gravity(q), md.qfrc_bias[imj], atol=1e-9)
        np.testing.assert_allclose(dev.jacobian(q), jp[:, imj], atol=1e-9)
        np.testing.assert_allclose(dev.fk(q), md.xpos[mj.body(ee).id], atol=1e-9)


def test_panda_gripper_locked_with_message_and_max_force_without_fingers(panda):
    with pytest.warns(UserWarning, match="panda_finger_joint1"):
        rhi.device_from_description("panda", ee_frame="panda_hand_tcp")
    assert panda.joint_names == [f"panda_joint{i}" for i in range(1, 8)]
    assert panda.locked_joints == {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    np.testing.assert_allclose(panda.torque_max, [87, 87, 87, 87, 12, 12, 12])
    q = np.array([0.1, -0.4, 0.2, -2.0, 0.1, 1.6, 0.5])
    J, M = panda.jacobian(q), panda.mass_matrix(q)
    u = np.array([0.0, 0.0, 1.0])
    f = metrics.max_force(J, u, torque_min=panda.torque_min, torque_max=panda.torque_max, projector="dynamic", M=M)
    # the same LP on the raw model's seven arm columns: the 100 N finger "motors" take no part
    raw = pin.buildModelFromUrdf(str(rhi.description_path("panda")))
    data = raw.createData()
    th = np.r_[q, 0.0, 0.0]
    Jr = pin.computeFrameJacobian(raw, data, th, raw.getFrameId("panda_hand_tcp"), pin.LOCAL_WORLD_ALIGNED)[:3, :7]
    Mr = pin.crba(raw, data, th)
    Mr = (np.triu(Mr) + np.triu(Mr, 1).T)[:7, :7]
    lim = raw.effortLimit[:7]
    assert f == pytest.approx(metrics.max_force(Jr, u, torque_min=-lim, torque_max=lim, projector="dynamic", M=Mr), rel=1e-9)


def test_panda_xacro_expanded_and_compared_with_pinocchio():
    import xacro

    # rtb-data's Panda xacro has no inertials: refused unless an armature gives each motor inertia
    with pytest.raises(ModelError, match="mass matrix.*panda_joint1"):
        rhi.device_from_urdf(XACRO, ee_frame="panda_hand")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dev = rhi.device_from_urdf(XACRO, ee_frame="panda_hand", armature=0.01)
    assert dev.n == 7
    from rhi.devices._urdf import _xacro_find

    with _xacro_find(XACRO.parent, ()):
        raw = pin.buildModelFromXML(xacro.process_file(str(XACRO)).toxml())
    data = raw.createData()
    q = np.linspace(-0.5, 0.5, 7)
    th = pin.neutral(raw)
    th[:7] = q
    J = pin.computeFrameJacobian(raw, data, th, raw.getFrameId("panda_hand"), pin.LOCAL_WORLD_ALIGNED)[:3, :7]
    np.testing.assert_allclose(dev.jacobian(q), J, atol=1e-9)
    np.testing.assert_allclose(dev.mass_matrix(q), 0.01 * np.eye(7), atol=1e-12)


def _urdf(joints: str, links: str | None = None, mass: str = "1.0", inertia: str = "0.01") -> str:
    link = (f'<inertial><mass value="{mass}"/><inertia ixx="{inertia}" iyy="{inertia}" izz="{inertia}" '
            'ixy="0" ixz="0" iyz="0"/></inertial>')
    links = links or "".join(f'<link name="l{i}">{link if i else ""}</link>' for i in range(4))
    return f'<robot name="r">{links}{joints}</robot>'


LIMIT = '<limit effort="2" velocity="1" lower="-2" upper="2"/>'


def _joint(name, parent, child, kind="revolute", extra="", axis="0 0 1", limit=LIMIT, x=0.3):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{x} 0 0"/><axis xyz="{axis}"/>{limit}{extra}</joint>')


CHAIN = _joint("j1", "l0", "l1", x=0) + _joint("j2", "l1", "l2") + _joint("j3", "l2", "l3")


def test_mimic_joint_follows_its_primary():
    xml = _urdf(_joint("j1", "l0", "l1", x=0) + _joint("j2", "l1", "l2") +
                _joint("j3", "l2", "l3", extra='<mimic joint="j2" multiplier="-0.5" offset="0.1"/>'))
    dev = rhi.device_from_urdf(xml, ee_frame="l3", task="xy")
    assert dev.joint_names == ["j1", "j2"]
    q = np.array([0.3, 0.7])
    np.testing.assert_allclose(dev.theta(q), [0.3, 0.7, -0.35 + 0.1])
    free = rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", task="xy")
    np.testing.assert_allclose(dev.fk(q), free.fk([0.3, 0.7, -0.25]), atol=1e-12)
    # the Jacobian is the chain rule through the mimic map
    Jf = free.jacobian([0.3, 0.7, -0.25])
    np.testing.assert_allclose(dev.jacobian(q), Jf[:, :2] + np.outer(Jf[:, 2], [0, -0.5]), atol=1e-12)
    with pytest.raises(InvalidInput, match="lock: 'j3' mimics 'j2'"):
        rhi.device_from_urdf(xml, ee_frame="l3", task="xy", lock={"j3": 0.0})


def test_continuous_joints_unbounded():
    xml = _urdf(_joint("j1", "l0", "l1", kind="continuous", x=0, limit="") + _joint("j2", "l1", "l2") +
                _joint("j3", "l2", "l3"))
    dev = rhi.device_from_urdf(xml, ee_frame="l3", task="xy", torque_max=1.5)
    assert dev.q_min[0] == -np.inf and dev.q_max[0] == np.inf
    np.testing.assert_allclose(dev.torque_max, [1.5, 1.5, 1.5])
    assert dev.within_limits([10.0, 0.1, 0.1])
    q = dev.ik(dev.fk([0.2, 0.3, 0.4]), [0.0, 0.1, 0.1])
    np.testing.assert_allclose(dev.fk(q), dev.fk([0.2, 0.3, 0.4]), atol=1e-8)
    res = rhi.all_measures(dev, [0.2, 0.3, 0.4])
    assert np.isfinite(res["max_force (LP, dynamic projector) [N]"])
    # every limit-aware function takes the unbounded joint: no penalty, no barrier force, a plant without a range
    q = np.array([7.0, 0.3, 0.4])
    P = metrics.joint_limit_penalty(q, q_min=dev.q_min, q_max=dev.q_max, k_q=1.0)
    assert P[0] == 1.0 and 0 < P[1] < 1
    from rhi import control as ctl

    c = ctl.NullSpaceController(dev, ctl.ControllerConfig(ctl.ForceRendering(), objectives=(
        ctl.ObjectiveTerm(ctl.JointLimitBarrier(0.1), 0.1), ctl.ObjectiveTerm(ctl.Manipulability(k_q=1.0), 0.1))))
    tau = c.step(0.0, q, np.zeros(3), {"force": np.zeros(2)})
    assert np.all(np.isfinite(tau))
    plant = Plant(dev)
    plant.reset(q)
    plant.apply(np.array([0.5, 0.0, 0.0]))
    plant.step(200)
    assert plant.q[0] > 7.0


def test_ee_frame_checks_offset_and_lock():
    with pytest.raises(ModelError, match="valid frames: l0, l1, l2, l3"):
        rhi.device_from_urdf(_urdf(CHAIN), ee_frame="tip")
    with pytest.raises(ModelError, match="'j3' is a joint.*'l3'"):
        rhi.device_from_urdf(_urdf(CHAIN), ee_frame="j3")
    dev = rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", task="xy")
    tool = rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", task="xy", ee_offset=[0.1, 0, 0])
    q = np.array([0.2, -0.3, 0.5])
    np.testing.assert_allclose(tool.fk(q), dev.fk(q) + 0.1 * np.array([np.cos(q.sum()), np.sin(q.sum())]), atol=1e-12)
    locked = rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", task="xy", lock={"j1": 0.2})
    assert locked.joint_names == ["j2", "j3"] and locked.locked_joints == {"j1": 0.2}
    np.testing.assert_allclose(locked.fk(q[1:]), dev.fk(q), atol=1e-12)
    with pytest.raises(InvalidInput, match="lock: unknown joint 'jx'"):
        rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", lock={"jx": 0.0})
    with pytest.raises(InvalidInput, match=r"lock\['j1'\]: 5.0 outside"):
        rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", lock={"j1": 5.0})
    with pytest.raises(InvalidInput, match="task"):
        rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", task="xx")


@pytest.mark.parametrize("xml, match", [
    (_urdf(CHAIN, mass="abc"), "link 'l1' <mass>: attribute value='abc' is not numeric"),
    (_urdf(CHAIN, mass="-0.5"), "link 'l1' <mass>: value must be >= 0"),
    (_urdf(CHAIN, inertia="-0.01"), "link 'l1' <inertia>: not positive definite"),
    (_urdf(CHAIN.replace('axis xyz="0 0 1"', 'axis xyz="0 0 0"', 1)), "joint 'j1' <axis>: xyz must be a non-zero"),
    (_urdf(CHAIN.replace('<limit effort="2" velocity="1" lower="-2" upper="2"/>', "", 1)), "torque_max: joint.*'j1'.*no effort"),
    (_urdf(CHAIN, links="".join(f'<link name="l{i}"/>' for i in range(4))), "mass matrix.*j1, j2, j3 move no mass"),
    ('<robot name="r"></robot>', "no <link> elements"),
    ("<robot name='r'><link", "malformed URDF XML"),
    ('<?xml version="1.0"?><robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r"><xacro:nope/></robot>', "xacro"),
])
def test_malformed_descriptions_name_the_culprit(xml, match):
    with pytest.raises(ModelError, match=match):
        rhi.device_from_urdf(xml, ee_frame="l3", task="xy")


def test_inconsistent_inertia_refused():
    links = ('<link name="l0"/>' + "".join(
        f'<link name="l{i}"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="3" ixy="0" ixz="0" iyz="0"/>'
        "</inertial></link>" for i in range(1, 4)))
    with pytest.raises(ModelError, match="link 'l1' <inertia>: physically inconsistent"):
        rhi.device_from_urdf(_urdf(CHAIN, links=links), ee_frame="l3")


def test_device_requires_finite_positive_torque_limits():
    with pytest.raises(InvalidInput, match="torque_max"):
        rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", torque_max=[1.0, np.inf, 1.0])
    with pytest.raises(ModelError, match="torque_max.*positive"):
        rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", torque_max=[1.0, 0.0, 1.0])
    with pytest.raises(ModelError, match="torque_min.*negative"):
        rhi.device_from_urdf(_urdf(CHAIN), ee_frame="l3", torque_min=0.5, torque_max=1.0)
    with pytest.raises(ModelError, match="torque_max"):
        rhi.Device(pin.buildModelFromXML(_urdf(CHAIN)), name="x", ee_frame="l3")


def test_plant_friction_is_the_devices_own(tmp_path):
    phantom, locked = rhi.device("phantom"), rhi.device("rhi4").lock(q1=0, q2=0)
    for f in ("damping", "frictionloss"):
        np.testing.assert_array_equal(getattr(device_friction(phantom), f), getattr(device_friction(locked), f))
    # a user URDF saved under a bundled device's name gets its own (zero / given) friction, not rhi4's
    path = tmp_path / "rhi4.urdf"
    path.write_text(_urdf(CHAIN))
    dev = rhi.device_from_urdf(path, ee_frame="l3", task="xy")
    assert dev.name == "rhi4"
    np.testing.assert_array_equal(device_friction(dev).damping, np.zeros(3))
    dev = rhi.device_from_urdf(path, ee_frame="l3", task="xy", friction={"damping": 0.02, "frictionloss": [0, 0.01, 0]})
    np.testing.assert_allclose(Plant(dev).model.tendon_damping[:3], 0.02)
    np.testing.assert_allclose(dev.lock(j1=0.0).frictionloss, [0.01, 0.0])
    with pytest.raises(InvalidInput, match="friction"):
        rhi.device_from_urdf(path, ee_frame="l3", friction={"viscous": 1.0})


def test_urdf_dynamics_become_plant_friction(panda):
    np.testing.assert_allclose(panda.damping, 0.003)  # panda.urdf: <dynamics damping="0.003" .../>


def test_device_from_mjcf(tmp_path):
    xml = """<mujoco><worldbody><body name="a"><joint name="j1" type="hinge" axis="0 0 1" damping="0.1"
      frictionloss="0.2" armature="0.01" actuatorfrcrange="-5 5"/><geom type="sphere" size=".1" mass="1"/>
      <body name="b" pos="1 0 0"><joint name="j2" type="hinge" axis="0 0 1" range="-90 90"/>
      <geom type="sphere" size=".1" mass="1"/><site name="tip" pos="0.5 0 0"/></body></body></worldbody>
      <actuator><motor joint="j2" ctrlrange="-2 2" ctrllimited="true" gear="3"/></actuator></mujoco>"""
    path = tmp_path / "arm.xml"
    path.write_text(xml)
    dev = rhi.device_from_mjcf(path, ee_frame="tip", task="xy")
    np.testing.assert_allclose(dev.torque_max, [5.0, 6.0])
    np.testing.assert_allclose(dev.armature, [0.01, 0.0])
    np.testing.assert_allclose(dev.damping, [0.1, 0.0])
    np.testing.assert_allclose(dev.frictionloss, [0.2, 0.0])
    assert dev.q_min[0] == -np.inf and dev.q_max[1] == pytest.approx(np.pi / 2)
    mj = mujoco.MjModel.from_xml_path(str(path))
    md = mujoco.MjData(mj)
    q = np.array([0.3, -0.4])
    md.qpos[:] = q
    mujoco.mj_forward(mj, md)
    jp = np.zeros((3, 2))
    mujoco.mj_jacSite(mj, md, jp, None, mj.site("tip").id)
    M = np.zeros((2, 2))
    mujoco.mj_fullM(mj, md, M)
    np.testing.assert_allclose(dev.jacobian(q), jp[:2], atol=1e-9)
    np.testing.assert_allclose(dev.mass_matrix(q), M, atol=1e-9)
    with pytest.raises(ModelError, match="malformed MJCF"):
        bad = tmp_path / "bad.xml"
        bad.write_text("<mujoco><worldbody><body><joint type='hinge' axis='0 0 0'/></body></worldbody></mujoco>")
        rhi.device_from_mjcf(bad, ee_frame="a")


def test_unknown_description():
    with pytest.raises(UnknownDevice, match="panda"):
        rhi.description_path("nonexistent_robot")
