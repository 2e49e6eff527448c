"""`rhi view --compare`: the RHI and its locked NHI side by side in one page under the same hand."""

from __future__ import annotations

import re
import threading
import time

import numpy as np
import pytest

import rhi
from rhi.errors import InvalidInput
from rhi.sim.hand import DraggableHand

pytest.importorskip("viser")

import browser  # noqa: E402  (tests/browser.py)
from test_viz_view import need_browser  # noqa: E402


def test_following_hand_moves_by_the_leaders_displacement_from_its_own_start():
    from rhi.viz.compare import FollowingHand

    lead = DraggableHand(stiffness=200.0, damping=5.0, max_force=12.0)
    follow = FollowingHand(lead, [0.5, 0.3], [0.5, -0.2])
    assert follow.target is None and np.all(follow.force(0.0, np.zeros(2), np.zeros(2)) == 0.0)
    lead.target = [0.52, 0.35]
    np.testing.assert_allclose(follow.target, [0.52, -0.15], atol=1e-15)
    # the leader's hand law: the same stiffness, damping and saturation
    np.testing.assert_allclose(follow.force(0.0, np.array([0.5, -0.2]), np.zeros(2)), [4.0, 10.0], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(follow.force(0.0, np.array([0.5, -0.5]), np.zeros(2))), 12.0)
    lead.target = None
    assert follow.target is None
    with pytest.raises(InvalidInput, match="target"):
        follow.target = [0.0, 0.0]
    with pytest.raises(InvalidInput, match="x_self"):
        FollowingHand(lead, [0.0, 0.0], [np.nan, 0.0])


def test_devices_are_placed_side_by_side_without_overlap():
    from rhi.viz.compare import side_by_side
    from rhi.viz.posed import Posed, rest_configuration

    devs = [rhi.device("rhi4"), rhi.device("phantom")]
    q0s = [rest_configuration(d) for d in devs]
    offsets = side_by_side(devs, q0s)
    assert np.all(offsets[0] == 0.0) and offsets[1][0] > 0.0 and np.all(offsets[1][1:] == 0.0)
    boxes = []
    for d, q, off in zip(devs, q0s, offsets):
        p = Posed(d)
        p.set(q)
        lo, hi = p.bounds()
        boxes.append((lo + off, hi + off))
    assert boxes[1][0][0] > boxes[0][1][0]  # the second device starts right of the first one's box


def _forces(b) -> list[tuple[float, float]]:
    """(|F_h|, |F_env|) [N] read from each device's read-out panel in the page, left to right."""
    out = []
    for text in b.evaluate("[...document.querySelectorAll('#rhi-state')].map(e => e.innerText)"):
        fh = re.search(r"\|F_h\| \[N\]\s+([\d.]+)", text)
        fe = re.search(r"\|F_env\| \[N\]\s+([\d.]+)", text)
        out.append((float(fh.group(1)) if fh else np.nan, float(fe.group(1)) if fe else np.nan))
    return out


@pytest.mark.realtime
def test_compare_view_shows_two_devices_whose_forces_differ_on_a_push():
    """rhi4 and phantom in one page; a 5 cm push of the gizmo into both walls: the read-outs differ."""
    need_browser()
    import msgspec
    import viser
    from viser import _messages
    from websockets.sync.client import connect

    from rhi.runtime import SafetyConfig
    from rhi.viz.compare import compare
    from rhi.viz.posed import rest_configuration

    devs = [rhi.device("rhi4"), rhi.device("phantom")]
    pages, lines, out = [], [], {}
    # two 1 kHz loops beside a software-rendering browser on a loaded machine: the host's silence and staleness
    # limits (20 ms, 3 ticks: a real link's) tripped the rhi4 after the push; the push moves the handles at up to
    # about 1.2 m/s
    safety = SafetyConfig(range_margin=0.3, max_handle_speed=3.0, silence=5.0, stale_ticks=10**6)
    session = threading.Thread(target=lambda: out.setdefault("runs", compare(
        devs, duration=None, port=0, on_start=pages.append, say=lines.append, safety=safety)), daemon=True)
    session.start()
    deadline = time.monotonic() + 240
    while not pages and time.monotonic() < deadline:
        time.sleep(0.1)
    page = pages[0]
    b = browser.Browser(page.url, width=1200, height=800)
    try:
        # the push as soon as both loops tick: left alone, the demo's null-space motion moves the rhi4 (up to
        # 0.05 m/s), and a push after many seconds of that met a pose where joint 3 ran away (a speed fault)
        deadline = time.monotonic() + 300
        while any(c.status()[1] != "live" for c in page.commands):
            assert time.monotonic() < deadline, ([c.status() for c in page.commands], lines)
            time.sleep(0.05)
        assert all(np.all(tel.latest().F_hand == 0.0) for tel in page.telemetries)  # nobody pushes yet
        x0 = devs[0].fk(rest_configuration(devs[0]))
        goal = x0 + np.array([0.0, 0.05])  # 4 cm into the wall 1 cm beyond the start handle
        msg = _messages.TransformControlsUpdateMessage(name="/device0/hand", wxyz=(1.0, 0.0, 0.0, 0.0),
                                                       position=(float(goal[0]), float(goal[1]), 0.0))
        with connect(f"ws://127.0.0.1:{page.port}", subprotocols=[f"viser-v{viser.__version__}"]) as ws:
            ws.send(msgspec.msgpack.encode(msg.as_serializable_dict()))
            deadline = time.monotonic() + 60
            while page.hand.target is None and time.monotonic() < deadline:
                time.sleep(0.01)
        np.testing.assert_allclose(page.hand.target, goal, atol=1e-9)  # set through the page's gizmo
        # both hands push (the phantom's follows the gizmo's displacement) and both walls push back: 2.5 s to settle
        t_push = [tel.latest().t for tel in page.telemetries]
        deadline = time.monotonic() + 300
        while min(tel.latest().t - t for tel, t in zip(page.telemetries, t_push)) < 2.5:
            assert time.monotonic() < deadline, ([c.status() for c in page.commands], lines)
            time.sleep(0.2)
        snaps = [tel.latest() for tel in page.telemetries]
        assert all(s.safety == "ok" for s in snaps), ([c.status() for c in page.commands], lines)
        for c in page.commands:  # held where they are (zero torque) while the page is read: however slow the browser
            c.paused = True
        # the page: both devices, each with its status, read-outs and torques
        status = "[...document.querySelectorAll('#rhi-status')].map(e => e.innerText)"
        assert b.wait_for(f"{status}.length === 2", timeout=300), lines
        text = b.evaluate("document.body.innerText")
        assert "rhi4" in text and "phantom" in text
        assert b.evaluate("document.querySelectorAll('#rhi-state').length") == 2
        assert b.evaluate("document.querySelectorAll('#rhi-torques').length") == 2
        assert b.wait_for("[...document.querySelectorAll('#rhi-state')].every(e => "
                          "/\\|F_env\\| \\[N\\]\\s+[1-9]/.test(e.innerText))", timeout=120), _forces(b)
        (fh_a, fe_a), (fh_b, fe_b) = _forces(b)
        assert fh_a > 1.0 and fh_b > 1.0, _forces(b)
        # the same push, different devices: the read-outs differ (rhi4 about 8 N, the locked NHI about 20 N)
        assert abs(fe_a - fe_b) > 0.25 * max(fe_a, fe_b), (fe_a, fe_b)
        assert abs(np.linalg.norm(snaps[0].F_env) - np.linalg.norm(snaps[1].F_env)) > 1.0
        assert b.wait_for(f"{status}.every(s => s.startsWith('paused'))", timeout=120), b.evaluate(status)
        page.commands[0].request_stop()
        session.join(60)
        assert not session.is_alive()
    finally:
        b.close()
        if session.is_alive():
            for cmd in page.commands:
                cmd.request_stop()
            session.join(60)
    runs = out["runs"]
    assert len(runs) == 2 and all(len(r) == 1 for r in runs), runs  # one run each: no fault, no restart
    assert all(r[0].summary["fault_kind"] == "estop" and "paused in the view" in r[0].fault for r in runs)
