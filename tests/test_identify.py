"""`rhi identify`: joint friction and M_x identified through the runtime, on the simulated plant and over UDP.

The truth is what the plant simulates: its friction (set here, unlike the model's `device.toml` values) and Λ of
eq. 3.13 from MuJoCo's own inertia (with the plant's 1 g handle, which the controller's model lacks). Tolerance,
as docs/runtime.md states it: 10 % on every motor's viscous and Coulomb friction and on M_x.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib

import numpy as np
import pytest
from conftest import child_env, free_udp_port

import rhi
from rhi.analysis.sysid.excitation import Excitation, Programme
from rhi.analysis.sysid.on_device import identify_device
from rhi.cli import main
from rhi.errors import InvalidInput
from rhi.runtime import SimLink
from rhi.sim import Plant
from rhi.sim.mjcf import PlantFriction

#: Table 6.1's M_Free^des configuration at [0.5, 0.1] m (ch6_fme_aso): motors 1–2 and 3–4 within 0.08 and 0.05 rad
#: of their linear limits, where the first prototype misidentified motors 1–2.
Q0 = np.array([1.2566003121300144, 0.37538824658166875, -0.09834521628298676, 0.8113294816500943])
DAMPING = np.array([0.08, 0.03, 0.015, 0.006])
FRICTIONLOSS = np.array([0.03, 0.01, 0.008, 0.004])
TOL = 0.10


def true_inertia(dev: rhi.Device, q: np.ndarray, u=(0.0, 1.0)) -> float:
    """Λ along u (eq. 3.13) from the plant's MuJoCo inertia and Jacobian at q [kg]."""
    plant = Plant(dev, friction=None)
    plant.reset(q)
    J, M, u = plant.motor_jacobian(), plant.motor_mass_matrix(), np.asarray(u)
    return 1.0 / float(u @ J @ np.linalg.solve(M, J.T @ u))


def within(got, want, tol=TOL) -> bool:
    return bool(np.all(np.abs(np.asarray(got) / np.asarray(want) - 1.0) <= tol))


def test_simlink_identification_recovers_the_plants_friction_and_inertia(rhi4):
    plant = Plant(rhi4, friction=PlantFriction(DAMPING, FRICTIONLOSS))
    plant.reset(Q0 + [-0.1, 0.0, 0.1, 0.0])  # the programme first moves to the hold configuration
    res = identify_device(SimLink(plant), rhi4, q0=Q0, programme=Programme(trials=4), realtime=False)
    f = res.friction
    assert within(f.damping, DAMPING), f.damping
    assert within(f.frictionloss, FRICTIONLOSS), f.frictionloss
    assert np.all(f.r2 > 0.99)
    lam = true_inertia(rhi4, Q0)
    assert within(res.inertia.mass, lam), (res.inertia.mass, lam)
    assert res.inertia.r_squared > 0.99 and res.inertia.n_trials == 4
    # every motor swept both ways at three speeds, inside every joint and linear limit
    for i in range(4):
        speeds = sorted(w.speed for w in res.windows if w.joint == i)
        assert len(speeds) == 6 and speeds[0] < 0 < speeds[-1]
    toml = tomllib.loads(res.friction_toml())["plant"]
    assert np.allclose(toml["damping"], f.damping, rtol=1e-3)
    assert np.allclose(toml["frictionloss"], f.frictionloss, rtol=1e-3)
    json.dumps(res.to_dict(), default=float)


def test_excitation_keeps_every_stroke_inside_the_limits(rhi4):
    ex = Excitation(rhi4, (0.0, 1.0), q0=Q0)
    L = rhi4.linear_limits
    for i, (a, b, top) in enumerate(ex.strokes(Q0)):
        assert b - a > 0.2 and top > 0
        for qi in (a, b):
            q = Q0.copy()
            q[i] = qi
            assert rhi4.within_limits(q)
            rows = L.C[:, i] != 0  # the limits motor i moves along (Q0 itself is within 0.05 rad of the other)
            s = L.C[rows] @ q
            assert np.all(s >= L.lower[rows] + 0.1 - 1e-9) and np.all(s <= L.upper[rows] - 0.1 + 1e-9)


def test_default_hold_configuration_is_the_nearest_inside_the_limits(rhi4):
    """Without q0 the hold is the configuration nearest the first reading that is the margin inside every limit.

    rhi4's mid-range start lies on its first linear limit (q1 − q2 = −55°).
    """
    ex = Excitation(rhi4, (0.0, 1.0))
    lo, hi = rhi4.joint_limits
    mid = 0.5 * (lo + hi)
    q = ex.inside(mid)
    assert ex._distances(q).min() >= 0.1 - 1e-9 and ex._distances(mid).min() < 1e-9
    assert np.linalg.norm(q - mid) < 0.1  # moved only as far as needed (0.1 along the row, split over q1 and q2)
    np.testing.assert_array_equal(ex.inside(Q0 + [-0.2, 0.0, 0.0, -0.2]), Q0 + [-0.2, 0.0, 0.0, -0.2])
    with pytest.raises(InvalidInput, match="^q0: no configuration"):
        Excitation(rhi4, (0.0, 1.0), programme=Programme(margin=1.5)).inside(mid)


def test_bad_arguments_name_what_is_wrong(rhi4, tmp_path, capsys):
    with pytest.raises(InvalidInput, match="^u:"):
        Excitation(rhi4, (0.0, 0.0))
    with pytest.raises(InvalidInput, match="^q0: motor 2"):
        Excitation(rhi4, (0.0, 1.0), q0=[0.0, 3.0, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="^q0: linear joint limit 1"):
        Excitation(rhi4, (0.0, 1.0), q0=[1.5, 0.0, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="^trials:"):
        Programme(trials=1)
    with pytest.raises(InvalidInput, match="^speeds:"):
        Programme(speeds=(1.0, 0.5))
    (tmp_path / "file").write_text("")
    for argv, flag in ((["--direction", "1,2,3"], "--direction"), (["--q0", "1,2"], "--q0"),
                       (["--trials", "1"], "--trials"), (["--out", str(tmp_path / "file")], "--out"),
                       (["--link", "bogus://x"], "bogus"), (["--q0", "0,3,0,0"], "q0: motor 2")):
        assert main(["identify", "rhi4", "--no-realtime", *argv]) == 2, argv
        assert flag in capsys.readouterr().err, argv
    assert main(["identify", "--no-realtime"]) == 2
    assert "device:" in capsys.readouterr().err


def test_help_has_an_example(capsys):
    with pytest.raises(SystemExit):
        main(["identify", "--help"])
    out = capsys.readouterr().out
    assert "rhi identify rhi4 --link udp://" in out and "friction.toml" in out


@pytest.mark.realtime
def test_identify_over_udp_against_a_device_server_recovers_friction_and_inertia(rhi4, tmp_path):
    """The acceptance test: `rhi identify rhi4 --link udp://...` against a `rhi device-server` process.

    The device is paced by its clock in lock step (it waits for each reading's command) and the host runs as fast
    as the device answers (`--no-realtime`), as docs/runtime.md advises for a loaded machine: a free-running host
    that misses deadlines on a loaded 2-core machine reads the device at a third of its rate. The host's stale,
    silence and age limits and the device's watchdog are loosened for the same reason.
    """
    cfg = tmp_path / "ident.toml"
    cfg.write_text(f"""description = "identification test: known plant friction"
[safety]  # no [controller]: neither rhi identify nor rhi device-server needs one
stale_ticks = 100
silence = 1.0
max_age = 1.0
[sim]
q0 = {Q0.tolist()}
friction = {{ damping = {DAMPING.tolist()}, frictionloss = {FRICTIONLOSS.tolist()} }}
""")
    port = free_udp_port()
    server = subprocess.Popen([sys.executable, "-m", "rhi", "device-server", "rhi4", "--config", str(cfg), "--port",
                               str(port), "--lockstep", "--watchdog-ms", "2000", "--duration", "600"],
                              env=child_env(), stdout=subprocess.PIPE, text=True)
    out = tmp_path / "ident"
    try:
        assert "rhi4 (simulated" in server.stdout.readline()  # listening
        assert main(["identify", "rhi4", "--link", f"udp://127.0.0.1:{port}", "--config", str(cfg), "--trials", "5",
                     "--no-realtime", "--out", str(out)]) == 0
    finally:
        server.terminate()
        server.wait(20)
    res = json.loads((out / "identification.json").read_text())
    motors = res["joint_friction"]
    assert within([m["damping"] for m in motors], DAMPING), motors
    assert within([m["frictionloss"] for m in motors], FRICTIONLOSS), motors
    assert all(m["r2"] > 0.95 for m in motors)
    mx = res["apparent_inertia"]
    assert within(mx["M_x"], true_inertia(rhi4, Q0)), mx
    assert mx["trials"] == 5 and mx["r2"] > 0.95
    toml = tomllib.loads((out / "friction.toml").read_text())["plant"]
    assert within(toml["damping"], DAMPING) and within(toml["frictionloss"], FRICTIONLOSS)
    assert rhi.sim.Log.load(out / "identify.rhilog").fault is None
