"""The thesis's comparison in one page: an RHI and its locked NHI side by side under the same hand.

`compare("rhi4", "phantom")` runs each device's live demonstration (`rhi.viz.live.demo_setup`: the
chapter-7 controller and its own 1000 N/m wall 1 cm beyond its own start handle) in its own
`rhi.runtime.run` loop over a `SimLink` — the first in the calling thread, the others in threads —
each under `rhi.viz.session.supervise` (its own pause, reset and fault line). One child process
(`RemoteCompare`) serves one viser page with a `View` per device, side by side along x, each with
its ellipsoids, force read-outs and plots in a folder named after the device. The gizmo is the
first device's hand (`SharedDraggableHand`); every other device's hand (`FollowingHand`) pulls its
handle by the same displacement from its own start, so the difference a user feels is the
difference they see.
"""

from __future__ import annotations

import threading

import numpy as np

from rhi._lifetime import die_with_parent
from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.runtime import SafetyConfig, SimLink, run
from rhi.sim.hand import DraggableHand
from rhi.viz.commands import ViewCommands
from rhi.viz.posed import Posed
from rhi.viz.remote import SharedDraggableHand, SharedTelemetry, ViewProcess

#: free space between two devices in the page, as a fraction of the larger one's size
GAP = 0.3
#: browser updates per second of each device's view (the page's one process draws them all)
FPS = 20.0


class FollowingHand(DraggableHand):
    """A hand that follows another hand's displacement: target = leader's target − x_leader + x_self.

    Args:
        leader: the hand the user moves (e.g. the gizmo's `SharedDraggableHand`); its stiffness, damping and
            saturation are used.
        x_leader: (m,) the leader's reference point (its device's start handle) [m].
        x_self: (m,) this hand's reference point (this device's start handle) [m].
    """

    def __init__(self, leader: DraggableHand, x_leader, x_self) -> None:
        super().__init__(stiffness=leader.stiffness, damping=leader.damping, max_force=leader.max_force)
        self.leader = leader
        self.shift = np.asarray(x_self, dtype=float) - np.asarray(x_leader, dtype=float)
        if self.shift.ndim != 1 or not np.all(np.isfinite(self.shift)):
            raise InvalidInput(f"x_self: expected two finite points (m,), got a shift {self.shift.tolist()}")

    @property
    def target(self) -> np.ndarray | None:
        """(m,) the leader's target moved by `shift` [m], or None while the leader lets go."""
        t = self.leader.target
        return None if t is None else t + self.shift

    @target.setter
    def target(self, x) -> None:
        raise InvalidInput("target: a FollowingHand follows its leader; move the leader's target")


def side_by_side(devices: list[Device], q0s: list[np.ndarray]) -> list[np.ndarray]:
    """Offsets (3,) [m] placing the devices (at q0s) left to right along x, `GAP` of the largest size apart."""
    boxes = []
    for dev, q in zip(devices, q0s):
        p = Posed(dev)
        p.set(q)
        boxes.append(p.bounds())
    gap = GAP * max(float(np.max(hi - lo)) for lo, hi in boxes)
    offsets, x = [], 0.0
    for i, (lo, hi) in enumerate(boxes):
        if i:
            x += gap - float(lo[0])
        offsets.append(np.array([x, 0.0, 0.0]))
        x += float(hi[0])
    return offsets


def _serve(devices, tels, kws, offsets, host: str, port: int, ready, stop) -> None:
    import viser

    from rhi.viz.view import View, aim_camera

    die_with_parent()  # a killed `rhi view --compare` takes its page with it
    server = viser.ViserServer(host=host, port=port, verbose=False)
    server.gui.configure_theme(control_width="medium", show_logo=False)
    telemetries = [SharedTelemetry(*sizes, name=name) for name, sizes in tels]
    views = []
    for i, (dev, tel, kw, off) in enumerate(zip(devices, telemetries, kws, offsets)):
        root = f"/device{i}"
        views.append(View(dev, tel, server=server, root=root, offset=off, **kw))
        lo, hi = views[-1].posed.bounds()
        server.scene.add_label(f"{root}/name", dev.name, position=(0.5 * (lo[0] + hi[0]), float(hi[1]), float(hi[2])))
    boxes = [v.posed.bounds() for v in views]
    lo = np.min([b[0] + off for b, off in zip(boxes, offsets)], axis=0)
    hi = np.max([b[1] + off for b, off in zip(boxes, offsets)], axis=0)
    aim_camera(server, lo, hi, planar=all(set(d.task_axes) <= {"x", "y"} for d in devices))
    for v in views:
        v.start()
    ready.put(int(server.get_port()))
    stop.wait()
    for v, kw in zip(views, kws):
        v.close()
        kw["commands"].close()
        if kw.get("hand") is not None:
            kw["hand"].close()
    server.stop()
    for tel in telemetries:
        tel.close()


class RemoteCompare(ViewProcess):
    """One page with a `View` per device, served from a child process, each fed by its own `SharedTelemetry`.

    Args:
        devices: the devices, drawn left to right.
        q0s: their start configurations (n_i,) [rad].
        hand: the first device's `SharedDraggableHand` (the page's gizmo), or None.
        kws: per device, the `View` options (virtual, fme, fps, ...).
        host, port: where the page is served (port 0: a free port).
        every: publish one tick in `every`.

    Attributes:
        telemetries: per device, the `SharedTelemetry` its loop publishes into.
        commands: per device, its `ViewCommands` (pause, reset, stop, status line).
        port: the page's port.
    """

    def __init__(self, devices: list[Device], q0s: list[np.ndarray], *, hand: SharedDraggableHand | None = None,
                 kws: list[dict] | None = None, host: str = "127.0.0.1", port: int = 8080, every: int = 10) -> None:
        if len(devices) < 2 or len(q0s) != len(devices):
            raise InvalidInput(f"devices: expected two or more devices with a q0 each, got {len(devices)} and "
                               f"{len(q0s)} q0")
        kws = [dict(k) for k in (kws or [{} for _ in devices])]
        self.hand = hand
        self.telemetries = [SharedTelemetry(d.n, d.m, every=every) for d in devices]
        self.commands = [ViewCommands() for _ in devices]
        for i, (kw, q0, cmd) in enumerate(zip(kws, q0s, self.commands)):
            kw.update(q0=q0, commands=cmd, hand=hand if i == 0 else None)
        offsets = side_by_side(devices, q0s)
        tels = [(t.name, t.sizes) for t in self.telemetries]
        self._spawn(_serve, (devices, tels, kws, offsets, host, port), "rhi-compare-view")

    def _shared(self) -> list:
        return [*self.telemetries, *self.commands]


def compare(devices: list[Device], *, duration: float | None = 3600.0, host: str = "127.0.0.1", port: int = 8080,
            on_start=None, say=print, safety: SafetyConfig | None = None) -> list[list]:
    """Run each device's live demonstration side by side in one page, the mouse as every device's hand.

    Args:
        devices: torque-controlled devices, e.g. ``[rhi.device("rhi4"), rhi.device("phantom")]`` (the RHI and its
            NHI, the rhi4 locked at q1 = q2 = 0); the page's gizmo moves the first one's hand.
        duration: run time of each device [s] over all its restarts; None: until Ctrl-C or the page's stop.
        host: the address the page listens on.
        port: the port the page listens on (0: a free port).
        on_start: called with the `RemoteCompare` once it serves.
        say: where the session's lines go (faults, resets), each prefixed with its device's name.
        safety: each device's safety limits (default: `SafetyConfig(range_margin=0.3)`).

    Returns:
        Per device, the `RunResult` of every run.
    """
    from rhi.control.schedule import schedule_of
    from rhi.viz.live import demo_setup
    from rhi.viz.session import supervise

    setups = [demo_setup(d) for d in devices]
    x0 = [d.fk(s[3]) for d, s in zip(devices, setups)]
    lead = SharedDraggableHand(devices[0].m)
    hands: list[DraggableHand] = [lead] + [FollowingHand(lead, x0[0], x) for x in x0[1:]]
    page = RemoteCompare(devices, [s[3] for s in setups], hand=lead, host=host, port=port,
                         kws=[dict(virtual=wall, fme=schedule_of(ctrl.config.objectives), fps=FPS)
                              for _, ctrl, wall, _ in setups])
    results: list[list] = [[] for _ in devices]

    def session(i: int) -> None:
        dev, (plant, ctrl, wall, q0), hand, cmd = devices[i], setups[i], hands[i], page.commands[i]
        links = [SimLink(plant, hand=hand)]
        tell = lambda line: say(f"[{dev.name}] {line}")  # noqa: E731

        def restart() -> None:
            if i == 0:
                lead.target = None
            plant.reset(q0)
            ctrl.reset()
            links[0] = SimLink(plant, hand=hand)

        results[i] = supervise(
            lambda guard, left: run(links[0], ctrl, duration=left, virtual=wall, telemetry=page.telemetries[i],
                                    safety=guard),
            cmd, dev, restart, config=safety or SafetyConfig(range_margin=0.3), duration=duration, say=tell)

    others = [threading.Thread(target=session, args=(i,), daemon=True, name=f"rhi-compare-{i}")
              for i in range(1, len(devices))]
    try:
        if on_start is not None:
            on_start(page)
        for cmd in page.commands:
            cmd.set_status("warming up: loading the controller's compiled kernels …")
        say("rhi view: warming up (the first start compiles the kernels: up to a minute or two) …")
        for _, ctrl, _, _ in setups:
            ctrl.warmup()
        say("rhi view: live")
        for t in others:
            t.start()
        session(0)
    finally:
        for cmd in page.commands:  # the first device's session ended (its duration, Ctrl-C, its stop): all end
            cmd.request_stop()
        page.request_close()  # the page closes while the loops end, not after them
        for t in others:
            if t.is_alive():
                t.join(30)
        page.close()
    return results
