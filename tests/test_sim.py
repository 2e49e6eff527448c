"""rhi.sim: the MuJoCo plant agrees with the Pinocchio model; hand, environments, loop, teleoperation."""

import numpy as np
import pytest

from rhi.control import ControllerConfig, ForceRendering, NullSpaceController, ObjectiveTerm, VMEMatching
from rhi.devices.model import available_devices, device
from rhi.errors import InvalidInput, Unreachable
from rhi.sim import (
    Fixture,
    Hand,
    HandPath,
    HandSequence,
    Plant,
    PlantFriction,
    PushForce,
    Spring,
    Teleoperation,
    Wall,
    check_path_in_workspace,
    compose,
    simulate,
    stop,
    w_path,
)

Q_CH5 = np.array([-0.63, 0.25, 0.28, 0.09])


def _random_q(dev, rng, k):
    lo = np.where(np.isfinite(dev.q_min), dev.q_min, -1.0)
    hi = np.where(np.isfinite(dev.q_max), dev.q_max, 1.0)
    out = []
    while len(out) < k:
        q = rng.uniform(lo, hi)
        if dev.within_limits(q):
            out.append(q)
    return out


@pytest.mark.parametrize("name", available_devices())
def test_plant_agrees_with_pinocchio(name, rng):
    """FK, Jacobian and mass matrix (motor coordinates, armature included) agree at random configurations."""
    dev = device(name)
    plant = Plant(dev, handle_mass=0.0)
    for q in _random_q(dev, rng, 5):
        plant.reset(q)
        np.testing.assert_allclose(plant.q, q, atol=1e-12)
        np.testing.assert_allclose(plant.x, dev.fk(q), atol=1e-12)
        np.testing.assert_allclose(plant.motor_jacobian(), dev.jacobian(q), atol=1e-12)
        M = dev.mass_matrix(q)
        # MuJoCo needs a minimum mass/inertia on bodies Pinocchio leaves empty (1e-6 kg, 1e-9 kg m²)
        np.testing.assert_allclose(plant.motor_mass_matrix(), M, atol=3e-6 + 1e-6 * np.abs(M).max())


@pytest.mark.parametrize("name", available_devices())
def test_plant_steps_without_warnings(name):
    dev = device(name)
    plant = Plant(dev)
    plant.reset(_random_q(dev, np.random.default_rng(1), 1)[0])
    plant.apply(np.zeros(dev.n))
    plant.step(200)
    assert np.all(np.isfinite(plant.q))
    assert all(w.number == 0 for w in plant.data.warning)


def test_torque_limits_enforced(rhi4):
    plant = Plant(rhi4)
    plant.reset(Q_CH5)
    plant.apply(np.array([100.0, -100.0, 100.0, -100.0]))
    plant.step()
    np.testing.assert_allclose(plant.data.actuator_force, [3.0, -3.0, 1.0, -1.0])


def test_friction_acts_on_motor_coordinates(rhi4):
    d = np.array([0.05, 0.04, 0.01, 0.02])
    plant = Plant(rhi4, friction=PlantFriction(d, np.zeros(4)))
    dq = np.array([0.3, -0.2, 0.5, 0.1])
    plant.reset(Q_CH5, dq)
    # generalized passive force on θ, seen by the motors through Aᵀ, is −D q̇
    np.testing.assert_allclose(rhi4.A.T @ plant.data.qfrc_passive, -d * dq, atol=1e-12)
    with pytest.raises(InvalidInput, match="damping"):
        Plant(rhi4, friction=PlantFriction(-d, np.zeros(4)))


def test_ft_sensor_reads_hand_force_in_equilibrium(rhi4):
    plant = Plant(rhi4, friction=None)
    plant.reset(Q_CH5)
    F = np.array([0.7, -1.3])
    plant.apply(-rhi4.jacobian(Q_CH5).T @ F, F)
    plant.step()
    np.testing.assert_allclose(plant.ft()[:2], F, atol=1e-9)
    np.testing.assert_allclose(plant.dq, 0.0, atol=1e-9)


class _Zero:
    def __init__(self, n):
        self.n = n

    def step(self, t, q, dq, sensors):
        return np.zeros(self.n)


def test_user_work_equals_kinetic_energy(rhi4):
    """Frictionless, unactuated, planar: the hand's work W (eq. 5.15) becomes kinetic energy."""
    plant = Plant(rhi4, friction=None, timestep=2e-4, handle_mass=0.0)
    plant.reset(Q_CH5)
    log = simulate(plant, _Zero(4), duration=0.05, hand=PushForce([0, 1], 0.5))
    assert plant.data.nefc == 0  # no joint limit reached
    q, dq = plant.q, plant.dq
    ke = 0.5 * dq @ rhi4.mass_matrix(q) @ dq
    assert ke > 1e-3
    assert abs(log.work[-1] - ke) < 0.02 * ke


def test_path_and_w_trajectory():
    p = HandPath([[0, 0], [0.1, 0], [0.1, 0.1]], speed=0.05, start=1.0)
    assert p.length == pytest.approx(0.2) and p.duration == pytest.approx(4.0)
    np.testing.assert_allclose(p(0.5)[0], [0, 0])
    x, v = p(3.0)
    np.testing.assert_allclose(x, [0.1, 0.0], atol=1e-12)
    x, v = p(4.0)
    np.testing.assert_allclose(x, [0.1, 0.05])
    np.testing.assert_allclose(v, [0, 0.05])
    np.testing.assert_allclose(p(10.0)[1], 0.0)
    w = w_path([0.45, 0.0], width=0.08, height=0.04, speed=0.02)
    assert len(w.points) == 5 and w.points[0, 1] - w.points[1, 1] == pytest.approx(0.04)
    with pytest.raises(InvalidInput, match="speed"):
        HandPath([[0, 0], [1, 0]], speed=0.0)


def test_hand_sequence_switches_hands_at_its_times():
    first = Hand(HandPath([[0.0, 0.0]]), stiffness=100.0, damping=0.0, max_force=None)
    second = Hand(HandPath([[0.1, 0.0]]), stiffness=100.0, damping=0.0, max_force=None)
    seq = HandSequence((first, second, first), (1.0, 2.0))
    x, v = np.zeros(2), np.zeros(2)
    for t, F in ((0.0, 0.0), (0.999, 0.0), (1.0, 10.0), (1.5, 10.0), (2.0, 0.0), (9.0, 0.0)):
        np.testing.assert_allclose(seq.force(t, x, v), [F, 0.0], err_msg=str(t))
    with pytest.raises(InvalidInput, match="switch: expected 1 times"):
        HandSequence((first, second), (1.0, 2.0))
    with pytest.raises(InvalidInput, match="switch: the times must not decrease"):
        HandSequence((first, second, first), (2.0, 1.0))
    with pytest.raises(InvalidInput, match=r"switch\[0\]"):
        HandSequence((first, second), (float("nan"),))
    with pytest.raises(InvalidInput, match=r"hands\[1\]"):
        HandSequence((first, "hand"), (1.0,))
    with pytest.raises(InvalidInput, match="hands"):
        HandSequence((), ())


def test_environments():
    wall = Wall([0.5, 0.1], [0, 1], 1000.0, damping=2.0)
    np.testing.assert_allclose(wall.force([0.5, 0.09], [0, 1.0]), [0, 0])  # outside: nothing
    np.testing.assert_allclose(wall.force([0.5, 0.11], [0, 0.0]), [0, -10.0])
    np.testing.assert_allclose(wall.force([0.5, 0.11], [0, -10.0]), [0, 0.0])  # never pulls
    fx = Fixture([0.5, 0.0], [0, 1], stiffness=500.0, damping=0.0)
    np.testing.assert_allclose(fx.force([0.52, 0.3], [0, 0]), [-10.0, 0.0])
    sp = Spring([0, 0], 100.0, direction=[1, 0])
    np.testing.assert_allclose(sp.force([[0.1, 0.1]], [[0, 0]]), [[-10.0, 0.0]])  # batch
    both = compose(wall, fx)
    np.testing.assert_allclose(both.force([0.52, 0.11], [0, 0]), [-10.0, -10.0])
    assert stop([0, 0.08], [0, 1]).stiffness >= 1e4
    with pytest.raises(InvalidInput, match="normal"):
        Wall([0, 0], [0, 0], 10.0)
    with pytest.raises(InvalidInput, match="stiffness"):
        Wall([0, 0], [0, 1], -10.0)
    with pytest.raises(InvalidInput, match="parts"):
        compose(wall, 3)


def test_palpation_renders_wall_and_stop(rhi4):
    """The hand pushes into a rendered 1000 N/m wall; a physical stop behind it holds the hand."""
    plant = Plant(rhi4)
    plant.reset(Q_CH5)
    x0 = rhi4.fk(Q_CH5)
    ctrl = NullSpaceController(rhi4, ControllerConfig(primary=ForceRendering(), saturation="ascm"))
    hand = Hand(HandPath([x0, x0 + [0, 0.06]], speed=0.05), stiffness=200.0)
    log = simulate(plant, ctrl, duration=1.6, hand=hand, virtual=Wall(x0 + [0, 0.01], [0, 1], 1000.0),
                   physical=stop(x0 + [0, 0.03], [0, 1]))
    assert log.fault is None
    assert log.x[-1, 1] < x0[1] + 0.031  # the stop holds
    depth = log.x[-1, 1] - (x0[1] + 0.01)
    assert 0.015 < depth
    # the rendered force is the wall's, within the torque limits
    assert np.all(np.abs(log.tau) <= rhi4.torque_max + 1e-12)
    np.testing.assert_allclose(log.F_env[-1, 1], -1000.0 * (log.x[-1, 1] - x0[1] - 0.01), rtol=0.05, atol=0.2)


def test_nan_mid_run_stops_safely(rhi4):
    class Glitch:
        def force(self, x, xdot):
            return np.full(2, np.nan) if glitch[0] else np.zeros(2)

    glitch = [False]
    plant = Plant(rhi4)
    plant.reset(Q_CH5)
    ctrl = NullSpaceController(rhi4, ControllerConfig(primary=ForceRendering()))

    def progress(k, n):
        glitch[0] = k > n // 2

    log = simulate(plant, ctrl, duration=0.2, hand=Hand(HandPath([rhi4.fk(Q_CH5)])), virtual=Glitch(), progress=progress)
    assert log.fault is not None and "force" in log.fault
    stopped = np.flatnonzero(np.all(log.tau == 0, axis=1) & (log.t > 0.1))
    assert stopped.size > 0 and np.all(log.tau[stopped[0]:] == 0)


def test_nullspace_motion_keeps_held_handle(rhi4):
    """With the hand holding the handle, the VME objective reconfigures the RHI; the handle moves < 0.5 mm."""
    plant = Plant(rhi4)
    plant.reset(Q_CH5)
    x0 = rhi4.fk(Q_CH5)
    obj = VMEMatching((0.0, 1.0))
    # the thesis's controller: without the passivity option, whose strict motor-port budget would let the
    # objectives reconfigure only on the energy the hand supplies (rhi.control.passivity)
    law = ForceRendering(passivity=None)
    ctrl = NullSpaceController(rhi4, ControllerConfig(primary=law, objectives=[ObjectiveTerm(obj, 2.0)], damping=0.05))
    hand = Hand(HandPath([x0]), stiffness=3000.0, damping=40.0)
    log = simulate(plant, ctrl, duration=1.0, hand=hand)
    assert np.linalg.norm(log.q[-1] - Q_CH5) > 0.05  # it did reconfigure
    assert np.max(np.linalg.norm(log.x - x0, axis=1)) < 5e-4


def test_teleoperation_slave_tracks_master(rhi4, tmp_path):
    slave = Plant(device("rehab_slave"))
    x_m = rhi4.fk(Q_CH5)
    slave.reset(device("rehab_slave").ik(x_m, q0=np.array([0.0, 1.0])))
    tele = Teleoperation(slave)
    plant = Plant(rhi4)
    plant.reset(Q_CH5)
    ctrl = NullSpaceController(rhi4, ControllerConfig(primary=ForceRendering()))
    hand = Hand(HandPath([x_m, x_m + [0.03, 0.03]], speed=0.03))
    log = simulate(plant, ctrl, duration=2.0, hand=hand, teleop=tele,
                   record=lambda: {"slave_q": slave.q, "alpha2": 2 * ctrl.state.alpha})
    err = np.linalg.norm(log.slave_x - log.x, axis=1)
    assert err[-1] < 1e-3 and err.max() < 5e-3
    # the record hook: one row per tick, after the period (the slave's encoders give its logged position)
    assert log.extra["slave_q"].shape == (len(log), 2) and log.extra["alpha2"].shape == (len(log),)
    np.testing.assert_allclose(slave.device.fk(log.extra["slave_q"]), log.slave_x, atol=1e-9)
    np.testing.assert_array_equal(log.extra["alpha2"], 2 * log.alpha)
    log.to_csv(tmp_path / "log.csv")
    assert "slave_q2" in (tmp_path / "log.csv").read_text().splitlines()[0].split(",")
    with pytest.raises(InvalidInput, match="record: .*'q'.* log columns"):
        simulate(plant, ctrl, duration=0.01, record=lambda: {"q": 0.0})
    names = iter([{"a": 0.0}, {"b": 0.0}])
    with pytest.raises(InvalidInput, match="record: returned"):
        simulate(plant, ctrl, duration=0.01, record=lambda: next(names))


def test_teleoperation_torque_is_the_cartesian_pd_of_the_device_api():
    """`Teleoperation.follow`'s unchecked fast path applies τ_s = J_sᵀ(K_p(x_des − x_s) − K_d ẋ_s) + g_s exactly."""
    dev = device("rehab_slave")
    slave = Plant(dev)
    slave.reset(dev.ik(np.array([0.42, -0.03]), q0=np.array([0.0, 1.0])), np.array([0.3, -0.2]))
    tele = Teleoperation(slave, kp=1500.0, kd=40.0, scale=1.1, offset=[0.01, -0.02])
    for x_m in ([0.40, -0.02], [0.41, -0.01]):
        q, dq = slave.q.copy(), slave.dq.copy()
        J = dev.jacobian(q)
        want = J.T @ (1500.0 * (tele.target(x_m) - dev.fk(q)) - 40.0 * (J @ dq)) + dev.gravity(q)
        tele.follow(np.array(x_m), 0.001)
        np.testing.assert_array_equal(slave.data.ctrl, want)


def test_bad_input(rhi4):
    plant = Plant(rhi4)
    with pytest.raises(InvalidInput, match="q: contains NaN"):
        plant.reset([0.0, np.nan, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="duration"):
        simulate(plant, _Zero(4), duration=-1.0)
    with pytest.raises(InvalidInput, match="friction"):
        Plant(rhi4, friction="sticky")
    with pytest.raises(Unreachable, match="path"):
        check_path_in_workspace(rhi4, HandPath([[0.5, -0.2], [3.0, 0.0]], speed=0.5), step=0.2)
