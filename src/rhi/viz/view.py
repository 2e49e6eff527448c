"""`View`: the device live in the browser (viser), from a running loop or a replayed log.

The view polls a *source* — anything with ``latest()`` returning the newest snapshot
(`rhi.runtime.Telemetry`, which `rhi.sim.simulate` and `rhi.runtime.run` publish into
without blocking, or a `LogPlayer`) — from its own thread at `fps` frames per second and
sends the browser only the body poses, overlays and panels. The control loop never waits
on it: publishing is one reference assignment, and the view copies what it reads.

With a `DraggableHand` the view adds a gizmo at the handle: dragging it in the browser
moves the hand's target, so the mouse is the simulated user's hand (planar devices: the
gizmo moves in the task plane).
"""

from __future__ import annotations

import html
import threading
import time
import types

import numpy as np

from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.sim.environment import Wall, from_description
from rhi.sim.hand import DraggableHand
from rhi.sim.log import Log
from rhi.viz.commands import ViewCommands
from rhi.viz.overlays import GROUPS, HandleMeasures, Overlays, handle_measures
from rhi.viz.panels import legend, state_panel, status_line, torque_panel
from rhi.viz.posed import Posed, rest_configuration
from rhi.viz.recorder import Recorder
from rhi.viz.replay import SPEEDS, LogPlayer
from rhi.viz.scene import DeviceScene
from rhi.viz.timeplots import History, TimePlots

_AXES = {"x": 0, "y": 1, "z": 2}


def _play_state(p: LogPlayer) -> str:
    return f'<div id="rhi-play" style="font:12px monospace">{p.state}</div>'


def aim_camera(server, lo: np.ndarray, hi: np.ndarray, *, planar: bool) -> None:
    """Point `server`'s initial camera at the box lo..hi: (3,) [m] (from above for planar devices)."""
    c = 0.5 * (lo + hi)
    size = float(np.max(hi - lo))
    back = np.array([0.35, -0.6, 1.0]) if planar else np.array([1.0, -0.9, 0.6])
    right = np.cross(-back, [0.0, 0.0, 1.0])
    shift = 0.25 * size * right / np.linalg.norm(right)  # the panel covers the right of the page
    server.initial_camera.position = tuple(c + back * 1.5 * size + shift)
    server.initial_camera.look_at = tuple(c + shift)
    server.initial_camera.up = (0.0, 0.0, 1.0)


class View:
    """A browser view of a device.

    Args:
        device: the device drawn (the controller's model).
        source: where snapshots come from: an object with ``latest()`` (e.g. `rhi.runtime.Telemetry`),
            a `Log` (replayed with a timeline slider and play/pause), or None (the device at rest at `q0`).
        hand: a `DraggableHand` moved by a gizmo in the browser (the mouse as the hand), or None.
        virtual: the rendered environment to draw (wall, spring, fixture), or None.
        fme: a desired-FME schedule whose M_des(Ω) is drawn, or None.
        q0: (n,) configuration shown before the first snapshot [rad] (default: mid-range).
        host, port: where the server listens (port 0: a free port).
        fps: browser updates per second (the thread's rate).
        lp_every: solve the force-capability LP every this many frames (it costs milliseconds).
        commands: the run's `ViewCommands` (`rhi.viz.session.supervise`): pause / resume and reset buttons and the
            run's status line (warming up, live, paused, the fault and its reason), or None.
        plot_window: the plots over time show the last this many seconds [s].
        record_folder: where the record button writes its videos (`rhi.viz.recorder.Recorder`).
        server: a `viser.ViserServer` shared with other views (`rhi.viz.compare`): the view's controls go in a
            folder named after the device and the server's camera is left to the caller; None: the view's own.
        root: scene node under which the device, its overlays and the gizmo are drawn ("" : the scene's root).
        offset: (3,) where the `root` frame sits [m]: the device's MuJoCo coordinates are shifted by it.

    Attributes:
        server: the `viser.ViserServer`.
        frames: updates sent so far.
        cpu: CPU time the update thread spent drawing them [s] (so cpu / frames is the cost of a frame).
        player: the `LogPlayer` when replaying a log.
    """

    def __init__(self, device: Device, source=None, *, hand: DraggableHand | None = None, virtual=None, fme=None,
                 q0=None, host: str = "127.0.0.1", port: int = 8080, fps: float = 45.0, lp_every: int = 10,
                 commands: ViewCommands | None = None, plot_window: float = 5.0, record_folder="out", server=None,
                 root: str = "", offset=(0.0, 0.0, 0.0)) -> None:
        import viser

        if not np.isfinite(fps) or not 1 <= fps <= 240:
            raise InvalidInput(f"fps: expected 1..240 frames per second, got {fps!r}")
        if hand is not None and not isinstance(hand, DraggableHand):
            raise InvalidInput(f"hand: expected a rhi.sim.DraggableHand, got {type(hand).__name__}")
        self.device, self.hand, self.fps, self.lp_every = device, hand, float(fps), max(1, int(lp_every))
        self.commands = commands
        self._status = (-1, "")
        self._scales: tuple = (None, None)
        self._meas: HandleMeasures | None = None  # the last measures (the LP's force kept between LP frames)
        self.player = LogPlayer(source) if isinstance(source, Log) else None
        self.source = self.player or source
        if self.source is not None and not callable(getattr(self.source, "latest", None)):
            raise InvalidInput(f"source: expected a Log or an object with latest(), got {type(source).__name__}")
        if self.player is not None:
            q0 = self.player.log.q[0] if q0 is None else q0
            virtual = virtual if virtual is not None else from_description(self.player.log.meta.get("environment"))
        self.q0 = rest_configuration(device) if q0 is None else np.asarray(q0, dtype=float)
        self.rows = [_AXES[a] for a in device.task_axes]
        self._own_server = server is None
        self.server = viser.ViserServer(host=host, port=port, verbose=False) if server is None else server
        if self._own_server:
            self.server.gui.configure_theme(control_width="medium", show_logo=False)
        self.root = root
        if root:
            self.server.scene.add_frame(root, show_axes=False, position=tuple(np.asarray(offset, dtype=float)))
        self.posed = Posed(device)
        self.posed.set(self.q0)
        self.scene = DeviceScene(self.server, self.posed, root=f"{root}/device")
        blo, bhi = self._motion_bounds()
        self.size = float(np.max(bhi - blo))
        self.overlays = Overlays(self.server, device, self.size, virtual=virtual, fme=fme, root=f"{root}/overlays")
        if self._own_server:
            aim_camera(self.server, blo, bhi, planar=set(device.task_axes) <= {"x", "y"})
        self._grip = threading.Lock()  # the gizmo's position vs the hand's target (view thread vs viser's loop)
        lo, hi = device.torque_limits
        self.history = History(device.n, lo, hi, window=plot_window)
        walls = [e for e in getattr(virtual, "parts", (virtual,)) if isinstance(e, Wall)]
        self.u_plot = walls[0].normal if walls else np.eye(device.m)[min(1, device.m - 1)]
        self.recorder = Recorder(device, record_folder, virtual=virtual)
        self._build_gui()
        self.frames = 0
        self.cpu = 0.0
        self._last_t = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._draw(self._rest_snapshot(), force=True)

    # ----------------------------------------------------------------- set-up
    @property
    def port(self) -> int:
        """The port the view's server listens on."""
        return int(self.server.get_port())

    @property
    def url(self) -> str:
        """The view's address in a browser."""
        return f"http://127.0.0.1:{self.port}"

    def _motion_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The drawn geometry's box at q0, and over the logged motion when replaying (20 poses along the log)."""
        lo, hi = self.posed.bounds()
        if self.player is not None:
            Q = self.player.log.q
            for q in Q[np.linspace(0, len(Q) - 1, min(20, len(Q))).astype(int)]:
                if np.all(np.isfinite(q)):
                    self.posed.set(q)
                    a, b = self.posed.bounds()
                    lo, hi = np.minimum(lo, a), np.maximum(hi, b)
            self.posed.set(self.q0)
        return lo, hi

    def _build_gui(self) -> None:
        if self._own_server:
            self._build_controls()
        else:
            with self.server.gui.add_folder(self.device.name, expand_by_default=True):
                self._build_controls()

    def _build_controls(self) -> None:
        gui = self.server.gui
        gui.add_markdown(f"**rhi** · `{self.device.name}` (n = {self.device.n}, task {self.device.task_axes})")
        if self.player is not None:
            self._build_replay_controls(self.player)
        if self.commands is not None:
            self._build_run_controls(self.commands)
        self.state_html = gui.add_html(state_panel(self._rest_snapshot()))
        self.torque_html = gui.add_html("")
        self.legend_html = gui.add_html(legend(None, None))
        self.record_button = gui.add_button("● record a video")
        self.record_html = gui.add_html("")

        @self.record_button.on_click
        def _(event) -> None:
            rec = self.recorder
            rec.stop() if rec.recording else rec.start()
            self.record_button.label = "■ stop and save the video" if rec.recording else "● record a video"

        with gui.add_folder("plots over time", expand_by_default=True):
            self.plots = TimePlots(gui, self.device.joint_names)
        with gui.add_folder("overlays", expand_by_default=False):
            for group, label in GROUPS.items():
                gui.add_checkbox(label, initial_value=True).on_update(self._toggle(group))
        self.gizmo = None
        hand = self.hand
        if hand is not None:
            active = [a in self.device.task_axes for a in "xyz"]
            axes = (active[0], active[1], active[2])
            gizmo = self.gizmo = self.server.scene.add_transform_controls(
                f"{self.root}/hand", scale=0.35 * self.size, active_axes=axes, disable_rotations=True,
                position=tuple(self.scene.handle_position()))
            self.release = gui.add_button("let go of the handle")

            # on the event loop, in order (a threadpool callback read the gizmo after the view had put it back
            # on the free handle); the grip keeps the view from placing the gizmo between a drag's start and
            # the target it sets
            @gizmo.on_update
            async def _(event) -> None:
                with self._grip:
                    hand.target = np.asarray(event.target.position, dtype=float)[self.rows]

            @self.release.on_click
            def _(event) -> None:
                with self._grip:
                    hand.target = None

    def _build_replay_controls(self, p: LogPlayer) -> None:
        """Timeline, play / pause (labelled with the state), frame steps and the speed (`SPEEDS`, 0.1–4×)."""
        gui = self.server.gui
        step = max((p.t1 - p.t0) / 1000.0, 1e-4)
        self.timeline = gui.add_slider("time [s]", min=p.t0, max=p.t1, step=step, initial_value=p.t0)
        self.play_state = gui.add_html(_play_state(p))
        self.play_button = gui.add_button("▶ play")
        steps = gui.add_button_group("step a frame", ("◀ frame", "frame ▶"))
        speeds = gui.add_button_group("speed", tuple(f"{v:g}×" for v in SPEEDS))

        @self.timeline.on_update
        def _(event) -> None:
            if event.client is not None:  # the user moved it (the view moves it while playing)
                p.seek(float(self.timeline.value))

        @self.play_button.on_click
        def _(event) -> None:
            p.pause() if p.playing else p.play()
            self._replay_state()

        @steps.on_click
        def _(event) -> None:
            p.step(-1 if event.target.value.startswith("◀") else 1, self.fps)
            self._replay_state()

        @speeds.on_click
        def _(event) -> None:
            p.speed = float(event.target.value.rstrip("×"))
            self._replay_state()

    def _toggle(self, group: str):
        """The callback of one overlay group's checkbox."""
        def on_update(event) -> None:
            self.overlays.show(group, bool(event.target.value))
        return on_update

    def _replay_state(self) -> None:
        p = self.player
        if p is None:
            return
        label, state = "⏸ pause" if p.playing else "▶ play", _play_state(p)
        if self.play_button.label != label:
            self.play_button.label = label
        if self.play_state.content != state:  # only changes go to the browser
            self.play_state.content = state

    def _build_run_controls(self, cmd: ViewCommands) -> None:
        """The run's status line, a pause / resume button, a reset button and a stop button."""
        gui = self.server.gui
        self.status_html = gui.add_html(status_line("starting …"))
        self.pause_button = gui.add_button("pause")
        self.reset_button = gui.add_button("reset (re-arm safety, restart)")
        self.stop_button = gui.add_button("stop the session", color="red")

        @self.pause_button.on_click
        def _(event) -> None:
            cmd.paused = not cmd.paused
            self.pause_button.label = "resume" if cmd.paused else "pause"

        @self.reset_button.on_click
        def _(event) -> None:
            if self.hand is not None:
                with self._grip:
                    self.hand.target = None
            cmd.request_reset()
            self.pause_button.label = "pause"

        @self.stop_button.on_click
        def _(event) -> None:
            cmd.request_stop()

    def _rest_snapshot(self):
        z = np.zeros(self.device.m)
        return types.SimpleNamespace(t=0.0, q=self.q0, tau=np.zeros(self.device.n), F_hand=z, F_env=z, V=np.nan,
                                     omega=np.nan, alpha=np.nan, beta=np.nan, safety="ok", fault=None)

    # ----------------------------------------------------------------- frames
    def _draw(self, snap, *, force: bool = False) -> None:
        q = np.asarray(snap.q, dtype=float)
        if not np.all(np.isfinite(q)):
            return
        self.posed.set(q)
        handle = self.scene.handle_position()
        F = np.asarray(getattr(snap, "F_hand", np.zeros(self.device.m)), dtype=float)
        Fe = np.asarray(getattr(snap, "F_env", np.zeros(self.device.m)), dtype=float)
        u = F if np.linalg.norm(F) > 0.05 else Fe if np.linalg.norm(Fe) > 0.05 else np.eye(self.device.m)[0]
        lp = force or self.frames % self.lp_every == 0
        try:
            meas = handle_measures(self.device, q, u, lp=lp)
        except Exception:  # noqa: BLE001 - a singular or degenerate pose must not stop the view
            meas = None
        if meas is not None:
            if not lp and self._meas is not None:
                meas.f_lp = self._meas.f_lp
            self._meas = meas
        with self.server.atomic():  # one batch of messages per frame
            self.scene.update(q)
            if meas is not None:
                self.overlays.update(handle, snap, meas)
            lo, hi = self.device.torque_limits
            self.torque_html.content = torque_panel(snap.tau, lo, hi, self.device.joint_names)
            self.state_html.content = state_panel(snap)
            scales = (self.overlays.force_scale, self.overlays.velocity_scale)
            if scales != self._scales:  # the first frame, and whenever a larger force rescales the arrows
                self._scales = scales
                self.legend_html.content = legend(*scales)
            if self.gizmo is not None and self.hand is not None:
                with self._grip:
                    if self.hand.target is None:  # a free hand: the gizmo follows the handle
                        self.gizmo.position = tuple(handle)
            self.recorder.add(snap)
            if self.player is None:
                self.history.add(snap, self.u_plot)
            # about 9 Hz (a chart's redraw costs the browser more than a frame), and every frame of a paused replay
            if self.frames % 5 == 0 or (self.player is not None and not self.player.playing):
                if self.player is not None:
                    self.history.fill(self.player.log, float(snap.t), self.u_plot)
                self.plots.update(self.history)
            if self.player is not None:
                self.timeline.value = float(snap.t)  # type: ignore[misc]  # viser's slider has a setter; mypy sees a read-only props field
                self._replay_state()
        self.frames += 1

    def step(self) -> bool:
        """Draw the newest snapshot if there is a new one; returns whether it drew."""
        if self.player is not None:
            self._replay_state()  # the end of the log pauses the player: the button and the state follow
        line = f'<div id="rhi-record" style="font:12px monospace">{html.escape(self.recorder.status)}</div>'
        if self.record_html.content != line:
            self.record_html.content = line
        if self.commands is not None:
            st = self.commands.status()
            if st[0] != self._status[0]:
                self._status = st
                self.status_html.content = status_line(st[1])
        snap = self.source.latest() if self.source is not None else None
        if snap is None or (self._last_t is not None and snap.t == self._last_t):
            return False
        self._last_t = snap.t
        self._draw(snap)
        return True

    def _run(self) -> None:
        period = 1.0 / self.fps
        nxt = time.monotonic()
        while not self._stop.is_set():
            c0 = time.thread_time()
            if self.step():
                self.cpu += time.thread_time() - c0
            nxt += period
            delay = nxt - time.monotonic()
            if delay < -period:
                nxt = time.monotonic()
            self._stop.wait(max(delay, 0.0))

    def start(self) -> View:
        """Start updating the browser from the source in a background thread (daemon)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="rhi-view", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the update thread and the server."""
        self._stop.set()
        if self._thread is not None:  # its update in flight ends before the server does: a daemon thread still
            self._thread.join(timeout=10.0)  # drawing when the interpreter exits can crash it (SIGSEGV, not 143)
        if self._own_server:
            self.server.stop()

    def __enter__(self) -> View:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()
