"""Wheeled mobile manipulator control and simulation (thesis App. A and B): `rhi.control.mobile`, `rhi.sim.mobile`."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import fd_jacobian

from rhi import thesis as T
from rhi.control.mobile import (
    W_TAU_LIMITS,
    AMDConfig,
    AMDController,
    DMConfig,
    JointBounds,
    PinvAccelConfig,
    PinvAccelController,
    WeightedConfig,
    WeightedDistributionController,
    WMMKinematics,
    acceleration_bounds,
    auxiliary_projection,
    auxiliary_projector,
    base_stop_acceleration,
    chain_jacobian_derivatives,
    det_terms,
    distribution_gamma,
    distribution_ratio,
    dm_cartesian_gradient,
    dm_gradient,
    dm_value,
    joint_bounds,
    manipulability_det,
    manipulability_det_gradient,
    manipulability_det_hessian,
    motion_weights,
    scale_factor,
    sns_acceleration,
    velocity_bounds,
    weighted_pinv_psd,
)
from rhi.devices.model import device
from rhi.errors import InfeasibleLimits, InvalidInput
from rhi.metrics import directional_manipulability
from rhi.sim.mobile import (
    MobilePlant,
    SlipModel,
    Trajectory,
    circle,
    hold,
    simulate_mobile,
)

PI = np.pi
Q0 = np.array([0, 0, 0, 0, PI / 6, 0, PI / 2, 0, -PI / 6, 0.0])  # thesis §A.4.1 / §B.4.1


@pytest.fixture(scope="module")
def wmm():
    return device("wmm")


@pytest.fixture(scope="module")
def kin(wmm):
    return WMMKinematics(wmm)


@pytest.fixture(scope="module")
def bounds(wmm):
    return joint_bounds(wmm)


def _configs(rng, k):
    """Seeded configurations around the thesis start, well inside the joint limits (non-singular arm)."""
    return Q0 + rng.normal(scale=0.4, size=(k, 10)) * np.r_[1, 1, 1, np.ones(7)]


def _arm(kin, q):
    """(J_m, ∂J_m/∂q_m, ∂²J_m/∂q_m²) of the arm columns at q."""
    J6 = kin.jacobian6(q)[1][:, 3:]
    dJ, d2J = chain_jacobian_derivatives(J6)
    return J6[:3], dJ, d2J


# ================================================================= derivatives vs finite differences
def test_chain_derivatives_match_device_and_finite_differences(wmm, kin):
    rng = np.random.default_rng(1)
    for q in _configs(rng, 3):
        J6 = kin.jacobian6(q)[1]
        dJ, d2J = chain_jacobian_derivatives(J6)
        np.testing.assert_allclose(dJ, wmm.jacobian_derivative(q), rtol=0, atol=1e-12)
        fd = fd_jacobian(lambda qq: chain_jacobian_derivatives(kin.jacobian6(qq)[1], second=False)[0], q)
        np.testing.assert_allclose(d2J, fd, rtol=0, atol=1e-8)
        np.testing.assert_allclose(d2J, np.swapaxes(d2J, -1, -2), rtol=0, atol=1e-14)


def test_dm_value_and_gradient_A9(kin):
    rng = np.random.default_rng(2)
    for q in _configs(rng, 4):
        for u in ([1.0, 0, 0], [0, 0, 1.0], rng.normal(size=3)):
            Jm, dJ, _ = _arm(kin, q)
            h2 = dm_value(Jm, u, W_TAU_LIMITS)
            assert h2 == pytest.approx(float(directional_manipulability(Jm, u, W_TAU_LIMITS)), rel=1e-12)
            g = dm_gradient(Jm, dJ, u, W_TAU_LIMITS)

            def H(qm, q=q, u=u):
                return dm_value(kin.jacobian6(np.r_[q[:3], qm])[1][:3, 3:], u, W_TAU_LIMITS)

            fd = fd_jacobian(H, q[3:])
            np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-7 * abs(h2))


def test_dm_cartesian_gradient_A10(kin):
    """∇_x H₂ is the rate of H₂ when the end-effector moves along each axis by q̇_m = J_m⁺ e_i."""
    rng = np.random.default_rng(3)
    u = np.array([1.0, 0, 0])
    for q in _configs(rng, 3):
        Jm, dJ, _ = _arm(kin, q)
        gx = dm_cartesian_gradient(Jm, dJ, u, W_TAU_LIMITS)
        Jp = np.linalg.pinv(Jm)
        for i in range(3):
            h = 1e-6

            def H(s, q=q, i=i, Jp=Jp):
                return dm_value(kin.jacobian6(np.r_[q[:3], q[3:] + s * Jp[:, i]])[1][:3, 3:], u, W_TAU_LIMITS)

            assert gx[i] == pytest.approx((H(h) - H(-h)) / (2 * h), rel=1e-6, abs=1e-8)


def test_det_gradient_and_hessian_B14_B18(kin):
    rng = np.random.default_rng(4)
    for q in _configs(rng, 3):
        Jm, dJ, d2J = _arm(kin, q)

        def Hq(qm, q=q):
            return manipulability_det(kin.jacobian6(np.r_[q[:3], qm])[1][:3, 3:])

        def grad(qm, q=q):
            Jq, dJq, _ = _arm(kin, np.r_[q[:3], qm])
            return manipulability_det_gradient(Jq, dJq)

        g = manipulability_det_gradient(Jm, dJ)
        H = manipulability_det_hessian(Jm, dJ, d2J)
        np.testing.assert_allclose(g, fd_jacobian(Hq, q[3:]), rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(H, fd_jacobian(grad, q[3:]), rtol=1e-6, atol=1e-8)
        np.testing.assert_allclose(H, H.T, rtol=0, atol=1e-14)
        # the controller's O(m²) path: the same H, ∇H, ∇²H q̇ and σ_min
        v = rng.normal(size=7)
        det, g2, hv, sigma = det_terms(kin.jacobian6(q)[1][:, 3:], v)
        assert det == pytest.approx(manipulability_det(Jm), rel=1e-12)
        np.testing.assert_allclose(g2, g, rtol=1e-10, atol=1e-15)
        np.testing.assert_allclose(hv, H @ v, rtol=1e-9, atol=1e-14)
        assert sigma == pytest.approx(np.linalg.svd(Jm, compute_uv=False)[-1], rel=1e-10)


def test_derivative_functions_broadcast(kin):
    rng = np.random.default_rng(5)
    qs = _configs(rng, 6).reshape(2, 3, 10)
    J6 = np.stack([[kin.jacobian6(q)[1][:, 3:] for q in row] for row in qs])
    dJ, d2J = chain_jacobian_derivatives(J6)
    assert dJ.shape == (2, 3, 3, 7, 7) and d2J.shape == (2, 3, 3, 7, 7, 7)
    H = manipulability_det_hessian(J6[..., :3, :], dJ, d2J)
    g = manipulability_det_gradient(J6[..., :3, :], dJ)
    gd = dm_gradient(J6[..., :3, :], dJ, [0, 0, 1], W_TAU_LIMITS)
    J1, dJ1, d2J1 = _arm(kin, qs[1, 2])
    np.testing.assert_allclose(H[1, 2], manipulability_det_hessian(J1, dJ1, d2J1), rtol=1e-12, atol=1e-16)
    np.testing.assert_allclose(g[1, 2], manipulability_det_gradient(J1, dJ1), rtol=1e-12, atol=1e-16)
    np.testing.assert_allclose(gd[1, 2], dm_gradient(J1, dJ1, [0, 0, 1], W_TAU_LIMITS), rtol=1e-12)


# ================================================================================ bounds (B.6–B.8, A.13)
def test_joint_bounds_table_B1(bounds):
    np.testing.assert_array_equal(bounds.dq_max, [0.25, 0.25, 1.0, 1.75, 1.75, 1.75, 1.75, 3.14, 3.14, 3.14])
    np.testing.assert_array_equal(bounds.ddq_max, [0.025, 0.025, 1.5, 3, 3, 3, 3, 5, 5, 5])
    np.testing.assert_array_equal(bounds.q_max[[4, 6, 8]], [2.2, 2.5, 2.0])
    np.testing.assert_array_equal(bounds.dq_min, -bounds.dq_max)


def _viable(q, dq, b, T, tol=1e-12):
    """The joint can still stop before each position bound at full deceleration (sampled stopping distance)."""
    up = q + 0.5 * dq * T + np.maximum(dq, 0) ** 2 / (2 * -b.ddq_min) + -b.ddq_min * T * T / 8 <= b.q_max + tol
    lo = q + 0.5 * dq * T - np.minimum(dq, 0) ** 2 / (2 * b.ddq_max) - b.ddq_max * T * T / 8 >= b.q_min - tol
    return up & lo


def test_acceleration_bounds_keep_every_bound_over_one_sample(bounds):
    rng = np.random.default_rng(6)
    T = 0.005
    lo_q = np.where(np.isfinite(bounds.q_min), bounds.q_min, -3.0)
    hi_q = np.where(np.isfinite(bounds.q_max), bounds.q_max, 3.0)
    q = rng.uniform(lo_q, hi_q, size=(4000, 10))
    q[:2000, [4, 6, 8]] = hi_q[[4, 6, 8]] - rng.uniform(0, 0.02, size=(2000, 3))  # close to the bounds
    dq = rng.uniform(bounds.dq_min, bounds.dq_max, size=(4000, 10))
    lo, hi = acceleration_bounds(q, dq, bounds, T)
    assert np.all(lo <= hi)
    viable = _viable(q, dq, bounds, T)
    assert viable.mean() > 0.5 and (~viable).sum() > 100
    for a in (lo, hi, 0.5 * (lo + hi)):
        q1, dq1 = q + dq * T + 0.5 * a * T * T, dq + a * T
        assert np.all(a >= bounds.ddq_min - 1e-12) and np.all(a <= bounds.ddq_max + 1e-12)
        assert np.all(dq1 >= bounds.dq_min - 1e-9) and np.all(dq1 <= bounds.dq_max + 1e-9)
        # from a viable state the next one is within the position bounds and still viable
        ok = (q1 <= bounds.q_max + 1e-12) & (q1 >= bounds.q_min - 1e-12) & _viable(q1, dq1, bounds, T)
        assert np.all(ok | ~viable)


def test_acceleration_bounds_brake_near_a_position_bound(bounds):
    """Fig. B.2: a joint pushed toward its bound at full speed brakes in time and creeps up to the bound."""
    T = 0.001
    q, dq = np.array(Q0), np.zeros(10)
    dq[4] = bounds.dq_max[4]  # joint q2 (bounded at 2.2 rad) at full speed
    peak = q[4]
    for _ in range(3000):
        lo, hi = acceleration_bounds(q, dq, bounds, T)
        a = hi.copy()  # always push as hard as allowed toward the bound
        q, dq = q + dq * T + 0.5 * a * T * T, dq + a * T
        peak = max(peak, q[4])
    assert peak <= bounds.q_max[4]
    assert peak >= bounds.q_max[4] - 1e-3  # it does get there
    assert abs(dq[4]) < 0.05 * bounds.dq_max[4]


def test_velocity_bounds_A13(bounds):
    T = 0.01
    q = Q0.copy()
    lo, hi = velocity_bounds(q, bounds, T)
    np.testing.assert_allclose(hi, bounds.dq_max)  # far from every position bound
    q[4] = bounds.q_max[4] - 0.01
    lo, hi = velocity_bounds(q, bounds, T)
    assert hi[4] == pytest.approx(math.sqrt(2 * 3.0 * 0.01))  # braking distance
    assert lo[4] == pytest.approx(bounds.dq_min[4])


def test_scale_factor_fig_B4():
    lo, hi = -np.ones(3), np.ones(3)
    assert scale_factor([0.5, 0, 0], [0, 0, 0], lo=lo, hi=hi) == (1.0, 0)
    s, i = scale_factor([2.0, 0.5, -4.0], [0.0, 0.0, 0.0], lo=lo, hi=hi)
    assert (s, i) == (0.25, 2)
    s, i = scale_factor([1.0, 0, 0], [0.0, 1.5, 0.0], lo=lo, hi=hi)  # a fixed part out of bounds
    assert (s, i) == (0.0, 1)


def test_base_stop_acceleration_B20():
    T, A = 0.01, np.array([0.025, 0.025, 1.5])
    v = np.array([0.05, -0.012, 0.0])
    steps = 0
    while np.any(v != 0):
        a = base_stop_acceleration(v, -A, A, T)
        assert np.all(np.abs(a) <= A + 1e-15)
        v = v + a * T
        steps += 1
    assert steps == math.ceil(0.05 / 0.025 / T)  # t_f − t₀ = |V_b / A_min,b|


# ============================================================================ weighted distribution (App. A)
def test_weighted_pinv_and_gamma_A11_A15(kin, wmm):
    ctl = WeightedDistributionController(wmm)
    _, J, _ = ctl.jacobian(Q0)
    for g in (0.2, 0.5, 0.9):
        w = motion_weights(g, 4, 7)
        W = np.diag(w)
        np.testing.assert_allclose(weighted_pinv_psd(J, w), W @ J.T @ np.linalg.inv(J @ W @ J.T), rtol=1e-9, atol=1e-12)
    J0 = weighted_pinv_psd(J, motion_weights(0.0, 4, 7))
    np.testing.assert_array_equal(J0[:4], 0)  # γ = 0: the arm does everything
    np.testing.assert_allclose(J @ J0, np.eye(3), atol=1e-12)
    np.testing.assert_array_equal(distribution_gamma([0.1, 0.2, 0.5, 1.0, 3.0], 0.2), [0, 0, 0.5, 1.0, 1.0])
    assert distribution_ratio([0.5, -1.0], [-2.0, -4.0], [1.0, 1.0]) == pytest.approx(0.5)
    assert distribution_ratio([0.5, -1.0], [-2.0, 0.0], [1.0, 1.0]) == math.inf


def test_weighted_controller_keeps_base_still_for_slow_tasks(wmm):
    ctl = WeightedDistributionController(wmm, WeightedConfig(dt=0.01))
    x0 = wmm.fk(Q0)
    cmd = ctl.step(0.0, Q0, x0 + [0.0, 0.0, 0.005], np.zeros(3))
    assert cmd.gamma == 0.0 and np.all(cmd.v[:4] == 0)
    _, J, _ = ctl.jacobian(Q0)
    np.testing.assert_allclose(J @ cmd.v, 10.0 * np.array([0, 0, 0.005]), atol=1e-12)
    trad = WeightedDistributionController(wmm, WeightedConfig(dt=0.01, distribution="pinv"))
    assert np.any(trad.step(0.0, Q0, x0 + [0.0, 0.0, 0.005], np.zeros(3)).v[:4] != 0)


def test_dm_enhancement_raises_dm_cartesian_then_null_space(wmm):
    """§A.4.3: along x the Cartesian phase lowers the end-effector and raises DM, the null space raises it further."""
    dt = 0.01
    ctl = WeightedDistributionController(wmm, WeightedConfig(dt=dt, dm=DMConfig(u=(1.0, 0, 0))))
    log1 = simulate_mobile(ctl, hold(wmm.fk(Q0), duration=5.0, dt=dt), Q0, stage="dm_cartesian")
    q1 = log1.q[-1] + log1.dq[-1] * dt
    d0, d1 = ctl.dm(Q0), ctl.dm(q1)
    assert d0 == pytest.approx(3.825, abs=0.005)  # thesis Fig. A.9
    assert d1 > d0 + 0.03 and np.all(np.diff(log1.dm) >= -1e-12)
    x1 = wmm.fk(q1)
    assert 0.36 <= x1[2] < wmm.fk(Q0)[2] - 0.02  # thesis: z 0.492 -> 0.456, within the bounds of A.18
    np.testing.assert_allclose(x1[:2], wmm.fk(Q0)[:2], atol=1e-4)  # only z is optimised
    log2 = simulate_mobile(ctl, hold(x1, duration=5.0, dt=dt), q1, stage="dm_null")
    q2 = log2.q[-1] + log2.dq[-1] * dt
    assert ctl.dm(q2) > d1 + 0.2
    assert np.abs(log2.x - x1).max() < 1e-3  # the self-motion keeps the end-effector in place
    assert log1.bounds_ok and log2.bounds_ok


# ============================================================================== AMD (App. B)
def _state(rng, q=None):
    q = Q0 + rng.normal(scale=0.2, size=10) if q is None else q
    dq = rng.normal(scale=0.05, size=10) * np.r_[0.2, 0.2, 0.2, np.ones(7)]
    return q, dq


def test_sns_meets_the_task_exactly_when_feasible(kin, bounds):
    rng = np.random.default_rng(7)
    T = 0.005
    n_feasible = n_scaled = 0
    for _ in range(60):
        q, dq = _state(rng)
        J = kin.jacobian6(q)[1][:3]
        b = kin.drift(q, dq)
        lo, hi = acceleration_bounds(q, dq, bounds, T)
        ddx = rng.normal(scale=rng.choice([0.1, 3.0]), size=3)
        enabled = np.r_[np.zeros(3, bool), np.ones(7, bool)]
        res = sns_acceleration(J, b, ddx, lo=lo, hi=hi, enabled=enabled, fixed=np.zeros(10))
        assert np.all(res.ddq >= lo - 1e-12) and np.all(res.ddq <= hi + 1e-12)
        assert np.all(res.ddq[:3] == 0)  # the disabled base stays at its fixed (zero) acceleration
        if res.feasible:
            n_feasible += 1
            np.testing.assert_allclose(J @ res.ddq, ddx - b, rtol=0, atol=1e-9)
        elif res.alpha > 0:
            n_scaled += 1
            np.testing.assert_allclose(J @ res.ddq, res.alpha * ddx - b, rtol=0, atol=1e-9)
    assert n_feasible > 10 and n_scaled > 0


def test_auxiliary_projector_B10(kin):
    rng = np.random.default_rng(8)
    q = Q0 + rng.normal(scale=0.2, size=10)
    J = kin.jacobian6(q)[1][:3]
    P_N = np.eye(10) - np.linalg.pinv(J) @ J
    active = np.ones(10, bool)
    active[[0, 1, 2, 6]] = False
    P_A = auxiliary_projector(P_N, active)
    np.testing.assert_allclose(J @ P_A, 0, atol=1e-12)
    np.testing.assert_allclose(P_A[~active], 0, atol=1e-12)  # (I − S) P_A = 0
    np.testing.assert_allclose(P_A @ P_A, P_A, atol=1e-12)
    JS = J[:, active]  # the orthogonal projector onto null(J_S) on the active joints
    np.testing.assert_allclose(P_A[np.ix_(active, active)], np.eye(active.sum()) - np.linalg.pinv(JS) @ JS, atol=1e-12)


def test_auxiliary_projection_is_the_B10_projector(kin, bounds):
    """The AMD's O(r n) projection equals `auxiliary_projector` (B.10 as printed) on the SNS active sets."""
    rng = np.random.default_rng(11)
    enabled = np.r_[np.zeros(3, bool), np.ones(7, bool)]
    checked = 0
    for _ in range(20):
        q, dq = _state(rng)
        J = kin.jacobian6(q)[1][:3]
        lo, hi = acceleration_bounds(q, dq, bounds, 0.005)
        res = sns_acceleration(J, kin.drift(q, dq), rng.normal(scale=3.0, size=3), lo=lo, hi=hi, enabled=enabled,
                               fixed=np.zeros(10))
        if res.gram_inv is None:
            continue
        v = rng.normal(size=10)
        P_N = np.eye(10) - np.linalg.pinv(J) @ J
        # the reference pseudo-inverts P_N[D, D], whose condition number grows as cond(J_S)²
        # (seen: differences up to 3e-15 cond(J_S)²)
        tol = 1e-14 * np.linalg.cond(J[:, res.active]) ** 2
        np.testing.assert_allclose(auxiliary_projection(J, res.active, res.gram_inv, v),
                                   auxiliary_projector(P_N, res.active) @ v, rtol=0, atol=tol)
        checked += 1
    assert checked >= 10


def test_amd_step_task_and_bounds(wmm, kin):
    """J q̈ = α ẍ − J̇q̇ to 1e-9 (the tertiary motion lies in the null space) and q̈ within B.6–B.8."""
    rng = np.random.default_rng(9)
    ctl = AMDController(wmm, AMDConfig(dt=0.005))
    x0 = wmm.fk(Q0)
    for k in range(40):
        q, dq = _state(rng)
        target = x0 + rng.normal(scale=0.02, size=3), rng.normal(scale=0.05, size=3), np.zeros(3)
        cmd = ctl.step(k * 0.005, q, dq, *target)
        J = kin.jacobian6(q)[1][:3]
        assert np.all(cmd.ddq >= cmd.lo - 1e-12) and np.all(cmd.ddq <= cmd.hi + 1e-12)
        if cmd.alpha > 0:
            np.testing.assert_allclose(J @ cmd.ddq, cmd.alpha * cmd.ddx - kin.drift(q, dq), rtol=0, atol=1e-9)
        if not cmd.base_active:
            np.testing.assert_array_equal(cmd.active[:3], False)


def test_amd_keeps_the_base_still_inside_the_workspace(wmm):
    """§B.4.3: a circle the arm can follow alone: AMD commands no base motion at all (exactly zero)."""
    ctl = AMDController(wmm, AMDConfig(dt=0.01))
    log = simulate_mobile(ctl, circle(wmm.fk(Q0), 0.05, duration=20.0, dt=0.01), Q0)
    assert np.all(log.dq[:, :3] == 0) and np.all(log.ddq[:, :3] == 0)
    assert np.all(log.base_active == 0) and np.all(log.alpha == 1)
    assert np.abs(log.error).max() < 2e-3
    assert log.bounds_ok
    trad = simulate_mobile(PinvAccelController(wmm, PinvAccelConfig(dt=0.01)),
                    circle(wmm.fk(Q0), 0.05, duration=5.0, dt=0.01), Q0)
    assert np.abs(trad.dq[:, :3]).max() > 1e-3  # the traditional controller always moves the base


def test_amd_singularity_avoidance_B42(wmm):
    """§B.4.2: beyond the workspace, plain AMD drives the arm singular; with avoidance the base takes over."""
    traj = circle(wmm.fk(Q0), 0.25, duration=12.0, dt=0.01)
    plain = simulate_mobile(AMDController(wmm, AMDConfig(dt=0.01, singularity_avoidance=False)), traj, Q0)
    sa = simulate_mobile(AMDController(wmm, AMDConfig(dt=0.01)), traj, Q0)
    assert plain.sigma.min() < 0.05 < 0.1 < sa.sigma.min()
    first = sa.t[np.argmax(sa.base_active > 0)]
    assert 4.0 < first < 9.0  # thesis: 6.40 s
    assert np.all(sa.dq[sa.t < first, :3] == 0)
    assert np.linalg.norm(sa.error, axis=1).max() < 0.01 < np.linalg.norm(plain.error, axis=1).max()
    assert plain.bounds_ok and sa.bounds_ok


# ====================================================================================== plant
def test_plant_kinematics_match_the_device(wmm):
    plant = MobilePlant(wmm)
    rng = np.random.default_rng(10)
    for q in _configs(rng, 3):
        plant.reset(q)
        np.testing.assert_allclose(plant.x, wmm.fk(q), rtol=0, atol=1e-12)
        np.testing.assert_allclose(plant.q, q, rtol=0, atol=0)


def test_plant_base_follows_commands_and_slips(wmm):
    v = np.array([0.05, 0.02, 0.1])  # generalized base velocity [m/s, m/s, rad/s]
    end = {}
    for name, slip in (("none", SlipModel.none()), ("slip", SlipModel(seed=3)), ("slip2", SlipModel(seed=3))):
        plant = MobilePlant(wmm, slip=slip)
        plant.reset(Q0)
        th = 0.0
        for _ in range(100):  # 1 s at 100 Hz, constant body twist
            wheels = plant.wheel_speeds(v, th)
            plant.step(wheels, Q0[3:], np.zeros(7), 0.01)
            th += v[2] * 0.01
        end[name] = plant.q
    np.testing.assert_allclose(end["none"][2], 0.1, atol=2e-3)
    assert np.linalg.norm(end["none"][:2]) == pytest.approx(np.linalg.norm(v[:2]), rel=0.02)
    np.testing.assert_allclose(end["none"][3:], Q0[3:], atol=1e-3)  # the arm holds its pose
    assert np.linalg.norm(end["slip"][:2]) < np.linalg.norm(end["none"][:2])  # slip loses motion
    np.testing.assert_array_equal(end["slip"], end["slip2"])  # seeded: bit for bit


def test_plant_step_is_the_substep_loop(wmm):
    """`MobilePlant.step` (its loop with hoisted lookups) equals the plain per-substep loop bit for bit."""
    import mujoco

    a, b = MobilePlant(wmm, slip=SlipModel(seed=4)), MobilePlant(wmm, slip=SlipModel(seed=4))
    a.reset(Q0)
    b.reset(Q0)
    dqa = np.linspace(-0.2, 0.2, 7)
    wheels = a.wheel_speeds(np.array([0.05, 0.02, 0.1]), 0.0)
    for _ in range(3):
        qa = a.q[3:]
        a.step(wheels, lambda u, qa=qa: qa + dqa * u, dqa, 0.01)
        twist = b.realised_twist(wheels, 0.01)  # the same seeded slip draw as a's
        d = b.data
        for i in range(int(round(0.01 / b.timestep))):
            c, sn = math.cos(d.qpos[b._qadr[2]]), math.sin(d.qpos[b._qadr[2]])
            d.ctrl[b._base_act] = (c * twist[0] - sn * twist[1], sn * twist[0] + c * twist[1], twist[2])
            d.ctrl[b._pos_act] = qa + dqa * ((i + 1) * b.timestep)
            d.ctrl[b._vel_act] = dqa
            mujoco.mj_step(b.model, d)
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.data.ctrl, b.data.ctrl)


def test_closed_loop_on_the_plant_bounds_and_errors(wmm):
    """A short AMD run beyond the workspace on MuJoCo: commands within bounds, arm encoders within joint limits."""
    dt = 0.01
    ctl = AMDController(wmm, AMDConfig(dt=dt))
    plant = MobilePlant(wmm)
    log = simulate_mobile(ctl, circle(wmm.fk(Q0), 0.25, duration=9.0, dt=dt), Q0, plant=plant)
    b = ctl.bounds
    assert log.bounds_ok
    assert np.all(log.q_true[:, 3:] >= b.q_min[3:] - 1e-3) and np.all(log.q_true[:, 3:] <= b.q_max[3:] + 1e-3)
    assert np.abs(log.q_true[:, 3:] - log.q[:, 3:]).max() < 1e-3  # the arm servo tracks the command
    moved = np.any(log.dq[:, :3] != 0, axis=1)
    assert moved.any() and np.abs(log.x - log.x_est).max() > 0  # the base slipped: the truth differs
    assert np.abs(log.error).max() < 0.02


# ================================================================================ bad input
def test_bad_input_errors(wmm, bounds):
    with pytest.raises(InfeasibleLimits, match="q_min"):
        JointBounds(np.ones(10), np.zeros(10), -np.ones(10), np.ones(10), -np.ones(10), np.ones(10))
    with pytest.raises(InfeasibleLimits, match="ddq_min"):
        JointBounds(-np.ones(2), np.ones(2), -np.ones(2), np.ones(2), np.ones(2), 2 * np.ones(2))
    with pytest.raises(InvalidInput, match="dq_min"):
        JointBounds(-np.ones(2), np.ones(2), [np.nan, -1], np.ones(2), -np.ones(2), np.ones(2))
    t = np.arange(3) * 0.01
    x = np.zeros((3, 3))
    x[1, 0] = np.nan
    with pytest.raises(InvalidInput, match="trajectory.x"):
        Trajectory(t, x, np.zeros((3, 3)), np.zeros((3, 3)))
    ctl = AMDController(wmm, AMDConfig(dt=0.01))
    outside = Q0.copy()
    outside[4] = 2.5  # joint q2 is bounded at ±2.2 rad (Table B.1)
    with pytest.raises(InvalidInput, match="q0"):
        simulate_mobile(ctl, hold(wmm.fk(Q0), duration=0.1, dt=0.01), outside)
    with pytest.raises(InvalidInput, match="q0"):
        MobilePlant(wmm).reset(outside)
    with pytest.raises(InvalidInput, match="trajectory"):
        simulate_mobile(ctl, hold(wmm.fk(Q0), duration=0.1, dt=0.02), Q0)
    with pytest.raises(InvalidInput, match="x_des"):
        ctl.step(0.0, Q0, np.zeros(10), [np.nan, 0, 0], np.zeros(3), np.zeros(3))
    with pytest.raises(InvalidInput, match="dt"):
        AMDConfig(dt=0.0)
    with pytest.raises(InfeasibleLimits, match="x_min"):
        DMConfig(x_min=(0.6,), x_max=(0.5,))
    with pytest.raises(InvalidInput, match="stage"):
        WeightedDistributionController(wmm).step(0.0, Q0, wmm.fk(Q0), np.zeros(3), stage="dm_null")
    with pytest.raises(InvalidInput, match="gamma"):
        motion_weights(1.5, 4, 7)
    with pytest.raises(InvalidInput, match="lateral"):
        SlipModel(lateral=1.2)
    with pytest.raises(InvalidInput, match="device"):
        AMDController(device("gen3"))


# ========================================================================== experiments (short)
def test_short_experiments_report_thesis_beside_ours():
    from rhi.experiments import appa, appb

    r = appa.dm_enhancement(dt=0.02, t_cartesian=1.0, t_null=1.0, t_long=0.0)
    rows = {row.quantity: row for t in r.tables for row in t.rows}
    # rhi's Gen3 (thesis 1.125: xfail in test_thesis_numbers)
    assert rows["DM along z at q0"].ours == pytest.approx(1.12444, abs=1e-5)
    assert rows["‖W_τ τ‖ for a 10 N z force at q0"].ours == pytest.approx(8.89, abs=0.01)  # = 10 N / DM
    r = appb.singularity(duration=1.0, dt=0.02)
    rows = {row.quantity: row for row in r.tables[0].rows}
    # the thesis enables the base at 6.40 s: not within the first second
    assert rows["with avoidance: base first enabled"].source == T.BASE_ON_B.key
    assert not rows["with avoidance: base first enabled"].ours <= 1.0
    assert rows["with avoidance: min σ_min(J_m)"].ours > 0.2  # 1 s into the circle the arm is far from singular
    assert r.arrays["with_sigma"].shape == r.arrays["t"].shape == (51,)


def test_box_push_static_rows(wmm):
    """Fig. A.8 read statically: at the push force the weighted torque norm at q0 is the thesis's 40 N m.

    The rows are recomputed as τ = J_mᵀ F e_x at q0 and at a configuration with the shoulder turned.
    """
    from rhi.control.mobile import W_TAU_LIMITS
    from rhi.experiments.appa import kinematic as appa

    w_tau = np.diag(1.0 / np.asarray(W_TAU_LIMITS))
    q1 = appa.Q0.copy()
    q1[4] += 0.3
    rows = appa._push_rows(wmm, w_tau, (("q0", {"q_end": appa.Q0}), ("turned", {"q_end": q1})))
    F = rows[0].ours
    t0 = wmm.jacobian(appa.Q0)[:, 3:].T @ np.array([F, 0.0, 0.0])
    assert np.linalg.norm(w_tau @ t0) == pytest.approx(40.0)
    assert rows[1].ours == 1 + np.argmax(np.abs(t0) / appa.PUSH_LIMITS) and rows[1].thesis == T.PUSH_JOINT
    assert rows[2].ours == pytest.approx(np.abs(t0).max()) and rows[2].bound == "max"
    t1 = wmm.jacobian(q1)[:, 3:].T @ np.array([F, 0.0, 0.0])
    assert rows[3].ours == pytest.approx(np.abs(t1).max()) and rows[3].ours != pytest.approx(rows[2].ours)
