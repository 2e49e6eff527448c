"""rhi's ch. 5 and ch. 6 controllers against a second, independent transcription of the thesis (issue 23).

`tests/transcription.py` is written from the thesis text in plain NumPy and imports only the
device model. Each test feeds both the same inputs and states its tolerance; where the two
readings of the thesis differ (eqs. 6.17–6.18 read literally vs the hysteresis of §6.3.2), the
test pins the difference so it cannot silently change.
"""

from __future__ import annotations

import numpy as np
import pytest
import transcription as tr
from conftest import random_q

import rhi
from rhi.control import FMEMatching, FMESchedule, TransitionConfig, TransitionState, transition_step
from rhi.control.manipulability import Manipulability
from rhi.control.transition import aso_volume
from rhi.experiments.ch6.setup import K_D, Q_HOME, X0, U, desired_fmes, palpation_controller
from rhi.metrics import tmi

EPS1, EPS2, RHO = 0.7, 0.95, 0.003


@pytest.fixture(scope="module")
def fmes(rhi4):
    return desired_fmes(rhi4, np.array(U), Q_HOME)


def test_aso_equals_eq_6_14(rhi4, rng):
    lo, hi = rhi4.torque_min, rhi4.torque_max
    for tau in rng.uniform(lo, hi, size=(200, 4)):
        assert aso_volume(tau, torque_min=lo, torque_max=hi, S=50.0) == pytest.approx(
            tr.aso(tau, lo, hi, 50.0), abs=1e-12)
    assert aso_volume(hi * 1.01, torque_min=lo, torque_max=hi) == tr.aso(hi * 1.01, lo, hi, 50.0) == 0.0


def test_desired_fmes_are_the_thesis_numbers(fmes):
    K, zeta, Mf, Ms = fmes
    # §6.4: "𝒦 and ζ are calculated as 123 and 3.3"; M_Free^des = diag{123, 3.3} with u = [0, 1]
    assert (round(K), round(zeta, 1)) == (123, 3.3)
    np.testing.assert_allclose(Mf, np.diag([K, zeta]), atol=1e-9)
    np.testing.assert_allclose(Ms, np.diag([zeta, K]), atol=1e-9)


def test_fme_gradient_equals_finite_differences_of_eq_6_10(rhi4, rng, fmes):
    _, _, Mf, Ms = fmes
    for q in random_q(rhi4, rng, 20):
        for M_des in (Mf, Ms, 0.3 * Mf + 0.7 * Ms):
            g = FMEMatching(M_des, rhi4.torque_max).gradient(rhi4, q)
            g_tr = tr.gradient_fd(lambda p, M_des=M_des: tr.nu_fme(rhi4.jacobian, p, M_des, rhi4.torque_max), q)
            np.testing.assert_allclose(g, g_tr, rtol=1e-6, atol=1e-6 * (1 + np.abs(g_tr).max()))


def test_palpation_tick_equals_eqs_6_2_to_6_6_inside_the_torque_box(rhi4, rng, fmes):
    """One tick of rhi's §6.4 controller (no limit barrier) = τ_m + (I − JᵀJ#ᵀ)(−β∇ν − K_d q̇), to 1e-6 N m.

    β = 0.5 and 2: away from the matched configuration β = 20 puts −β∇ν outside the torque box at
    almost every configuration, where the thesis does not say how the torque is limited (see the
    closed-loop comparison).
    """
    _, _, Mf, Ms = fmes
    x0, u = np.array(X0), np.array(U)
    q_near = rhi4.ik(x0 + np.array([0.0, 0.001]), np.array([0.3, 0.5, 0.4, 0.6]))
    compared = 0
    for k in range(16):
        beta = (0.5, 2.0)[k % 2]
        q = q_near + rng.normal(0.0, 0.05, 4)
        dq = rng.normal(0.0, 0.5, 4)
        ctrl = palpation_controller(rhi4, Mf, limits=False, beta=beta)
        tau = ctrl.step(0.0, q, dq, {"ft": np.zeros(6), "force": np.zeros(2)})
        J = rhi4.jacobian(q)
        tau_m = J.T @ tr.spring_force(rhi4.fk(q), x0, u, 1000.0)
        tau_tr = tr.fme_torque(rhi4.jacobian, rhi4.mass_matrix, q, dq, tau_m, Mf, rhi4.torque_max, beta, K_D)
        if np.any(np.abs(tau_tr) >= rhi4.torque_max):  # outside the box the thesis leaves the handling open
            continue
        compared += 1
        np.testing.assert_allclose(tau, tau_tr, atol=1e-6)
    assert compared >= 8


def _omegas_rhi(V, t, distance):
    state, cfg, out = TransitionState(), TransitionConfig(eps1=EPS1, eps2=EPS2, rho=RHO), []
    for tk, vk in zip(t, V):
        state, om = transition_step(state, tk, vk, distance, cfg)
        out.append(om)
    return np.array(out)


def _omegas_literal(V, t, distance):
    lit = tr.LiteralOmega(EPS1, EPS2, RHO, distance)
    return np.array([lit(tk, vk) for tk, vk in zip(t, V)])


def test_transition_equals_eqs_6_17_to_6_19_when_V_crosses_each_threshold_once(fmes):
    _, _, Mf, Ms = fmes
    d = float(np.linalg.norm(Mf - Ms))
    t = np.arange(0.0, 3.0, 1e-3)
    V = np.where(t < 0.5, 1.0, np.where(t < 1.6, 0.3, np.where(t < 1.8, 0.8, 0.99)))  # drain, hover, refill
    np.testing.assert_allclose(_omegas_rhi(V, t, d), _omegas_literal(V, t, d), atol=1e-12)
    # the transition takes ρ‖M_Free − M_Stiff‖_F = 0.508 s, as §6.4 says ("performed in 0.5 second")
    om = _omegas_rhi(V, t, d)
    assert 0.5 < t[np.flatnonzero(om == 0.0)[0]] - 0.5 <= 0.509


def test_transition_differs_from_the_literal_eq_6_17_when_V_recovers_midway(fmes):
    """The two readings of §6.3.2 part when V falls below ε₁ and comes back to [ε₁, ε₂) during the blend.

    Eq. 6.17 read literally sets Ω = 1 again as soon as V ≥ ε₁ (a jump of the desired FME);
    rhi's hysteresis ("two separate thresholds ... to avoid [chattering]") keeps blending to
    M_Stiff until V ≥ ε₂. The Fig. 6.11 dossier reports both.
    """
    _, _, Mf, Ms = fmes
    d = float(np.linalg.norm(Mf - Ms))
    t = np.arange(0.0, 2.0, 1e-3)
    V = np.where((t >= 0.5) & (t < 0.7), 0.5, 0.85)
    om_rhi, om_lit = _omegas_rhi(V, t, d), _omegas_literal(V, t, d)
    k = np.flatnonzero(t >= 0.7)[0]
    assert om_lit[k] == 1.0 and om_lit[k - 1] < 0.9  # literal: jumps back to M_Free
    assert om_rhi[-1] == 0.0  # hysteresis: completes the blend to M_Stiff
    assert np.max(np.abs(np.diff(om_rhi))) <= np.pi * 1e-3 / (2 * RHO * d) + 1e-12


def test_fme_schedule_tick_uses_the_blended_desired_fme(rhi4, fmes):
    """Ω M_Free + (1 − Ω) M_Stiff (eq. 6.16) reaches the controller's FME term."""
    _, _, Mf, Ms = fmes
    sched = FMESchedule(Mf, Ms, transition=TransitionConfig(eps1=EPS1, eps2=EPS2, rho=RHO))
    q = np.array([0.3, 0.5, 0.4, 0.6])
    for om in (1.0, 0.25, 0.0):
        g = sched.objective(om, rhi4.torque_max).gradient(rhi4, q)
        g_tr = tr.gradient_fd(lambda p, om=om: tr.nu_fme(rhi4.jacobian, p, om * Mf + (1 - om) * Ms,
                                                          rhi4.torque_max), q)
        np.testing.assert_allclose(g, g_tr, rtol=1e-6, atol=1e-6)


# ------------------------------------------------------------------------------ chapter 5
def test_tmi_equals_eqs_4_11_to_4_17(rng):
    rhi5, slave = rhi.device("rhi4", d2=0.1405), rhi.device("rehab_slave")
    for q, qs in zip(random_q(rhi5, rng, 30), random_q(slave, rng, 30)):
        Jm, Js = rhi5.jacobian(q), slave.jacobian(qs)
        assert float(tmi(Jm, Js)) == pytest.approx(tr.tmi(Jm, Js), rel=1e-10)


def test_yoshikawa_gradient_is_eq_5_14(rng):
    """The scenario-2 objective of rhi with plain J (k_q=None, log=False) is −μ of eq. 5.14: ∂ν/∂q = −∂μ/∂q."""
    dev = rhi.device("rhi4", d2=0.1405)
    obj = Manipulability(log=False, k_q=None)
    for q in random_q(dev, rng, 10):
        g_tr = tr.gradient_fd(lambda p: tr.yoshikawa(dev.jacobian(p)), q)
        np.testing.assert_allclose(-np.asarray(obj.gradient(dev, q)), g_tr, rtol=1e-6, atol=1e-9)
        assert -obj.value(dev, q) == pytest.approx(tr.yoshikawa(dev.jacobian(q)), rel=1e-12)


def test_clipped_tick_equals_the_transcription_at_beta_20_in_saturation(rhi4, rng, fmes):
    """With null_space="clipped" rhi's tick is the thesis's law with each joint clipped, saturated or not (1e-6 N m)."""
    _, _, Mf, Ms = fmes
    x0, u = np.array(X0), np.array(U)
    q_near = rhi4.ik(x0 + np.array([0.0, 0.01]), np.array([0.3, 0.5, 0.4, 0.6]))
    saturated = 0
    for _ in range(10):
        q = q_near + rng.normal(0.0, 0.05, 4)
        dq = rng.normal(0.0, 0.5, 4)
        ctrl = palpation_controller(rhi4, Mf, limits=False, null_space="clipped")
        tau = ctrl.step(0.0, q, dq, {"ft": np.zeros(6), "force": np.zeros(2)})
        ref = tr.ThesisPalpation(rhi4, Mf, Ms, lambda t, V: 1.0, x0=x0, u=u, beta=20.0, k_d=K_D)
        tau_tr = ref.step(0.0, q, dq)
        saturated += int(np.any(np.abs(tau_tr) >= rhi4.torque_max - 1e-12))
        np.testing.assert_allclose(tau, tau_tr, atol=1e-6)
        assert ctrl.state.alpha == pytest.approx(ref.state.alpha, abs=1e-12)
    assert saturated >= 5  # the comparison covers the saturated regime


def test_scaled_tick_keeps_the_torque_in_the_null_space_where_the_transcription_clips(rhi4, fmes):
    """The two readings part in saturation: 'scaled' (Algorithm 2) differs from the clipped law."""
    _, _, Mf, Ms = fmes
    x0, u = np.array(X0), np.array(U)
    q = rhi4.ik(x0 + np.array([0.0, 0.01]), np.array([0.3, 0.5, 0.4, 0.6])) + 0.05
    ctrl = palpation_controller(rhi4, Mf, limits=False, null_space="scaled")
    tau = ctrl.step(0.0, q, np.zeros(4), {"ft": np.zeros(6), "force": np.zeros(2)})
    tau_tr = tr.ThesisPalpation(rhi4, Mf, Ms, lambda t, V: 1.0, x0=x0, u=u, beta=20.0, k_d=K_D).step(0.0, q, np.zeros(4))
    assert np.any(np.abs(tau_tr) >= rhi4.torque_max - 1e-12)
    assert np.max(np.abs(tau - tau_tr)) > 0.1


# ------------------------------------------------------------------------------ §5.4.1, Fig. 5.3
def test_tmi_matching_is_eq_5_11_and_the_tick_is_eq_5_9(rng):
    """Scenario 1 (§5.4.1): rhi's ν and tick are eqs. 5.11 and 5.9.

    ν of eq. 5.11 (k_q = None: ᵐM = JJᵀ as printed; k_q = 10: J^q of eq. 4.19) and its gradient equal the
    transcription's (1e-10, FD 1e-6), and one tick of ch. 5's controller is eq. 5.9, τ_m + (I − JᵀJ#ᵀ)(−α∂ν/∂q
    − k_D q̇), each joint clipped at its limit (1e-6 N m, saturated ticks included; τ_m from the same controller
    without objective and damping). Chapter 7's scaling of the null-space torque into the box would fail it.
    """
    import design_transcription as dtr

    from rhi.control import TMIMatching
    from rhi.experiments.ch5.setup import GAIN, NULL_DAMPING, Q_FIXED, SLAVE_SEED, controller, devices

    devs = devices()
    dev, slave = devs["RHI"], devs["slave"]
    compared = clipped = 0
    qs = slave.ik(dev.fk(Q_FIXED), SLAVE_SEED)
    Js = slave.jacobian(qs)
    for k_q, gain in ((None, GAIN), (10.0, GAIN), (None, 20.0 * GAIN)):  # the last one saturates joints
        obj = TMIMatching(slave, qs, k_q=k_q)
        ctrl = controller(dev, obj, gain, NULL_DAMPING)

        def nu(q, k_q=k_q):
            J = dev.jacobian(q)
            if k_q is not None:
                J = J * dtr.penalty(q, dev.q_min, dev.q_max, k_q)[None, :]
            return tr.jbld(Js @ Js.T, J @ J.T)

        for q in [Q_FIXED, *random_q(dev, rng, 12)]:
            assert obj.value(dev, q) == pytest.approx(nu(q), rel=1e-10, abs=1e-12)
            g_tr = tr.gradient_fd(nu, q)
            np.testing.assert_allclose(obj.gradient(dev, q), g_tr, rtol=1e-6, atol=1e-8)
            dq = rng.normal(0.0, 0.3, dev.n)
            sensors = {"ft": np.zeros(6), "force": np.zeros(2)}
            tau = ctrl.step(0.0, q, dq, sensors)
            tau_m = controller(dev, None, 0.0, 0.0).step(0.0, q, dq, sensors)  # the impedance part alone
            if np.any(np.abs(tau_m) >= dev.torque_max - 1e-9):
                continue
            J = dev.jacobian(q)
            P = np.eye(dev.n) - J.T @ tr.jsharp(J, dev.mass_matrix(q)).T
            tau_tr = np.clip(tau_m + P @ (-gain * g_tr - NULL_DAMPING * dq), dev.torque_min, dev.torque_max)
            np.testing.assert_allclose(tau, tau_tr, atol=1e-6)
            compared += 1
            clipped += bool(np.any(np.abs(tau_tr) >= dev.torque_max - 1e-9))
    assert compared >= 24 and clipped >= 3
