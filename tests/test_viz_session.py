"""The live view's session: start poses of every device, faults shown and reset, pause and resume."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import rhi
from rhi.device_spec import available_devices
from rhi.errors import InvalidInput
from rhi.mobile_base import BASE_JOINTS
from rhi.viz.commands import ViewCommands
from rhi.viz.posed import WELL_CONDITIONED, rest_configuration

pytest.importorskip("viser")

import browser  # noqa: E402  (tests/browser.py)
from test_viz_view import need_browser  # noqa: E402


@pytest.mark.parametrize("name", available_devices())
def test_every_bundled_device_starts_in_a_well_conditioned_pose(name):
    from rhi.viz.live import demo_setup

    dev = rhi.device(name)
    q = rest_configuration(dev)
    assert np.all(q >= dev.q_min) and np.all(q <= dev.q_max)
    s = np.linalg.svd(dev.jacobian(q), compute_uv=False)
    assert s[-1] / s[0] >= WELL_CONDITIONED, (name, q, s)
    if tuple(dev.joint_names[:3]) == BASE_JOINTS:
        with pytest.raises(InvalidInput, match="velocity-commanded"):
            demo_setup(dev)
        return
    _, ctrl, _, q0 = demo_setup(dev)
    for k in range(3):  # the live demo's controller runs at the start pose
        tau = ctrl.step(1e-3 * k, q0, np.zeros(dev.n), {"force": np.zeros(dev.m)})
    assert np.all(np.isfinite(tau)) and not ctrl.state.stopped
    with pytest.raises(InvalidInput, match="q0"):
        demo_setup(dev, q0=np.full(dev.n, 1e3))


def test_view_commands_cross_processes():
    import pickle

    cmd = ViewCommands()
    other = pickle.loads(pickle.dumps(cmd))  # what the view's process receives: the same block
    try:
        assert not cmd.paused and cmd.resets == 0 and cmd.status() == (0, "")
        other.paused = True
        assert cmd.paused
        other.request_reset()
        assert cmd.resets == 1 and not cmd.paused  # a reset also resumes
        cmd.set_status("fault (speed) at t = 1.234 s: handle speed 2.0 m/s > 1.5")
        seq, text = other.status()
        assert seq == 2 and text.startswith("fault (speed)")
        cmd.set_status("live")
        assert other.status() == (4, "live")
    finally:
        other.close()
        cmd.close()


@pytest.mark.realtime
def test_fault_is_shown_in_the_page_and_reset_restarts_the_run():
    """A hand kick trips the safety layer: the page shows the reason; its reset button re-arms and restarts."""
    need_browser()
    import msgspec
    import viser
    from viser import _messages
    from websockets.sync.client import connect

    from rhi.runtime import SafetyConfig
    from rhi.viz.live import live

    dev = rhi.device("rhi4")
    q0 = rest_configuration(dev)
    views, lines, out = [], [], {}
    safety = SafetyConfig(range_margin=0.3, max_handle_speed=0.05, silence=5.0, stale_ticks=10**6)
    session = threading.Thread(target=lambda: out.setdefault("runs", live(
        dev, duration=None, port=0, on_start=views.append, q0=q0, say=lines.append, safety=safety)), daemon=True)
    session.start()
    deadline = time.monotonic() + 120
    while not views and time.monotonic() < deadline:
        time.sleep(0.1)
    view = views[0]
    b = browser.Browser(view.url)
    try:
        assert b.wait_for("document.body.innerText.includes('live')", timeout=120)
        # the kick: the gizmo dragged 10 cm away at once; the hand pulls the handle faster than 0.05 m/s
        goal = dev.fk(q0) + np.array([0.1, -0.05])
        msg = _messages.TransformControlsUpdateMessage(name="/hand", wxyz=(1.0, 0.0, 0.0, 0.0),
                                                       position=(float(goal[0]), float(goal[1]), 0.0))
        with connect(f"ws://127.0.0.1:{view.port}", subprotocols=[f"viser-v{viser.__version__}"]) as ws:
            ws.send(msgspec.msgpack.encode(msg.as_serializable_dict()))
            assert b.wait_for("document.body.innerText.includes('handle speed')", timeout=20)
        text = b.evaluate("document.getElementById('rhi-status').innerText")
        assert text.startswith("fault (") and "press reset" in text, text
        assert any("handle speed" in line for line in lines)
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.includes('reset')).click()")
        assert b.wait_for("document.getElementById('rhi-status').innerText === 'live'", timeout=20)
        assert view.hand.target is None  # the mouse hand let go
        t1 = view.telemetry.latest().t
        time.sleep(0.5)
        snap = view.telemetry.latest()
        assert snap.t > t1 and snap.safety == "ok"  # running again
        # pause: the run stops with zero torque; resume goes on from where the device is
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.includes('pause')).click()")
        assert b.wait_for("document.getElementById('rhi-status').innerText.startsWith('paused')", timeout=30)
        t_pause = view.telemetry.latest().t
        time.sleep(0.5)
        assert view.telemetry.latest().t == pytest.approx(t_pause, abs=5e-3)
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.includes('resume')).click()")
        assert b.wait_for("document.getElementById('rhi-status').innerText === 'live'", timeout=30)
        assert view.telemetry.latest().t > t_pause
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.includes('stop the')).click()")
        session.join(30)
        assert not session.is_alive()
    finally:
        b.close()
        if session.is_alive():
            views[0].commands.request_stop()
            session.join(30)
    runs = out["runs"]
    assert [r.summary["fault_kind"] for r in runs] == ["handle_speed", "estop", "estop"], [r.fault for r in runs]
    assert "paused" in runs[1].fault and "stopped in the view" in runs[2].fault
    assert runs[1].log.t[0] < 0.01 < runs[0].log.t[-1]  # the reset restarted the device at its start
    assert runs[2].log.t[0] == pytest.approx(runs[1].log.t[-1], abs=0.01)  # resume goes on where it paused
