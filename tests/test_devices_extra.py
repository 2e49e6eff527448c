"""rehab_slave, planar3r and phantom3.

Closed-form Jacobians (thesis eqs. 5.12b, 4.25b, 4.26), derivatives, mass matrices (closed forms; Çavuşoğlu et al.
2002 for the PHANToM), limits, IK and design parameters.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import fd_jacobian, random_q

import rhi
from rhi.devices.model import device as load_device_by_name  # the loader the rest of the package uses
from rhi.errors import InvalidInput, Unreachable

s, c = np.sin, np.cos
G0 = 9.81  # Pinocchio's default gravity magnitude [m/s²], checked below

# --------------------------------------------------------------------------- closed forms from the thesis
L_SLAVE = (0.34, 0.375)  # eq. (5.12b)
L_3R = 0.25  # §6.3.1
L1_PH = 0.21  # PHANToM first link: d3 of §3.5 / §5.4 / §7.5


def j_slave(q, l=L_SLAVE):
    """Eq. (5.12b), θ1 and θ2 absolute."""
    t1, t2 = q
    return np.array([[-l[0] * s(t1), l[1] * c(t2)], [l[0] * c(t1), l[1] * s(t2)]])


def j_3r(q, L=L_3R):
    """Serial 3R with relative angles."""
    a = np.cumsum(q)
    Jx = [-L * np.sum(s(a[i:])) for i in range(3)]
    Jy = [L * np.sum(c(a[i:])) for i in range(3)]
    return np.array([Jx, Jy])


def j_phantom(q, l2=0.165, l1=L1_PH):
    """Eq. (4.25b)."""
    t1, t2, t3 = q
    r = l1 * c(t2) + l2 * s(t3)
    return np.array([
        [-s(t1) * r, -l1 * c(t1) * s(t2), l2 * c(t1) * c(t3)],
        [c(t1) * r, -l1 * s(t1) * s(t2), l2 * c(t3) * s(t1)],
        [0.0, l1 * c(t2), l2 * s(t3)],
    ])


def rot_z(a):
    return np.array([[c(a), -s(a), 0.0], [s(a), c(a), 0.0], [0.0, 0.0, 1.0]])


def x_slave(q, l=L_SLAVE):
    t1, t2 = q
    return np.array([l[0] * c(t1) + l[1] * s(t2), l[0] * s(t1) - l[1] * c(t2)])


def x_3r(q, L=L_3R):
    a = np.cumsum(q)
    return L * np.array([np.sum(c(a)), np.sum(s(a))])


def x_phantom(q, l2=0.165, l1=L1_PH):
    """Position whose Jacobian is eq. (4.25b); base frame at the shoulder on the yaw axis."""
    t1, t2, t3 = q
    r = l1 * c(t2) + l2 * s(t3)
    return np.array([c(t1) * r, s(t1) * r, l1 * s(t2) - l2 * c(t3)])


CLOSED = {
    "rehab_slave": j_slave,
    "planar3r": j_3r,
    "phantom3": j_phantom,
}
FK = {"rehab_slave": x_slave, "planar3r": x_3r, "phantom3": x_phantom}


# --------------------------------------------------------------------------- every device
@pytest.mark.parametrize("name", sorted(CLOSED))
def test_loads_and_is_listed(name):
    dev = load_device_by_name(name)
    assert name in rhi.available_devices()
    assert dev.name == name
    assert dev.n == {"rehab_slave": 2, "planar3r": 3, "phantom3": 3}[name]
    assert dev.task_axes == {"rehab_slave": "xy", "planar3r": "xy", "phantom3": "xyz"}[name]


@pytest.mark.parametrize("name", sorted(CLOSED))
def test_jacobian_closed_form_and_finite_differences(name, rng):
    dev = rhi.device(name)
    closed = CLOSED[name]
    for q in random_q(dev, rng, 20):
        J = dev.jacobian(q)
        np.testing.assert_allclose(dev.fk(q), FK[name](q), rtol=0, atol=1e-14)
        np.testing.assert_allclose(J, closed(q), rtol=0, atol=1e-12)
        np.testing.assert_allclose(J, fd_jacobian(dev.fk, q), rtol=0, atol=1e-8)
        np.testing.assert_allclose(dev.jacobian_derivative(q), fd_jacobian(dev.jacobian, q), rtol=0, atol=1e-6)


@pytest.mark.parametrize("name", sorted(CLOSED))
def test_mass_matrix_spd_and_passive(name, rng):
    dev = rhi.device(name)
    Q = random_q(dev, rng, 50)
    M = dev.mass_matrix(Q)
    np.testing.assert_allclose(M, np.swapaxes(M, -1, -2), rtol=0, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(M) > 0)
    # Ṁ − 2C is skew-symmetric; Ṁ by central differences along q̇
    q, dq = Q[0], rng.normal(size=dev.n)
    Mdot = (dev.mass_matrix(q + 1e-6 * dq) - dev.mass_matrix(q - 1e-6 * dq)) / 2e-6
    S = Mdot - 2 * dev.coriolis(q, dq)
    np.testing.assert_allclose(S, -S.T, rtol=0, atol=1e-9)


def test_gravity_direction():
    for name in CLOSED:
        np.testing.assert_allclose(rhi.device(name).model.gravity.linear, [0, 0, -G0], atol=1e-12)


@pytest.mark.parametrize("name", ["rehab_slave", "planar3r"])
def test_planar_devices_feel_no_gravity(name, rng):
    dev = rhi.device(name)
    np.testing.assert_allclose(dev.gravity(random_q(dev, rng, 10)), 0.0, atol=1e-14)


@pytest.mark.parametrize(
    "name, targets, q0, far",
    [
        ("rehab_slave", [(0.424, 0.1), (0.424, -0.1), (0.48, -0.35)], np.deg2rad([30, 40]), (1.0, 0.0)),
        ("planar3r", [(0.4, 0.2), (0.19153, -0.06470), (0.5, 0.3)], [np.pi / 6, -np.pi / 3, -3 * np.pi / 4], (0.8, 0.0)),
        ("phantom3", [(0.25, 0.05, 0.0539), (0.2, -0.1, -0.065), (0.3, 0.0, 0.0)], [0.0, 0.5, 0.5], (0.5, 0.0, 0.0)),
    ],
)
def test_ik_round_trip_and_unreachable(name, targets, q0, far):
    dev = rhi.device(name)
    for x in targets:
        q = dev.ik(x, q0)
        assert dev.within_limits(q)
        np.testing.assert_allclose(dev.fk(q), x, rtol=0, atol=1e-9)
    with pytest.raises(Unreachable, match="x"):
        dev.ik(far, q0)


# --------------------------------------------------------------------------- rehab_slave
def test_rehab_slave_limits_cover_the_thesis_slave_points():
    dev = rhi.device("rehab_slave")
    np.testing.assert_allclose(np.rad2deg(dev.q_min), [-55, 0])
    np.testing.assert_allclose(np.rad2deg(dev.q_max), [90, 145])
    # §4.4 task A → B and the §5.4 start point, on the elbow branch with q1 − q2 + 90° in [35°, 145°]
    for x in [(0.424, -0.1), (0.424, 0.0), (0.424, 0.1), (0.48, -0.35)]:
        q = dev.ik(x, np.deg2rad([30, 40]))
        assert dev.within_limits(q)
    assert not dev.within_limits(np.deg2rad([80, 10]))  # parallelogram angle 160° > 145°
    np.testing.assert_allclose(dev.fk([0.0, np.pi / 2]), [0.34 + 0.375, 0.0], atol=1e-15)


def test_rehab_slave_mass_matrix_closed_form(rng):
    """Two thin rods in absolute angles: M12 = m2 l1 r2 sin(θ2 − θ1)."""
    dev = rhi.device("rehab_slave")
    m1, r1, I1 = 0.8, 0.17, 0.8 * 0.34**2 / 12
    m2, r2, I2 = 0.89, 0.1875, 0.89 * 0.375**2 / 12
    l1 = 0.34
    for q in random_q(dev, rng, 10):
        M12 = m2 * l1 * r2 * s(q[1] - q[0])
        Mc = np.array([[I1 + m1 * r1**2 + m2 * l1**2, M12], [M12, I2 + m2 * r2**2]])
        np.testing.assert_allclose(dev.mass_matrix(q), Mc, rtol=1e-6, atol=0)


# --------------------------------------------------------------------------- planar3r
def test_planar3r_thesis_example_values():
    dev = rhi.device("planar3r")
    np.testing.assert_allclose(dev.torque_limits[1], [0.5, 0.5, 0.5])
    W = np.diag(1.0 / dev.torque_limits[1])  # §6.3.1: W = diag{2, 2, 2}
    np.testing.assert_allclose(W, 2 * np.eye(3))
    for q in ([np.pi / 6, -np.pi / 3, -3 * np.pi / 4], [np.pi / 4, -np.pi / 3, -np.pi / 6]):  # §6.3.1, §7.3
        assert dev.within_limits(q)
    np.testing.assert_allclose(dev.fk([0, 0, 0]), [0.75, 0.0], atol=1e-15)


def test_planar3r_point_mass_inertia(rng):
    """M = Σ m Jcᵀ Jc + I 1ᵢ1ᵢᵀ with 0.5 kg at each link middle and I = 1e-6 kg m² (README)."""
    dev = rhi.device("planar3r")
    for q in random_q(dev, rng, 10):
        a = np.cumsum(q)
        M = np.zeros((3, 3))
        for i in range(3):
            Jc = np.zeros((2, 3))
            for k in range(i + 1):
                # COM of link i: links k..i-1 full length, link i half length
                lens = [L_3R] * (i - k) + [L_3R / 2]
                ang = a[k:i + 1]
                Jc[:, k] = [-np.dot(lens, s(ang)), np.dot(lens, c(ang))]
            ones = np.array([1.0 if k <= i else 0.0 for k in range(3)])
            M += 0.5 * Jc.T @ Jc + 1e-6 * np.outer(ones, ones)
        np.testing.assert_allclose(dev.mass_matrix(q), M, rtol=0, atol=1e-14)


# --------------------------------------------------------------------------- phantom3
# Çavuşoğlu, Feygin & Tendick (2002) parameters (README), with l1 = 0.21 as in the URDF
MA, MC, MBE, MDF = 0.0202, 0.0249, 0.2359, 0.1906
IA = (0.4864e-4, 0.001843e-4, 0.4864e-4)
IC = (0.959e-4, 0.959e-4, 0.0051e-4)
IBE = (11.09e-4, 10.06e-4, 0.591e-4)
IDF = (7.11e-4, 0.629e-4, 6.246e-4)
IBASE = 11.87e-4
LA, L3, L5, L6 = 0.170, 0.0325, -0.0368, 0.0527
# the two yaw moments raised so the COM tensors are physical (README, "Adjustments")
IBE_YY_URDF = 7.31e-4 + MBE * L5**2
IDF_ZZ_URDF = 1.19e-4 + MDF * L6**2


def m_cavusoglu(q, ibe_yy=IBE[1], idf_zz=IDF[2], l1=L1_PH, l2=LA):
    """Joint-space inertia of the PHANToM (Çavuşoğlu et al. 2002), absolute angles θ1..θ3."""
    _, t2, t3 = q
    Iaxx, Iayy, Iazz = IA
    Icxx, Icyy, Iczz = IC
    Ibexx, _, Ibezz = IBE
    Idfxx, Idfyy, _ = IDF
    m00 = (
        0.125 * (4 * Iayy + 4 * Iazz + 8 * IBASE + 4 * ibe_yy + 4 * Ibezz + 4 * Icyy + 4 * Iczz + 4 * Idfyy + 4 * idf_zz
                 + 4 * l1**2 * MA + l2**2 * MA + l1**2 * MC + 4 * L3**2 * MC)
        + 0.125 * (4 * ibe_yy - 4 * Ibezz + 4 * Icyy - 4 * Iczz + l1**2 * (4 * MA + MC)) * c(2 * t2)
        + 0.125 * (4 * Iayy - 4 * Iazz + 4 * Idfyy - 4 * idf_zz - l2**2 * MA - 4 * L3**2 * MC) * c(2 * t3)
        + l1 * (l2 * MA + L3 * MC) * c(t2) * s(t3)
    )
    m11 = Ibexx + Icxx + l1**2 * MA + 0.25 * l1**2 * MC
    m12 = -0.5 * l1 * (l2 * MA + L3 * MC) * s(t2 - t3)
    m22 = Iaxx + Idfxx + 0.25 * l2**2 * MA + L3**2 * MC
    return np.array([[m00, 0, 0], [0, m11, m12], [0, m12, m22]])


def g_cavusoglu(q, l1=L1_PH, l2=LA):
    _, t2, t3 = q
    return np.array([
        0.0,
        0.5 * G0 * (2 * l1 * MA + 2 * L5 * MBE + l1 * MC) * c(t2),
        0.5 * G0 * (l2 * MA + 2 * L3 * MC - 2 * L6 * MDF) * s(t3),
    ])


def test_phantom3_dynamics_equal_cavusoglu_model(rng):
    dev = rhi.device("phantom3")
    for q in random_q(dev, rng, 20):
        M = dev.mass_matrix(q)
        # the θ2/θ3 block uses the published numbers unchanged
        np.testing.assert_allclose(M[1:, 1:], m_cavusoglu(q)[1:, 1:], rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(M, m_cavusoglu(q, IBE_YY_URDF, IDF_ZZ_URDF), rtol=1e-12, atol=1e-18)
        # the yaw inertia moves by at most the two adjustments
        assert abs(M[0, 0] - m_cavusoglu(q)[0, 0]) <= (IBE_YY_URDF - IBE[1]) + (IDF_ZZ_URDF - IDF[2])
        np.testing.assert_allclose(dev.gravity(q), g_cavusoglu(q), rtol=1e-12, atol=1e-15)


def test_phantom3_mass_model_does_not_follow_l2(rng):
    q = random_q(rhi.device("phantom3"), rng, 1)[0]
    np.testing.assert_array_equal(rhi.device("phantom3", l2=0.3).mass_matrix(q), rhi.device("phantom3").mass_matrix(q))


def test_phantom3_l2_scales_the_third_column(rng):
    base = rhi.device("phantom3")
    for l2 in (0.165, 0.269, 0.365):  # bounds of eq. (4.27) and the C2 optimum of Table 4.1
        dev = rhi.device("phantom3", l2=l2)
        assert dev.params["l2"] == l2
        for q in random_q(dev, rng, 5):
            J, J0 = dev.jacobian(q), base.jacobian(q)
            np.testing.assert_allclose(J, j_phantom(q, l2=l2), rtol=0, atol=1e-12)
            np.testing.assert_allclose(J[:, 2], J0[:, 2] * l2 / 0.165, rtol=0, atol=1e-12)
            np.testing.assert_allclose(J[:, 1], J0[:, 1], rtol=0, atol=1e-15)
    with pytest.raises(InvalidInput, match="l2"):
        rhi.device("phantom3", l2=0.4)


def test_phantom3_theta_z_rotates_the_xy_rows(rng):
    """Eq. (4.26): J_M^2D = R_z(θz)[:2] J_PH; the z row is unchanged."""
    base = rhi.device("phantom3")
    for tz in np.deg2rad([-63.5, 0.0, 2.0, 89.0]):  # values of §4.4 and Table 4.1
        dev = rhi.device("phantom3", theta_z=tz)
        for q in random_q(dev, rng, 5):
            J, J0 = dev.jacobian(q), base.jacobian(q)
            np.testing.assert_allclose(J, rot_z(tz) @ j_phantom(q), rtol=0, atol=1e-12)
            np.testing.assert_allclose(J[:2], rot_z(tz)[:2, :2] @ J0[:2], rtol=0, atol=1e-12)
            np.testing.assert_allclose(J[2], J0[2], rtol=0, atol=1e-15)
            np.testing.assert_allclose(dev.fk(q), rot_z(tz) @ base.fk(q), rtol=0, atol=1e-15)
    with pytest.raises(InvalidInput, match="theta_z"):
        rhi.device("phantom3", theta_z=2.0)


def test_phantom3_z_ph_moves_only_the_working_plane(rng):
    base = rhi.device("phantom3")
    for z in (-0.2162, -0.065, 0.0539):  # Table 4.1 and §4.4
        dev = rhi.device("phantom3", z_ph=z)
        assert dev.params["z_ph"] == z
        fid = dev.model.getFrameId("working_plane")
        np.testing.assert_allclose(dev.model.frames[fid].placement.translation, [0, 0, z])
        q = random_q(dev, rng, 1)[0]
        np.testing.assert_array_equal(dev.fk(q), base.fk(q))
        np.testing.assert_array_equal(dev.jacobian(q), base.jacobian(q))
    with pytest.raises(InvalidInput, match="z_ph"):
        rhi.device("phantom3", z_ph=1.0)


def test_phantom3_table_4_1_planes_are_reachable():
    """A point of each thesis working plane is reachable with that design's l2 (IK lands on z = z_ph)."""
    for l2, z, tz in [(0.165, 0.0539, 0.0), (0.365, -0.2162, np.deg2rad(-63.5)), (0.269, -0.065, 0.0)]:
        dev = rhi.device("phantom3", l2=l2, z_ph=z, theta_z=tz)
        x = np.array([*(rot_z(tz)[:2, :2] @ [0.25, 0.0]), z])
        q = dev.ik(x, [tz, 0.3, 0.6])
        assert dev.within_limits(q)
        np.testing.assert_allclose(dev.fk(q)[2], dev.params["z_ph"], rtol=0, atol=1e-9)


def test_phantom3_limits_and_home():
    dev = rhi.device("phantom3")
    np.testing.assert_allclose(np.rad2deg(dev.q_min), [-90, -55, -20])
    np.testing.assert_allclose(np.rad2deg(dev.q_max), [90, 115, 80])
    np.testing.assert_allclose(dev.torque_limits[1], [1, 1, 1])
    assert not dev.within_limits(np.deg2rad([0, 70, 10]))  # θ2 − θ3 = 60° > 55°
    # eq. (4.25b) at θ = 0: x = l1, z = −l2
    np.testing.assert_allclose(dev.fk([0, 0, 0]), [0.21, 0.0, -0.165], atol=1e-15)
    np.testing.assert_allclose(dev.fk([0, np.pi / 2, np.pi / 2]), [0.165, 0.0, 0.21], atol=1e-15)


def test_per_joint_values_are_checked_by_name():
    """A device's and the plant's per-joint values go through one check (`rhi._validate.per_joint`).

    A scalar is every joint's; a bad value is refused naming its argument.
    """
    from rhi.devices.model import Device
    from rhi.sim.mjcf import PlantFriction

    base = load_device_by_name("planar3r")
    kw = dict(name="p", ee_frame=base.ee_frame, task_axes="xy", torque_max=base.torque_max)
    dev = Device(base.model, velocity_max=2.0, damping=[0.1, 0.2, 0.3], **kw)
    np.testing.assert_array_equal(dev.velocity_max, [2.0, 2.0, 2.0])
    np.testing.assert_array_equal(dev.armature, 0.0)
    for arg, bad in (("velocity_max", [1.0, 0.0, 1.0]), ("acceleration_max", [1.0, 1.0]), ("damping", -0.1),
                     ("frictionloss", [0.0, np.nan, 0.0]), ("armature", "heavy")):
        with pytest.raises(InvalidInput, match=f"^{arg}:"):
            Device(base.model, **{**kw, arg: bad})
    assert PlantFriction(0.1, [0.0, 0.1, 0.2]).check(3).damping.tolist() == [0.1, 0.1, 0.1]
    with pytest.raises(InvalidInput, match="^frictionloss:"):
        PlantFriction(0.1, [0.0, -0.1, 0.2]).check(3)
