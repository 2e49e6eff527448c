"""§A.4.3, Fig. A.8: the box push on the WMM's MuJoCo plant (`rhi.sim.box_push`, `rhi.experiments.appa.push`).

The plant's torques are checked against the statics of its own contact force (τ = J_mᵀ F, gravity compensated),
the contact force against Coulomb's law while the box slides, and Fig. A.8's claim numbers are recomputed here
from the run's torque arrays, in plain NumPy, before the headline judges them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from rhi.devices.model import device
from rhi.errors import InvalidInput
from rhi.experiments.appa import push
from rhi.report import headline, rules
from rhi.report.claims import CLAIMS
from rhi.report.steps import STEPS
from rhi.sim.box_push import Box, BoxPushPlant, push_trajectory

#: the --quick settings of `rhi reproduce` (rhi.report.steps), but the choice of runs
QUICK: dict[str, Any] = {k: v for s in STEPS if s.name == "appa.box_push" for k, v in s.quick.items()
                         if k not in ("alternatives", "frictions")}


def _first_saturation(t, tau, start):
    """(joint 1–7, time) of the first sample from `start` on where a joint reaches 99.9 % of 32/13 N m; NaNs if none."""
    lim = np.array([32.0] * 4 + [13.0] * 3)
    for k in range(t.size):
        if t[k] < start - 1e-9:
            continue
        over = [i for i in range(7) if abs(tau[k, i]) >= 0.999 * lim[i]]
        if over:
            return over[0] + 1, t[k]
    return math.nan, math.nan


def test_quick_box_push_rows_and_claims_follow_from_its_torques():
    assert set(QUICK) == {"t_cartesian", "t_null", "distance", "duration", "hold", "settle"}
    r = push.box_push(**QUICK, alternatives=False, frictions=())
    rows = {row.quantity: row for t in r.tables for row in t.rows}
    a = r.arrays
    start = QUICK["t_cartesian"] + QUICK["t_null"]
    for case, label in (("without", push.CASES["without"][3]), ("with", push.CASES["with"][3])):
        t, tau = a[f"{case}_t"], a[f"{case}_tau"]
        assert tau.shape == (t.size, 7) and a[f"{case}_box"].shape == (t.size, 3)
        assert t[0] == pytest.approx(start - QUICK["settle"])
        assert t[-1] == pytest.approx(start + QUICK["duration"] + QUICK["hold"])
        on = t >= start - 1e-9
        joint, when = _first_saturation(t, tau, start)
        got = rows[f"{label}: first arm joint to saturate"].ours
        assert (math.isnan(joint) and math.isnan(got)) or got == joint
        assert rows[f"{label}: largest arm joint torque during the push"].ours == pytest.approx(np.abs(tau[on]).max())
        assert rows[f"{label}: largest |τ_4| during the push"].ours == pytest.approx(np.abs(tau[on, 3]).max())
        w = np.sqrt(np.sum((tau[on] * [1, 1, 1, 1, 2.5, 2.5, 2.5]) ** 2, axis=1)).max()
        assert rows[f"{label}: largest ‖W_τ τ‖ during the push"].ours == pytest.approx(w)
        assert np.abs(tau).max() <= 32.0 + 1e-6  # one torque limit per joint
        assert np.all(np.abs(tau[:, 4:]) <= 13.0 + 1e-6)
    # the headline's two Fig. A.8 claims read these rows: their numbers and verdicts recomputed
    verdicts = {v.claim.key: v for v in headline.evaluate(CLAIMS, [r])}
    j4 = verdicts["figA_8.joint4_first"]
    joint, _ = _first_saturation(a["without_t"], a["without_tau"], start)
    assert j4.ours == float(joint == 4)
    within = verdicts["figA_8.within_20"]
    on = a["with_t"] >= start - 1e-9
    assert within.ours == float(np.abs(a["with_tau"][on]).max() <= 20.0)
    for v in (j4, within):
        assert v.verdict == (rules.REPRODUCED if v.ours == 1.0 else rules.NOT_REPRODUCED)
        assert "{" not in v.reason and any(ch.isdigit() for ch in v.reason)


def test_plant_torques_are_the_statics_of_the_contact_force_and_the_box_slides_by_coulomb():
    """τ = J_m(q)ᵀ F (the arm's gravity compensated: what a torque sensor minus gravity reads) and F = μ m g sliding.

    μ = 0.2 keeps the arm within its limits, so the box slides through the push.
    """
    mu = 0.2
    out = push.push_case("without", mu, dt=0.01, **QUICK)
    dev = device("wmm")
    t, tau, F, box = out["t"], out["tau"], out["force"], out["box"]
    steady = np.r_[False, (np.abs(np.diff(F[:, 0]))[:-1] < 1.0) & (np.abs(np.diff(F[:, 0]))[1:] < 1.0), False]
    loaded = np.flatnonzero((F[:, 0] > 20.0) & steady)  # quasi-static samples: no contact impact, no stick-slip
    assert loaded.size > 50
    for k in loaded[::5]:
        statics = dev.jacobian(out["q"][k])[:, 3:].T @ F[k]
        assert np.allclose(tau[k], statics, atol=0.02 * np.abs(statics).max() + 0.1), (t[k], tau[k], statics)
    v = np.gradient(box[:, 0], t)
    sliding = np.flatnonzero(v > 0.005)
    assert sliding.size > 30 and box[-1, 0] - box[0, 0] > 0.03
    mg = 26.0 * 9.81
    assert np.median(F[sliding, 0]) == pytest.approx(mu * mg, rel=0.05)
    assert np.abs(F[:, 1:]).max() < 0.02 * mu * mg  # frictionless tip: the push is normal to the face


def test_push_trajectory_is_a_hold_then_a_minimum_jerk_push():
    x0 = np.array([0.65, -0.0246, 0.456])
    tr = push_trajectory(x0, 0.2, start=1.0, duration=4.0, hold=0.5, dt=0.01)
    assert tr.t[-1] == pytest.approx(5.5)
    assert np.allclose(tr.x[tr.t <= 1.0], x0) and np.allclose(tr.x[-1], x0 + [0.2, 0, 0])
    assert np.allclose(tr.x[:, 1:], x0[1:]) and np.all(np.diff(tr.x[:, 0]) >= 0)
    mid = int(np.argmin(np.abs(tr.t - 3.0)))
    assert tr.dx[mid, 0] == pytest.approx(1.875 * 0.2 / 4.0)  # the minimum-jerk peak speed
    assert np.allclose(np.cumsum(tr.dx[:, 0]) * 0.01, tr.x[:, 0] - x0[0], atol=2e-3)


def test_box_push_bad_input_raises():
    for kw, name in (({"friction": -0.1}, "box.friction"), ({"mass": math.nan}, "box.mass"),
                     ({"depth": 0.0}, "box.depth"), ({"tip_radius": True}, "box.tip_radius")):
        with pytest.raises(InvalidInput, match=name):
            Box(**kw)
    x0 = np.zeros(3)
    for kw, name in (({"distance": 0.0}, "distance"), ({"start": -1.0}, "start"), ({"hold": math.inf}, "hold"),
                     ({"dt": -0.01}, "dt")):
        args = {"distance": 0.1, "start": 0.0, "duration": 1.0, "hold": 0.0, "dt": 0.01, **kw}
        with pytest.raises(InvalidInput, match=name):
            push_trajectory(x0, args.pop("distance"), **args)
    with pytest.raises(InvalidInput, match="x0"):
        push_trajectory([0.0, 1.0], 0.1, start=0.0, duration=1.0, hold=0.0, dt=0.01)
    with pytest.raises(InvalidInput, match="contact"):
        BoxPushPlant([0.6, 0.0, -1.0])  # below the floor
    with pytest.raises(InvalidInput, match="contact"):
        BoxPushPlant([0.6, 0.0])
    with pytest.raises(InvalidInput, match="box"):
        BoxPushPlant([0.6, 0.0, 0.4], box=0.5)  # type: ignore[arg-type]
    with pytest.raises(InvalidInput, match="box.friction"):
        push.box_push(frictions=(0.3, -0.5))
    with pytest.raises(InvalidInput, match="distance"):
        push.box_push(distance=-0.2)
