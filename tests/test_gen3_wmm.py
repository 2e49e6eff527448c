"""Kinova Gen3 (`gen3`) and the wheeled mobile manipulator (`wmm`) of thesis App. A/B, and `rhi.devices.mobile_base`."""

from __future__ import annotations

import numpy as np
import pytest

from rhi.devices.mobile_base import body_map, mecanum_map, wheel_geometry, wmm_jacobian
from rhi.devices.model import device
from rhi.errors import InvalidInput

PI = np.pi
Q0_ARM = np.array([0, PI / 6, 0, PI / 2, 0, -PI / 6, 0])  # thesis §A.4.1 / §B.4.1 (arm part of q0)
X0 = np.array([0.65, -0.0246, 0.4921])  # thesis §A.4.1 / §B.4.1
W_TAU = np.diag([1, 1, 1, 1, 2.5, 2.5, 2.5])  # thesis §A.4.3

# Kinova Gen3 user guide, classic DH table: (alpha, d, theta offset); a = 0; leading row base -> 1 = Rx(pi)
DH = [
    (PI / 2, -(0.1564 + 0.1284), 0.0),
    (PI / 2, -(0.0054 + 0.0064), PI),
    (PI / 2, -(0.2104 + 0.2104), PI),
    (PI / 2, -(0.0064 + 0.0064), PI),
    (PI / 2, -(0.2084 + 0.1059), PI),
    (PI / 2, 0.0, PI),
    (PI, -(0.1059 + 0.0615), PI),
]


def _dh(alpha, d, theta):
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    return np.array([[ct, -st * ca, st * sa, 0], [st, ct * ca, -ct * sa, 0], [0, sa, ca, d], [0, 0, 0, 1.0]])


def dh_fk(q):
    """Flange position of the published DH table, independent of the URDF and Pinocchio."""
    T = _dh(PI, 0.0, 0.0)
    for (alpha, d, off), qi in zip(DH, q):
        T = T @ _dh(alpha, d, qi + off)
    return T[:3, 3]


def dm(J, u, W):
    """Directional manipulability [uᵀ J W Wᵀ Jᵀ u]^(-1/2) (thesis eq. A.8)."""
    return float((u @ J @ W @ W.T @ J.T @ u) ** -0.5)


@pytest.fixture(scope="module")
def gen3():
    return device("gen3")


@pytest.fixture(scope="module")
def wmm():
    return device("wmm")


@pytest.fixture(scope="module")
def geom():
    return wheel_geometry("wmm")


def _random_q(dev, rng, k):
    lo = np.where(np.isfinite(dev.q_min), dev.q_min, -PI)
    hi = np.where(np.isfinite(dev.q_max), dev.q_max, PI)
    return rng.uniform(0.9 * lo, 0.9 * hi, size=(k, dev.n))


def _fd_jacobian(dev, q, h=1e-6):
    cols = [(dev.fk(q + h * e) - dev.fk(q - h * e)) / (2 * h) for e in np.eye(dev.n)]
    return np.stack(cols, axis=-1)


# ------------------------------------------------------------------- thesis numbers
def test_gen3_fk_thesis_start(gen3):
    # App. A.4.1: x0 = [0.65, -0.0246, 0.4921] at the tool interface, robot base frame (z up)
    np.testing.assert_allclose(gen3.fk(Q0_ARM), X0, rtol=0, atol=1e-3)


def test_gen3_directional_manipulability_thesis(gen3):
    J = gen3.jacobian(Q0_ARM)
    assert dm(J, np.array([0, 0, 1.0]), W_TAU) == pytest.approx(1.125, abs=0.005)  # §A.4.3, z
    assert dm(J, np.array([1.0, 0, 0]), W_TAU) == pytest.approx(3.825, abs=0.005)  # §A.4.3 / Fig. A.9, x


def test_wmm_start_and_dm(wmm, gen3):
    q0 = np.concatenate([[0, 0, 0], Q0_ARM])  # thesis q0 (10 coordinates)
    np.testing.assert_allclose(wmm.fk(q0), X0, rtol=0, atol=1e-3)
    Jm = wmm.jacobian(q0)[:, 3:]
    np.testing.assert_allclose(Jm, gen3.jacobian(Q0_ARM), rtol=0, atol=1e-12)
    assert dm(Jm, np.array([0, 0, 1.0]), W_TAU) == pytest.approx(1.125, abs=0.005)


# --------------------------------------------------------------------- kinematics
def test_gen3_urdf_matches_published_dh(gen3):
    rng = np.random.default_rng(0)
    for q in _random_q(gen3, rng, 20):
        np.testing.assert_allclose(gen3.fk(q), dh_fk(q), rtol=0, atol=1e-12)


def test_wmm_is_gen3_on_a_planar_base(wmm, gen3):
    rng = np.random.default_rng(1)
    for q in _random_q(wmm, rng, 10):
        x, y, th = q[:3]
        Rz = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
        np.testing.assert_allclose(wmm.fk(q), np.array([x, y, 0]) + Rz @ gen3.fk(q[3:]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["gen3", "wmm"])
def test_jacobian_matches_finite_differences(name):
    dev = device(name)
    rng = np.random.default_rng(2)
    for q in _random_q(dev, rng, 5):
        np.testing.assert_allclose(dev.jacobian(q), _fd_jacobian(dev, q), rtol=0, atol=1e-8)


@pytest.mark.parametrize("name", ["gen3", "wmm"])
def test_jacobian_derivative_matches_finite_differences(name):
    dev = device(name)
    rng = np.random.default_rng(3)
    h = 1e-5
    for q in _random_q(dev, rng, 3):
        fd = np.stack([(dev.jacobian(q + h * e) - dev.jacobian(q - h * e)) / (2 * h) for e in np.eye(dev.n)], -1)
        np.testing.assert_allclose(dev.jacobian_derivative(q), fd, rtol=0, atol=1e-6)


def test_jacobian_batches(gen3):
    q = _random_q(gen3, np.random.default_rng(4), 6).reshape(2, 3, 7)
    J = gen3.jacobian(q)
    assert J.shape == (2, 3, 3, 7)
    np.testing.assert_allclose(J[1, 2], gen3.jacobian(q[1, 2]), rtol=0, atol=0)


# ----------------------------------------------------------------------- dynamics
@pytest.mark.parametrize("name", ["gen3", "wmm"])
def test_mass_matrix_spd(name):
    dev = device(name)
    for q in _random_q(dev, np.random.default_rng(5), 10):
        M = dev.mass_matrix(q)
        np.testing.assert_allclose(M, M.T, rtol=0, atol=1e-14)
        assert np.linalg.eigvalsh(M).min() > 1e-6


def test_gravity(gen3, wmm):
    g = gen3.gravity(Q0_ARM)
    assert np.linalg.norm(g) > 1.0  # N m: the arm (about 7 kg) is not weightless
    assert abs(g[0]) < 1e-9  # joint 1 axis is vertical
    gw = wmm.gravity(np.concatenate([[0.3, -0.2, 0.7], Q0_ARM]))
    np.testing.assert_allclose(gw[:3], 0, rtol=0, atol=1e-9)  # planar base coordinates do no work against gravity
    np.testing.assert_allclose(gw[3:], g, rtol=0, atol=1e-9)  # the base pose does not change the arm's gravity torque


def test_gravity_is_gradient_of_potential_energy(gen3):
    import pinocchio as pin

    def V(q):
        return pin.computePotentialEnergy(gen3.model, gen3.data, gen3.theta(q))

    q = _random_q(gen3, np.random.default_rng(6), 1)[0]
    h = 1e-6
    fd = np.array([(V(q + h * e) - V(q - h * e)) / (2 * h) for e in np.eye(7)])
    np.testing.assert_allclose(gen3.gravity(q), fd, rtol=0, atol=1e-7)


# ------------------------------------------------------------------------- limits
def test_limits(gen3, wmm):
    inf = np.inf
    np.testing.assert_array_equal(gen3.q_max, [inf, 2.2, inf, 2.5, inf, 2.0, inf])  # Table B.1
    np.testing.assert_array_equal(gen3.q_min, -gen3.q_max)
    np.testing.assert_array_equal(gen3.torque_max, [32, 32, 32, 32, 13, 13, 13])  # §A.4.3
    np.testing.assert_array_equal(wmm.q_max[3:], gen3.q_max)
    assert np.all(np.isinf(wmm.q_max[:3]))
    np.testing.assert_array_equal(wmm.torque_max[3:], gen3.torque_max)
    assert wmm.joint_names[:3] == ["x_b", "y_b", "theta_b"]
    assert gen3.within_limits(Q0_ARM) and not gen3.within_limits(Q0_ARM + [0, 2.0, 0, 0, 0, 0, 0])


# ----------------------------------------------------------------------------- ik
@pytest.mark.parametrize("name", ["gen3", "wmm"])
def test_ik_round_trip(name):
    dev = device(name)
    rng = np.random.default_rng(7)
    for q in _random_q(dev, rng, 3):
        x = dev.fk(q)
        q_ik = dev.ik(x, q + rng.normal(scale=0.1, size=dev.n))
        assert np.linalg.norm(dev.fk(q_ik) - x) <= 1e-9  # Device.ik tolerance [m]
        assert dev.within_limits(q_ik)


# --------------------------------------------------------------------- mobile base
def _wheel_speeds_from_rolling(twist, R, l1, l2):
    """No-slip Mecanum wheels (rollers at 45°, X layout) at (±l1, ±l2): independent inverse of J_V."""
    vx, vy, w = twist
    pos = np.array([[l1, l2], [l1, -l2], [-l1, l2], [-l1, -l2]])  # fl, fr, bl, br
    sign = np.array([1, -1, -1, 1])  # roller direction of each wheel
    out = []
    for (px, py), s in zip(pos, sign):
        v_wheel = np.array([vx - w * py, vy + w * px])  # velocity of the wheel centre (base frame)
        out.append((v_wheel[0] - s * v_wheel[1]) / R)
    return np.array(out)


def test_body_map_inverts_rolling_constraints(geom):
    R, l1, l2 = geom["wheel_radius"], geom["half_length"], geom["half_width"]
    JV = body_map(**geom)
    rng = np.random.default_rng(8)
    for twist in rng.normal(size=(5, 3)):
        np.testing.assert_allclose(JV @ _wheel_speeds_from_rolling(twist, R, l1, l2), twist, rtol=0, atol=1e-12)


def _base_pose(qb0, v_b, t, geom):
    """Exact base pose after t seconds of constant wheel speeds (constant body twist)."""
    vx, vy, w = body_map(**geom) @ v_b
    th0 = qb0[2]
    Ic = (np.sin(th0 + w * t) - np.sin(th0)) / w  # ∫ cos(θ0 + w s) ds
    Is = -(np.cos(th0 + w * t) - np.cos(th0)) / w  # ∫ sin(θ0 + w s) ds
    return qb0 + np.array([vx * Ic - vy * Is, vx * Is + vy * Ic, w * t])


def test_mecanum_map_matches_pose_integration(geom):
    rng = np.random.default_rng(9)
    h = 1e-6
    for _ in range(5):
        qb, v_b, t = rng.normal(size=3), rng.normal(size=4) * 5, rng.uniform(0, 2)
        fd = (_base_pose(qb, v_b, t + h, geom) - _base_pose(qb, v_b, t - h, geom)) / (2 * h)
        P = mecanum_map(_base_pose(qb, v_b, t, geom)[2], **geom)
        np.testing.assert_allclose(P @ v_b, fd, rtol=0, atol=1e-8)


def test_mecanum_map_shapes_and_errors(geom):
    th = np.linspace(-3, 3, 6).reshape(2, 3)
    P = mecanum_map(th, **geom)
    assert P.shape == (2, 3, 3, 4)
    np.testing.assert_allclose(P[1, 2], mecanum_map(th[1, 2], **geom), rtol=0, atol=0)
    with pytest.raises(InvalidInput, match="wheel_radius"):
        mecanum_map(0.0, wheel_radius=-0.1, half_length=0.2, half_width=0.2)
    with pytest.raises(InvalidInput, match="theta_b"):
        mecanum_map(np.nan, **geom)


def test_wmm_jacobian_is_time_derivative_of_fk(wmm, geom):
    rng = np.random.default_rng(10)
    h = 1e-6
    for q in _random_q(wmm, rng, 4):
        v_b, dq_m = rng.normal(size=4) * 3, rng.normal(size=7)

        def q_at(t, q=q, v_b=v_b, dq_m=dq_m):
            return np.concatenate([_base_pose(q[:3], v_b, t, geom), q[3:] + t * dq_m])

        fd = (wmm.fk(q_at(h)) - wmm.fk(q_at(-h))) / (2 * h)
        J = wmm_jacobian(wmm, q, **geom)
        assert J.shape == (3, 11)
        np.testing.assert_allclose(J @ np.concatenate([v_b, dq_m]), fd, rtol=0, atol=1e-8)


def test_wmm_jacobian_batches_and_rejects_fixed_base(wmm, gen3, geom):
    q = _random_q(wmm, np.random.default_rng(11), 4).reshape(2, 2, 10)
    J = wmm_jacobian(wmm, q, **geom)
    assert J.shape == (2, 2, 3, 11)
    np.testing.assert_allclose(J[0, 1], wmm_jacobian(wmm, q[0, 1], **geom), rtol=0, atol=0)
    with pytest.raises(InvalidInput, match="device"):
        wmm_jacobian(gen3, Q0_ARM, **geom)
