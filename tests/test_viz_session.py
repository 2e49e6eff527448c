"""The live view's session: start poses of every device, faults shown and reset, pause and resume."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import rhi
from rhi.devices.mobile_base import BASE_JOINTS
from rhi.devices.spec import available_devices
from rhi.errors import InvalidInput
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


def test_status_reads_live_only_from_the_first_tick_and_an_error_is_shown():
    from rhi.runtime import SimLink
    from rhi.sim import Plant
    from rhi.viz.session import supervise

    dev = rhi.device("rhi4")
    plant = Plant(dev)
    plant.reset(rest_configuration(dev))
    cmd = ViewCommands()
    seen = []

    def once(guard, left):
        time.sleep(0.3)  # the kernels load: the watcher polls meanwhile
        seen.append(cmd.status()[1])
        guard.check(SimLink(plant).read(), None)  # the first tick's reading
        deadline = time.monotonic() + 30
        while cmd.status()[1] != "live" and time.monotonic() < deadline:
            time.sleep(0.01)
        seen.append(cmd.status()[1])
        raise RuntimeError("the link broke")

    try:
        with pytest.raises(RuntimeError, match="the link broke"):
            supervise(once, cmd, dev, lambda: None, say=lambda line: None)
        assert seen == ["starting …", "live"]
        assert cmd.status()[1] == "stopped: RuntimeError: the link broke"  # not "live" for a session that ended
    finally:
        cmd.close()


def test_a_stop_signal_ends_a_session_that_waits_for_a_reset(monkeypatch):
    """A faulted session waits for the page's reset; a stop signal the command received (rhi._lifetime) ends it."""
    from rhi import _lifetime
    from rhi.runtime import SimLink, run
    from rhi.sim import Plant
    from rhi.viz.session import supervise

    dev = rhi.device("rhi4")
    plant = Plant(dev)
    plant.reset(rest_configuration(dev))

    class Boom:
        device = dev

        def step(self, t, q, dq, sensors):
            if t > 0.01:
                raise RuntimeError("a user objective failed")
            return np.zeros(dev.n)

    cmd = ViewCommands()
    lines = []

    def say(line: str) -> None:  # the fault is shown: now the SIGTERM comes, while the session waits for a reset
        lines.append(line)
        _lifetime.STOP_SIGNALS.append("SIGTERM")

    try:
        results = supervise(lambda guard, left: run(SimLink(plant), Boom(), duration=left, safety=guard,
                                                    realtime=False), cmd, dev, lambda: None, duration=5.0,
                            say=say, poll=0.01)
        resets, status = cmd.resets, cmd.status()[1]
    finally:
        _lifetime.STOP_SIGNALS.clear()
        cmd.close()
    assert [r.summary["fault_kind"] for r in results] == ["controller", "estop"] and resets == 0
    assert results[1].fault.endswith("SIGTERM") and len(results[1].log) <= 1
    assert "press reset" in lines[0] and status.startswith("stopped: ")


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
    # 0.3 m/s: the kick below moves the handle at about 2.5 m/s; the demo on its own moves it at up to 0.05 m/s
    # (its null-space motion; a limit of 0.05 m/s tripped every run by itself at t = 3.158 s, and a test that read
    # the telemetry after that waited for a restarted run that had already stopped: the "never ticks" defect)
    safety = SafetyConfig(range_margin=0.3, max_handle_speed=0.3, silence=5.0, stale_ticks=10**6)
    session = threading.Thread(target=lambda: out.setdefault("runs", live(
        dev, duration=None, port=0, on_start=views.append, q0=q0, say=lines.append, safety=safety)), daemon=True)
    session.start()
    deadline = time.monotonic() + 120
    while not views and time.monotonic() < deadline:
        time.sleep(0.1)
    view = views[0]
    b = browser.Browser(view.url)
    try:
        # the first start may compile the kernels (a cold cache: about 2 min, more on a loaded machine)
        assert b.wait_for("document.getElementById('rhi-status')?.innerText === 'live'", timeout=400), lines
        # the kick: the gizmo dragged 10 cm away at once; the hand pulls the handle faster than 0.05 m/s
        goal = dev.fk(q0) + np.array([0.1, -0.05])
        msg = _messages.TransformControlsUpdateMessage(name="/hand", wxyz=(1.0, 0.0, 0.0, 0.0),
                                                       position=(float(goal[0]), float(goal[1]), 0.0))
        with connect(f"ws://127.0.0.1:{view.port}", subprotocols=[f"viser-v{viser.__version__}"]) as ws:
            ws.send(msgspec.msgpack.encode(msg.as_serializable_dict()))
            assert b.wait_for("document.body.innerText.includes('handle speed')", timeout=60)
        text = b.evaluate("document.getElementById('rhi-status').innerText")
        assert text.startswith("fault (") and "press reset" in text, text
        assert any("handle speed" in line for line in lines)
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.includes('reset')).click()")
        status = "document.getElementById('rhi-status').innerText"
        # "live" is said at the restarted run's first tick (the run first loads its kernels: run's warmup)
        assert b.wait_for(f"{status} === 'live'", timeout=120), (b.evaluate(status), lines)
        assert view.commands.status()[1] == "live" and view.hand.target is None  # the mouse hand let go
        t1 = view.telemetry.latest().t
        deadline = time.monotonic() + 60
        while view.telemetry.latest().t == t1 and time.monotonic() < deadline:
            time.sleep(0.05)
        snap = view.telemetry.latest()
        assert snap.t != t1 and snap.safety == "ok", (snap.t, t1, view.commands.status(), lines)  # running again
        # pause: the run stops with zero torque; resume goes on from where the device is
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.includes('pause')).click()")
        assert b.wait_for(f"{status}.startsWith('paused')", timeout=60)
        t_pause = view.telemetry.latest().t
        time.sleep(0.5)
        assert view.telemetry.latest().t == pytest.approx(t_pause, abs=5e-3)
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.includes('resume')).click()")
        assert b.wait_for(f"{status} === 'live'", timeout=120), (b.evaluate(status), lines)
        deadline = time.monotonic() + 60
        while view.telemetry.latest().t <= t_pause and time.monotonic() < deadline:
            time.sleep(0.05)
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


def test_environment_description_round_trips_through_a_log(tmp_path):
    from rhi.sim import Fixture, Spring, Wall, compose, simulate
    from rhi.sim.environment import describe, from_description
    from rhi.sim.log import Log
    from rhi.viz.live import demo_setup

    env = compose(Wall([0.1, 0.2], [0.0, 1.0], 1000.0, 2.0), Spring([0.0, 0.1], 50.0, direction=[1.0, 0.0]),
                  Fixture([0.0, 0.0], [0.0, 1.0]))
    back = from_description(describe(env))
    x, v = np.array([0.05, 0.25]), np.array([0.1, -0.2])
    np.testing.assert_allclose(back.force(x, v), env.force(x, v), rtol=0, atol=1e-15)
    with pytest.raises(InvalidInput, match=r"environment\[0\]"):
        from_description([{"type": "wall", "point": [0, 0], "normal": [0, 1], "stifness": 1.0}])
    plant, ctrl, wall, _ = demo_setup(rhi.device("rhi4"))
    simulate(plant, ctrl, duration=0.01, virtual=wall, log=tmp_path / "run.rhilog")
    drawn = from_description(Log.load(tmp_path / "run.rhilog").meta["environment"])
    assert isinstance(drawn, Wall) and drawn.stiffness == wall.stiffness
    np.testing.assert_array_equal(drawn.point, wall.point)


def test_log_player_speed_steps_and_state():
    from rhi.sim.log import Log
    from rhi.viz.replay import LogPlayer

    t = np.arange(0.0, 1.0, 1e-3)
    n = len(t)
    log = Log(t=t, q=np.zeros((n, 4)), dq=np.zeros((n, 4)), tau=np.zeros((n, 4)), x=np.zeros((n, 2)),
              xdot=np.zeros((n, 2)), F_hand=np.zeros((n, 2)), F_env=np.zeros((n, 2)), ft=np.zeros((n, 6)),
              work=np.zeros(n), V=np.zeros(n), omega=np.zeros(n), alpha=np.zeros(n), beta=np.zeros(n),
              slave_x=np.zeros((n, 0)))
    p = LogPlayer(log, speed=2.0)
    assert not p.playing and p.state == "paused at t = 0.000 s"
    p.step(3, fps=30.0)
    assert p.time == pytest.approx(0.1) and not p.playing
    p.step(-10, fps=30.0)
    assert p.time == 0.0
    for bad in (0.0, 5.0, float("nan"), "2", True):
        with pytest.raises(InvalidInput, match="speed"):
            p.speed = bad
    p.seek(10.0)
    assert p.state == "at the end"


@pytest.mark.realtime
def test_replay_opens_paused_and_plays_at_twice_the_speed(tmp_path):
    """In the page: paused at t = 0 with the logged wall drawn; at 2× a 3 s log ends in 1.5 s (±20 %)."""
    need_browser()
    from rhi.sim import DraggableHand, simulate
    from rhi.sim.log import Log
    from rhi.viz.live import demo_setup
    from rhi.viz.view import View

    dev = rhi.device("rhi4")
    plant, ctrl, wall, q0 = demo_setup(dev)
    hand = DraggableHand()
    hand.target = dev.fk(q0) + [0.0, 0.03]  # into the wall
    simulate(plant, ctrl, duration=3.0, hand=hand, virtual=wall, log=tmp_path / "run.rhilog")
    log = Log.load(tmp_path / "run.rhilog")
    v = View(dev, log, port=0).start()
    b = browser.Browser(v.url)
    try:
        assert v.overlays.virtual is not None  # the wall, from the log's header
        state = "document.getElementById('rhi-play').innerText"
        assert b.wait_for(f"{state} === 'paused at t = 0.000 s'", timeout=60)
        time.sleep(0.5)
        assert v.player.time == log.t[0] and not v.player.playing
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.trim() === '2×').click()")
        assert b.wait_for(f"{state} === 'paused at t = 0.000 s'", timeout=60)
        deadline = time.monotonic() + 10
        while v.player.speed != 2.0 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert v.player.speed == 2.0
        b.evaluate("[...document.querySelectorAll('button')].find(e => e.innerText.includes('play')).click()")
        deadline = time.monotonic() + 20
        while not v.player.playing and time.monotonic() < deadline:
            time.sleep(0.002)
        started = time.monotonic()
        while v.player.playing and time.monotonic() - started < 10:
            time.sleep(0.002)
        elapsed = time.monotonic() - started
        assert 0.8 * 1.5 <= elapsed <= 1.2 * 1.5, elapsed  # 3 s of log at 2×
        assert b.wait_for(f"{state} === 'at the end'", timeout=60)
    finally:
        b.close()
        v.close()


def test_history_keeps_the_last_window_and_restarts_when_time_goes_back():
    import types

    from rhi.viz.timeplots import History

    h = History(2, [-1.0, -2.0], [1.0, 4.0], window=0.5, capacity=64)
    u = np.array([0.0, 1.0])
    for k in range(200):  # 2 s at 100 Hz: the ring wraps
        h.add(types.SimpleNamespace(t=0.01 * k, tau=np.array([0.5, -1.0]), F_hand=np.array([1.0, 2.0]),
                                    F_env=np.array([0.0, -3.0]), V=0.2, alpha=1.0, beta=0.5), u)
    a = h.arrays()
    assert a["t"][-1] == pytest.approx(1.99) and a["t"][0] >= 1.99 - 0.5 - 1e-12
    assert np.all(np.diff(a["t"]) > 0)
    np.testing.assert_allclose(a["tau"][-1], [0.5, -0.5])  # fractions of the limit on each side
    assert a["F_hand_u"][-1] == 2.0 and a["F_env_u"][-1] == -3.0 and a["beta"][-1] == 0.5
    h.add(types.SimpleNamespace(t=0.0, tau=np.zeros(2), F_hand=np.zeros(2), F_env=np.zeros(2)), u)
    assert len(h.arrays()["t"]) == 1  # a restart (reset, replay seek) starts afresh


@pytest.mark.realtime
def test_live_view_plots_over_time_and_records_a_video(tmp_path):
    need_browser()
    import imageio_ffmpeg

    from rhi.runtime import SafetyConfig, SimLink, run
    from rhi.viz.live import demo_setup
    from rhi.viz.remote import RemoteView

    dev = rhi.device("rhi4")
    plant, ctrl, wall, q0 = demo_setup(dev)
    view = RemoteView(dev, virtual=wall, fme=ctrl.schedule[1], q0=q0, port=0, every=5, record_folder=tmp_path)
    b = browser.Browser(view.url)
    try:
        assert b.wait_for("document.querySelectorAll('.uplot').length === 3", timeout=60)
        assert b.wait_for("document.body.innerText.includes('τ / limit') && "
                          "document.body.innerText.includes('forces along u')", timeout=60)
        ink = "[...document.querySelectorAll('.uplot canvas')].map(c => c.toDataURL().length)"
        before = b.evaluate(ink)
        click = "[...document.querySelectorAll('button')].find(e => e.innerText.includes('{}')).click()"
        b.evaluate(click.format("record a video"))
        assert b.wait_for("document.getElementById('rhi-record').innerText.startsWith('recording')", timeout=60)
        # 2 s on the wall clock (simulate, as fast as it goes, can end before the view has drawn the few frames that
        # redraw the charts), limits loose enough for a loaded machine
        res = run(SimLink(plant), ctrl, duration=2.0, virtual=wall, telemetry=view.telemetry,
                  safety=SafetyConfig(range_margin=0.3, silence=5.0, stale_ticks=10**6))
        assert res.fault is None, res.fault
        # the three charts draw the run's series: their canvases gain ink
        assert b.wait_for(f"{ink}.every((n, i) => n > {before}[i] + 500)", timeout=60), (before, b.evaluate(ink))
        b.evaluate(click.format("stop and save"))
        assert b.wait_for("document.getElementById('rhi-record').innerText.startsWith('saved')", timeout=60)
        videos = list(tmp_path.glob("view-*.mp4"))
        assert len(videos) == 1
        frames, _ = imageio_ffmpeg.count_frames_and_secs(str(videos[0]))
        span = float(res.log.t[-1] - res.log.t[0])  # the run's device time (< 2 s where a loaded machine skips slots)
        assert frames >= span * 30 * 0.8, (frames, span)  # the run (frames drawn at the view's rate, written at 30 fps)
    finally:
        b.close()
        view.close()


def test_render_writes_a_video_of_a_log_with_its_forces(tmp_path):
    """`rhi render --log`: round(T·fps) + 1 frames (the log's duration × the frame rate, ±1), a drawn first frame."""
    import imageio_ffmpeg

    from rhi.cli import main
    from rhi.sim import DraggableHand, simulate
    from rhi.viz.live import demo_setup

    dev = rhi.device("rhi4")
    plant, ctrl, wall, q0 = demo_setup(dev)
    hand = DraggableHand()
    hand.target = dev.fk(q0) + [0.0, 0.03]  # into the wall: hand and wall forces to draw
    log_path = tmp_path / "run.rhilog"
    simulate(plant, ctrl, duration=1.0, hand=hand, virtual=wall, log=log_path)
    out = tmp_path / "run.mp4"
    assert main(["render", "--log", str(log_path), "-o", str(out), "--fps", "20", "--width", "320",
                 "--height", "240"]) == 0
    n, secs = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert abs(n - 1.0 * 20) <= 1, n
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = next(reader)
    assert tuple(meta["size"]) == (320, 240)
    first = np.frombuffer(next(reader), dtype=np.uint8).reshape(240, 320, 3)
    assert first.std() > 10  # not blank: the device on its background
    most = 0
    for raw in reader:
        img = np.frombuffer(raw, dtype=np.uint8).reshape(240, 320, 3).astype(int)
        most = max(most, int(((img[..., 0] > 150) & (img[..., 1] < 90) & (img[..., 2] > 110)).sum()))
    assert most > 20  # the hand force's arrow (magenta), pushing into the wall
    with pytest.raises(InvalidInput, match="path"):
        from rhi.sim.log import Log
        from rhi.viz.video import render_video

        render_video(dev, Log.load(log_path), tmp_path / "run.gif")
