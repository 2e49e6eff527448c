"""Chapter 5: TMI null-space control of the RHI in unilateral teleoperation (reduced runs)."""

import matplotlib.pyplot as plt
import numpy as np
import pytest
from conftest import random_q, row

from rhi import thesis as T
from rhi.control import Manipulability, TMIMatching
from rhi.control.manipulability import penalty
from rhi.errors import InvalidInput, Unreachable
from rhi.experiments import ch5
from rhi.metrics import jbld, joint_limit_penalty, penalized_jacobian
from rhi.plots import ch5 as pl5


@pytest.fixture(scope="module")
def devs():
    return ch5.setup.devices()


@pytest.fixture(scope="module")
def fixed():
    return ch5.fixed_point(duration=3.0, variants=False)


@pytest.fixture(scope="module")
def wtraj():
    return ch5.w_trajectory(scale=0.08, settle=1.0, ellipses=5)


def _fd(f, q, h=1e-6):
    return np.array([(f(q + h * e) - f(q - h * e)) / (2 * h) for e in np.eye(q.size)])


def test_penalty_and_its_derivative(devs, rng):
    dev = devs["RHI"]
    for q in random_q(dev, rng, 5):
        for k in (1.0, 10.0):
            p, dp = penalty(q, q_min=dev.q_min, q_max=dev.q_max, k_q=k)
            np.testing.assert_allclose(p, joint_limit_penalty(q, q_min=dev.q_min, q_max=dev.q_max, k_q=k), rtol=1e-12, atol=1e-15)
            lim = dict(q_min=dev.q_min, q_max=dev.q_max, k_q=k)
            fd = [(penalty(q + 1e-6 * e, **lim)[0] - penalty(q - 1e-6 * e, **lim)[0])[i] / 2e-6 for i, e in enumerate(np.eye(4))]
            np.testing.assert_allclose(dp, fd, rtol=1e-6, atol=1e-8)
    # outside the limits: clipped to 0 with zero slope; no finite limits: 1
    p, dp = penalty(dev.q_min - 0.1, q_min=dev.q_min, q_max=dev.q_max, k_q=10.0)
    assert np.all(p == 0) and np.all(dp == 0)
    p, dp = penalty(np.zeros(2), q_min=np.full(2, -np.inf), q_max=np.full(2, np.inf), k_q=10.0)
    assert np.all(p == 1) and np.all(dp == 0)


@pytest.mark.parametrize("k_q,pen_slave,rot", [(None, False, 0.0), (10.0, False, 0.0), (1.0, True, 0.0),
                                               (10.0, False, 0.4)])
def test_tmi_objective_value_and_gradient(devs, rng, k_q, pen_slave, rot):
    """ν of eq. 5.11 and its analytic gradient (penalised Jacobian, optional H) against finite differences."""
    rhi, slave = devs["RHI"], devs["slave"]
    qs = slave.ik((0.5, 0.0), ch5.setup.SLAVE_SEED)
    H = None if rot == 0 else np.array([[np.cos(rot), -np.sin(rot)], [np.sin(rot), np.cos(rot)]])
    obj = TMIMatching(slave, qs, k_q=k_q, penalize_slave=pen_slave, H=H)
    for q in random_q(rhi, rng, 4):
        J = rhi.jacobian(q)
        Js = slave.jacobian(qs)
        if k_q is not None:
            J = penalized_jacobian(J, q, q_min=rhi.q_min, q_max=rhi.q_max, k_q=k_q)
            if pen_slave:
                Js = penalized_jacobian(Js, qs, q_min=slave.q_min, q_max=slave.q_max, k_q=k_q)
        if H is not None:
            J = H @ J
        assert obj.value(rhi, q) == pytest.approx(float(jbld(Js @ Js.T, J @ J.T)), rel=1e-12)
        g = obj.gradient(rhi, q)
        np.testing.assert_allclose(g, _fd(lambda v: obj.value(rhi, v), q), rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(obj.gradient_at(rhi.terms(q)), g, rtol=1e-12, atol=1e-14)


def test_tmi_objective_reads_the_slave_encoders(devs):
    rhi, slave = devs["RHI"], devs["slave"]
    state = {"q": slave.ik((0.5, 0.0), ch5.setup.SLAVE_SEED)}
    obj = TMIMatching(slave, lambda: state["q"], k_q=ch5.setup.K_Q)
    v0 = obj.value(rhi, ch5.setup.Q_FIXED)
    state["q"] = slave.ik((0.45, -0.2), ch5.setup.SLAVE_SEED)
    assert obj.value(rhi, ch5.setup.Q_FIXED) != pytest.approx(v0)  # not a stale cache
    state["q"] = np.array([np.nan, 0.2])
    with pytest.raises(InvalidInput, match="slave_q"):
        obj.value(rhi, ch5.setup.Q_FIXED)


def test_penalized_manipulability(devs, rng):
    rhi = devs["RHI"]
    plain, literal = Manipulability(log=True, k_q=None), Manipulability(log=True)
    pen = Manipulability(log=True, k_q=10.0)
    for q in random_q(rhi, rng, 4):
        assert plain.value(rhi, q) == pytest.approx(literal.value(rhi, q), rel=1e-12)
        np.testing.assert_allclose(plain.gradient(rhi, q), literal.gradient(rhi, q), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(pen.gradient(rhi, q), _fd(lambda v: pen.value(rhi, v), q), rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(pen.gradient_at(rhi.terms(q)), pen.gradient(rhi, q), rtol=1e-12)


def test_objectives_reject_bad_input(devs):
    slave = devs["slave"]
    with pytest.raises(InvalidInput, match="k_q"):
        TMIMatching(slave, np.zeros(2), k_q=0.0)
    with pytest.raises(InvalidInput, match="slave_q"):
        TMIMatching(slave, np.zeros(3))
    with pytest.raises(InvalidInput, match="k_q"):
        Manipulability(log=True, k_q=-1.0)


def test_fixed_point_controller_increases_tme(fixed, devs):
    """Fig. 5.3's claim: with the handle held, the TMI null-space controller enlarges the TME."""
    inc = row(fixed, "TME area increase by the TMI", unique=True).ours
    assert inc > 0.0  # the direction of §5.4.1's +18.1 % (its size: test_fixed_point_tme_increase_value)
    a = fixed.arrays
    assert a["tmi"][-1] > a["tmi"][0]
    assert row(fixed, "ν after", unique=True).ours < 0.5 * row(fixed, "ν before", unique=True).ours
    # the end-effector stays put while the HI reconfigures (null-space motion), within the joint limits
    assert row(fixed, "max end-effector drift", unique=True).ours < 0.5  # mm
    assert np.linalg.norm(a["qT"] - a["q0"]) > 0.1
    assert devs["RHI"].within_limits(a["qT"], tol=1e-3)
    # TME never exceeds the slave's own ME (it is inside the intersection)
    assert row(fixed, "TME area λ = σ₁σ₂ after", unique=True).ours <= row(fixed, "upper bound of λ", unique=True).ours + 1e-12
    np.testing.assert_allclose(a["x0"], ch5.setup.X_FIXED, atol=2e-3)  # FK of the thesis's q is (0.48, −0.35)


def test_w_trajectory_scenarios(wtraj):
    """Reduced W: the slave follows.

    Both RHI scenarios keep a larger TME than the 2-DoF Rehab, and the TMI objective brings the TME close to its bound
    (the slave's own ME). The effort order of Fig. 5.6 needs the full W (see the report); here the effort accounting
    is checked instead.
    """
    s1, s2, s3 = (row(wtraj, f"mean TME area, scenario {i}", unique=True).ours for i in (1, 2, 3))
    bound = row(wtraj, "mean of the slave's own σ₁σ₂", unique=True).ours
    assert s3 < s2 <= bound and s3 < s1 <= bound
    assert s1 > 0.9 * bound
    for i in (1, 2, 3):
        assert row(wtraj, f"slave error to the reference point, RMS, scenario {i}", unique=True).ours < 5.0  # mm
        assert row(wtraj, f"closest approach to a joint limit, scenario {i}", unique=True).ours > 0.0
        # user work + actuator work = friction losses + Δ kinetic energy (eq. 5.15's W is accounted for)
        parts = [row(wtraj, f"{what}, scenario {i}", unique=True).ours for what in
                 ("user work over the W", "actuator work over the W", "energy dissipated by joint friction over the W")]
        resid = row(wtraj, f"energy balance residual over the W, scenario {i}", unique=True).ours
        assert abs(resid) < 0.02 * sum(abs(p) for p in parts)
        assert row(wtraj, f"user work over the W, scenario {i}", unique=True).ours > 0
    # the work curve of eq. 5.15 starts at 0 when the W starts; the rendered damping is common to all
    a = wtraj.arrays
    assert a["s1_work"][np.argmin(np.abs(a["s1_t"]))] == pytest.approx(0.0, abs=1e-9)
    damp = [row(wtraj, f"energy dissipated by the rendered damping B^d over the W, scenario {i}", unique=True).ours
            for i in (1, 2, 3)]
    assert max(damp) / min(damp) < 1.1


def test_w_trajectory_reports_the_alternative_readings(wtraj):
    """Issue 23: the plain-J and literal-eq.-5.14 readings of scenarios 1–2 stand beside the headline."""
    bound = row(wtraj, "mean of the slave's own σ₁σ₂", unique=True).ours
    s3 = row(wtraj, "mean TME area, scenario 3", unique=True).ours
    for name in ("reading 'plain J' (k_q = None in eqs. 5.11, 5.14): mean TME area, scenario 1",
                 "reading 'plain J': mean TME area, scenario 2",
                 "reading 'literal eq. 5.14' (τ_N = α ∂μ/∂q, plain J): mean TME area, scenario 2"):
        assert s3 < row(wtraj, name, unique=True).ours <= bound  # an RHI objective beats the Rehab, inside the slave's ME
    for name in ("reading 'plain J': scenario 2's mean TME area below", "reading 'literal eq. 5.14': scenario 2's"):
        assert np.isfinite(row(wtraj, name, unique=True).ours)


def test_w_outside_workspace_raises():
    with pytest.raises(Unreachable, match="path"):
        ch5.w_trajectory(center=(1.5, 0.0))
    with pytest.raises(Unreachable, match="path"):  # starts inside, leaves the Rehab's crescent
        ch5.w_trajectory(height=0.6)


def test_bad_input():
    with pytest.raises(InvalidInput, match="scale"):
        ch5.w_trajectory(scale=0.0)
    with pytest.raises(InvalidInput, match="speed"):
        ch5.w_trajectory(speed=-0.02)
    with pytest.raises(InvalidInput, match="friction"):
        ch5.w_trajectory(friction="sticky")
    with pytest.raises(InvalidInput, match="duration"):
        ch5.fixed_point(duration=0.0)
    with pytest.raises(InvalidInput, match="area_samples"):
        ch5.workspaces(samples=100, area_samples=10)


def test_workspaces():
    res = ch5.workspaces(samples=4000, area_samples=20000)
    assert row(res, "RHI workspace larger", unique=True).ours == 1.0
    for nm in ("RHI", "Rehab", "slave"):
        assert row(res, f"W inside the workspace of the {nm}", unique=True).ours == 1.0
    assert res.arrays["workspaces"].shape == (3, 4000, 2)


def test_figures_draw(fixed, wtraj):
    ws = ch5.workspaces(samples=500, area_samples=500)
    for fn, res in ((pl5.fig5_3, fixed), (pl5.fixed_point_convergence, fixed), (pl5.fig5_4, ws),
                    (pl5.fig5_5, wtraj), (pl5.fig5_6, wtraj), (pl5.tme_along_w, wtraj)):
        fig = fn(res)
        assert fig.axes and all(ax.lines for ax in fig.axes)
        plt.close(fig)


@pytest.mark.xfail(strict=True, reason="the TME increase depends on the start configuration's distance from the "
                                      "optimum and on the joint-limit penalty k_q, which the thesis does not give "
                                      "(ch5 docstring); rhi's is larger than 18.1 %")
def test_fixed_point_tme_increase_value(fixed):
    assert T.TME_INCREASE.within(row(fixed, "TME area increase by the TMI", unique=True).ours)


@pytest.mark.xfail(strict=True, reason="Table 5.1's effort order comes from human users feeling the hardware's "
                                      "uncompensated friction; rhi's simulated hand pays mostly the rendered damping "
                                      "B^d, which is the same in every scenario, so the order does not follow")
def test_table_5_1_effort_order(wtraj):
    assert row(wtraj, "effort order 1 < 2 < 3 holds", unique=True).ours == float(T.EFFORT_ORDER)
