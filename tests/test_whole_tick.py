"""The whole tick in one compiled call (`rhi.control._compiled.whole`) equals the reference composition."""

from __future__ import annotations

import numpy as np
import pytest
from numba import typeof, types
from numba.core import compiler, compiler_machinery, typed_passes
from numba.core.registry import cpu_target
from test_control import _tick_cases

import rhi
import rhi.control.controller as controller_module
from rhi.control import (
    ControllerConfig,
    FMEMatching,
    FMESchedule,
    ForceRendering,
    ImpedanceControl,
    JointFriction,
    JointLimitBarrier,
    Manipulability,
    NullSpaceController,
    ObjectiveTerm,
    Passivity,
    SpringPalpation,
    TMIMatching,
    VMEMatching,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.errors import InvalidInput

FRICTION = JointFriction(viscous=0.01, coulomb=0.005)


def _law(kind: str, m: int):
    u = np.zeros(m)
    u[1] = 1.0
    return {
        "render": ForceRendering(damping=0.01, friction=FRICTION),
        "render_handle": ForceRendering(damping=0.02 * np.eye(m), gain=0.7, passivity=Passivity(port="handle")),
        "render_plain": ForceRendering(damping=0.01, passivity=None, gravity=False),
        "spring": SpringPalpation(1000.0, tuple(0.01 * np.ones(m)), normal=tuple(u), damping=0.01),
        "spring_all": SpringPalpation(300.0, tuple(np.zeros(m)), coriolis=False, friction=FRICTION),
        "free": ImpedanceControl(damping=0.5, friction=FRICTION),
    }[kind]


def _objectives(dev, kind: str, free: np.ndarray, stiff: np.ndarray) -> tuple[ObjectiveTerm, ...]:
    """The null-space terms of a set-up: VME matching, plus static FME matching and joint-limit barriers."""
    u = np.zeros(dev.m)
    u[1] = 1.0
    vme = ObjectiveTerm(VMEMatching(tuple(u)), 0.5)
    return {
        "vme": (vme,),
        # beyond.passivity and the ch6 palpation controller: FME matching to M_Stiff, the quadratic barrier
        "static": (ObjectiveTerm(FMEMatching(stiff, dev.torque_max), 20.0), ObjectiveTerm(JointLimitBarrier(0.1), 100.0)),
        # the barriers' sampled-exact form (the discrete gradient along ΔT q̇, issue 25)
        "sampled": (ObjectiveTerm(FMEMatching(stiff, dev.torque_max), 20.0),
                    ObjectiveTerm(JointLimitBarrier(0.1, hold=1e-3), 100.0),
                    ObjectiveTerm(JointLimitBarrier(0.2, 0.5, hold=2e-3), 10.0)),
        # the ch3/ch7 null-space runs: the inverse barrier; two FME terms, one with a scalar torque limit
        "inverse": (vme, ObjectiveTerm(JointLimitBarrier(0.087, 2.0, kind="inverse"), 0.5),
                    ObjectiveTerm(FMEMatching(free, float(dev.torque_max.min())), 5.0),
                    ObjectiveTerm(FMEMatching(stiff, dev.torque_max), 3.0),
                    ObjectiveTerm(JointLimitBarrier(0.2, 0.5), 10.0)),
    }[kind]


def _config(dev, kind: str, saturation: str = "ascm", projector: str = "dynamic", objectives: str = "vme",
            **kw) -> dict:
    u = np.zeros(dev.m)
    u[1] = 1.0
    K, z = fme_shape(dev.jacobian(np.full(dev.n, 0.3)), dev.torque_max)
    free, stiff = desired_fme_free(u, K, z), desired_fme_stiff(u, K, z)
    schedule = () if objectives in ("static", "sampled") else (ObjectiveTerm(FMESchedule(free, stiff), 20.0),)
    return dict(primary=_law(kind, dev.m), objectives=_objectives(dev, objectives, free, stiff) + schedule,
                saturation=saturation, projector=projector, **kw)


def _pair(dev, **kw) -> tuple[NullSpaceController, NullSpaceController]:
    fast = NullSpaceController(dev, ControllerConfig(**kw))
    assert fast._kernel is not None and fast._kernel.whole_ok  # the whole tick runs
    return fast, NullSpaceController(dev, ControllerConfig(**kw, implementation="reference"))


def _compare(fast, ref, dev, cases, t0: float = 0.0, atol: float = 1e-10) -> int:
    """Step both through the cases; equal torques, states and passivity states. Returns how many held a joint."""
    held, scale = 0, 1.0
    for k, (q, dq, F) in enumerate(cases):
        t = t0 + k * 1e-3
        a = fast.step(t, q, dq, {"force": F})
        b = ref.step(t, q, dq, {"force": F})
        np.testing.assert_allclose(a, b, rtol=0, atol=atol, err_msg=f"tick {k}")
        sf, sr = fast.state, ref.state
        for attr in ("V", "omega", "alpha", "beta", "clipped"):
            assert getattr(sf, attr) == pytest.approx(getattr(sr, attr), abs=atol), (k, attr)
        # α_pc = (w₀ − E_obs) / (ΔT q̇ᵀMq̇) [1/s]: an energy difference over a small kinetic energy
        assert sf.alpha_pc == pytest.approx(sr.alpha_pc, rel=1e-9, abs=1e-10, nan_ok=True), k
        # the observed energy is a running sum: its rounding is relative to the largest it has been
        # (random jumps between configurations give hundreds of J)
        scale = max(scale, abs(sr.E_obs) if np.isfinite(sr.E_obs) else 0.0)
        assert sf.E_obs == pytest.approx(sr.E_obs, abs=1e-12 * scale, nan_ok=True), k
        np.testing.assert_array_equal(sf.saturated, sr.saturated)
        tf, tr = sf.transition, sr.transition
        assert (tf.stiff, tf.omega_start, tf.t0, tf.tf) == pytest.approx((tr.stiff, tr.omega_start, tr.t0, tr.tf)), k
        if fast.passivity is not None:
            pf, pr = fast.passivity, ref.passivity
            assert (pf.energy, pf.dissipated) == pytest.approx((pr.energy, pr.dissipated), rel=1e-12, abs=1e-12 * scale)
            assert (pf.scale, pf.t) == pytest.approx((pr.scale, pr.t), abs=atol)
            np.testing.assert_allclose(pf.effort, pr.effort, rtol=0, atol=atol)
        held += bool(sf.saturated.any())
    assert not fast.state.stopped and not ref.state.stopped
    return held


@pytest.mark.parametrize(
    "name,kind,saturation,projector,objectives",
    [("rhi4", "render", "ascm", "dynamic", "vme"), ("rhi4", "render_handle", "ascm", "pseudoinverse", "vme"),
     ("rhi4", "render_plain", "scaling", "dynamic", "vme"), ("rhi4", "render", "none", "dynamic", "vme"),
     ("rhi4", "render", "active_set", "dynamic", "vme"), ("rhi4", "spring", "ascm", "dynamic", "vme"),
     ("planar3r", "spring_all", "ascm", "dynamic", "vme"), ("rhi4", "free", "ascm", "dynamic", "vme"),
     ("gen3", "render", "ascm", "dynamic", "vme"), ("rhi4", "render", "ascm", "dynamic", "static"),
     ("rhi4", "render", "ascm", "dynamic", "sampled"),
     ("rhi4", "spring", "scaling", "dynamic", "static"), ("rhi4", "free", "ascm", "pseudoinverse", "inverse"),
     ("planar3r", "render", "ascm", "dynamic", "inverse"), ("gen3", "render", "ascm", "dynamic", "inverse")],
)
def test_whole_tick_equals_reference(name, kind, saturation, projector, objectives, rng):
    """Terms, primary law, allocation, objectives and the passivity layer in one call = the reference, to 1e-10."""
    dev = rhi.device(name)
    fast, ref = _pair(dev, **_config(dev, kind, saturation, projector, objectives))
    cases = [(q, dq, F * (10.0 if dev.m == 3 else 1.0)) for q, dq, F in _tick_cases(dev, rng, 150)]
    if objectives != "vme":  # half of the ticks near the joint limits, where the barriers act
        span = dev.q_max - dev.q_min
        edge = np.where(np.isfinite(span), np.where(np.arange(dev.n) % 2, dev.q_max, dev.q_min), 0.3)
        cases = [(np.where(k % 2, q, edge + 0.02 * rng.normal(size=dev.n)), dq, F) for k, (q, dq, F) in enumerate(cases)]
    if objectives == "inverse":  # inside the limits: past one, the inverse barrier's ~1e10 gradient makes β ill-posed
        inside = JointLimitBarrier(1.0)
        cases = [(np.clip(q, dev.q_min + 0.01, dev.q_max - 0.01), dq, F) for q, dq, F in cases]
        cases = [c for c in cases if inside.distances(dev, c[0]).min() > 0.005]
        assert len(cases) > 50
    if objectives != "vme":  # the barriers act on a good share of the ticks
        bar = fast.barriers[0][1]
        assert sum(bool(bar.gradient(dev, q).any()) for q, _, _ in cases) > len(cases) // 5
    held = _compare(fast, ref, dev, cases)
    if saturation in ("ascm", "scaling") and name == "rhi4" and kind.startswith("render"):
        assert held > len(cases) // 5  # saturation exercised


@pytest.mark.parametrize("saturation,objectives", [("scaling", "static"), ("ascm", "vme"), ("none", "static")])
def test_clipped_null_space_runs_compiled_and_equals_reference(rhi4, saturation, objectives, rng):
    """``null_space="clipped"`` (chapter 6's law as written) runs the compiled tick and equals the reference to 1e-10.

    The null-space torque pushes joints past their limits on a good share of the ticks (then clipped).
    """
    kw = _config(rhi4, "spring", saturation, "dynamic", objectives, null_space="clipped")
    fast, ref = _pair(rhi4, **kw)
    cases = _tick_cases(rhi4, rng, 150)
    _compare(fast, ref, rhi4, cases)
    scaled = NullSpaceController(rhi4, ControllerConfig(**{**kw, "null_space": "scaled"}))
    differ = sum(not np.allclose(fast.step(k * 1e-3, q, dq, {"force": F}), scaled.step(k * 1e-3, q, dq, {"force": F}))
                 for k, (q, dq, F) in enumerate(cases))
    assert differ > len(cases) // 10  # the two readings differ where the box binds


def test_whole_tick_along_a_path_with_reset_and_fallback(rhi4, monkeypatch):
    """A continuous path (the passivity layer damping), a reset halfway, and the reference fallback all agree.

    Against the same kernels composed in Python (`KernelTick.__call__`, then the passivity layer's own call)
    to 1e-12; against the reference to 1e-9 (the observed energy carries rounding along a path).
    """
    fallbacks = []
    reference_tick = controller_module.reference_tick

    def counting(ctrl, t, kin, sensors, forces=None, parts=None):
        if forces is not None and ctrl._kernel.whole_ok:
            fallbacks.append(t)
        return reference_tick(ctrl, t, kin, sensors, forces, parts)

    monkeypatch.setattr(controller_module, "reference_tick", counting)
    cfg = _config(rhi4, "render")
    fast, ref = _pair(rhi4, **cfg)
    composed = NullSpaceController(rhi4, ControllerConfig(**cfg))
    composed._kernel.whole_ok = False
    q0 = np.array([0.3, 0.5, 0.2, 0.4])
    cases = [(q0 + 0.05 * np.sin(0.01 * k + np.arange(4)), 0.3 * np.cos(0.02 * k + np.arange(4)),
              np.array([0.0, -14.0 * np.sin(0.005 * k) ** 2])) for k in range(600)]

    def both(part, t0):
        _compare(fast, composed, rhi4, part, t0, atol=1e-12)
        for c in (fast, composed):  # replay for the reference, whose comparison is looser
            c.reset()
        _compare(fast, ref, rhi4, part, t0, atol=1e-9)

    both(cases[:300], 0.0)
    assert fast.passivity.dissipated > 0.0  # the PC acted
    for c in (fast, ref, composed):
        c.reset()
    both(cases[300:], 0.3)
    # the kernel's FALLBACK hands the tick to the reference on the terms it computed
    from rhi.control._compiled import whole

    kernel = fast._kernel._whole_fn

    def undecided(*args):  # the kernel's work done, then FALLBACK, as for an undecidable held set
        kernel(*args)
        return whole.FALLBACK

    monkeypatch.setattr(fast._kernel, "_whole_fn", undecided)
    for c in (fast, ref):
        c.reset()
    _compare(fast, ref, rhi4, cases[:20], atol=1e-9)
    assert len(fallbacks) == 20


@pytest.mark.parametrize("saturation,null_space", [("none", "clipped"), ("ascm", "scaled")])
def test_whole_tick_computes_the_jacobian_objectives(rhi4, saturation, null_space, rng):
    """Chapter 5's Jacobian objectives in the whole tick = the reference (their `gradient_at` in Python), to 1e-10.

    TMI matching to a slave ME that moves every tick or to a fixed one, −log μ and −μ, with and without the joint-limit
    penalty.
    """
    slave = rhi.device("rehab_slave")
    qs = np.array([0.4, 1.2])
    for objectives in ((ObjectiveTerm(TMIMatching(slave, lambda: qs, k_q=10.0), 0.02),
                        ObjectiveTerm(Manipulability(log=True, k_q=10.0), 0.05)),
                       (ObjectiveTerm(TMIMatching(slave, lambda: qs), 0.02), ObjectiveTerm(Manipulability(), 0.3),
                        ObjectiveTerm(Manipulability(k_q=3.0), 0.1)),
                       (ObjectiveTerm(TMIMatching(slave, [0.7, 0.9], k_q=10.0), 0.02),)):  # a fixed slave: ˢM held
        kw = dict(primary=ImpedanceControl(damping=0.5), objectives=objectives, saturation=saturation,
                  null_space=null_space)
        fast, ref = _pair(rhi4, **kw)
        assert len(fast._kernel.live) == len(objectives)
        for k, (q, dq, F) in enumerate(_tick_cases(rhi4, rng, 60)):
            qs[:] = [0.4 + 0.3 * np.sin(0.2 * k), 1.2 + 0.2 * np.cos(0.3 * k)]
            q = np.clip(q, rhi4.q_min + 0.05, rhi4.q_max - 0.05)
            a, b = fast.step(k * 1e-3, q, dq, {"force": F}), ref.step(k * 1e-3, q, dq, {"force": F})
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-10, err_msg=f"tick {k}")
            assert fast.state.beta == pytest.approx(ref.state.beta, abs=1e-10)


def test_whole_tick_only_where_it_applies(rhi4):
    """Objectives computed in Python, or a law with a desired inertia, keep the composed tick."""
    cfg = _config(rhi4, "render")
    cfg["objectives"] = (ObjectiveTerm(TMIMatching(rhi.device("rehab_slave"), [0.4, 1.2], H=np.eye(2)), 0.05),)
    assert not NullSpaceController(rhi4, ControllerConfig(**cfg))._kernel.whole_ok
    cfg = _config(rhi4, "render")
    cfg["primary"] = ImpedanceControl(damping=0.5, inertia=np.diag([0.2, 0.3]))
    assert not NullSpaceController(rhi4, ControllerConfig(**cfg))._kernel.whole_ok


def test_whole_tick_bad_force(rhi4):
    fast = NullSpaceController(rhi4, ControllerConfig(**_config(rhi4, "render")))
    with pytest.raises(InvalidInput, match=r"sensors\['force'\]"):
        fast.step(0.0, np.array([0.3, 0.5, 0.2, 0.4]), np.zeros(4), {"force": np.zeros(3)})


def test_whole_tick_reuses_the_loops_terms(monkeypatch):
    """A loop that read `Device.terms(q, dq)` first (the runtime's handle speed, a virtual wall) is not computed twice."""
    from rhi.control._compiled import whole

    whole_for, ready = whole.whole_for, []

    def recording(parts):
        kernel = whole_for(parts)
        return lambda *args: ready.append(args[15]) or kernel(*args)  # `ready`, after (t, q, dq, force) and the chain

    monkeypatch.setattr(whole, "whole_for", recording)
    devs = rhi.device("rhi4"), rhi.device("rhi4")
    a, b = (NullSpaceController(d, ControllerConfig(**_config(d, "render"))) for d in devs)
    q0 = np.array([0.3, 0.5, 0.2, 0.4])
    for k in range(50):
        q, dq, F = q0 + 0.01 * np.sin(0.1 * k + np.arange(4)), 0.2 * np.cos(0.1 * k + np.arange(4)), np.array([0, -3.0])
        devs[0].terms(q, dq)
        np.testing.assert_array_equal(a.step(k * 1e-3, q, dq, {"force": F}), b.step(k * 1e-3, q, dq, {"force": F}))
    assert ready[0::2] == [True] * 50 and ready[1::2] == [False] * 50


def test_whole_tick_runs_the_experiments_controllers(rhi4, monkeypatch):
    """The §6.4 palpation controllers (static FME matching + the limit barrier) and beyond.passivity's run in one call."""
    from rhi.control._compiled import whole
    from rhi.experiments.beyond import passivity
    from rhi.experiments.ch6 import setup as ch6

    whole_for, calls = whole.whole_for, []

    def counting(parts):
        kernel = whole_for(parts)
        return lambda *args: calls.append(args[0]) or kernel(*args)

    monkeypatch.setattr(whole, "whole_for", counting)
    _, _, Mf, Ms = ch6.desired_fmes(rhi4, np.array(ch6.U), ch6.Q_HOME)
    schedule = FMESchedule(Mf, Ms)
    q = np.array([0.3, 0.5, 0.2, 0.4])
    for k, ctrl in enumerate((ch6.palpation_controller(rhi4, Ms), ch6.palpation_controller(rhi4, None, schedule),
                              passivity.controller(rhi4, objectives=True, port="motors"))):
        assert ctrl.barriers and ctrl._kernel.whole_ok
        ctrl.step(float(k), q, np.zeros(4), {"force": np.zeros(2)})
    assert calls == [0.0, 1.0, 2.0]


def test_whole_tick_decides_an_ill_conditioned_full_held_set(rhi4, rng, monkeypatch):
    """beyond.passivity's palpation holds joints 1 and 3 (n − m of them) with σ_min(Z_S) < 0.01: decided in the kernel.

    The projector form squares that condition number; the kernel decides the square Z_S from a basis of P
    instead of handing the tick to the reference, and equals it to 1e-10.
    """
    from rhi.control import WeightedSum
    from rhi.control.saturation import null_basis
    from rhi.experiments.beyond import passivity
    from rhi.experiments.ch6 import setup as ch6

    fallbacks = []
    reference_tick = controller_module.reference_tick

    def counting(ctrl, t, kin, sensors, forces=None, parts=None):
        if forces is not None:
            fallbacks.append(t)
        return reference_tick(ctrl, t, kin, sensors, forces, parts)

    monkeypatch.setattr(controller_module, "reference_tick", counting)
    _, _, _, Ms = ch6.desired_fmes(rhi4, np.array(ch6.U), ch6.Q_HOME)
    q0 = ch6.best_match(rhi4, np.array(ch6.X0), WeightedSum(ch6.controller_terms(Ms, rhi4.torque_max)), starts=1)
    fast = passivity.controller(rhi4, objectives=True, port=None)
    ref = NullSpaceController(rhi4, ControllerConfig(**{**fast.config.__dict__, "implementation": "reference"}))
    cases = [(q0 + 0.02 * rng.normal(size=4), 0.2 * rng.normal(size=4), np.array([rng.normal(), -rng.uniform(0, 60)]))
             for _ in range(100)]
    _compare(fast, ref, rhi4, cases)
    ill = 0
    for q, dq, F in cases:
        fast.step(0.0, q, dq, {"force": F})
        S = fast.state.saturated
        kin = rhi4.terms(q, dq)
        ill += S.sum() == 2 and np.linalg.svd(null_basis(kin.J, kin.M)[S], compute_uv=False)[-1] < 0.01
    assert ill > 50 and not fallbacks


def test_whole_tick_compiles_only_the_parts_its_controller_has(rhi4):
    """An ASCM tick with an FME schedule and VME matching types no active set, tank, passivity layer or objectives."""
    from rhi.control import _compiled as kernels
    from rhi.control._compiled import whole

    cfg = _config(rhi4, "render")
    cfg["primary"] = ForceRendering(damping=0.01, passivity=None)
    k = NullSpaceController(rhi4, ControllerConfig(**cfg))._kernel
    assert k.parts == whole.Parts(code=kernels.ASCM, scheduled=True, vme=True, safe=True, clipped_null=False, tank=False,
                                  objectives=False, passivity=False)
    q = np.array([0.3, 0.5, 0.2, 0.4])
    args = (0.0, q, np.zeros(4), np.zeros(2), *k._chain, False, *k._mid, k._x, k._buf, *k._out)

    assert k._whole_fn(*args) == whole.OK
    called = _typed_callees(k._whole_fn, args)
    assert {"fme_gradient", "vme_gradient", "tertiary_to", "held_torque"} <= called
    assert not called & {"active_set", "active_set_start", "allocate_scaling", "blend", "direction", "objectives",
                         "apply", "ascm_into", "chain_terms"}  # the last two by address (`ascm_ref`, `terms_ref`)



@compiler_machinery.register_pass(mutates_CFG=False, analysis_only=True)
class _Typemap(compiler_machinery.AnalysisPass):
    """The last pass of `_TypingOnly`: ends the compilation with the typemap."""

    _name = "rhi_test_typemap"

    def __init__(self):
        compiler_machinery.AnalysisPass.__init__(self)

    def run_pass(self, state):
        raise compiler._EarlyPipelineCompletion(state.typemap)


class _TypingOnly(compiler.CompilerBase):
    """Numba's untyped passes (inlining, pruning the branches of constant flags) and its type inference; no lowering."""

    def define_pipelines(self):
        pm = compiler_machinery.PassManager("typing only")
        for cls, what in compiler.DefaultPassBuilder.define_untyped_pipeline(self.state).passes:
            pm.add_pass(cls, what)
        pm.add_pass(typed_passes.NopythonTypeInference, "nopython frontend")
        pm.add_pass(_Typemap, "the typemap")
        pm.finalize()
        return [pm]


def _typed_callees(kernel, args) -> set[str]:
    """The compiled functions Numba's type inference of `kernel` for `args` types (its typemap's dispatchers' names).

    Typed here (a kernel loaded from the cache has no typemap), stopped before lowering and machine code: the typemap a
    full compile keeps, in half its time.
    """
    flags = compiler.Flags()
    flags.nrt, flags.error_model = True, "numpy"
    typemap = compiler.compile_extra(cpu_target.typing_context, cpu_target.target_context, kernel.py_func,
                                     tuple(typeof(a) for a in args), None, flags, {}, pipeline_class=_TypingOnly)
    return {t.dispatcher.py_func.__name__ for t in typemap.values() if isinstance(t, types.Dispatcher)}
