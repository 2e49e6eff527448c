"""The device side of a live study: every probe or run in the runtime loop, on its own log, one at a time.

Each condition's controller comes from its run configuration (`rhi.runtime.config`; a condition without one
renders through ``ForceRendering`` with no null-space task, the §3.5 NHIs). A probe renders a one-sided spring
of the sample's stiffness from the fixture's point along its direction plus the virtual fixture (`rhi.sim.Wall`
+ `rhi.sim.Fixture`); a path-following run renders nothing but the controller, and a simulated slave robot
follows the master by teleoperation (`rhi.study.slave`; its position is logged as ``slave_x``). The loop is
`rhi.runtime.run` in a thread of its own (zero torque and a log whatever ends it), stopped by an event when the
participant moves on. The link: ``sim`` — a fresh MuJoCo plant at the start point per probe, the physical
obstacle as a stop, and as the hand either the simulated one (a minimum-jerk stroke, or the W path mapped into
the master's frame) or, for a dry run, the mouse (`rhi.sim.DraggableHand`, its target set from the
experimenter's page, or for path following from the participant's canvas); or ``udp://HOST:PORT`` — a device
process (`rhi device-server` or a lab's driver), whose obstacle is physical. With a teleoperated slave either
link is wrapped in `rhi.runtime.teleoperated.Teleoperated`: the slave is simulated here and follows the device's
handle (start a device process where the map sends it onto the path's first point).
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np

from rhi.control import NullSpaceController
from rhi.errors import InvalidInput
from rhi.runtime.config import RunConfig, load_config, parse_config
from rhi.study import slave as sl
from rhi.study.protocol import Condition, Protocol

_RENDERING = {"controller": {"primary": {"law": "force_rendering", "damping": 0.0, "passivity": "off"},
                             "damping": 0.0, "saturation": "none"}}


def condition_config(c: Condition) -> RunConfig:
    """The run configuration of condition `c` (its ``config``, else force rendering without a null-space task)."""
    if c.config is not None:
        cfg = load_config(c.config, device_name=c.device)
        if c.params and any(abs(cfg.device.params.get(k, np.nan) - v) > 1e-12 for k, v in c.params.items()):
            raise InvalidInput(f"conditions.{c.name}.params: {c.params} differ from {c.config}'s device "
                               f"parameters {cfg.device.params}")
        return cfg
    data = {"device": {"name": c.device, "params": dict(c.params)}, **_RENDERING}
    return parse_config(data, name=f"{c.name}-rendering", device_name=c.device)


class Haptics:
    """One device loop at a time for a live study (see the module docstring).

    Args:
        protocol: the study protocol.
        link: "sim" or "udp://HOST:PORT".
        rate: control rate [Hz].
        mouse: with "sim", the mouse is the hand (`hand_target`).

    Raises:
        InvalidInput: a bad link, the mouse on a real device, a condition whose configuration fails.
    """

    def __init__(self, protocol: Protocol, link: str, *, rate: float = 1000.0, mouse: bool = False) -> None:
        if link != "sim" and not link.startswith("udp://"):
            raise InvalidInput(f"link: expected sim or udp://HOST:PORT, got {link!r}")
        if mouse and link != "sim":
            raise InvalidInput("mouse: the mouse is the hand of the simulated device only (--link sim)")
        if link != "sim":
            from rhi.runtime.udp import parse_url

            self._address = parse_url(link)
        self.protocol, self.link, self.rate, self.mouse = protocol, link, float(rate), mouse
        self.configs = {c.name: condition_config(c) for c in protocol.conditions}
        self.slave = None if protocol.teleoperation is None else sl.slave_device(protocol)
        if self.slave is not None and self.slave.m != len(protocol.task["center"]):
            raise InvalidInput(f"teleoperation.slave: {self.slave.name} moves in {self.slave.m} axes, the path in "
                               f"{len(protocol.task['center'])} (task.center)")
        fx = protocol.fixture
        self.start_point: np.ndarray | None = None if fx is None else np.asarray(fx["point"], float)
        self.direction: np.ndarray = np.zeros(0) if fx is None else \
            np.asarray(fx["direction"], float) / np.linalg.norm(fx["direction"])
        self.status: dict[str, Any] = {}
        self.last: dict[str, Any] | None = None
        self._thread: threading.Thread | None = None
        self._until = threading.Event()
        self._hand: Any = None
        self._lock = threading.Lock()
        self.telemetry: Any = None

    # ------------------------------------------------------------------ environment
    def virtual(self, stiffness: float | None):
        """The rendered environment of a probe of `stiffness` [N/m] (None: the fixture alone, or nothing)."""
        from rhi.sim import Fixture, Wall, compose

        fx = self.protocol.fixture
        if fx is None or self.start_point is None:
            return None
        fixture = Fixture(self.start_point, self.direction, fx["stiffness"], fx["damping"])
        return fixture if stiffness is None else compose(Wall(self.start_point, self.direction, stiffness), fixture)

    def _sim_link(self, cfg: RunConfig):
        from rhi.runtime import SimLink
        from rhi.sim import Hand, MinimumJerkPalpation, Plant, stop
        from rhi.sim.hand import DraggableHand

        dev, s, task = cfg.device, cfg.sim, self.protocol.task
        plant = Plant(dev, friction=s["friction"], timestep=s["timestep"], handle_mass=s["handle_mass"])
        q0 = np.asarray(s["q0"], float)
        goal = self.start_point if self.start_point is not None else sl.master_path(self.protocol).points[0]
        if np.linalg.norm(dev.fk(q0) - goal) > 1e-3:
            q0 = dev.ik(goal, np.full(dev.n, 0.3))
        plant.reset(q0)
        physical = None
        ob = self.protocol.obstacle
        if ob is not None:
            physical = stop(self.start_point + ob["distance"] * self.direction, self.direction,
                            stiffness=ob["stiffness"], damping=ob["damping"])
        hand: Any
        if self.mouse:
            hand = DraggableHand()
            hand.target = goal
        elif task["kind"] == "discrimination_2afc" and self.start_point is not None:
            depth = (ob["distance"] if ob is not None else 0.08) + 0.01
            hand = MinimumJerkPalpation(self.start_point, self.direction, depth, task["stroke_time"])
        else:
            hand = Hand(sl.master_path(self.protocol))
        self._hand = hand
        return SimLink(plant, rate=self.rate, hand=hand, physical=physical)

    def hand_target(self, depth: float) -> None:
        """Dry run: move the mouse-hand's target `depth` [m] along the fixture's direction from the start point.

        Raises:
            InvalidInput: not a mouse dry run, or a depth that is not finite.
        """
        if not self.mouse or self.start_point is None:
            raise InvalidInput("hand: the mouse is the hand only in a dry run (--mouse) of a task with a fixture")
        if not np.isfinite(depth) or abs(depth) > 0.5:
            raise InvalidInput(f"depth: expected a finite offset within 0.5 m, got {depth!r}")
        self._grip(self.start_point + float(depth) * self.direction)

    def hand_point(self, point) -> None:
        """Dry run of path following: the mouse-hand pulls the master to where the map sends the slave to `point`.

        Args:
            point: (m,) the pointer in the slave's frame, the participant's canvas [m].

        Raises:
            InvalidInput: not a mouse dry run of a path-following task, or a point that is not (m,) finite values
                within 1 m of the path's centre.
        """
        if not self.mouse or self.slave is None:
            raise InvalidInput("hand: the mouse drives the master only in a dry run (--mouse) of a path-following task")
        c = np.asarray(self.protocol.task["center"], float)
        try:
            x = np.asarray(point, dtype=float)
        except (TypeError, ValueError):
            x = np.full(1, np.nan)
        if x.shape != c.shape or not np.isfinite(x).all() or np.linalg.norm(x - c) > 1.0:
            raise InvalidInput(f"point: expected {len(c)} finite coordinates within 1 m of task.center, got {point!r}")
        self._grip(sl.to_master(self.protocol, x))

    def _grip(self, target: np.ndarray) -> None:
        with self._lock:
            if self._hand is not None:
                self._hand.target = target

    # ------------------------------------------------------------------ the loop
    @property
    def running(self) -> bool:
        """A probe or run is in progress."""
        return self._thread is not None and self._thread.is_alive()

    def start(self, condition: str, log: Path, stiffness: float | None = None) -> None:
        """Start rendering condition `condition` (a probe of `stiffness` [N/m], or a run), logging to `log`.

        Raises:
            InvalidInput: another probe still running, an unknown condition.
        """
        if self.running:
            raise InvalidInput("haptics: a probe is still running; stop it first")
        if condition not in self.configs:
            raise InvalidInput(f"condition: {condition!r} is not one of {sorted(self.configs)}")
        cfg = self.configs[condition]
        tele = None if self.slave is None else sl.teleoperation(self.protocol, self.slave)
        controller = cfg.controller() if tele is None else \
            NullSpaceController(cfg.device, sl.live_tmi(cfg.controller_config, tele))
        if self.link == "sim":
            link = self._sim_link(cfg)
        else:
            from rhi.runtime.udp import UDPLink

            link = UDPLink(*self._address, rate=self.rate, connect_timeout=10.0)  # the device process may be starting
        if tele is not None:
            from rhi.runtime.teleoperated import Teleoperated

            link = Teleoperated(link, cfg.device, tele, rate=self.rate)
        limit = self.protocol.task.get("probe_time") or self.protocol.task.get("time_limit")
        from rhi.sim.telemetry import Telemetry

        self._until = threading.Event()
        self.telemetry = Telemetry(every=max(1, int(self.rate // 50)))
        self.status = {"condition": condition, "t": 0.0, "ticks": 0, "missed": 0, "fault": None}
        self._thread = threading.Thread(target=self._run, args=(cfg, controller, link, log, stiffness, limit,
                                                                 self._until),
                                        name="rhi-study-probe", daemon=True)
        self._thread.start()

    def _run(self, cfg: RunConfig, controller, link, log: Path, stiffness, limit, until: threading.Event) -> None:
        from rhi.runtime import run

        def progress(s: dict) -> None:
            self.status = {**self.status, **s}

        try:
            res = run(link, controller, rate=self.rate, duration=limit, safety=cfg.safety, log=log,
                      virtual=self.virtual(stiffness), progress=progress, until=until, telemetry=self.telemetry)
            self.last = {**res.summary, "log": str(log)}
            self.status = {**self.status, "fault": res.summary["fault"], "ticks": res.summary["ticks"]}
        except Exception as exc:  # noqa: BLE001 - shown to the experimenter, never a crash of the pages
            self.last = {"fault": f"{type(exc).__name__}: {exc}", "log": str(log)}
            self.status = {**self.status, "fault": self.last["fault"]}

    def state(self) -> dict[str, Any]:
        """The newest tick of the probe in progress.

        Keys: x [m], F_env [N], τ [N m], the slave's slave_x [m] if any, and in a mouse dry run hand [m], the point
        the mouse-hand pulls the handle to.
        """
        snap = None if self.telemetry is None or not self.running else self.telemetry.latest()
        if snap is None:
            return {}
        out = {"x": np.asarray(snap.x).tolist(), "F_env": np.asarray(snap.F_env).tolist(),
               "tau": np.asarray(snap.tau).tolist(), "safety": snap.safety}
        if hasattr(snap, "slave_x"):
            out["slave_x"] = np.asarray(snap.slave_x).tolist()
        target = getattr(self._hand, "target", None) if self.mouse else None
        if target is not None:
            out["hand"] = np.asarray(target).tolist()
        return out

    def stop(self) -> dict[str, Any] | None:
        """End the probe in progress (zero torque, log closed); returns its summary (None if none ran)."""
        self._until.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
            self._thread = None
        return self.last


__all__ = ["Haptics", "condition_config"]
