"""rhi.runtime.step: the compiled step of a `run` tick equals the Python reference, faults and all.

Both steps see the same readings (views of one float array, as `UDPLink`'s) with a fault injected at one
tick; every tick's torque, ẋ and virtual force, the safety events with their reasons, the latched fault, the
clamp count and ratio, the controller's state and the safety layer's state afterwards must be equal. Mutations
of the compiled path must be caught by the same comparison.
"""

from __future__ import annotations

import dataclasses
import math
import types

import numpy as np
import pytest

import rhi
from rhi.control import (
    ControllerConfig,
    FMESchedule,
    ForceRendering,
    NullSpaceController,
    ObjectiveTerm,
    VMEMatching,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.runtime import Reading, Safety, SafetyConfig, run
from rhi.runtime.link import Status
from rhi.runtime.step import FastStep, ReferenceStep, make_step
from rhi.sim import Wall
from rhi.sim.loop import Kinematics

Q0 = np.array([-0.63, 0.25, 0.28, 0.09])
N = 70
FAULT_AT = 30
ENABLED = int(Status.ENABLED)


@pytest.fixture(scope="module")
def dev():
    return rhi.device("rhi4")


def _controller(dev):
    K, z = fme_shape(dev.jacobian(np.zeros(dev.n)), dev.torque_max, 5.0)
    return NullSpaceController(dev, ControllerConfig(
        ForceRendering(damping=0.01),
        objectives=(ObjectiveTerm(VMEMatching((0.0, 1.0), 0.01), 0.5),
                    ObjectiveTerm(FMESchedule(desired_fme_free([0, 1], K, z), desired_fme_stiff([0, 1], K, z)), 20.0)),
        damping=0.1, saturation="ascm"))


def _wall(dev):
    return Wall(dev.fk(Q0) + [0.0, 0.002], [0, 1], 1000.0)


class _Packed:
    """A link's readings layout: q, q̇, then a 6-value F/T in one array (`FastStep.attach`)."""

    def __init__(self, n: int) -> None:
        self.packed = {"ft": slice(2 * n, 2 * n + 6)}


def _readings(fault: str) -> list[tuple[Reading, float | None]]:
    """(reading, the host's time of the check) per tick: a hand moving the handle into the wall, the fault at FAULT_AT."""
    out = []
    seq, t, arrival = 0, 0.0, 100.0
    q_frozen = None
    for k in range(N):
        s = 1e-3 * k
        q = Q0 + 0.02 * np.sin([3.0 * s, 2.0 * s + 0.3, 4.0 * s, 1.5 * s]) + [0.0, 0.004 * k / N, 0.0, 0.0]
        dq = 0.02 * np.array([3.0, 2.0, 4.0, 1.5]) * np.cos([3.0 * s, 2.0 * s + 0.3, 4.0 * s, 1.5 * s])
        ft = np.array([0.1 * math.sin(7 * s), 0.2 + 0.05 * k, 0.0, 0.0, 0.0, 0.01])
        status, age, now_gap = ENABLED, 2e-4, 1e-4
        bad = k == FAULT_AT
        seq, t, arrival = seq + 1, t + 1e-3, arrival + 1e-3
        if fault == "nan" and bad:
            q[2] = math.nan
        elif fault == "ft_nan" and bad:
            ft[1] = math.inf
        elif fault == "status" and bad:
            status |= int(Status.WATCHDOG)
        elif fault == "stale" and FAULT_AT <= k < FAULT_AT + 4:
            seq, t, arrival = seq - 1, t - 1e-3, arrival - 1e-3
        elif fault == "order" and bad:
            seq -= 5
        elif fault == "clock" and bad:
            t -= 1e-3
        elif fault == "silence" and bad:
            arrival += 0.03
        elif fault == "silence_now" and bad:
            now_gap = 0.025
        elif fault == "latency" and bad:
            age = 0.05
        elif fault == "speed" and bad:
            dq[1] = 25.0
        elif fault == "range" and bad:
            q[0] = 5.0
        elif fault == "handle_speed" and bad:
            dq[:] = [15.0, 15.0, 0.0, 0.0]
        elif fault in ("frozen", "ft_frozen") and k >= 5:
            if fault == "frozen":
                q_frozen = (q.copy(), dq.copy() + 0.5) if q_frozen is None else q_frozen
                q, dq = q_frozen[0].copy(), q_frozen[1].copy()
            else:
                ft[:] = [0.3, 0.4, 0.0, 0.0, 0.0, 0.02]
        v = np.concatenate([q, dq, ft])
        n = len(q)
        r = Reading(t, seq, v[:n], v[n:2 * n], {"ft": v[2 * n:]}, status, seq - 1, "", arrival, age)
        out.append((r, arrival + now_gap))
    return out


def _compare(dev, fault: str, mutate=None, *, limits: float = 1.0, estop_at: int = -1, reset_at: int = -1) -> list[str]:
    """The differences between the reference and the compiled step over `_readings(fault)` ([] where none)."""
    cfg = SafetyConfig(range_margin=0.3)
    limited = types.SimpleNamespace(**{f: getattr(dev, f) for f in ("n", "q_min", "q_max")},
                                    torque_min=limits * dev.torque_min, torque_max=limits * dev.torque_max)
    runs = []
    for fast in (False, True):
        ctrl, guard = _controller(dev), Safety(limited, cfg)
        kin = Kinematics(dev, _wall(dev))
        step = make_step(guard, kin, ctrl) if fast else ReferenceStep(guard, kin, ctrl)
        assert type(step) is (FastStep if fast else ReferenceStep), step.route
        step.attach(_Packed(dev.n))
        if fast and mutate is not None:
            mutate(step)
        ticks = []
        for k, (r, now) in enumerate(_readings(fault)):
            if k == estop_at:
                guard.estop("test")
            if k == reset_at:
                guard.reset()
            tau, xdot, F = step(r, now)
            s = ctrl.state
            ticks.append((tau.tolist(), None if xdot is None else xdot.tolist(), F.tolist(), guard.drain(), guard.fault,
                          guard.fault_kind, guard.clamped, guard.ratio, guard.last_t, s.V, s.omega, s.alpha, s.beta,
                          s.ticks, s.t, s.clipped, None if s.saturated is None else s.saturated.tolist(),
                          dataclasses.astuple(s.transition), s.tau.tolist()))
        step.close()
        ticks.append(tuple(repr(getattr(guard, a)) for a in (
            "_last_seq", "_same", "_last_new", "_last_t", "_joints", "_joints_same", "_joints_t0", "_ft", "_ft_same",
            "_ft_q0")))
        runs.append(ticks)
    ref, fast = runs
    return [f"tick {k}: {a} != {b}" for k, (a, b) in enumerate(zip(ref, fast)) if repr(a) != repr(b)]


FAULTS = ("none", "nan", "ft_nan", "status", "stale", "order", "clock", "silence", "silence_now", "latency", "speed",
          "range", "handle_speed", "frozen", "ft_frozen")


@pytest.mark.parametrize("fault", FAULTS)
def test_compiled_step_equals_the_reference(dev, fault):
    assert _compare(dev, fault) == []


def test_the_faults_happen_and_the_compiled_step_runs_the_clean_ticks(dev, monkeypatch):
    """The comparison is not vacuous: each fault trips its own rule, and the ticks before it are the kernel's."""
    python = []
    reference = ReferenceStep.__call__
    monkeypatch.setattr(ReferenceStep, "__call__", lambda self, r, now: (python.append(r.seq), reference(self, r, now))[1])
    kinds = {}
    for fault in FAULTS[1:]:
        guard, ctrl = Safety(dev, SafetyConfig(range_margin=0.3)), _controller(dev)
        step = make_step(guard, Kinematics(dev, _wall(dev)), ctrl)
        step.attach(_Packed(dev.n))
        python.clear()
        for k, (r, now) in enumerate(_readings(fault)):
            step(r, now)
            if guard.fault is None:
                assert not python, (fault, k)  # no reference tick before the fault
        kinds[fault] = guard.fault_kind
        assert ctrl.state.ticks >= (FAULT_AT if fault not in ("frozen", "ft_frozen") else 50), fault
    assert kinds == {"nan": "nan", "ft_nan": "nan", "status": "device", "stale": "stale", "order": "order",
                     "clock": "clock", "silence": "silence", "silence_now": "silence", "latency": "latency",
                     "speed": "speed", "range": "range", "handle_speed": "handle_speed", "frozen": "frozen",
                     "ft_frozen": "frozen"}


def test_clamps_estop_and_reset_equal_the_reference(dev):
    # torque limits of the safety layer below the controller's: clamped ticks (the reference's filter)
    assert _compare(dev, "none", limits=0.02) == []
    assert _compare(dev, "none", estop_at=20) == []
    assert _compare(dev, "stale", reset_at=40) == []  # a fault, then the operator's reset mid-run
    assert _compare(dev, "none", reset_at=40) == []  # a reset while the kernel holds the safety state


def _stale_limit(step):
    step._lim[0] += 1  # L_STALE


def _forget_frozen(step):
    release = step._release

    def broken():
        own = step._own
        release()
        if own:
            step.guard._joints_same = 0
    step._release = broken
    step.close = broken


def _wide_box(step):
    step._lim[8 + 3 * step.guard.n:] *= 100.0  # the filter's torque box (after N_L and q_lo, q_hi, max |q̇|)


def _ignore_status(step):
    step._lim[7] = 0  # L_BAD: the status flags ignored


@pytest.mark.parametrize(("mutate", "fault", "limits"), [(_stale_limit, "stale", 1.0), (_forget_frozen, "frozen", 1.0),
                                                        (_wide_box, "none", 0.02), (_ignore_status, "status", 1.0)])
def test_a_broken_compiled_step_is_caught(dev, mutate, fault, limits):
    assert _compare(dev, fault, mutate, limits=limits)


class _ScriptLink:
    """Scripted readings as `run` reads them (`packed` or not), commands recorded."""

    def __init__(self, readings, n: int, packed: bool) -> None:
        self.readings, self.n, self.k, self.sent = readings, n, 0, []
        if packed:
            self.packed = _Packed(n).packed

    def open(self) -> None:
        self.k = 0

    def read(self) -> Reading:
        self.k += 1
        return self.readings[min(self.k, len(self.readings)) - 1]

    def write(self, tau, *, enable: bool) -> None:
        self.sent.append((np.array(tau, dtype=float).tolist(), enable))

    def close(self) -> None:
        pass


@pytest.mark.parametrize("fault", ["none", "speed", "stale"])
def test_run_logs_equal_on_both_steps(dev, fault):
    readings = [dataclasses.replace(r, arrival=None, age=math.nan) for r, _ in _readings(fault)]
    out = []
    for packed in (False, True):
        link = _ScriptLink(readings, dev.n, packed)
        res = run(link, _controller(dev), rate=1000.0, duration=N * 1e-3, safety=SafetyConfig(range_margin=0.3),
                  virtual=_wall(dev), realtime=False)
        assert res.summary["step"] == ("compiled" if packed else
                                       "python: the link's readings are not views of one float array (`packed`) with "
                                       "a 6-value F/T and the controller's sensors")
        cols = {c: v.tolist() for c, v in res.log.columns().items()
                if c not in ("t_tick", "t_read", "t_step", "t_write", "wall", "late")}
        out.append((cols, res.summary["events"], res.fault, link.sent))
    assert repr(out[0]) == repr(out[1])
    assert (out[0][2] is None) == (fault == "none")
