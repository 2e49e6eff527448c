"""Issue 25 item 2: the null-space sources made passive — the sampled-exact barrier and the gated redistribution."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import random_q

from rhi.control import JointLimitBarrier, NullSpaceTank, WeightedSum
from rhi.errors import InvalidInput


def _near_limits(dev, rng, margin, count):
    """Configurations with one joint inside `margin` of one of its bounds (past it for some)."""
    out = []
    for q in random_q(dev, rng, count):
        k = rng.integers(dev.n)
        bound = (dev.q_min if rng.random() < 0.5 else dev.q_max)[k]
        q[k] = bound + np.sign(0.5 * (dev.q_min[k] + dev.q_max[k]) - bound) * rng.uniform(-0.2, 1.2) * margin
        out.append(q)
    return out


@pytest.mark.parametrize("kind", ["quadratic", "inverse"])
def test_sampled_barrier_is_the_exact_discrete_gradient(kind, rhi4, rng):
    """∇̄νᵀΔq̂ = ν(q + Δq̂) − ν(q) for Δq̂ = ΔT q̇ (to rounding), across the margin's kink and the stops; ∇̄ν → ∇ν."""
    h = 1e-3
    bar = JointLimitBarrier(0.1, weight=3.0, kind=kind, hold=h)
    active = 0
    for q in _near_limits(rhi4, rng, bar.margin, 200):
        dq = rng.normal(scale=4.0, size=rhi4.n)  # up to a few rad/s: steps of a few mrad
        g = bar.sampled_gradient(rhi4, q, dq)
        dnu = bar.value(rhi4, q + h * dq) - bar.value(rhi4, q)
        assert g @ (h * dq) == pytest.approx(dnu, rel=1e-9, abs=1e-13 * (1.0 + bar.value(rhi4, q)))
        active += bool(np.any(g != 0.0))
        if bar.distances(rhi4, q).min() <= 2e-3 * bar.margin:
            continue  # the inverse barrier's floor: ν is flat there, its gradient is not (the sampled form follows ν)
        slow = bar.sampled_gradient(rhi4, q, 1e-6 * dq)  # a vanishing step: the gradient
        np.testing.assert_allclose(slow, bar.gradient(rhi4, q), rtol=1e-4, atol=1e-6 * (1 + np.abs(slow).max()))
    assert active > 100
    # the plain barrier and hold = 0 keep the gradient at q (sample-and-hold)
    q = _near_limits(rhi4, rng, 0.1, 1)[0]
    plain = JointLimitBarrier(0.1, weight=3.0, kind=kind)
    np.testing.assert_array_equal(plain.gradient_at(rhi4.terms(q, np.ones(rhi4.n))), plain.gradient(rhi4, q))
    np.testing.assert_array_equal(bar.gradient_at(rhi4.terms(q, np.ones(rhi4.n))),
                                  bar.sampled_gradient(rhi4, q, np.ones(rhi4.n)))


@pytest.mark.parametrize("kind", ["quadratic", "inverse"])
def test_barrier_generated_energy_books_each_hold(kind, rhi4, rng):
    """`barrier_generated` = the loop Σ τ_b(k)ᵀΔq(k) + gain Δν; on a path the prediction follows the sampled form is 0.

    A joint driven into and out of its limit margin at 1 kHz: the gradient sampled and held generates energy over
    the cycle (> 0), the discrete gradient generates none where q(k+1) = q(k) + ΔT q̇(k) (rounding only).
    """
    from types import SimpleNamespace

    from rhi.experiments.beyond.sources import barrier_generated

    h, gain = 1e-3, 100.0
    bar = JointLimitBarrier(0.1, weight=2.0, kind=kind)
    t = np.arange(2001) * h
    q = np.tile(0.5 * (rhi4.q_min + rhi4.q_max), (t.size, 1))
    q[:, 3] = rhi4.q_min[3] + 0.1 - 0.08 * np.sin(np.pi * t / t[-1]) ** 2  # into the margin and out again
    dq = np.gradient(q, h, axis=0)
    dq[:-1] = np.diff(q, axis=0) / h  # the prediction q(k) + ΔT q̇(k) is exact on this path
    log = SimpleNamespace(t=t, q=q, dq=dq)
    for sampled in (False, True):
        b = dataclasses.replace(bar, hold=h if sampled else 0.0)
        loop = sum(-gain * float(b.gradient_at(rhi4.terms(q[k], dq[k])) @ (q[k + 1] - q[k])) for k in range(t.size - 1))
        loop += gain * (b.value(rhi4, q[-1]) - b.value(rhi4, q[0]))
        assert barrier_generated(rhi4, bar, gain, log, sampled=sampled) == pytest.approx(loop, rel=1e-9, abs=1e-12)
    assert barrier_generated(rhi4, bar, gain, log, sampled=False) > 1e-4  # J: sample-and-hold generates
    assert abs(barrier_generated(rhi4, bar, gain, log, sampled=True)) < 1e-10  # J: the exact sampled form does not


def test_sampled_barrier_and_gate_bad_input():
    for bad in (-1e-3, float("nan"), float("inf"), True, "1"):
        with pytest.raises(InvalidInput, match="hold"):
            JointLimitBarrier(0.1, hold=bad)
    with pytest.raises(InvalidInput, match="tank.allocation"):
        NullSpaceTank(allocation="scale")  # type: ignore[arg-type]


def test_gated_allocation_fast_equals_reference_in_a_palpation(rhi4):
    """The compiled gate (whole tick) sends the reference's torque, θ and T_A; the redistribution is gated.

    Where θ < 1 the allocation is θ ASCM + (1 − θ) simple scaling: in the box, and the sent null-space torque of the
    allocation pays only what its account holds.
    """
    from rhi.experiments.beyond import passivity as P
    from rhi.experiments.ch6 import setup as ch6
    from rhi.sim import Hand, HandPath, Plant, Wall, simulate

    x0, u = np.array(ch6.X0), np.array(ch6.U)
    ref = P.controller(rhi4, objectives=True, port=None, tank=P.GATE_EMPTY, sampled=True, implementation="reference")
    fast = P.controller(rhi4, objectives=True, port=None, tank=P.GATE_EMPTY, sampled=True)
    assert fast._kernel is not None and fast._kernel.whole_ok
    q0 = ch6.best_match(rhi4, x0, WeightedSum(ref.config.objectives), starts=1)
    hand = Hand(HandPath(np.array([x0, x0 - P.OUT * u, x0 + P.DEPTH * u]), speed=0.03, start=0.1),
                stiffness=P.HAND[0], damping=P.HAND[1], max_force=P.HAND[2])
    plant = Plant(rhi4)
    plant.reset(q0)
    log = simulate(plant, ref, duration=0.8, hand=hand, virtual=Wall(x0, u, P.K_E),
                   record=lambda: {"theta": ref.state.tank.gate, "T_A": ref.state.tank.allocation,
                                   "held": int(ref.state.saturated.sum())})
    assert log.fault is None
    assert np.any(log.extra["theta"] < 1.0)  # the gate acted
    for k in range(len(log.t)):
        tau = fast.step(float(log.t[k]), log.q[k], log.dq[k], {"force": log.F_env[k]})
        np.testing.assert_allclose(tau, log.tau[k], atol=1e-9)
        assert fast.state.tank.gate == pytest.approx(log.extra["theta"][k], abs=1e-9)
        assert fast.state.tank.allocation == pytest.approx(log.extra["T_A"][k], abs=1e-12)


def test_passive_null_space_keeps_the_hand_passive_and_the_wall():
    """Issue 25 item 2, measured in the plant: the hand's work ∫F_hᵀẋ dt, not the controller's books.

    The same check on the old controller (ASCM's redistribution unbudgeted, the barrier's gradient sampled and held)
    and on the passive null space (the sampled-exact barrier, the redistribution and the objectives on the tank's
    gate, no passivity controller): the old one hands the user energy (the check fails), the new one does not, and
    with the tank full at the start it keeps the wall's largest force (away from the joint stops) within 10 % of the
    old one's. The sources, from the encoders: the allocation's work goes from more than half a joule to at most its
    account's initial budget, and the barrier's sample-and-hold energy on the old run's own trajectory vanishes in the
    sampled-exact form.
    """
    from rhi.experiments.beyond.passivity import _LABEL, GATE_FULL, SUMMARY, passivity

    r = passivity(duration=8.0, stiff=None, cases=("objectives", "passive", "passive_empty"))
    a = r.arrays
    s = {c: dict(zip(SUMMARY, a[f"{c}_summary"])) for c in ("objectives", "passive", "passive_empty")}

    def passive(c: str) -> bool:  # the hand's work at the end and at every time, ≥ −1 mJ
        return bool(s[c]["W"] >= -1e-3 and a[f"{c}_W"].min() >= -1e-3)

    assert not passive("objectives") and s["objectives"]["W"] < -0.05  # J: the old null space is active
    assert passive("passive") and passive("passive_empty")
    assert abs(s["passive"]["force_peak_wall"] / s["objectives"]["force_peak_wall"] - 1.0) <= 0.1
    assert s["passive"]["peak_at_stop"] == 0.0 and s["passive"]["qdot_max"] < s["objectives"]["qdot_max"]
    rows = {row.quantity: row.ours for t in r.tables for row in t.rows}
    assert rows[f"passive and the wall's largest force within 10 % of no PC's, {_LABEL['passive']}"] == 1.0
    old, new = _LABEL["objectives"], _LABEL["passive"]
    assert rows[f"  allocation's work while ASCM holds n − m joints, {old}"] > 0.5  # J
    budget = GATE_FULL.initial  # J: the allocation's account at the start, all it may spend beyond what it took in
    assert abs(rows[f"  allocation's work while ASCM holds n − m joints, {new}"]) <= budget + 1e-3
    assert rows[f"  allocation, {new}"] <= budget + 1e-3 < 0.1 * rows[f"  allocation, {old}"]
    zoh = "  energy the barrier's held torque generates, Σ τ_bᵀΔq + Δν ({} form on this run's trajectory), {}"
    assert rows[zoh.format("gradient", old)] > 0.1  # J: sample-and-hold of the steep barrier
    assert abs(rows[zoh.format("sampled", old)]) <= 0.02 * rows[zoh.format("gradient", old)]
    assert abs(rows[zoh.format("sampled", new)]) <= 2e-3
