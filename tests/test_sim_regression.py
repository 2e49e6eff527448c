"""The optimised simulation loop against the previous one: same log to 1e-9 on a seeded palpation scenario.

tests/data/sim_palpation_rhi4.npz was written by `scenario()` below with the loop, plant, hand and
Device of main at 941fa50 (before the speed work of issue 14: one `Device.terms` per tick, bisected
path segments, cheaper plant stepping). The hand follows a two-segment path into a rendered wall
while the full ch7 controller (force rendering, FME schedule, ASO, ASCM) runs at 1 kHz.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import rhi
from rhi.control import (
    ControllerConfig,
    FMESchedule,
    ForceRendering,
    NullSpaceController,
    ObjectiveTerm,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.errors import InvalidInput
from rhi.sim import Fixture, Hand, HandPath, Plant, Spring, Wall, compose, simulate, stop
from rhi.sim.loop import Kinematics, Session

REFERENCE = Path(__file__).parent / "data" / "sim_palpation_rhi4.npz"
FIELDS = ["t", "q", "dq", "tau", "x", "xdot", "F_hand", "F_env", "ft", "work", "V", "omega", "alpha", "beta"]
Q0 = np.array([-0.63, 0.25, 0.28, 0.09])


def scenario(duration: float = 0.9):
    dev = rhi.device("rhi4")
    K, z = fme_shape(dev.jacobian(np.zeros(4)), dev.torque_max, 5.0)
    cfg = ControllerConfig(ForceRendering(damping=0.01, passivity=None),
                           objectives=(ObjectiveTerm(FMESchedule(desired_fme_free([0, 1], K, z),
                                                                 desired_fme_stiff([0, 1], K, z)), 20.0),),
                           saturation="ascm")
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    hand = Hand(HandPath([x0, x0 + [0.01, 0.0], x0 + [0.01, 0.03]], speed=0.02), stiffness=300.0)
    return simulate(plant, NullSpaceController(dev, cfg), duration=duration, hand=hand,
                    virtual=Wall(x0 + [0.0, 0.005], [0, 1], 1000.0))


def test_log_equals_previous_loop():
    log = scenario()
    ref = np.load(REFERENCE)
    assert log.fault is None
    assert float(np.max(np.abs(ref["F_env"]))) > 0.1  # the wall is reached: contact is part of the check
    for f in FIELDS:
        np.testing.assert_allclose(getattr(log, f), ref[f], rtol=0, atol=1e-9, err_msg=f)


def test_path_segment_lookup_matches_linear_scan():
    P = np.array([[0.0, 0.0], [0.01, 0.0], [0.01, 0.0], [0.01, 0.02], [-0.01, 0.02]])  # a zero-length segment
    path = HandPath(P, speed=0.05, start=0.1)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    for t in np.linspace(0.0, 1.2, 241):
        d = (t - 0.1) * 0.05
        x, v = path(t)
        if t <= 0.1 or d >= s[-1]:
            assert np.array_equal(v, np.zeros(2))
            continue
        i = 0
        while s[i + 1] <= d:
            i += 1
        u = (P[i + 1] - P[i]) / (s[i + 1] - s[i])
        np.testing.assert_allclose(x, P[i] + (d - s[i]) * u, atol=1e-15)
        np.testing.assert_allclose(v, 0.05 * u, atol=1e-15)


def _screw_device() -> rhi.Device:
    """A chain with a helical joint: not a tree of revolute/prismatic joints (Pinocchio paths)."""
    model = pin.Model()
    jid = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "hinge")
    offset = pin.SE3(np.eye(3), np.array([0.3, 0.0, 0.0]))
    jid = model.addJoint(jid, pin.JointModelHZ(0.05), offset, "screw")
    model.appendBodyToJoint(jid, pin.Inertia.FromBox(1.0, 0.1, 0.2, 0.3), pin.SE3.Identity())
    model.addFrame(pin.Frame("tip", jid, 0, offset, pin.FrameType.OP_FRAME))
    return rhi.Device(model, name="screw", ee_frame="tip", torque_max=[1.0, 1.0])


def test_loop_kinematics_equal_device_terms():
    """The loop's FK with velocities (virtual environment, teleoperation) against Device.terms on every device.

    Bundled devices take the compiled kernel, the helical chain Pinocchio's forward kinematics.
    """
    rng = np.random.default_rng(7)
    devices = [rhi.device(name) for name in rhi.available_devices()] + [_screw_device()]
    assert all(Kinematics(dev)._compiled is not None for dev in devices[:-1])
    assert Kinematics(devices[-1])._compiled is None
    for dev in devices:
        name = dev.name
        kin = Kinematics(dev)
        for _ in range(3):
            q, dq = rng.uniform(-0.5, 0.5, dev.n), rng.normal(size=dev.n)
            x, xdot = kin(q, dq)
            ref = dev.terms(q, dq)
            np.testing.assert_allclose(x, ref.x, rtol=0, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(xdot, ref.xdot, rtol=0, atol=1e-12, err_msg=name)


def test_loop_rendering_equals_environment_force():
    """`Kinematics.render`: walls, fixtures and their sums in the compiled call, other environments through `force`.

    On every device a wall through a point near the handle (in contact or not, pushed back or not by
    the velocity), a spring, a fixture and sums of them: x, ẋ as `Kinematics`, the force as the
    environment's own `force`.
    """
    rng = np.random.default_rng(11)
    contact = 0
    for dev in [rhi.device(name) for name in rhi.available_devices()] + [_screw_device()]:
        for _ in range(6):
            q, dq = rng.uniform(-0.5, 0.5, dev.n), rng.normal(size=dev.n)
            x, xdot = Kinematics(dev)(q, dq)
            normal = rng.normal(size=dev.m)
            wall = Wall(x + rng.normal(scale=0.01, size=dev.m), normal, 800.0, damping=30.0)
            fixture = Fixture(x + rng.normal(scale=0.01, size=dev.m), rng.normal(size=dev.m), 1000.0, 5.0)
            envs = [wall, Spring(x + 0.01, 500.0, damping=2.0), None, fixture, compose(wall, fixture),
                    compose(wall, Spring(x, 10.0))]
            for k, env in enumerate(envs):
                kin = Kinematics(dev, env)
                assert kin._fused == (k in (0, 3, 4) and dev.name != "screw")
                xr, xdr, F = kin.render(q, dq)
                np.testing.assert_allclose(xr, x, rtol=0, atol=1e-15, err_msg=dev.name)
                np.testing.assert_allclose(xdr, xdot, rtol=0, atol=1e-15, err_msg=dev.name)
                ref = np.zeros(dev.m) if env is None else env.force(x, xdot)
                np.testing.assert_allclose(F, ref, rtol=0, atol=1e-12, err_msg=dev.name)
                contact += type(env) is Wall and bool(np.any(F != 0))
    assert 10 < contact < 60


def test_hand_and_wall_floats_equal_array_formulas():
    """Hand and Wall evaluate one point on plain floats; the array formulas are the reference."""
    rng = np.random.default_rng(3)
    P = np.array([[0.0, 0.0], [0.02, 0.0], [0.02, 0.03]])
    hand = Hand(HandPath(P, speed=0.02, start=0.1), stiffness=300.0, damping=10.0, max_force=2.0)
    wall = Wall([0.01, 0.005], [0.6, 0.8], 1000.0, damping=5.0)
    saturated = 0
    for t in np.linspace(0.0, 3.0, 61):
        x, xdot = rng.normal(scale=0.01, size=2) + 0.01, rng.normal(scale=0.05, size=2)
        xr, vr = hand.path(t)
        F = 300.0 * (xr - x) + 10.0 * (vr - xdot)
        if np.linalg.norm(F) > 2.0:
            F *= 2.0 / np.linalg.norm(F)
            saturated += 1
        np.testing.assert_allclose(hand.force(t, x, xdot), F, rtol=0, atol=1e-12)
        np.testing.assert_allclose(wall.force(x, xdot), wall.force(x[None], xdot[None])[0], rtol=0, atol=1e-12)
    assert 0 < saturated < 61


def test_contact_stage_skipped_only_when_nothing_collides(rhi4):
    """Without colliding geometry MuJoCo's collision stage is skipped: the same trajectory, bit for bit."""
    contact = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    assert not Plant(rhi4, collision=True).model.opt.disableflags & contact
    plants = [Plant(rhi4), Plant(rhi4)]
    assert plants[0].model.opt.disableflags & contact
    plants[1].model.opt.disableflags &= ~contact
    traj = []
    for plant in plants:
        plant.reset(Q0)
        rng = np.random.default_rng(0)
        rows = []
        for _ in range(300):
            plant.apply(rng.normal(scale=0.05, size=4), rng.normal(scale=2.0, size=2))
            plant.step(2)
            rows.append(np.r_[plant.q, plant.dq, plant.ft()])
        traj.append(np.array(rows))
    np.testing.assert_array_equal(traj[0], traj[1])


class _PythonHand(Hand):
    """A `Hand` the session does not recognise: its physical steps call `Hand.force` (the reference)."""


def test_compiled_hand_steps_equal_hand_force():
    """The session's compiled hand/wall step against `Hand.force` + `Wall.force` called at every step.

    A saturating hand that waits, moves along three segments and holds, pushing the handle into a
    physical stop: every branch of the kernel (hold, segment, saturation, wall contact).
    """
    dev = rhi.device("rhi4")
    x0 = dev.fk(Q0)
    P = [x0, x0 + [0.0, 0.004], x0 + [0.004, 0.004], x0 + [0.004, 0.012]]
    wall = stop(x0 + [0.0, 0.006], [0, 1], stiffness=5000.0, damping=20.0)
    runs = []
    for cls in (Hand, _PythonHand):
        hand = cls(HandPath(P, speed=0.05, start=0.05), stiffness=400.0, damping=8.0, max_force=1.0)
        plant = Plant(dev)
        plant.reset(Q0)
        sess = Session(plant, hand=hand, physical=wall)
        rows, saturated = [], 0
        for _ in range(600):
            assert sess.advance(np.zeros(4)) is None
            saturated += bool(np.linalg.norm(sess.F_hand) > 1.0 - 1e-9)
            rows.append(np.r_[sess.t, sess.work, sess.F_hand, plant.x, plant.xdot, plant.ft()])
        assert (sess._fused_for[0] is hand) == (cls is Hand)
        runs.append(np.array(rows))
        assert 0 < saturated < 600
    assert np.max(runs[0][:, 5]) > wall.point[1]  # the handle went into the stop
    np.testing.assert_allclose(runs[0], runs[1], rtol=0, atol=1e-12)


def test_compiled_hand_reports_non_finite_force():
    dev = rhi.device("rhi4")
    plant = Plant(dev)
    plant.reset(Q0)
    hand = Hand(HandPath([dev.fk(Q0)]), stiffness=1e308, max_force=None)
    sess = Session(plant, hand=hand)
    sess.plant.data.qvel[:] = 1.0
    mujoco.mj_forward(plant.model, plant.data)
    fault = sess.advance(np.zeros(4))
    assert fault is not None and "non-finite force" in fault and sess.fault == fault


def test_compiled_period_reports_divergence_as_the_reference_does():
    """A stiff hand kicks the handle with a huge, finite force: the physics diverges.

    The compiled period (MuJoCo's step called from compiled code, `rhi.sim.mjc`) reports it at the same
    step, time and work as the Python steps.
    """
    dev = rhi.device("rhi4")
    x0 = dev.fk(Q0)
    out = []
    for cls in (Hand, _PythonHand):
        plant = Plant(dev)
        plant.reset(Q0)
        hand = cls(HandPath([x0, x0 + [0.0, 0.01]], speed=0.1, start=0.0101), stiffness=1e8, max_force=None)
        sess = Session(plant, hand=hand)
        faults = [sess.advance(np.full(4, 0.01)) for _ in range(30)]
        k = next(i for i, f in enumerate(faults) if f is not None)
        assert (sess._fused_for[0] is hand) == (cls is Hand)
        out.append((k, faults[k], sess.work, sess.t))
    assert out[0][0] > 0 and "unstable physics" in out[0][1], out[0]  # a period after the first
    assert out[0] == out[1]


def test_plant_sensors_equal_encoders_and_ft(rhi4):
    """`Plant.sensors` (one compiled call) against `q`, `dq` and `ft()` along a pushed, driven motion."""
    plant = Plant(rhi4)
    plant.reset(Q0, np.full(4, 0.3))
    rng = np.random.default_rng(2)
    for _ in range(50):
        plant.apply(rng.normal(scale=0.05, size=4), rng.normal(scale=2.0, size=2))
        plant.step(2)
        r = plant.sensors()
        assert r.shape == (14,)
        np.testing.assert_array_equal(r, np.r_[plant.q, plant.dq, plant.ft()])
    assert np.abs(plant.ft()[:2]).max() > 0.1  # the F/T sensor reads the pushed handle


class _BadTorque:
    def step(self, t, q, dq, sensors):
        return np.zeros(3)


def test_simulate_refuses_torques_of_the_wrong_shape(rhi4):
    plant = Plant(rhi4)
    plant.reset(Q0)
    with pytest.raises(InvalidInput, match="controller"):
        simulate(plant, _BadTorque(), duration=0.01)
