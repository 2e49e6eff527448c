"""Control layer (thesis ch. 6–7): objective gradients, ASO, transition, ASCM, LP allocation, controller."""

from __future__ import annotations

import dataclasses
import math
import typing

import numpy as np
import pytest
from conftest import fd_jacobian, random_q

import rhi
from rhi.control import (
    Allocator,
    ControllerConfig,
    EllipsoidMatching,
    FMEMatching,
    FMESchedule,
    ForceRendering,
    ImpedanceControl,
    JointFriction,
    JointLimitBarrier,
    Manipulability,
    NullSpaceController,
    ObjectiveTerm,
    SpringPalpation,
    TransitionConfig,
    TransitionState,
    VMEMatching,
    WeightedSum,
    _compiled as kernels,
    allocate_lp,
    allocate_scaling,
    allocation_method,
    ascm,
    ascm_projector,
    aso_volume,
    basis_from_projector,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
    force_capability,
    gradient_function,
    hysteresis,
    null_basis,
    null_projector,
    output_force,
    tertiary,
    tertiary_projector,
    transition_step,
)
from rhi.control.allocation import LPOptimum, Saturation, allocate_active_set, method_names, ramp_peak, register
from rhi.errors import InfeasibleLimits, InvalidInput, NotSPD, Singular
from rhi.metrics import apparent_inertia, dynamic_pinv, force_ellipsoid, nullspace_projector


@pytest.fixture(scope="module")
def planar3r() -> rhi.Device:
    return rhi.device("planar3r")


def _fd(obj, dev, q, h=1e-6):
    return np.array([(obj.value(dev, q + h * e) - obj.value(dev, q - h * e)) / (2 * h) for e in np.eye(dev.n)])


# ------------------------------------------------------------------ objectives
def test_fme_shape_matches_thesis(rhi4, planar3r):
    # §6.4: home q = 0, μ = 5 -> 𝒦 = 123, ζ = 3.3
    K, zeta = fme_shape(rhi4.jacobian(np.zeros(4)), rhi4.torque_max, 5.0)
    assert K == pytest.approx(123, abs=0.5)
    assert zeta == pytest.approx(3.3, abs=0.05)
    # §6.3.1 example: eigenvalues 2.6 and 5.8 of M̂ at q = [π/6, −π/3, −3π/4], W = diag(2, 2, 2)
    q = np.array([np.pi / 6, -np.pi / 3, -3 * np.pi / 4])
    lam = np.linalg.eigvalsh(force_ellipsoid(planar3r.jacobian(q), planar3r.torque_max))
    np.testing.assert_allclose(lam, [2.6, 5.8], atol=0.05)


def test_desired_fmes_axes():
    Mf = desired_fme_free([0, 1], 123, 3.3)
    Ms = desired_fme_stiff([0, 1], 123, 3.3)
    np.testing.assert_allclose(Mf, np.diag([123, 3.3]), atol=1e-12)  # thesis §6.4
    np.testing.assert_allclose(Ms, np.diag([3.3, 123]), atol=1e-12)


@pytest.mark.parametrize("name", ["rhi4", "planar3r"])
def test_objective_gradients_match_finite_differences(name, rng):
    dev = rhi.device(name)
    K, z = fme_shape(dev.jacobian(random_q(dev, np.random.default_rng(1), 1)[0]), dev.torque_max)
    objectives = [
        FMEMatching(desired_fme_free([0, 1], K, z), dev.torque_max),
        FMEMatching(desired_fme_stiff([1, 1], K, z), dev.torque_max),
        EllipsoidMatching(np.array([[0.05, 0.01], [0.01, 0.02]])),
        EllipsoidMatching(np.diag([0.03, 0.01]), H=np.array([[0.0, 1.0], [-1.0, 0.0]])),
        Manipulability(),
        Manipulability(log=True),
        Manipulability(k_q=10.0),
        Manipulability(log=True, k_q=1.0),
        VMEMatching((0.0, 1.0)),
    ]
    for q in random_q(dev, rng, 6):
        if np.linalg.svd(dev.jacobian(q), compute_uv=False)[-1] < 0.05:
            continue
        for obj in objectives:
            g = obj.gradient(dev, q)
            fd = _fd(obj, dev, q)
            np.testing.assert_allclose(g, fd, atol=1e-6 * (1 + np.abs(fd).max()), err_msg=type(obj).__name__)


def test_fme_matching_zero_at_match(rhi4):
    q = np.array([0.3, 0.5, 0.2, 0.4])
    obj = FMEMatching(force_ellipsoid(rhi4.jacobian(q), rhi4.torque_max), rhi4.torque_max)
    assert obj.value(rhi4, q) == pytest.approx(0.0, abs=1e-10)
    np.testing.assert_allclose(obj.gradient(rhi4, q), 0.0, atol=1e-8)


def test_objective_bad_input():
    with pytest.raises(NotSPD, match="desired"):
        FMEMatching(np.diag([1.0, -1.0]), 1.0)
    with pytest.raises(NotSPD, match="desired"):
        EllipsoidMatching(np.array([[1.0, 2.0], [0.0, 1.0]]))
    with pytest.raises(InvalidInput, match="desired"):
        FMEMatching(np.array([[np.nan, 0], [0, 1]]), 1.0)
    with pytest.raises(InvalidInput, match="torque_max"):
        FMEMatching(np.eye(2), [1.0, -1.0])
    with pytest.raises(InvalidInput, match="mu"):
        fme_shape(np.eye(2), 1.0, mu=0.0)
    with pytest.raises(InvalidInput, match="k_q"):
        Manipulability(k_q=0.0)


def _near_limits(dev, rng, margin, count):
    """Configurations within the limits with one joint inside `margin` of one of its bounds."""
    out = []
    for q in random_q(dev, rng, 4 * count):
        k = rng.integers(dev.n)
        bound = (dev.q_min if rng.random() < 0.5 else dev.q_max)[k]
        q[k] = bound + np.sign(0.5 * (dev.q_min[k] + dev.q_max[k]) - bound) * rng.uniform(0.1, 0.9) * margin
        if dev.within_limits(q):
            out.append(q)
    return out[:count]


@pytest.mark.parametrize("kind", ["quadratic", "inverse"])
def test_joint_limit_barrier_gradient_matches_finite_differences(kind, rhi4, rng):
    bar = JointLimitBarrier(0.2, weight=3.0, kind=kind)
    checked = 0
    for q in _near_limits(rhi4, rng, bar.margin, 40):
        d = bar.distances(rhi4, q)
        if d.min() < 0.05 * bar.margin or np.any(np.abs(d - bar.margin) < 1e-4):
            continue  # FD across the kink at d = δ or too close to the pole of the inverse barrier
        g = bar.gradient(rhi4, q)
        assert np.abs(g).max() > 0  # active here
        fd = _fd(bar, rhi4, q, h=1e-7)
        np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6 * (1 + np.abs(g).max()))
        np.testing.assert_array_equal(bar.gradient_at(rhi4.terms(q)), g)
        checked += 1
    assert checked >= 15


@pytest.mark.parametrize("kind", ["quadratic", "inverse"])
def test_joint_limit_barrier_zero_inside_and_pushes_away(kind, rhi4):
    bar = JointLimitBarrier(0.2, kind=kind)
    mid = np.full(4, 0.5)  # > 0.2 rad from every box and linear limit
    assert np.min(bar.distances(rhi4, mid)) > bar.margin
    assert bar.value(rhi4, mid) == 0.0 and np.all(bar.gradient(rhi4, mid) == 0.0)
    for past in (0.05, -0.01):  # inside the margin, and past q4's lower limit (a plant's soft stop)
        q = mid.copy()
        q[3] = rhi4.q_min[3] + past
        assert bar.value(rhi4, q) > 0 and -bar.gradient(rhi4, q)[3] > 0
        assert np.isfinite(bar.value(rhi4, q))
    # the weight scales value and gradient
    q = mid.copy()
    q[3] = rhi4.q_min[3] + 0.05
    heavy = JointLimitBarrier(0.2, weight=4.0, kind=kind)
    assert heavy.value(rhi4, q) == pytest.approx(4.0 * bar.value(rhi4, q), rel=1e-12)
    np.testing.assert_allclose(heavy.gradient(rhi4, q), 4.0 * bar.gradient(rhi4, q), rtol=1e-12)


def test_joint_limit_barrier_shapes():
    """One limit at distance d: ½ w (δ − d)² (quadratic), w (δ/d − 1)² (inverse)."""
    dev = rhi.device("planar3r")
    k = int(np.flatnonzero(np.isfinite(dev.q_min))[0])
    q = 0.5 * (dev.q_min + dev.q_max)
    q = np.where(np.isfinite(q), q, 0.0)
    q[k] = dev.q_min[k] + 0.05
    assert np.sum(JointLimitBarrier(0.1).distances(dev, q) < 0.1) == 1  # exactly one limit within the margin
    assert JointLimitBarrier(0.1, weight=2.0).value(dev, q) == pytest.approx(0.5 * 2.0 * 0.05**2, rel=1e-9)
    assert JointLimitBarrier(0.1, weight=2.0, kind="inverse").value(dev, q) == pytest.approx(2.0 * 1.0, rel=1e-9)


def test_weighted_sum_value_and_gradient(rhi4, rng):
    a, b = VMEMatching((0.0, 1.0)), JointLimitBarrier(0.2)
    ws = WeightedSum([ObjectiveTerm(a, 2.0), ObjectiveTerm(b, 0.5)])
    assert isinstance(ws.terms, tuple)
    for q in _near_limits(rhi4, rng, 0.2, 6):
        assert ws.value(rhi4, q) == pytest.approx(2.0 * a.value(rhi4, q) + 0.5 * b.value(rhi4, q), rel=1e-12)
        g = ws.gradient(rhi4, q)
        np.testing.assert_allclose(g, 2.0 * a.gradient(rhi4, q) + 0.5 * b.gradient(rhi4, q), rtol=1e-12)
        d = b.distances(rhi4, q)
        if np.all(np.abs(d - b.margin) > 1e-4) and np.linalg.svd(rhi4.jacobian(q), compute_uv=False)[-1] > 0.05:
            fd = _fd(ws, rhi4, q)
            np.testing.assert_allclose(g, fd, atol=1e-6 * (1 + np.abs(fd).max()))


def test_joint_limit_barrier_bad_input():
    with pytest.raises(InvalidInput, match="margin"):
        JointLimitBarrier(0.0)
    with pytest.raises(InvalidInput, match="margin"):
        JointLimitBarrier(float("nan"))
    with pytest.raises(InvalidInput, match="weight"):
        JointLimitBarrier(0.1, weight=-1.0)
    with pytest.raises(InvalidInput, match="kind"):
        JointLimitBarrier(0.1, kind="log")


# ------------------------------------------------------------------ ASO, hysteresis, transition
def test_aso_range_and_shape(rng):
    lo, hi = np.array([-0.5, -2.0]), np.array([0.5, 2.0])
    assert aso_volume([0.0, 0.0], torque_min=lo, torque_max=hi) == pytest.approx(1.0)
    assert aso_volume([0.5, 0.0], torque_min=lo, torque_max=hi) == 0.0
    # two joints outside: the formula's sign flips back; V stays 0
    assert aso_volume([0.6, 3.0], torque_min=lo, torque_max=hi) == 0.0
    V = [aso_volume(t, torque_min=lo, torque_max=hi, S=S) for t in rng.uniform(-3, 3, (2000, 2)) for S in (1.0, 50.0)]
    assert min(V) >= 0.0 and max(V) <= 1.0
    # monotone towards a limit
    vs = [aso_volume([0.0, s], torque_min=lo, torque_max=hi) for s in np.linspace(0, 1.99, 50)]
    assert np.all(np.diff(vs) <= 1e-15)


def test_hysteresis_does_not_chatter():
    stiff = False
    modes = []
    for V in [0.9, 0.69, 0.8, 0.94, 0.9, 0.96, 0.8, 0.71]:
        stiff = hysteresis(stiff, V, 0.7, 0.95)
        modes.append(stiff)
    assert modes == [False, True, True, True, True, False, False, False]
    with pytest.raises(InvalidInput, match="eps1"):
        hysteresis(False, 0.5, 0.9, 0.8)


def test_transition_bounded_rate_and_duration():
    Mf, Ms = np.diag([123.0, 3.3]), np.diag([3.3, 123.0])
    dist = float(np.linalg.norm(Mf - Ms))
    cfg = TransitionConfig(eps1=0.7, eps2=0.95, rho=0.003)
    dt = 1e-3
    st = TransitionState()
    prev_M = Mf
    max_step = 0.0
    oms = []
    for k in range(1500):
        t = k * dt
        V = 0.5 if t < 0.8 else 0.99  # saturating, then released mid-way through the return transition too
        if 0.3 < t < 0.35:
            V = 0.99
        st, om = transition_step(st, t, V, dist, cfg)
        M = om * Mf + (1 - om) * Ms
        max_step = max(max_step, float(np.linalg.norm(M - prev_M)))
        assert 0.0 <= om <= 1.0
        prev_M = M
        oms.append(om)
    bound = math.pi * dt / (2 * cfg.rho)  # |dΩ/dt| ‖Mf − Ms‖_F <= π/(2ρ)
    assert max_step <= bound * (1 + 1e-9)
    assert max_step > 0.2 * bound  # the bound is not vacuous
    # a full transition from free to stiff lasts ρ‖Mf − Ms‖_F (eq. 6.19: 0.51 s for the thesis's FMEs)
    st, _ = transition_step(TransitionState(), 0.0, 0.0, dist, cfg)
    assert st.tf == pytest.approx(cfg.rho * dist)
    assert st.omega(st.tf) == 0.0 and st.omega(0.0) == 1.0
    assert st.omega(0.5 * st.tf) == pytest.approx(0.5)
    assert oms[-1] == 1.0


# ------------------------------------------------------------------ allocation invariants
def _cases(dev, rng, count):
    qs = random_q(dev, rng, 3 * count)
    out = []
    for q in qs:
        J = dev.jacobian(q)
        if np.linalg.svd(J, compute_uv=False)[-1] < 1e-3:
            continue
        out.append((q, J, dev.mass_matrix(q)))
        if len(out) == count:
            break
    return out


@pytest.mark.parametrize("projector", ["dynamic", "pseudoinverse"])
@pytest.mark.parametrize("name", ["rhi4", "planar3r"])
def test_ascm_never_exceeds_limits_and_preserves_direction(name, projector, rng):
    dev = rhi.device(name)
    lo, hi = dev.torque_limits
    worst_null = 0.0
    for _q, J, M in _cases(dev, rng, 500):
        F = rng.normal(size=dev.m) * rng.uniform(0.5, 60.0)
        b = J.T @ (0.1 * rng.normal(size=dev.m))
        Z = null_basis(J, M if projector == "dynamic" else None)
        al = ascm(J.T @ F, b, Z, torque_min=lo, torque_max=hi)
        assert np.all(al.tau <= hi + 1e-12) and np.all(al.tau >= lo - 1e-12)
        assert 0.0 <= al.alpha <= 1.0
        Jp_T = (dynamic_pinv(J, M) if projector == "dynamic" else np.linalg.pinv(J)).T
        worst_null = max(worst_null, float(np.abs(Jp_T @ al.tau_null).max()))
        if not al.clipped:  # output force = α F + F_b exactly: direction of F preserved
            np.testing.assert_allclose(Jp_T @ al.tau, Jp_T @ (al.alpha * (J.T @ F) + b), atol=1e-9)
    assert worst_null < 1e-9


@pytest.mark.parametrize("name", ["rhi4", "planar3r"])
def test_nullspace_torque_leaves_task_force_unchanged(name, rng):
    dev = rhi.device(name)
    for _q, J, M in _cases(dev, rng, 200):
        Z = null_basis(J, M)
        tau_n = Z @ rng.normal(size=Z.shape[1]) * 10
        assert np.abs(dynamic_pinv(J, M).T @ tau_n).max() < 1e-9
        Zk = null_basis(J, None)
        assert np.abs(np.linalg.pinv(J).T @ (Zk @ rng.normal(size=Zk.shape[1]))).max() < 1e-9


@pytest.mark.parametrize("projector", ["dynamic", "pseudoinverse"])
@pytest.mark.parametrize("name", ["rhi4", "planar3r"])
def test_active_set_reaches_the_lp_optimum(name, projector, rng):
    """ASCM (greedy) vs the LP allocation (HiGHS) vs the active-set allocation warm-started at ASCM.

    300 seeded cases per device and projector here (the 10,000 of issue 13 are in
    benchmarks/bench_allocation.py): the active set must reach the LP optimum in >= 99.9 %
    (here: every case) and never leave the torque box.
    """
    dev = rhi.device(name)
    lo, hi = dev.torque_limits
    reached_ascm = reached = 0
    cases = _cases(dev, rng, 300)
    for _q, J, M in cases:
        u = rng.normal(size=dev.m)
        u /= np.linalg.norm(u)
        Z = null_basis(J, M if projector == "dynamic" else None)
        a, b = 100.0 * (J.T @ u), J.T @ (0.05 * rng.normal(size=dev.m))
        lp = allocate_lp(a, b, Z, torque_min=lo, torque_max=hi)
        A = ascm(a, b, Z, torque_min=lo, torque_max=hi)
        S = allocate_active_set(a, b, Z, torque_min=lo, torque_max=hi, start=A)
        for al in (lp, A, S):
            assert np.all(al.tau <= hi + 1e-12) and np.all(al.tau >= lo - 1e-12)
        assert A.alpha <= lp.alpha * (1 + 1e-7) + 1e-12
        reached_ascm += A.alpha >= lp.alpha * (1 - 1e-6)
        reached += S.alpha >= lp.alpha * (1 - 1e-6)
        Jp_T = (dynamic_pinv(J, M) if projector == "dynamic" else np.linalg.pinv(J)).T
        np.testing.assert_allclose(Jp_T @ S.tau, Jp_T @ (S.alpha * a + b), atol=1e-9)  # direction kept
    print(f"\n{name} ({projector}): LP optimum reached by ASCM in {reached_ascm / len(cases):.1%}, "
          f"by the active set in {reached / len(cases):.1%} of {len(cases)} cases")
    assert len(cases) == 300
    assert reached / len(cases) >= 0.999


def test_tertiary_respects_limits_and_held_joints(rng, rhi4):
    lo, hi = rhi4.torque_limits
    for _q, J, M in _cases(rhi4, rng, 200):
        Z = null_basis(J, M)
        al = ascm(J.T @ (rng.normal(size=2) * 30), np.zeros(4), Z, torque_min=lo, torque_max=hi)
        N = np.eye(4) - J.T @ dynamic_pinv(J, M).T
        d, beta = tertiary(al.tau, al.saturated, Z, rng.normal(size=4) * 5, torque_min=lo, torque_max=hi, N=N)
        tau = al.tau + d
        assert 0.0 <= beta <= 1.0
        assert np.all(tau <= hi + 1e-12) and np.all(tau >= lo - 1e-12)
        np.testing.assert_allclose(d[al.saturated], 0.0, atol=1e-12)
        assert np.abs(dynamic_pinv(J, M).T @ d).max() < 1e-9


# ------------------------------------------------------------------ controller
def _controller(dev, **kw):
    K, z = fme_shape(dev.jacobian(np.array([0.3, 0.5, 0.2, 0.4])[: dev.n]), dev.torque_max)
    cfg = dict(
        primary=ForceRendering(damping=0.01, passivity=None),  # the thesis law (no PC)
        objectives=(ObjectiveTerm(VMEMatching((0.0, 1.0)), 0.5),
                    ObjectiveTerm(FMESchedule(desired_fme_free([0, 1], K, z), desired_fme_stiff([0, 1], K, z)), 20.0)),
        damping=0.1,
    )
    cfg.update(kw)
    return NullSpaceController(dev, ControllerConfig(**cfg))


@pytest.mark.parametrize("projector", ["dynamic", "pseudoinverse"])
@pytest.mark.parametrize("name", ["rhi4", "planar3r"])
def test_controller_limits_and_task_force(name, projector, rng):
    """ASCM on: 1,000 seeded random forces and configurations, no torque leaves its limit.

    And the null-space objectives, damping and barrier leave the task force α F + μ unchanged (eq. 7.9), measured with
    the projector's own inverse (J#ᵀ or J⁺ᵀ).
    """
    dev = rhi.device(name)
    c = _controller(dev, projector=projector,
                    objectives=(ObjectiveTerm(VMEMatching((0.0, 1.0)), 0.5), ObjectiveTerm(JointLimitBarrier(0.2), 5.0)))
    lo, hi = dev.torque_limits
    ticks, worst, saturated, clipped = 0, 0.0, 0, 0
    for k, q in enumerate(random_q(dev, rng, 1400)):
        kin = dev.terms(q, rng.normal(size=dev.n))
        if np.linalg.svd(kin.J, compute_uv=False)[-1] < 1e-3:
            continue
        F = rng.normal(size=2) * rng.uniform(0, 40)
        tau = c.step(k * 1e-3, q, kin.dq, {"force": F})
        assert np.all(tau <= hi + 1e-12) and np.all(tau >= lo - 1e-12)
        s = c.state
        assert 0.0 <= s.V <= 1.0 and 0.0 <= s.alpha <= 1.0 and 0.0 <= s.beta <= 1.0
        # J#ᵀτ = α F − B ẋ + C_x ẋ + G_x: what the primary law asked for, whatever the null space does
        if not s.clipped:  # μ alone inside the box (else nothing can render it and τ is clipped)
            F_out = output_force(kin.J, tau, kin.M if projector == "dynamic" else None)
            Jp_T = (kin.Jsharp if projector == "dynamic" else np.linalg.pinv(kin.J)).T
            mu = -0.01 * kin.xdot + kin.Cx @ kin.xdot + kin.Gx
            if projector == "pseudoinverse":  # (I − JᵀJ#ᵀ) g is a J#-null torque, not a J⁺-null one
                mu = mu + Jp_T @ (kin.g - kin.J.T @ kin.Gx)
            worst = max(worst, float(np.abs(F_out - (s.alpha * F + mu)).max()))
        clipped += s.clipped
        saturated += bool(s.saturated.any())
        ticks += 1
        if ticks == 1000:
            break
    assert ticks == 1000 and not c.state.stopped
    assert saturated > 100 and clipped < 50  # the limits were exercised
    assert worst < 1e-9


def test_controller_nan_sensor_stops_safely(rhi4):
    c = _controller(rhi4)
    q = np.array([0.3, 0.5, 0.2, 0.4])
    assert np.any(c.step(0.0, q, np.zeros(4), {"force": np.array([0.0, -2.0])}) != 0)
    tau = c.step(0.001, q, np.zeros(4), {"force": np.array([np.nan, 1.0])})
    np.testing.assert_array_equal(tau, 0.0)
    assert c.state.stopped and "force" in c.state.fault and "t=0.001" in c.state.fault
    # latched: zero torque afterwards even with good readings
    np.testing.assert_array_equal(c.step(0.002, q, np.zeros(4), {"force": np.array([0.0, 1.0])}), 0.0)
    c.reset()
    c.step(0.0, q, np.zeros(4), {"force": np.array([0.0, 1.0])})
    tau = c.step(0.001, q, np.array([np.inf, 0, 0, 0]), {"force": np.array([0.0, 1.0])})
    np.testing.assert_array_equal(tau, 0.0)
    assert "dq" in c.state.fault


def test_controller_nan_before_start_is_bad_input(rhi4):
    """A non-finite reading on the very first tick is bad input (the loop never started): it raises."""
    c = _controller(rhi4)
    q = np.array([0.3, 0.5, 0.2, 0.4])
    with pytest.raises(InvalidInput, match=r"sensors\['force'\]"):
        c.step(0.0, q, np.zeros(4), {"force": np.array([np.nan, 1.0])})
    with pytest.raises(InvalidInput, match="q: non-finite"):
        c.step(0.0, np.array([0.3, np.nan, 0.2, 0.4]), np.zeros(4), {"force": np.zeros(2)})
    assert not c.state.stopped
    with pytest.raises(InvalidInput, match=r"sensors\['force'\]: expected shape \(2,\)"):
        c.step(0.0, q, np.zeros(4), {"force": np.zeros(3)})
    with pytest.raises(InvalidInput, match=r"sensors\['force'\]: expected a vector"):
        c.step(0.0, q, np.zeros(4), {"force": 1.0})
    imp = _controller(rhi4, primary=ImpedanceControl(damping=0.1, inertia=np.eye(2)))
    with pytest.raises(InvalidInput, match=r"sensors\['ft'\]: expected a \(6,\) wrench"):
        imp.step(0.0, q, np.zeros(4), {"ft": np.zeros(3)})


def test_controller_singular_configuration_stops_safely():
    """Fully stretched planar 3R (rank-deficient J) mid-run: zero torque and a reason, no exception."""
    dev = rhi.device("planar3r")
    c = NullSpaceController(dev, ControllerConfig(ForceRendering(), objectives=(ObjectiveTerm(VMEMatching((0.0, 1.0)), 0.1),)))
    q = np.array([0.3, -0.4, 0.2])
    c.step(0.0, q, np.zeros(3), {"force": np.zeros(2)})
    tau = c.step(0.001, np.zeros(3), np.zeros(3), {"force": np.array([1.0, 0.0])})
    np.testing.assert_array_equal(tau, 0.0)
    assert c.state.stopped and "t=0.001" in c.state.fault


def test_controller_bad_input(rhi4):
    with pytest.raises(InfeasibleLimits, match="torque_min"):
        _controller(rhi4, torque_min=np.array([1.0, -1, -1, -1]), torque_max=np.ones(4))
    with pytest.raises(InfeasibleLimits, match="torque_max"):
        _controller(rhi4, torque_min=-np.ones(4), torque_max=np.array([1.0, -1, 1, 1]))
    with pytest.raises(InvalidInput, match="torque_max"):
        _controller(rhi4, torque_min=-np.ones(4), torque_max=np.array([1.0, np.nan, 1, 1]))
    with pytest.raises(NotSPD, match="stiff"):
        FMESchedule(np.eye(2), np.array([[1.0, 0.0], [0.0, -2.0]]))
    with pytest.raises(NotSPD, match="free"):
        FMESchedule(np.array([[1.0, 2.0], [2.0, 1.0]]), np.eye(2))
    with pytest.raises(InvalidInput, match="damping"):
        _controller(rhi4, damping=float("nan"))
    with pytest.raises(InvalidInput, match="saturation"):
        _controller(rhi4, saturation="magic")
    with pytest.raises(InvalidInput, match="implementation"):
        _controller(rhi4, implementation="turbo")

    class NoCheck:  # a law without `check` (the PrimaryLaw protocol: forces, required_sensors, check)
        def forces(self, t, kin, sensors):
            return np.zeros(2), np.zeros(2)

        def required_sensors(self):
            return ()

    with pytest.raises(InvalidInput, match="primary"):
        _controller(rhi4, primary=NoCheck())
    with pytest.raises(InvalidInput, match="gain"):
        ObjectiveTerm(Manipulability(), -1.0)
    with pytest.raises(InvalidInput, match="x0"):
        SpringPalpation(1000.0, (np.nan, 0.0))
    with pytest.raises(InvalidInput, match="x0"):  # checked against the device at construction
        _controller(rhi4, primary=SpringPalpation(1000.0, (0.5, 0.1, 0.0)))
    with pytest.raises(NotSPD, match="inertia"):
        ImpedanceControl(inertia=np.diag([0.1, -0.1]))
    with pytest.raises(InvalidInput, match="inertia"):
        _controller(rhi4, primary=ImpedanceControl(inertia=np.eye(3)))
    with pytest.raises(InvalidInput, match="damping"):
        ForceRendering(damping=-np.eye(2))
    with pytest.raises(InvalidInput, match="coulomb"):
        JointFriction(coulomb=[-0.1, 0.0, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="viscous"):
        _controller(rhi4, primary=ForceRendering(friction=JointFriction(viscous=np.ones(3))))
    with pytest.raises(InvalidInput, match="beta"):
        VMEMatching((0.0, 1.0), beta=-1.0)
    c = _controller(rhi4)
    with pytest.raises(InvalidInput, match="sensors"):
        c.step(0.0, np.zeros(4), np.zeros(4), {})
    with pytest.raises(InvalidInput, match="q/dq"):
        c.step(0.0, np.zeros(3), np.zeros(4), {"force": np.zeros(2)})


def test_controller_switches_fme_under_load(rhi4):
    """A hard contact drains the ASO and moves Ω from free (1) towards stiff (0), continuously.

    The desired FME changes by at most π dt / (2ρ) per tick (eqs. 6.16–6.19).
    """
    c = _controller(rhi4)
    fme = c.schedule[1]
    q = np.array([0.3, 0.5, 0.2, 0.4])
    dt = 1e-3
    oms, Ms = [], []
    for k in range(1400):
        F = np.array([0.0, -30.0]) if k < 700 else np.array([0.0, -0.5])  # contact, then released
        c.step(k * dt, q, np.zeros(4), {"force": F})
        oms.append(c.state.omega)
        Ms.append(fme.desired(c.state.omega))
    assert oms[0] == 1.0 and oms[1] < 1.0 and oms[699] == 0.0 and oms[-1] == 1.0
    steps = [float(np.linalg.norm(b - a)) for a, b in zip(Ms, Ms[1:])]
    bound = np.pi * dt / (2 * fme.transition.rho)
    assert max(steps) <= bound * (1 + 1e-9)
    assert max(steps) > 0.5 * bound  # the bound is attained, not vacuous


def test_spring_palpation_law(rhi4):
    law = SpringPalpation(1000.0, (0.5, 0.1), normal=(0.0, 1.0), damping=0.01, coriolis=False, gravity=False)
    np.testing.assert_allclose(law.spring(np.array([0.5, 0.105])), [0.0, -5.0])
    np.testing.assert_allclose(law.spring(np.array([0.5, 0.09])), 0.0)
    kin = rhi4.terms(np.array([0.3, 0.5, 0.2, 0.4]), np.array([0.1, -0.2, 0.3, 0.0]))
    F, Fx = law.forces(0.0, kin, {})
    np.testing.assert_allclose(F, law.spring(kin.x))
    np.testing.assert_allclose(Fx, -0.01 * kin.xdot)
    law2 = SpringPalpation(1000.0, (0.5, 0.1), normal=(0.0, 1.0), damping=0.01)  # eq. 7.20: + C_x ẋ
    np.testing.assert_allclose(law2.forces(0.0, kin, {})[1], -0.01 * kin.xdot + kin.Cx @ kin.xdot, atol=1e-12)


@pytest.mark.parametrize("method", ["none", "scaling", "lp", "active_set"])
def test_controller_other_allocations_stay_in_limits(method, planar3r, rng):
    c = NullSpaceController(planar3r, ControllerConfig(ForceRendering(), saturation=method,
                                                       objectives=(ObjectiveTerm(Manipulability(log=True), 0.1),)))
    lo, hi = planar3r.torque_limits
    for k, q in enumerate(random_q(planar3r, rng, 50)):
        tau = c.step(k * 1e-3, q, rng.normal(size=3), {"force": rng.normal(size=2) * 20})
        assert np.all(tau <= hi + 1e-12) and np.all(tau >= lo - 1e-12)



def test_allocation_strategies_are_one_registry(planar3r, rng):
    """The allocation strategies are one registry, and a new strategy is one object.

    The bundled names are the `Saturation` literal; the new strategy here is a half-force scaling defined in the test,
    which both implementations run (through the reference: it has no compiled branch).
    """
    assert set(typing.get_args(Saturation)) == set(method_names())  # a bundled strategy is in both
    for name in set(typing.get_args(Saturation)) - {"active_set"}:
        assert allocation_method(name).name == name
    # "active_set" is an alias: the LP optimum with the active-set solver in Python
    assert allocation_method("active_set") == LPOptimum(solver="active_set") and allocation_method("lp") == LPOptimum()
    with pytest.raises(InvalidInput, match="solver"):
        LPOptimum(solver="simplex")  # type: ignore[arg-type]
    with pytest.raises(InvalidInput, match="saturation"):
        allocation_method("magic")
    with pytest.raises(InvalidInput, match="already registered"):
        register(Allocator("ascm", ascm))
    assert [allocation_method(s).safe for s in ("none", "scaling", "ascm", "lp", "active_set")] == [
        True, False, True, True, True]

    def half(a, b, Z, *, torque_min, torque_max):
        return dataclasses.replace(allocate_scaling(0.5 * a, b, torque_min=torque_min, torque_max=torque_max),
                                   method="half")

    law = ForceRendering(passivity=None)
    new = [NullSpaceController(planar3r, ControllerConfig(law, saturation=Allocator("half", half, safe=False),
                                                          damping=0.0, implementation=impl))
           for impl in ("fast", "reference")]
    scaling = NullSpaceController(planar3r, ControllerConfig(law, saturation="scaling", damping=0.0))
    for k, q in enumerate(random_q(planar3r, rng, 20)):
        F = rng.normal(size=2) * 20
        want = scaling.step(k * 1e-3, q, np.zeros(3), {"force": 0.5 * F})
        for c in new:
            np.testing.assert_allclose(c.step(k * 1e-3, q, np.zeros(3), {"force": F}), want, atol=1e-12)
    # the capability of the LP optimum is HiGHS's whatever the solver, and the active set's ramp reaches it
    J = planar3r.jacobian(np.array([0.3, 0.5, 0.2]))
    lim = dict(torque_min=planar3r.torque_min, torque_max=planar3r.torque_max, projector="pseudoinverse")
    f_lp = force_capability(J, [0.0, 1.0], method="lp", **lim)
    assert force_capability(J, [0.0, 1.0], method="active_set", **lim) == f_lp
    t, Z, box = J.T @ [0.0, 1.0], null_basis(J), dict(torque_min=planar3r.torque_min, torque_max=planar3r.torque_max)
    f_s = force_capability(J, [0.0, 1.0], method="scaling", **lim)
    assert f_s < f_lp * (1 - 1e-3)  # the null space adds force here
    assert ramp_peak(lambda f: allocate_active_set(f * t, np.zeros(3), Z, **box).alpha, f_s, f_lp, 41) == pytest.approx(
        f_lp, rel=1e-9)
    with pytest.raises(InvalidInput, match="method"):
        force_capability(J, [0.0, 1.0], method="none", **lim)


# ------------------------------------------------------------------ device terms, task-space dynamics
@pytest.mark.parametrize("name", rhi.available_devices())
def test_device_terms_equal_per_call_methods(name, rng):
    """Device.terms (one Pinocchio pass, closed-form ∂J/∂q) equals fk/jacobian/jacobian_derivative/..."""
    dev = rhi.device(name)
    for q in random_q(dev, rng, 5):
        dq = rng.normal(size=dev.n)
        kin = dev.terms(q, dq)
        np.testing.assert_allclose(kin.x, dev.fk(q), atol=1e-12)
        np.testing.assert_allclose(kin.J, dev.jacobian(q), atol=1e-12)
        np.testing.assert_allclose(kin.dJ, dev.jacobian_derivative(q), atol=1e-12)
        np.testing.assert_allclose(kin.M, dev.mass_matrix(q), atol=1e-12)
        np.testing.assert_allclose(kin.g, dev.gravity(q), atol=1e-12)
        np.testing.assert_allclose(kin.C, dev.coriolis(q, dq), atol=1e-12)
        np.testing.assert_allclose(kin.Jdot, np.einsum("ijk,k->ij", dev.jacobian_derivative(q), dq), atol=1e-12)
    # ∂J/∂q also against finite differences of the Jacobian (not only against Pinocchio's time variation)
    q = random_q(dev, rng, 1)[0]
    np.testing.assert_allclose(dev.terms(q).dJ, fd_jacobian(dev.jacobian, q), atol=1e-7)


def test_device_terms_bad_input(rhi4):
    with pytest.raises(InvalidInput, match="q"):
        rhi4.terms([0.0, np.nan, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="dq"):
        rhi4.terms(np.zeros(4), np.zeros(3))
    with pytest.raises(InvalidInput, match="dq"):
        _ = rhi4.terms(np.zeros(4)).xdot  # the velocity needs dq


@pytest.mark.parametrize("name", ["rhi4", "planar3r", "gen3"])
def test_cartesian_dynamics_terms(name, rng):
    """M_x, J#, N against rhi.metrics.

    Ṁ_x = C_x + C_xᵀ along q̇ (finite differences of M_x); G_x = J#ᵀ g; and the task-space dynamics identity M_x ẍ +
    C_x ẋ + G_x = F of eq. 5.2 for τ = JᵀF with no self-motion (q̇ = J# ẋ), ẍ from forward dynamics and J̇ by finite
    differences.
    """
    dev = rhi.device(name)
    h = 1e-6
    for q in random_q(dev, rng, 8):
        J = dev.jacobian(q)
        if np.linalg.svd(J, compute_uv=False)[-1] < 0.05:
            continue
        dq = rng.normal(size=dev.n)
        kin = dev.terms(q, dq)
        np.testing.assert_allclose(kin.Lambda, apparent_inertia(J, kin.M), rtol=1e-9)
        np.testing.assert_allclose(kin.Jsharp, dynamic_pinv(J, kin.M), rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(kin.N, nullspace_projector(J, kin.M), atol=1e-9)
        np.testing.assert_allclose(kin.Gx, kin.Jsharp.T @ kin.g, atol=1e-12)
        Lam = lambda qq: apparent_inertia(dev.jacobian(qq), dev.mass_matrix(qq))  # noqa: E731
        dLam = (Lam(q + h * dq) - Lam(q - h * dq)) / (2 * h)
        np.testing.assert_allclose(kin.Cx + kin.Cx.T, dLam, atol=1e-6 * (1 + np.abs(dLam).max()))
        # eq. 5.2 with q̇ = J# ẋ (the end-effector dynamics describe motion without self-motion)
        xdot = rng.normal(size=dev.m) * 0.3
        v = kin.Jsharp @ xdot
        k2 = dev.terms(q, v)
        F = rng.normal(size=dev.m)
        qdd = np.linalg.solve(k2.M, J.T @ F - k2.C @ v - k2.g)
        Jdot = (dev.jacobian(q + h * v) - dev.jacobian(q - h * v)) / (2 * h)
        xdd = Jdot @ v + J @ qdd
        lhs = k2.Lambda @ xdd + k2.Cx @ xdot + k2.Gx
        np.testing.assert_allclose(lhs, F, atol=1e-6 * (1 + np.abs(F).max()))


def _closed_loop_xdd(dev, q, xdot, tau, F_hand, friction=None):
    """ẍ of the joint dynamics M q̈ + C q̇ + g + F_q = τ + Jᵀ F_h (eq. 5.1) at q̇ = J# ẋ; J̇ by finite differences."""
    kin = dev.terms(q, np.zeros(dev.n))
    v = kin.Jsharp @ xdot
    k2 = dev.terms(q, v)
    Fq = 0.0 if friction is None else friction.torque(v)
    qdd = np.linalg.solve(k2.M, tau + k2.J.T @ F_hand - k2.C @ v - k2.g - Fq)
    h = 1e-6
    Jdot = (dev.jacobian(q + h * v) - dev.jacobian(q - h * v)) / (2 * h)
    return k2, Jdot @ v + k2.J @ qdd


@pytest.mark.parametrize("name", ["rhi4", "gen3"])
def test_impedance_control_renders_null_stiffness_impedance(name, rng):
    """Eq. 5.4 closes the loop to M_x^d ẍ + B^d ẋ = F_h (eq. 5.5); with M_x^d = M_x it is eq. 5.6."""
    dev = rhi.device(name)
    m = dev.m
    B = np.diag(rng.uniform(0.5, 2.0, m))
    Md = np.diag(rng.uniform(0.3, 1.0, m))
    fr = JointFriction(viscous=rng.uniform(0, 0.05, dev.n), coulomb=rng.uniform(0, 0.02, dev.n), velocity_scale=0.05)
    laws = {"5.4": ImpedanceControl(damping=B, inertia=Md, friction=fr), "5.6": ImpedanceControl(damping=B, friction=fr)}
    assert laws["5.6"].required_sensors() == () and laws["5.4"].required_sensors() == ("ft",)
    for q in random_q(dev, rng, 6):
        if np.linalg.svd(dev.jacobian(q), compute_uv=False)[-1] < 0.05:
            continue
        xdot = rng.normal(size=m) * 0.2
        Fh = rng.normal(size=m) * 3
        for eq, law in laws.items():
            kin = dev.terms(q, dev.terms(q).Jsharp @ xdot)
            F_r, F_m = law.forces(0.0, kin, {"ft": Fh})
            np.testing.assert_array_equal(F_r, 0.0)
            # the handle's 6-axis F/T reading (world axes) gives the same law
            wrench = np.zeros(6)
            wrench[[ "xyz".index(a) for a in dev.task_axes]] = Fh
            wrench[3:] = rng.normal(size=3)
            np.testing.assert_allclose(law.forces(0.0, kin, {"ft": wrench})[1], F_m, atol=1e-12)
            k2, xdd = _closed_loop_xdd(dev, q, xdot, kin.J.T @ F_m, Fh, fr)
            Mdes = Md if eq == "5.4" else k2.Lambda
            np.testing.assert_allclose(Mdes @ xdd + B @ xdot, Fh, atol=1e-5 * (1 + np.abs(Fh).max()), err_msg=eq)


def test_force_rendering_closed_loop(rng):
    """Eq. 7.2 gives M_x ẍ + B^d ẋ = F_h − F_e (eq. 7.3) for a non-planar device (gravity, Coriolis)."""
    dev = rhi.device("gen3")
    law = ForceRendering(damping=0.7)
    for q in random_q(dev, rng, 4):
        if np.linalg.svd(dev.jacobian(q), compute_uv=False)[-1] < 0.05:
            continue
        xdot = rng.normal(size=3) * 0.2
        render = rng.normal(size=3) * 4  # −F_e
        Fh = rng.normal(size=3)
        kin = dev.terms(q, dev.terms(q).Jsharp @ xdot)
        F_r, F_x = law.forces(0.0, kin, {"force": render})
        k2, xdd = _closed_loop_xdd(dev, q, xdot, kin.J.T @ (F_r + F_x), Fh)
        np.testing.assert_allclose(k2.Lambda @ xdd + 0.7 * xdot, Fh + render, atol=1e-5 * (1 + np.abs(render).max()))
        # without compensation the Coriolis and gravity terms show up
        bare = ForceRendering(damping=0.7, coriolis=False, gravity=False)
        _, xdd2 = _closed_loop_xdd(dev, q, xdot, kin.J.T @ sum(bare.forces(0.0, kin, {"force": render})), Fh)
        assert np.abs(k2.Lambda @ xdd2 + 0.7 * xdot - Fh - render).max() > 1e-3


def test_controller_null_space_gravity(rng):
    """Law G_x + controller (I − JᵀJ#ᵀ) g compensate the whole gravity torque g(q)."""
    dev = rhi.device("gen3")
    c = NullSpaceController(dev, ControllerConfig(ImpedanceControl(coriolis=False), damping=0.0, saturation="none"))
    for k, q in enumerate(random_q(dev, rng, 5)):
        tau = c.step(k * 1e-3, q, np.zeros(dev.n))
        np.testing.assert_allclose(tau, np.clip(dev.gravity(q), *dev.torque_limits), atol=1e-9)


# ------------------------------------------------------------------ fast path == reference
def _tick_cases(dev, rng, count):
    """Seeded random ticks: configurations, velocities and forces from free motion to far beyond the limits."""
    out = []
    for q in random_q(dev, rng, 3 * count):
        if np.linalg.svd(dev.jacobian(q), compute_uv=False)[-1] < 1e-2:
            continue
        out.append((q, rng.normal(size=dev.n) * 0.5, rng.normal(size=dev.m) * rng.choice([0.5, 5.0, 40.0])))
        if len(out) == count:
            break
    return out


@pytest.mark.parametrize(
    "name,saturation,projector,law",
    [("rhi4", "ascm", "dynamic", "render"), ("rhi4", "ascm", "pseudoinverse", "render"),
     ("planar3r", "ascm", "dynamic", "render"), ("rhi4", "scaling", "dynamic", "render"),
     ("rhi4", "none", "dynamic", "render"), ("rhi4", "lp", "dynamic", "render"),
     ("planar3r", "lp", "pseudoinverse", "render"),
     ("rhi4", "ascm", "dynamic", "impedance")],
)
def test_fast_tick_equals_reference(name, saturation, projector, law, rng):
    """The fast tick (one Pinocchio pass, projector ASCM) equals the reference composition to 1e-10.

    "lp"'s compiled branch is the active set: its oracle is the reference with that solver,
    ``LPOptimum(solver="active_set")`` (HiGHS's own vertex: `test_lp_compiled_tick_reaches_the_highs_optimum`).
    """
    dev = rhi.device(name)
    K, z = fme_shape(dev.jacobian(np.array([0.3, 0.5, 0.2, 0.4])[: dev.n]), dev.torque_max)
    friction = JointFriction(viscous=0.01, coulomb=0.005)
    primary = (ForceRendering(damping=0.01, friction=friction) if law == "render" else
               ImpedanceControl(damping=0.5, inertia=np.diag([0.2, 0.3]), friction=friction))
    kw = dict(
        primary=primary,
        objectives=(ObjectiveTerm(VMEMatching((0.0, 1.0)), 0.5), ObjectiveTerm(Manipulability(log=True), 0.05),
                    ObjectiveTerm(FMESchedule(desired_fme_free([0, 1], K, z), desired_fme_stiff([0, 1], K, z)), 20.0)),
        saturation=saturation, projector=projector,
    )
    fast = NullSpaceController(dev, ControllerConfig(**kw))
    oracle = LPOptimum(solver="active_set") if saturation == "lp" else saturation
    ref = NullSpaceController(dev, ControllerConfig(**{**kw, "saturation": oracle}, implementation="reference"))
    cases = _tick_cases(dev, rng, 250)
    held = 0
    for k, (q, dq, F) in enumerate(cases):
        t = k * 1e-3
        sensors = {"force": F, "ft": np.concatenate([F, [0.0], rng.normal(size=3)])}
        a = fast.step(t, q, dq, sensors)
        b = ref.step(t, q, dq, sensors)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10, err_msg=f"tick {k}")
        sf, sr = fast.state, ref.state
        for attr in ("V", "omega", "alpha", "beta"):
            assert getattr(sf, attr) == pytest.approx(getattr(sr, attr), abs=1e-10), (k, attr)
        np.testing.assert_array_equal(sf.saturated, sr.saturated)
        held += bool(sf.saturated.any())
    assert not fast.state.stopped and not ref.state.stopped
    if saturation in ("ascm", "scaling") and law == "render":
        assert held > len(cases) // 5  # saturation exercised


@pytest.mark.parametrize("projector", ["dynamic", "pseudoinverse"])
@pytest.mark.parametrize("name", ["rhi4", "planar3r"])
def test_lp_compiled_tick_reaches_the_highs_optimum(name, projector, rng):
    """saturation="lp": the compiled tick (the active set) and the reference (HiGHS) reach the same optimum α*.

    Where the optimal face is more than a point they hold other joints (another vertex), so the torques are compared
    on what is unique: α* (to the relative 1e-6 of `test_active_set_reaches_the_lp_optimum`; measured ≤ 4e-13), the
    handle force α* F_render + F_extra (to 1e-9 N) and the box. No null-space torque of its own (safety room γ = 1).
    """
    dev = rhi.device(name)
    lo, hi = dev.torque_limits
    kw = dict(primary=ForceRendering(damping=0.01, passivity=None), damping=0.0, saturation="lp", projector=projector)
    fast = NullSpaceController(dev, ControllerConfig(**kw))
    ref = NullSpaceController(dev, ControllerConfig(**kw, implementation="reference"))
    assert fast.route.name == "whole" and ref.route.name == "reference"
    saturated = other_vertex = 0
    for q, dq, F in _tick_cases(dev, rng, 150):
        fast.reset(), ref.reset()
        taus = fast.step(0.0, q, dq, {"force": F}), ref.step(0.0, q, dq, {"force": F})
        kin = dev.terms(q, dq)
        F_r, F_x = kw["primary"].forces(0.0, kin, {"force": F})
        Jp_T = kin.Jsharp.T if projector == "dynamic" else np.linalg.pinv(kin.J).T
        for tau, s in zip(taus, (fast.state, ref.state)):
            assert not s.stopped and np.all(tau <= hi + 1e-12) and np.all(tau >= lo - 1e-12)
            if not s.clipped:
                np.testing.assert_allclose(Jp_T @ tau, Jp_T @ (s.alpha * (kin.J.T @ F_r) + kin.J.T @ F_x), rtol=0,
                                           atol=1e-9)
        assert fast.state.alpha == pytest.approx(ref.state.alpha, rel=1e-6, abs=1e-12)
        saturated += ref.state.alpha < 1.0
        other_vertex += bool(np.abs(taus[0] - taus[1]).max() > 1e-9)
    assert saturated > 30  # the allocation acted
    print(f"{name} {projector}: {saturated} saturated ticks of 150, {other_vertex} on another vertex of the optimal face")


def test_ascm_projector_equals_ascm(rng):
    """Projector-form ASCM = basis-form ASCM.

    Both on its fast path, where it hands an ill-conditioned held set (σ_min(Z_S) < 0.01) to the basis form, and
    where it decides such a set of n − m joints itself from a basis of P (Z_S square).
    """
    handed_over = fast = square = 0
    for name in ("rhi4", "planar3r"):
        dev = rhi.device(name)
        lo, hi = dev.torque_limits
        for _q, J, M in _cases(dev, rng, 300):
            F = rng.normal(size=dev.m) * rng.uniform(0.5, 60.0)
            b = J.T @ (0.1 * rng.normal(size=dev.m))
            Z = null_basis(J, M)
            P = null_projector(J, M)
            np.testing.assert_allclose(P, Z @ Z.T, atol=1e-12)
            ref = ascm(J.T @ F, b, Z, torque_min=lo, torque_max=hi)
            new = ascm_projector(J.T @ F, b, P, torque_min=lo, torque_max=hi)
            if ref.saturated.any():
                ok = kernels.ascm(J.T @ F, b, P, lo, hi, dev.n - dev.m, np.zeros(dev.n, bool))[3]
                handed_over += not ok
                S = ref.saturated
                ill = S.sum() == dev.n - dev.m and np.linalg.svd(Z[S], compute_uv=False)[-1] < 0.01
                square += ok and ill
                fast += ok and not ill
            np.testing.assert_allclose(new.tau, ref.tau, atol=1e-10)
            np.testing.assert_allclose(new.tau_null, ref.tau_null, atol=1e-10)
            assert new.alpha == pytest.approx(ref.alpha, abs=1e-10)
            np.testing.assert_array_equal(new.saturated, ref.saturated)
            assert np.all(new.tau <= hi + 1e-12) and np.all(new.tau >= lo - 1e-12)
            # the held torque lies in the null space: no task force
            assert np.abs(dynamic_pinv(J, M).T @ new.tau_null).max() < 1e-9
    assert fast > 100 and handed_over > 0 and square > 20, (fast, handed_over, square)  # every path exercised


@pytest.mark.parametrize("name", ["rhi4", "gen3"])
def test_gradient_at_equals_gradient(name, rng):
    dev = rhi.device(name)
    m = dev.m
    objectives = [
        VMEMatching(tuple(np.eye(m)[1])),
        EllipsoidMatching(np.diag(np.linspace(0.02, 0.05, m))),
        EllipsoidMatching(np.diag(np.linspace(0.02, 0.05, m)), H=np.roll(np.eye(m), 1, axis=0)),
        Manipulability(),
        Manipulability(log=True, k_q=10.0),
        JointLimitBarrier(0.3, kind="inverse"),
        FMEMatching(desired_fme_stiff(np.eye(m)[0], 100.0, 3.0), dev.torque_max),
    ]
    for q in random_q(dev, rng, 4):
        kin = dev.terms(q)
        for obj in objectives:
            np.testing.assert_allclose(obj.gradient_at(kin), obj.gradient(dev, q), rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(gradient_function(obj, dev)(kin), obj.gradient(dev, q), rtol=1e-9, atol=1e-12)
    # an objective with only the two-method protocol is wrapped, not special-cased
    class Plain:
        def value(self, device, q):
            return float(q @ q)

        def gradient(self, device, q):
            return 2 * q

    q = random_q(dev, rng, 1)[0]
    np.testing.assert_allclose(gradient_function(Plain(), dev)(dev.terms(q)), 2 * q)


def test_projector_forms(rng, rhi4):
    """null_projector = Z Zᵀ, basis_from_projector spans it, tertiary_projector = tertiary; singular J raises."""
    lo, hi = rhi4.torque_limits
    for _q, J, M in _cases(rhi4, rng, 100):
        Z = null_basis(J, M)
        P = null_projector(J, M)
        np.testing.assert_allclose(P, Z @ Z.T, atol=1e-12)
        Zp = basis_from_projector(P)
        np.testing.assert_allclose(Zp @ Zp.T, P, atol=1e-12)
        al = ascm(J.T @ (rng.normal(size=2) * 30), np.zeros(4), Z, torque_min=lo, torque_max=hi)
        N = nullspace_projector(J, M)
        tau_to = rng.normal(size=4) * 5
        d1, b1 = tertiary(al.tau, al.saturated, Z, tau_to, torque_min=lo, torque_max=hi, N=N)
        d2, b2 = tertiary_projector(al.tau, al.saturated, P, tau_to, torque_min=lo, torque_max=hi, N=N)
        np.testing.assert_allclose(d2, d1, atol=1e-10)
        assert b2 == pytest.approx(b1, abs=1e-10)
    with pytest.raises(Singular, match="J"):
        null_projector(np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0]]))


@pytest.mark.parametrize("saturation", ["lp", "ascm", "scaling", "none", "active_set"])
def test_a_non_finite_primary_force_is_a_safe_stop_in_every_saturation_mode(saturation):
    """Issue 24: with saturation="lp", a non-finite force (a singular configuration) raised `tau: contains NaN`."""
    import rhi
    from rhi.control import ControllerConfig, NullSpaceController

    dev = rhi.device("rhi4")

    class Blows:  # a primary law whose force overflows on the second tick (as near a singularity)
        def forces(self, t, kin, sensors):
            return (np.full(dev.m, np.nan) if t > 0 else np.ones(dev.m)), np.zeros(dev.m)

        def required_sensors(self):
            return ()

        def check(self, device):
            pass

    ctrl = NullSpaceController(dev, ControllerConfig(primary=Blows(), saturation=saturation))
    q = np.array([-0.63, 0.25, 0.28, 0.09])
    assert np.isfinite(ctrl.step(0.0, q, np.zeros(4))).all() and not ctrl.state.stopped
    np.testing.assert_array_equal(ctrl.step(1e-3, q, np.zeros(4)), 0.0)
    assert ctrl.state.stopped and "tau:" not in ctrl.state.fault, ctrl.state.fault
    np.testing.assert_array_equal(ctrl.step(2e-3, q, np.zeros(4)), 0.0)  # latched
