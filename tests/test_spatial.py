"""Spatial RHIs (srhi5, gen3 with a 3-D position task): model, derivatives, plant, and the 3-D controller invariants.

The invariants run on 1,000 seeded cases per device (issue 15): null-space torques leave the
handle force unchanged (< 1e-9 N), torques stay within the limits, and the objective
gradients match finite differences.
"""

import numpy as np
import pytest
from conftest import random_q

import rhi
from rhi.control import (
    ControllerConfig,
    FMEMatching,
    FMESchedule,
    ForceRendering,
    NullSpaceController,
    ObjectiveTerm,
    VMEMatching,
    desired_fme_free,
    desired_fme_stiff,
)
from rhi.metrics import desired_fme, desired_vme, jbld
from rhi.sim import Plant

CASES = 1000
SPATIAL = ("srhi5", "gen3")


def srhi5_fk(q: np.ndarray) -> np.ndarray:
    """Closed-form FK of srhi5 (models/srhi5/README.md): (..., 5) -> (..., 3) [m]."""
    q1, q2, q3, q4, q5 = np.moveaxis(q, -1, 0)
    psi, r = q2 + q3, 0.21 * np.cos(q4) + 0.181 * np.sin(q5)
    return np.stack([0.254 * np.cos(q1) + 0.141 * np.sin(q2) + r * np.cos(psi),
                     0.254 * np.sin(q1) - 0.141 * np.cos(q2) + r * np.sin(psi),
                     0.21 * np.sin(q4) - 0.181 * np.cos(q5)], -1)


def _fd(f, Q: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Central differences of a batch function f: (N, n) -> (N, ...), stacked on a last axis of size n."""
    n = Q.shape[-1]
    return np.stack([(f(Q + eps * e) - f(Q - eps * e)) / (2 * eps) for e in np.eye(n)], -1)


@pytest.fixture(scope="module", params=SPATIAL)
def spatial(request) -> rhi.Device:
    return rhi.device(request.param)


def test_srhi5_model():
    dev = rhi.device("srhi5")
    assert (dev.n, dev.m, dev.task_axes) == (5, 3, "xyz")
    Q = random_q(dev, np.random.default_rng(1), CASES)
    np.testing.assert_allclose(dev.fk(Q), srhi5_fk(Q), atol=1e-12)
    np.testing.assert_allclose(dev.jacobian(Q), _fd(srhi5_fk, Q), atol=1e-8)
    sub = rhi.device("srhi5_phantom")
    assert sub.n == 3 and sub.joint_names == ["q3", "q4", "q5"]
    np.testing.assert_allclose(sub.fk(Q[:, 2:]), dev.fk(np.c_[np.zeros((CASES, 2)), Q[:, 2:]]), atol=1e-12)
    # the rehab joints carry no gravity (vertical axes); the PHANToM's do
    g = dev.gravity(Q)
    assert np.abs(g[:, :3]).max() < 1e-12 and np.abs(g[:, 3:]).max() > 1e-2
    # the PHANToM half equals phantom3's model (l2 = 0.181 m) once the base is locked: J rows and g
    ph3 = rhi.device("phantom3", l2=0.181)
    Jp = ph3.jacobian(Q[:, 2:])
    Js = sub.jacobian(Q[:, 2:])
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # PHANToM faces +x: yaw 90° from link 2
    np.testing.assert_allclose(Js, R.T @ R @ Jp, atol=1e-12)
    np.testing.assert_allclose(sub.gravity(Q[:, 2:]), ph3.gravity(Q[:, 2:]), atol=1e-12)


def test_jacobian_and_derivative_vs_fd(spatial):
    Q = random_q(spatial, np.random.default_rng(2), CASES)
    np.testing.assert_allclose(spatial.jacobian(Q), _fd(spatial.fk, Q), atol=2e-8)
    dJ = spatial.jacobian_derivative(Q)
    np.testing.assert_allclose(dJ, _fd(spatial.jacobian, Q), atol=2e-7)


def test_pinocchio_and_mujoco_agree(spatial):
    plant = Plant(spatial, handle_mass=0.0)
    for q in random_q(spatial, np.random.default_rng(3), 50):
        plant.reset(q)
        np.testing.assert_allclose(plant.x, spatial.fk(q), atol=1e-12)
        np.testing.assert_allclose(plant.motor_jacobian(), spatial.jacobian(q), atol=1e-12)
        M = spatial.mass_matrix(q)
        np.testing.assert_allclose(plant.motor_mass_matrix(), M, atol=3e-6 + 1e-6 * np.abs(M).max())


def _directions(rng, k, m=3):
    u = rng.normal(size=(k, m))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def test_objective_gradients_vs_fd(spatial):
    """VME (eq. 3.22) and FME (eq. 6.10) matching along random 3-D directions: analytic gradients vs FD."""
    rng = np.random.default_rng(4)
    Q = random_q(spatial, rng, CASES)
    U = _directions(rng, CASES)
    lo, hi = spatial.torque_limits
    D_vme = desired_vme(U, 0.01)
    D_fme = desired_fme(U, 3.0, 100.0)  # M_Free^des: ζ along u, 𝒦 across (eq. 6.12)
    w2 = hi**-2.0

    def values(Qb):  # (N, n) -> (2, N): ν_VME, ν_FME in one batch
        J = spatial.jacobian(Qb)
        return np.stack([jbld(D_vme, J @ np.swapaxes(J, -1, -2)),
                         jbld(D_fme, np.linalg.inv((J * w2) @ np.swapaxes(J, -1, -2)))])

    fd = _fd(values, Q)  # (2, N, n)
    grads = np.array([[VMEMatching(tuple(u), 0.01).gradient(spatial, q), FMEMatching(d, hi).gradient(spatial, q)]
                      for q, u, d in zip(Q, U, D_fme)])  # (N, 2, n)
    err = np.abs(np.moveaxis(grads, 1, 0) - fd).max(-1) / (1.0 + np.abs(fd).max(-1))
    assert err.max() < 1e-5, err.max(axis=1)
    v = values(Q)[:, :20]  # the batch values are the objectives' own
    np.testing.assert_allclose(v[0], [VMEMatching(tuple(u), 0.01).value(spatial, q) for q, u in zip(Q, U[:20])])
    np.testing.assert_allclose(v[1], [FMEMatching(d, hi).value(spatial, q) for q, d in zip(Q, D_fme[:20])])


@pytest.mark.parametrize("saturation", ["scaling", "ascm", "lp"])
def test_controller_invariants_3d(spatial, saturation):
    """1,000 seeded states: τ in the box; the handle force is α F_render + F_extra to < 1e-9 N."""
    rng = np.random.default_rng(5)
    lo, hi = spatial.torque_limits
    K, zeta = 100.0, 3.0
    u = np.array([0.0, 0.0, -1.0])
    cfg = ControllerConfig(
        primary=ForceRendering(damping=0.5),
        objectives=(ObjectiveTerm(VMEMatching((0.3, 0.5, 0.8), 0.01), 0.05),
                    ObjectiveTerm(FMESchedule(desired_fme_free(u, K, zeta), desired_fme_stiff(u, K, zeta)), 0.5)),
        damping=0.1, saturation=saturation, projector="dynamic")
    ctrl = NullSpaceController(spatial, cfg)
    Q = random_q(spatial, rng, CASES)
    dQ = rng.normal(scale=0.5, size=Q.shape)
    F = rng.normal(scale=5.0 * hi.max(), size=(CASES, 3))
    checked = saturated = tertiary = 0
    worst = 0.0
    for q, dq, f in zip(Q, dQ, F):
        ctrl.reset()
        tau = ctrl.step(0.0, q, dq, {"force": f})
        s = ctrl.state
        assert not s.stopped, s.fault
        assert np.all(tau <= hi + 1e-12) and np.all(tau >= lo - 1e-12)
        assert 0.0 <= s.alpha <= 1.0
        if s.clipped:
            continue
        kin = spatial.terms(q, dq)
        F_r, F_x = cfg.primary.forces(0.0, kin, {"force": f})
        out = kin.Jsharp.T @ tau
        worst = max(worst, float(np.abs(out - (s.alpha * F_r + F_x)).max()))
        checked += 1
        saturated += s.alpha < 1.0
        tertiary += bool(s.beta > 0 and s.saturated is not None and s.saturated.any())
    assert checked >= CASES // 2
    assert saturated > 50  # the cases exercise the allocation, not only the interior
    if saturation == "ascm":  # the tertiary objective acts beside held joints (Algorithm 2, m = 3)
        assert tertiary > 20, tertiary
    assert worst < 1e-9, worst


def test_fast_equals_reference_3d(spatial):
    rng = np.random.default_rng(6)
    u = np.array([0.0, 1.0, 0.0])
    base = dict(primary=ForceRendering(damping=0.5),
                objectives=(ObjectiveTerm(VMEMatching(tuple(u), 0.01), 0.1),
                            ObjectiveTerm(FMESchedule(desired_fme_free(u, 100.0, 3.0), desired_fme_stiff(u, 100.0, 3.0)),
                                          0.5)),
                saturation="ascm")
    fast = NullSpaceController(spatial, ControllerConfig(**base))
    ref = NullSpaceController(spatial, ControllerConfig(**base, implementation="reference"))
    for q in random_q(spatial, rng, 100):
        dq, f = rng.normal(scale=0.5, size=spatial.n), rng.normal(scale=15.0, size=3)
        fast.reset(), ref.reset()
        np.testing.assert_allclose(fast.step(0.0, q, dq, {"force": f}), ref.step(0.0, q, dq, {"force": f}),
                                   atol=1e-9)


# ------------------------------------------------------------------------ experiments (reduced)
def test_spatial_remarks_reduced():
    from rhi.experiments.beyond.spatial import spatial_remarks

    res = spatial_remarks(resolution=2, workers=1)
    rows = {r.quantity: r.ours for r in res.tables[0].rows}
    for d, sub in (("srhi5", "srhi5_phantom"), ("gen3", "gen3_3dof")):
        pts, q = res.arrays[f"{d}_points"], res.arrays[f"{d}_q"]
        assert len(pts) >= 4
        dev = rhi.device(d)
        np.testing.assert_allclose(dev.fk(q), pts, atol=1e-8)  # the RHI reaches the sub-chain's points
        assert dev.within_limits(q, tol=1e-6).all()
        assert 0.0 <= rows[f"{d}: fraction with ρ_RHI ≥ ρ_{sub} (Remark I)"] <= 1.0
    with pytest.raises(rhi.errors.InvalidInput, match="resolution"):
        spatial_remarks(resolution=1)
    with pytest.raises(rhi.errors.InvalidInput, match="u"):
        spatial_remarks(resolution=2, u=(0.0, 0.0, 0.0))
    with pytest.raises(rhi.errors.InvalidInput, match="devices"):
        spatial_remarks(resolution=2, devices=("rhi4",))


def test_spatial_force_capability_orders_methods():
    from rhi.experiments.beyond.spatial import spatial_force_capability

    res = spatial_force_capability(configurations=2, directions=4)
    for d in ("srhi5", "gen3"):
        F = res.arrays[f"{d}_fmax"].reshape(-1, 3)
        assert np.all(F[:, 1] >= F[:, 0] - 1e-9)  # ASCM never below simple scaling
        assert np.all(F[:, 1] <= F[:, 2] * (1 + 1e-6))  # nor above the LP optimum
    with pytest.raises(rhi.errors.InvalidInput, match="directions"):
        spatial_force_capability(directions=0)


def test_capabilities_equal_the_reference_force_capability():
    """The experiments' compiled ASCM ramp (LP solved once) gives force_capability's numbers to 1e-10, both J#."""
    from rhi.control.allocation import force_capability
    from rhi.experiments.beyond.spatial import _pair_cached
    from rhi.experiments.setups import capabilities

    rng = np.random.default_rng(3)
    for d in ("srhi5", "gen3"):
        dev = _pair_cached(d)[0]
        lo, hi = dev.torque_limits
        qlo, qhi = np.where(np.isfinite(dev.q_min), dev.q_min, -3), np.where(np.isfinite(dev.q_max), dev.q_max, 3)
        Q = rng.uniform(qlo, qhi, size=(40, dev.n))
        saturated = 0
        for q in Q[dev.within_limits(Q)][:6]:
            J, M = dev.jacobian(q), dev.mass_matrix(q)
            for u, proj in zip(rng.normal(size=(8, 3)), ["dynamic", "pseudoinverse"] * 4):
                M_p = M if proj == "dynamic" else None
                ours = capabilities(J, u, torque_min=lo, torque_max=hi, projector=proj, M=M_p)
                ref = [force_capability(J, u, torque_min=lo, torque_max=hi, method=m, projector=proj, M=M_p)
                       for m in ("scaling", "ascm", "lp")]
                np.testing.assert_allclose(ours, ref, rtol=1e-10, atol=1e-10)
                saturated += ours[1] > ours[0] * (1 + 1e-6)  # ASCM above scaling: joints were held
        assert saturated > 0


def test_spatial_palpation_reduced():
    from rhi.experiments.beyond.spatial_palpation import spatial_palpation

    res = spatial_palpation(settle=0.05, depth=0.008, speed=0.02, hold=0.05, starts=1, cases=("free", "stiff"))
    rows = {r.quantity: r.ours for r in res.tables[0].rows}
    assert rows["torque-limit excess, M_Free^des"] <= 1e-12
    # M_Stiff^des renders more force along u than M_Free^des once both saturate
    assert rows["peak force along u (F/T sensor), M_Stiff^des"] < rows["peak force along u (F/T sensor), M_Free^des"]
    with pytest.raises(rhi.errors.InvalidInput, match="cases"):
        spatial_palpation(cases=("nope",))
