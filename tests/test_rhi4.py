"""rhi4 and its non-redundant halves: closed-form Jacobians (thesis §3.5), derivatives, limits, IK, thesis numbers."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import fd_jacobian, random_q

import rhi
from rhi import metrics
from rhi.errors import InvalidInput, UnknownDevice, Unreachable

D = (0.254, 0.141, 0.21, 0.181)
s, c = np.sin, np.cos


def j_rhi(q, d=D):
    d1, d2, d3, d4 = d
    q1, q2, q3, q4 = q
    return np.array([
        [-d1 * s(q1), d2 * c(q2) - d3 * s(q2 + q3) + d4 * c(q2 + q4), -d3 * s(q2 + q3), d4 * c(q2 + q4)],
        [d1 * c(q1), d2 * s(q2) + d3 * c(q2 + q3) + d4 * s(q2 + q4), d3 * c(q2 + q3), d4 * s(q2 + q4)],
    ])


def j_phantom(q, d=D):
    q3, q4 = q
    return np.array([[-d[2] * s(q3), d[3] * c(q4)], [d[2] * c(q3), d[3] * s(q4)]])


def j_rehab(q, d=D):
    q1, q2 = q
    return np.array([
        [-d[0] * s(q1), (d[1] + d[3]) * c(q2) - d[2] * s(q2)],
        [d[0] * c(q1), (d[1] + d[3]) * s(q2) + d[2] * c(q2)],
    ])


@pytest.mark.parametrize("name, closed", [("rhi4", j_rhi), ("phantom", j_phantom), ("rehab", j_rehab)])
def test_jacobian_closed_form_and_finite_differences(name, closed, rng):
    dev = rhi.device(name)
    for q in random_q(dev, rng, 20):
        J = dev.jacobian(q)
        np.testing.assert_allclose(J, closed(q), atol=1e-12)
        np.testing.assert_allclose(J, fd_jacobian(dev.fk, q), atol=1e-8)
        np.testing.assert_allclose(dev.jacobian_derivative(q), fd_jacobian(dev.jacobian, q), atol=1e-6)


def test_d2_parameter_for_chapter_5(rng):
    dev = rhi.device("rhi4", d2=0.1405)
    q = random_q(dev, rng, 1)[0]
    np.testing.assert_allclose(dev.jacobian(q), j_rhi(q, (0.254, 0.1405, 0.21, 0.181)), atol=1e-12)
    with pytest.raises(InvalidInput, match="d3"):
        rhi.device("rhi4", d3=0.2)


def test_batch_equals_loop(rhi4, rng):
    Q = random_q(rhi4, rng, 7).reshape(7, 1, 4)
    J = rhi4.jacobian(Q)
    M = rhi4.mass_matrix(Q)
    assert J.shape == (7, 1, 2, 4) and M.shape == (7, 1, 4, 4)
    for k in range(7):
        np.testing.assert_array_equal(J[k, 0], rhi4.jacobian(Q[k, 0]))
        np.testing.assert_array_equal(M[k, 0], rhi4.mass_matrix(Q[k, 0]))


def test_mass_matrix_spd_and_dynamics_consistent(rhi4, rng):
    Q = random_q(rhi4, rng, 50)
    M = rhi4.mass_matrix(Q)
    np.testing.assert_allclose(M, np.swapaxes(M, -1, -2), atol=1e-14)
    assert np.all(np.linalg.eigvalsh(M) > 0)
    # Ṁ − 2C is skew-symmetric (passivity), Ṁ by finite differences along q̇
    q, dq = Q[0], rng.normal(size=4)
    Mdot = (rhi4.mass_matrix(q + 1e-6 * dq) - rhi4.mass_matrix(q - 1e-6 * dq)) / 2e-6
    S = Mdot - 2 * rhi4.coriolis(q, dq)
    np.testing.assert_allclose(S, -S.T, atol=1e-8)
    np.testing.assert_allclose(rhi4.gravity(Q), 0.0, atol=1e-12)  # horizontal plane


def test_lock_gives_thesis_halves(rhi4, rng):
    ph = rhi4.lock(q1=0.0, q2=0.0)
    for q in random_q(ph, rng, 5):
        np.testing.assert_allclose(ph.jacobian(q), j_phantom(q), atol=1e-12)
        full = np.array([0, 0, *q])
        np.testing.assert_allclose(ph.mass_matrix(q), rhi4.mass_matrix(full)[2:, 2:], atol=1e-14)
    np.testing.assert_allclose(rhi.device("phantom").fk([0, 0]), [0.254 + 0.21, -0.141 - 0.181], atol=1e-12)
    with pytest.raises(InvalidInput, match="q9"):
        rhi4.lock(q9=0.0)


def test_limits(rhi4):
    np.testing.assert_allclose(np.rad2deg(rhi4.q_min), [-55, 0, -55, -20])
    np.testing.assert_allclose(np.rad2deg(rhi4.q_max), [90, 145, 115, 80])
    np.testing.assert_allclose(rhi4.torque_limits[1], [3, 3, 1, 1])
    q = np.deg2rad([0, 60, 0, 0])  # q1 − q2 + 90° = 30° < 35°
    assert not rhi4.within_limits(q)
    assert rhi4.within_limits(np.deg2rad([10, 40, 20, 10]))


def test_thesis_point_and_rho(rhi4):
    q = np.array([0.125, 0.022, 0.298, 0.175])
    np.testing.assert_allclose(rhi4.fk(q), [0.49, -0.22], atol=2e-3)
    assert metrics.effective_manipulability(rhi4.jacobian(q), [0, 1]) == pytest.approx(0.37, abs=0.01)


@pytest.mark.parametrize("name, expected", [("phantom", (0.188, 0.167)), ("rehab", (0.296, 0.315))])
def test_table_3_1_rho_by_ik(name, expected):
    dev = rhi.device(name)
    for x, rho in zip([(0.49, -0.22), (0.49, -0.14)], expected):
        q = dev.ik(x, [0.3, 0.3])
        np.testing.assert_allclose(dev.fk(q), x, atol=1e-9)
        assert metrics.effective_manipulability(dev.jacobian(q), [0, 1]) == pytest.approx(rho, abs=0.002)


def test_ik_redundant_respects_limits_and_unreachable(rhi4):
    q = rhi4.ik([0.45, -0.1], np.deg2rad([10, 40, 20, 10]))
    assert rhi4.within_limits(q)
    np.testing.assert_allclose(rhi4.fk(q), [0.45, -0.1], atol=1e-9)
    with pytest.raises(Unreachable, match="x"):
        rhi4.ik([2.0, 0.0], np.zeros(4))
    with pytest.raises(InvalidInput, match="x"):
        rhi4.ik([np.nan, 0.0], np.zeros(4))


def test_home_force_ellipsoid_k_and_zeta(rhi4):
    """§6.4: with W = diag(1/T_i) at q = 0 and μ = 5, K = μ λmax = 123 and ζ = λmin/μ = 3.3."""
    F = metrics.force_ellipsoid(rhi4.jacobian(np.zeros(4)), rhi4.torque_limits[1])
    lam = np.linalg.eigvalsh(F)
    assert 5 * lam[-1] == pytest.approx(123, abs=1)
    assert lam[0] / 5 == pytest.approx(3.3, abs=0.05)


def test_remarks_I_and_II(rhi4, rng):
    """§3.3: ρ(RHI) ≥ ρ(PHANToM sub-chain) and Λ(RHI) ≤ Λ(sub-chain), joints 1–2 held at q1, q2."""
    Q = random_q(rhi4, rng, 1000)
    u = rng.normal(size=(1000, 2))
    J, M = rhi4.jacobian(Q), rhi4.mass_matrix(Q)
    Js, Ms = J[:, :, 2:], M[:, 2:, 2:]
    rho, rho_s = metrics.effective_manipulability(J, u), metrics.effective_manipulability(Js, u)
    lam, lam_s = metrics.effective_inertia(J, M, u), metrics.effective_inertia(Js, Ms, u)
    assert np.all(rho >= rho_s * (1 - 1e-12))
    assert np.all(lam <= lam_s * (1 + 1e-12))
    # the sub-chain is exactly the locked device
    sub = rhi4.lock(q1=Q[0, 0], q2=Q[0, 1])
    np.testing.assert_allclose(sub.jacobian(Q[0, 2:]), Js[0], atol=1e-14)
    np.testing.assert_allclose(sub.mass_matrix(Q[0, 2:]), Ms[0], atol=1e-14)


def test_bad_input(rhi4, tmp_path):
    with pytest.raises(UnknownDevice, match="nope"):
        rhi.device("nope")
    with pytest.raises(InvalidInput, match="q"):
        rhi4.jacobian([0.0, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="NaN"):
        rhi4.fk([0.0, np.nan, 0.0, 0.0])
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/><joint name='j' type='revolute'><parent link='a'/></joint></robot>")
    with pytest.raises(rhi.errors.ModelError, match="path"):
        rhi.device_from_urdf(bad, ee_frame="a")


def test_device_from_urdf_matches_bundled(rhi4):
    from rhi.devices.model import MODELS

    path = MODELS / "rhi4" / "rhi4.urdf"
    dev = rhi.device_from_urdf(path, ee_frame="handle", task="xy")
    th = rhi4.theta(np.array([0.1, 0.2, 0.3, 0.4]))
    np.testing.assert_allclose(dev.fk(th), rhi4.fk([0.1, 0.2, 0.3, 0.4]), atol=1e-14)
    with pytest.raises(rhi.errors.ModelError, match="ee_frame"):
        rhi.device_from_urdf(path, ee_frame="nope")


def test_mass_matrix_equals_kinetic_energy_by_hand(rhi4, rng):
    """M from Pinocchio equals Σ m J_cᵀJ_c + I_zz J_ωᵀJ_ω with centre-of-mass kinematics written out by hand.

    Inertial values are read from the URDF text and the rotor inertias from device.toml (not through Pinocchio).
    """
    import tomllib
    import xml.etree.ElementTree as ET

    from rhi.devices.model import MODELS

    root = ET.parse(MODELS / "rhi4" / "rhi4.urdf").getroot()
    body = {}
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is not None:
            com_x = float(inertial.find("origin").get("xyz").split()[0])
            body[link.get("name")] = (float(inertial.find("mass").get("value")), com_x,
                                      float(inertial.find("inertia").get("izz")))
    d1, d2, d3, d4 = D

    def com_and_angle(q):
        q1, q2, q3, q4 = q
        e = lambda a: np.array([c(a), s(a)])  # noqa: E731
        p2 = d1 * e(q1)
        p3 = p2 + d2 * e(q2 - np.pi / 2)
        p4 = p3 + d3 * e(q2 + q3)
        frames = {"rehab_link1": (np.zeros(2), q1), "rehab_link2": (p2, q2 - np.pi / 2),
                  "phantom_base": (p3, q2 - np.pi / 2), "phantom_link1": (p3, q2 + q3),
                  "phantom_link2": (p4, q2 + q4 - np.pi / 2)}
        return {k: (o + body[k][1] * e(a), a) for k, (o, a) in frames.items()}

    assert set(body) == {"rehab_link1", "rehab_link2", "phantom_base", "phantom_link1", "phantom_link2"}
    for q in random_q(rhi4, rng, 5):
        M = np.diag(tomllib.loads((MODELS / "rhi4" / "device.toml").read_text())["armature"])
        for name, (mass, _, izz) in body.items():
            Jc = fd_jacobian(lambda p, name=name: com_and_angle(p)[name][0], q)
            Jw = fd_jacobian(lambda p, name=name: np.array(com_and_angle(p)[name][1]), q)
            M += mass * Jc.T @ Jc + izz * np.outer(Jw, Jw)
        np.testing.assert_allclose(rhi4.mass_matrix(q), M, atol=1e-9)
