"""rhi's App. A controller against a second, independent transcription of the thesis's equations.

`tests/wmm_transcription.py` transcribes eqs. A.5–A.21 step by step in plain NumPy from the thesis
text (only the device model is shared: fk, the generalized Jacobian, limits, Mecanum geometry;
∂J/∂q by finite differences). Each test drives the transcription in closed loop and, at sampled
states along the run, asks rhi's `WeightedDistributionController` for its command at the *same*
state: the two must agree to the stated tolerance. A planted error in either (a changed gain, a
changed reading) makes them disagree, which `test_the_comparison_can_fail` checks.
"""

from __future__ import annotations

import numpy as np
import pytest
from wmm_transcription import Q0, Transcription, desired_circle, run

from rhi.control.mobile import DMConfig, WeightedConfig, WeightedDistributionController
from rhi.devices.model import device

#: Agreement of the commands [rad/s, m/s] at the same state: analytic vs finite-difference ∂J/∂q
#: (step 1e-6) and two different routes to the weighted pseudoinverse.
TOL_V = 1e-6


@pytest.fixture(scope="module")
def wmm():
    return device("wmm")


def _rhi(dev, **kw) -> WeightedDistributionController:
    return WeightedDistributionController(dev, WeightedConfig(**{"dt": 0.01, "k_x": 10.0, "epsilon": 0.2, **kw}))


def _compare(ctl: WeightedDistributionController, tr: Transcription, states, stage: str, target) -> dict[str, float]:
    """Largest |rhi − transcription| of the generalized command q̇, γ and η over the states (rhi's clipped ones skipped)."""
    dv = dg = de = 0.0
    clipped = 0
    for t, q in states:
        xd, dxd = target(t)
        mine = tr.command(q, t, xd, dxd, stage=stage)
        cmd = ctl.step(t, q, xd, dxd, stage=stage)
        if cmd.clipped:
            clipped += 1
            continue
        dv = max(dv, float(np.abs(cmd.dq - mine["dq"]).max()))
        if ctl.config.distribution == "weighted":
            dg, de = max(dg, abs(cmd.gamma - mine["gamma"])), max(de, abs(cmd.eta - mine["eta"]))
    return {"v": dv, "gamma": dg, "eta": de, "clipped": clipped, "n": len(states)}


def test_tracking_A19_matches_the_transcription(wmm):
    """§A.4.2 (Table A.1): the proposed weighted distribution agrees with the transcription.

    Literal reading (wheel-speed Jacobian, η of the arm-only
    solution), along the whole 0.25 m circle including the 7–20 s where γ > 0.
    """
    tr = Transcription(wmm)
    x0 = wmm.fk(Q0)
    out = run(tr, Q0, 40.0, lambda t: "track", lambda t: desired_circle(x0, t))
    assert out["gamma"].max() > 0.5  # the base takes part: the comparison covers γ > 0
    states = list(zip(out["t"][::8], out["q"][::8]))
    d = _compare(_rhi(wmm), Transcription(wmm), states, "track", lambda t: desired_circle(x0, t))
    assert d["clipped"] == 0
    assert d["v"] < TOL_V and d["gamma"] < 1e-9 and d["eta"] < 1e-9, d


def test_traditional_pinv_matches_the_transcription(wmm):
    """§A.4.2's traditional controller J⁺ = Jᵀ(JJᵀ)⁻¹ agrees with the transcription at W_x = I.

    the wheel-speed Jacobian
    (``pinv``, as printed) and the generalized one (``pinv_generalized``, base velocities mapped by P⁺).
    """
    x0 = wmm.fk(Q0)
    rng = np.random.default_rng(3)
    states = [(t, Q0 + np.r_[rng.normal(scale=0.05, size=3), rng.normal(scale=0.1, size=7)]) for t in (0.0, 9.0, 21.0)]
    for dist, jac in (("pinv", "wheel"), ("pinv_generalized", "generalized")):
        ctl = _rhi(wmm, distribution=dist)
        for t, q in states:
            dxd = desired_circle(x0, t)[1]
            xd = wmm.fk(q) + 0.002  # a small error: no bound is reached
            Jq, P, J = Transcription(wmm, jacobian=jac).jacobians(q)
            v = J.T @ np.linalg.solve(J @ J.T, dxd + 10.0 * (xd - wmm.fk(q)))
            dq = np.r_[P @ v[:4], v[4:]] if jac == "wheel" else v
            assert np.abs(ctl.step(t, q, xd, dxd).dq - dq).max() < 1e-9


@pytest.mark.parametrize(("u", "projector"), [((1, 0, 0), "weighted"), ((1, 0, 0), "generalized"),
                                              ((0, 0, 1), "generalized")])
def test_dm_enhancement_A17_A20_matches_the_transcription(wmm, u, projector):
    """§A.4.3: the DM enhancement agrees with the transcription.

    Cartesian phase (A.17–A.18, z only) and null-space phase (A.19–A.20) along u, k_C = 0.01,
    k_N = 0.2, W_τ = diag(1, 1, 1, 1, 2.5, 2.5, 2.5); rhi's "generalized" projector is the transcription's
    "orthogonal" (I − J_q⁺J_q, eq. A.7 with Q = I).
    """
    tr = Transcription(wmm, u=u, null_projector="weighted" if projector == "weighted" else "orthogonal")
    x0 = wmm.fk(Q0)
    a = run(tr, Q0, 2.0, lambda t: "dm_cartesian", lambda t: (x0, np.zeros(3)))
    q1 = a["q"][-1]
    x1 = wmm.fk(q1)
    b = run(tr, q1, 3.0, lambda t: "dm_null", lambda t: (x1, np.zeros(3)))
    ctl = _rhi(wmm, null_space=projector, dm=DMConfig(u=u, k_c=0.01, k_n=0.2))
    assert abs(ctl.dm(Q0) - tr.H2(Q0)) < 1e-12
    d1 = _compare(ctl, tr, list(zip(a["t"][::25], a["q"][::25])), "dm_cartesian", lambda t: (x0, np.zeros(3)))
    d2 = _compare(ctl, tr, list(zip(b["t"][::25], b["q"][::25])), "dm_null", lambda t: (x1, np.zeros(3)))
    for d in (d1, d2):
        assert d["clipped"] == 0 and d["v"] < TOL_V, d
    assert tr.H2(b["q"][-1]) > tr.H2(q1)  # the null-space phase does raise DM: the comparison is not at rest


def test_dm_gradient_A9_reading(wmm):
    """Eq. A.9's factor: rhi uses the exact derivative, the printed one differs by H₂^4.5.

    Eq. A.9 prints the factor −½ H₂^(−3/2); the derivative of H₂ = s^(−1/2) has −½ s^(−3/2) = −½ H₂³.
    rhi uses the latter; the two differ by H₂^4.5 (≈ 420 at DM_x = 3.8), so the readings are distinguishable.
    """
    tr_exact = Transcription(wmm, u=(1, 0, 0))
    tr_print = Transcription(wmm, u=(1, 0, 0), grad_factor="printed")
    ctl = _rhi(wmm, dm=DMConfig(u=(1, 0, 0)))
    from rhi.control.mobile.measures import dm_gradient
    terms = wmm.terms(Q0)
    g_rhi = dm_gradient(terms.J[:, 3:], terms.dJ[:, 3:, 3:], (1, 0, 0), ctl.config.dm.torque_limits)
    h = tr_exact.H2(Q0)
    assert np.allclose(g_rhi, tr_exact.grad_H2(Q0), rtol=1e-6, atol=1e-8)
    assert np.allclose(tr_print.grad_H2(Q0) * h**4.5, tr_exact.grad_H2(Q0), rtol=1e-9)
    # the finite difference of H₂ itself decides which factor is the derivative
    e = np.zeros(wmm.n)
    e[4] = 1e-6
    fd = (tr_exact.H2(Q0 + e) - tr_exact.H2(Q0 - e)) / 2e-6
    assert fd == pytest.approx(tr_exact.grad_H2(Q0)[1], rel=1e-5)


def test_the_comparison_can_fail(wmm):
    """The comparison detects a planted difference: another ε, another η reading, another Jacobian."""
    tr = Transcription(wmm)
    x0 = wmm.fk(Q0)
    out = run(tr, Q0, 12.0, lambda t: "track", lambda t: desired_circle(x0, t))
    states = list(zip(out["t"][700::40], out["q"][700::40]))  # 7–12 s: γ > 0
    target = lambda t: desired_circle(x0, t)  # noqa: E731
    assert _compare(_rhi(wmm, epsilon=0.3), Transcription(wmm), states, "track", target)["v"] > 1e-3
    assert _compare(_rhi(wmm), Transcription(wmm, jacobian="generalized"), states, "track", target)["v"] > 1e-3
    prev = Transcription(wmm, eta_from="previous")
    assert _compare(_rhi(wmm), prev, states, "track", target)["gamma"] > 1e-3


def test_alternative_readings_match_the_transcription(wmm):
    """The two readings rhi offers besides the literal one agree with the transcription's.

    W_x on the generalized
    Jacobian (``weighting="generalized"``) along the circle, and eq. A.9's factor as printed in the Cartesian phase.
    """
    x0 = wmm.fk(Q0)
    tr = Transcription(wmm, jacobian="generalized")
    out = run(tr, Q0, 12.0, lambda t: "track", lambda t: desired_circle(x0, t))
    assert out["gamma"].max() > 0.2
    d = _compare(_rhi(wmm, weighting="generalized"), Transcription(wmm, jacobian="generalized"),
                 list(zip(out["t"][::20], out["q"][::20])), "track", lambda t: desired_circle(x0, t))
    assert d["clipped"] == 0 and d["v"] < TOL_V and d["gamma"] < 1e-9, d
    tr = Transcription(wmm, u=(1, 0, 0), grad_factor="printed")
    a = run(tr, Q0, 1.0, lambda t: "dm_cartesian", lambda t: (x0, np.zeros(3)))
    ctl = _rhi(wmm, dm=DMConfig(u=(1, 0, 0), gradient="printed"))
    d = _compare(ctl, Transcription(wmm, u=(1, 0, 0), grad_factor="printed"), list(zip(a["t"][::20], a["q"][::20])),
                 "dm_cartesian", lambda t: (x0, np.zeros(3)))
    assert d["v"] < 1e-9 and np.abs(a["dq"]).max() > 0, d


def test_self_motion_at_a_joint_bound_keeps_the_task(wmm):
    """At a joint bound the self-motion is scaled down and the task is kept.

    At the elbow's position bound (q4 = 2.5 rad, reached by the z enhancement after ≈ 27 s) the DM gradient
    pushes past the bound: rhi scales the self-motion down instead of clipping the joint, so J q̇ = ẋ_c still
    holds (clipping let the end effector drift 24 cm upwards while DM was 'enhanced').
    """
    q = np.array([0.3499, 0.0278, 0.0232, -0.0232, -0.2782, 0.1164, 2.5 - 1e-5, -0.0199, -0.5612, 0.0])
    x = wmm.fk(q)
    ctl = _rhi(wmm, dm=DMConfig(u=(0, 0, 1)), null_space="generalized")
    tr = Transcription(wmm, u=(0, 0, 1), null_projector="orthogonal")
    free = tr.command(q, 0.0, x, np.zeros(3), stage="dm_null")["dq"]
    assert free[6] * 0.01 > 1e-5  # the unbounded law would drive q4 past 2.5 within one sample
    cmd = ctl.step(0.0, q, x, np.zeros(3), stage="dm_null")
    assert cmd.clipped and q[6] + cmd.dq[6] * 0.01 <= 2.5 + 1e-12
    assert np.abs(wmm.jacobian(q) @ cmd.dq).max() < 1e-9  # the held position is kept: J q̇ = 0


# --------------------------------------------------------------------------------------------- App. B
def _amd_states(dev, radius: float, duration: float):
    """Rhi's AMD run (kinematic) on the circle of `radius` [m]: the states the comparison is made at."""
    from rhi.control.mobile import AMDConfig, AMDController
    from rhi.sim.mobile import circle, simulate_mobile

    traj = circle(dev.fk(Q0), radius, duration=duration, dt=0.005)
    return traj, simulate_mobile(AMDController(dev, AMDConfig(dt=0.005)), traj, Q0)


def _amd_compare(dev, traj, log, ks, *, sigma_min: float = 0.15) -> dict[str, float]:
    from amd_transcription import AMDTranscription

    from rhi.control.mobile import AMDConfig, AMDController

    tr = AMDTranscription(dev, sigma_min=sigma_min)
    ctl = AMDController(dev, AMDConfig(dt=0.005, sigma_min=0.15))
    A = dev.acceleration_max[:3]
    out = {"ddq": 0.0, "alpha": 0.0, "beta": 0.0, "base": 0, "n": 0, "scaled": 0, "base_on": 0}
    for k in ks:
        q, dq = log.q[k], (log.dq[k - 1] if k else np.zeros(dev.n))
        # B.20: a disabled base decelerates at its bound until it stops (the last sample lands on zero)
        stop = np.where(np.abs(dq[:3]) > A * 0.005, -np.sign(dq[:3]) * A, -dq[:3] / 0.005)
        mine = tr.step(q, dq, traj.x[k], traj.dx[k], traj.ddx[k], stop)
        ctl.reset()
        cmd = ctl.step(float(log.t[k]), q, dq, traj.x[k], traj.dx[k], traj.ddx[k])
        out["ddq"] = max(out["ddq"], float(np.abs(cmd.ddq - mine["ddq"]).max()))
        out["alpha"] = max(out["alpha"], abs(cmd.alpha - mine["alpha"]))
        out["beta"] = max(out["beta"], abs(cmd.beta - mine["beta"]))
        out["base"] += int(cmd.base_active != mine["base_active"])
        out["base_on"] += int(mine["base_active"])
        out["scaled"] += int(mine["alpha"] < 1 or mine["beta"] < 1)
        out["n"] += 1
    return out


def test_amd_B9_B19_matches_the_transcription_within_the_workspace(wmm):
    """Table B.2: rhi's AMD agrees with the transcription within the workspace.

    Within the workspace (R = 0.1 m), rhi's AMD and the transcription (B.6–B.19, finite-difference
    J̇q̇, ∇H, ∇²H q̇) agree on every sampled state, including the base activation (σ_m < σ_m,min = 0.15) that the
    thesis says never happens. Tolerance 1e-4 rad/s²: the nested finite differences of ∇²H q̇.
    """
    traj, log = _amd_states(wmm, 0.1, 20.0)
    on = np.flatnonzero(np.nan_to_num(log.base_active) > 0)
    assert on.size > 0  # the base is enabled on this circle: the comparison covers both branches
    d = _amd_compare(wmm, traj, log, [*range(0, log.t.size, 160), *on[::60]])
    assert d["base"] == 0 and d["base_on"] > 0, d
    assert d["ddq"] < 1e-4 and d["alpha"] < 1e-9 and d["beta"] < 1e-6, d
    # and it can fail: a transcription with another σ_m,min disagrees at those states
    assert _amd_compare(wmm, traj, log, on[::60], sigma_min=0.14)["base"] > 0


def test_amd_B9_B19_matches_the_transcription_beyond_the_workspace(wmm):
    """§B.4.3 / Fig. B.11: rhi's AMD agrees with the transcription beyond the workspace (R = 0.25 m), base decisions too.

    The states the base is enabled at (the 'base on' time of Fig. B.11) are among those compared (q̈ to 1e-4
    rad/s², as within the workspace; β to 1e-4, measured 5e-5), and a transcription with another σ_m,min
    disagrees there.
    """
    traj, log = _amd_states(wmm, 0.25, 20.0)
    on = np.flatnonzero(np.nan_to_num(log.base_active) > 0)
    assert on.size > 0
    first = int(on[0])
    d = _amd_compare(wmm, traj, log, [*range(0, log.t.size, 200), *range(max(first - 2, 0), first + 3), *on[::80]])
    assert d["base"] == 0 and d["base_on"] > 0, d
    # β scales the null-space term, which carries the transcription's finite-difference ∇²H q̇: 1e-4, as q̈
    assert d["ddq"] < 1e-4 and d["alpha"] < 1e-9 and d["beta"] < 1e-4, d
    assert _amd_compare(wmm, traj, log, on[::80], sigma_min=0.14)["base"] > 0


def test_the_arm_alone_cannot_keep_sigma_min_on_the_inner_circle(wmm):
    """The arm alone cannot keep σ_min(J_m) ≥ σ_m,min at the far point of the R = 0.1 m circle.

    At the far point of the R = 0.1 m circle, x0 + [0.2, 0, 0], the best
    σ_min(J_m) the arm alone can have (base fixed, joint limits) is below σ_m,min = 0.15, so the thesis's own rule
    (§B.3.2: "after the singularity criterion ... becomes lower than σ_m,min, the mobile base will be activated")
    must enable the base. Independent of rhi's best_sigma: SLSQP on the device model from several starts.
    """
    from scipy.optimize import minimize

    x_far = wmm.fk(Q0) + np.array([0.2, 0.0, 0.0])
    lo = np.where(np.isfinite(wmm.q_min), wmm.q_min, -2 * np.pi)
    hi = np.where(np.isfinite(wmm.q_max), wmm.q_max, 2 * np.pi)
    lo[:3] = hi[:3] = 0.0
    rng = np.random.default_rng(7)
    best = 0.0
    for k in range(5):
        q0 = Q0 + (0 if k == 0 else np.r_[np.zeros(3), rng.normal(scale=0.5, size=7)])
        res = minimize(lambda q: -np.linalg.svd(wmm.jacobian(q)[:, 3:], compute_uv=False)[-1], np.clip(q0, lo, hi),
                       method="SLSQP", bounds=list(zip(lo, hi)),
                       constraints=[{"type": "eq", "fun": lambda q: wmm.fk(q) - x_far}], options={"maxiter": 300})
        if np.linalg.norm(wmm.fk(res.x) - x_far) < 1e-6:
            best = max(best, -res.fun)
    assert 0.09 < best < 0.15


def test_self_motion_goes_on_without_a_joint_held_at_its_bound(wmm):
    """A joint at its bound is left out of the generalized self-motion; the others carry on.

    With the elbow at its bound (q4 = 2.5 rad) the other joints go on raising DM (saturation in the null
    space [51]) instead of stopping there; the task is kept.
    """
    q = np.array([0.3499, 0.0278, 0.0232, -0.0232, -0.2782, 0.1164, 2.5, -0.0199, -0.5612, 0.0])
    x = wmm.fk(q)
    ctl = _rhi(wmm, dm=DMConfig(u=(0, 0, 1)), null_space="generalized")
    cmd = ctl.step(0.0, q, x, np.zeros(3), stage="dm_null")
    tr = Transcription(wmm, u=(0, 0, 1))
    assert tr.grad_H2(q)[3] > 0  # the gradient pushes the elbow past its bound
    assert abs(cmd.dq[6]) < 1e-9 and np.abs(cmd.dq[3:]).max() > 1e-3
    assert np.abs(wmm.jacobian(q) @ cmd.dq).max() < 1e-9
    assert tr.H2(q + 0.01 * cmd.dq) > tr.H2(q)


def test_traditional_B_matches_the_transcription_beyond_the_workspace(wmm):
    """§B.4.3's traditional controller equals the transcription on App. B's 'beyond' circle.

    q̈ = J†(ẍ − J̇q̇) + (I − J†J) q̈_A with J† = Jᵀ(JJᵀ)⁻¹ and q̈_A of eq. B.13 (line 2489), finite-difference J̇q̇
    and ∇²H q̇ (1e-4 rad/s²) on the R = 0.25 m circle; with limit="clip" each joint is then clipped at its bound
    (B.7–B.8), which the thesis's baseline does not mention.
    """
    from amd_transcription import AMDTranscription

    from rhi.control.mobile import PinvAccelConfig, PinvAccelController
    from rhi.sim.mobile import circle, simulate_mobile

    traj = circle(wmm.fk(Q0), 0.25, duration=20.0, dt=0.005)
    log = simulate_mobile(PinvAccelController(wmm, PinvAccelConfig(dt=0.005)), traj, Q0)
    tr = AMDTranscription(wmm)
    worst = {"none": 0.0, "clip": 0.0}
    mine = np.zeros(wmm.n)
    for k in range(0, log.t.size, 200):
        q, dq = log.q[k], (log.dq[k - 1] if k else np.zeros(wmm.n))
        J = wmm.jacobian(q)
        ddx = traj.ddx[k] + tr.kd * (traj.dx[k] - J @ dq) + tr.kp * (traj.x[k] - wmm.fk(q))
        Jp = J.T @ np.linalg.inv(J @ J.T)
        mine = Jp @ (ddx - tr.drift(q, dq)) + (np.eye(wmm.n) - Jp @ J) @ tr.qdd_A(q, dq)
        lo, hi = tr.accel_limits(q, dq)
        for limit, want in (("none", mine), ("clip", np.clip(mine, lo, hi))):
            cmd = PinvAccelController(wmm, PinvAccelConfig(dt=0.005, limit=limit)).step(
                float(log.t[k]), q, dq, traj.x[k], traj.dx[k], traj.ddx[k])
            worst[limit] = max(worst[limit], float(np.abs(cmd.ddq - want).max()))
    assert worst["none"] < 1e-4 and worst["clip"] < 1e-4, worst
    # and it can fail: the same controller without the null-space term (I − J†J) q̈_A differs from it
    k = log.t.size - 1 - (log.t.size - 1) % 200  # the last state compared above (`mine` is its command)
    cmd = PinvAccelController(wmm, PinvAccelConfig(dt=0.005, manipulability=False, limit="none")).step(
        float(log.t[k]), log.q[k], log.dq[k - 1], traj.x[k], traj.dx[k], traj.ddx[k])
    assert np.abs(cmd.ddq - mine).max() > 1e-3


@pytest.mark.parametrize(("axis", "at_q0", "printed"), [(2, 1.125, 4.031), (0, 3.825, 5.88)])
def test_the_printed_dm_needs_the_base(wmm, axis, at_q0, printed):
    """§A.4.3's enhanced DM (z: 1.125 → 4.031, x: 3.905 → 5.88) is out of reach of the arm alone.

    DM = [uᵀ J_m W_τᵀW_τ J_mᵀ u]^(−1/2) (eq. A.8, W_τ = diag(1, 1, 1, 1, 2.5, 2.5, 2.5) as printed) equals the printed
    value at q0; with the base fixed (eq. A.19 as printed moves it only once γ > 0) and the end effector held at
    q0's x, y with any height in the Cartesian phase's [0.36, 0.56] m, SLSQP on the device model from 12 starts
    finds at most 1.57 along z and 4.21 along x (30 starts: 1.568, 4.208): the printed values need the base.
    """
    from scipy.optimize import minimize

    w2 = np.array([1.0, 1.0, 1.0, 1.0, 2.5, 2.5, 2.5]) ** 2

    def dm(q):
        v = wmm.jacobian(q)[axis, 3:]
        return float(v @ (w2 * v)) ** -0.5

    assert dm(Q0) == pytest.approx(at_q0, abs=2e-3)
    x0 = wmm.fk(Q0)
    lo = np.where(np.isfinite(wmm.q_min), wmm.q_min, -2 * np.pi)
    hi = np.where(np.isfinite(wmm.q_max), wmm.q_max, 2 * np.pi)
    lo[:3] = hi[:3] = 0.0
    cons = [{"type": "eq", "fun": lambda q: wmm.fk(q)[:2] - x0[:2]},
            {"type": "ineq", "fun": lambda q: np.r_[wmm.fk(q)[2] - 0.36, 0.56 - wmm.fk(q)[2]]}]
    rng = np.random.default_rng(11)
    best = 0.0
    for k in range(12):
        q0 = Q0 + (0 if k == 0 else np.r_[np.zeros(3), rng.normal(scale=0.6, size=7)])
        res = minimize(lambda q: -min(dm(q), 1e3), np.clip(q0, lo, hi), method="SLSQP", bounds=list(zip(lo, hi)),
                       constraints=cons, options={"maxiter": 300})
        x = wmm.fk(res.x)
        if np.abs(x[:2] - x0[:2]).max() < 1e-6 and 0.36 - 1e-6 <= x[2] <= 0.56 + 1e-6:
            best = max(best, -float(res.fun))
    assert dm(Q0) < best < 0.75 * printed
