"""The `rhi render` and `rhi view` commands (registered by `rhi.cli`)."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from rhi import cli_args as A
from rhi.cli_device import add_device_options, device_from_args, device_table
from rhi.errors import InvalidInput


def _pick_gl() -> None:
    """Offscreen rendering without a display: MuJoCo's EGL backend unless the user chose one (MUJOCO_GL)."""
    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY") and "mujoco" not in sys.modules:
        os.environ["MUJOCO_GL"] = "egl"


def _render(args: argparse.Namespace) -> int:
    _pick_gl()
    if args.log is not None:
        return _video(args)
    from rhi.viz.posed import rest_configuration
    from rhi.viz.render import render, save_png

    dev = device_from_args(args)
    q = args.q if args.q is not None else rest_configuration(dev)
    img = render(dev, q, width=args.width, height=args.height, azimuth=args.azimuth, elevation=args.elevation)
    print(save_png(img, args.out))
    return 0


def _video(args: argparse.Namespace) -> int:
    from rhi.sim.log import Log
    from rhi.viz.video import render_video

    log = Log.load(args.log)
    if args.device is None and device_table(args) is None:  # the log's own device
        args.device = log.meta.get("device")
    out = args.out if args.out != "device.png" else str(Path(args.log).with_suffix(".mp4"))
    total = [0]

    def progress(i: int, n: int) -> None:
        if i == 1 or i == n or i % 30 == 0:
            print(f"\rrhi render: frame {i}/{n}", end="" if i < n else "\n", file=sys.stderr, flush=True)
        total[0] = n

    path = render_video(device_from_args(args), log, out, fps=args.fps, width=args.width, height=args.height,
                        progress=progress)
    print(f"{path} ({total[0]} frames at {args.fps:g} fps)")
    return 0


def _view(args: argparse.Namespace) -> int:
    from rhi.viz.view import View

    if args.compare is not None:
        return _compare(args)
    dev = device_from_args(args)
    if args.log is not None:
        from rhi.sim.log import Log

        log = Log.load(args.log)
        if log.q.shape[1:] != (dev.n,):
            raise InvalidInput(f"device: the log has {log.q.shape[1]} motors, {dev.name} has {dev.n} (use --device)")
        fme = virtual = None
        if args.config is not None:
            from rhi.control.schedule import schedule_of
            from rhi.runtime.config import load_config

            cfg = load_config(args.config, device_name=dev.name)
            fme, virtual = schedule_of(cfg.controller_config.objectives), cfg.virtual
        view = View(dev, log, host=args.host, port=args.port, fme=fme, virtual=virtual, q0=args.q0)
        print(f"rhi view: {args.log} ({log.t[-1] - log.t[0]:.2f} s) at {view.url}, paused at its start: press "
              "play in the page", flush=True)
        return _serve(view)
    from rhi.devices.mobile_base import BASE_JOINTS
    from rhi.viz.live import live

    if tuple(dev.joint_names[:3]) == BASE_JOINTS:  # velocity-commanded: drawn, not simulated live
        view = View(dev, None, q0=args.q0, host=args.host, port=args.port)
        print(f"rhi view: {dev.name} is velocity-commanded (App. A/B): shown at rest at {view.url} (replay its "
              "logs with `rhi view LOG --device ...`)", flush=True)
        return _serve(view)

    def hello(view) -> None:
        print(f"rhi view: {dev.name} simulated live at 1 kHz at {view.url} (drag the gizmo to push the handle "
              "into the wall; pause and reset in the page; Ctrl-C to stop)", flush=True)

    results = live(dev, duration=args.duration, host=args.host, port=args.port, on_start=hello, q0=args.q0,
                   say=lambda line: print(line, flush=True))
    ticks = sum(r.summary["ticks"] for r in results)
    missed = sum(r.summary["missed"] for r in results)
    print(f"rhi view: {len(results)} run(s), {ticks} ticks, missed deadlines {missed} "
          f"({100.0 * missed / max(ticks, 1):.3f} %)")
    code = results[-1].exit_code
    return code if code > 1 else 0  # a signal's e-stop (Ctrl-C, kill) is the shell's code; a shown fault is not


def _compare(args: argparse.Namespace) -> int:
    import rhi
    from rhi.viz.compare import compare

    if args.log is not None or len(args.compare) < 2:
        raise InvalidInput("--compare: expected two or more device names and no log, e.g. --compare rhi4 phantom")
    devices = [rhi.device(name) for name in args.compare]

    def hello(page) -> None:
        print(f"rhi view: {', '.join(d.name for d in devices)} side by side at {page.url} (the gizmo is the hand "
              f"of all of them; Ctrl-C to stop)", flush=True)

    results = compare(devices, duration=args.duration, host=args.host, port=args.port, on_start=hello,
                      say=lambda line: print(line, flush=True))
    for dev, runs in zip(devices, results):
        print(f"rhi view: {dev.name}: {len(runs)} run(s), {sum(r.summary['ticks'] for r in runs)} ticks, missed "
              f"deadlines {sum(r.summary['missed'] for r in runs)}")
    # the first device's loop runs in this thread and takes the signals: a kill's e-stop is the shell's code
    code = results[0][-1].exit_code if results[0] else 0
    return code if code > 1 else 0


def _serve(view) -> int:
    from rhi._lifetime import STOP_SIGNALS

    view.start()
    try:  # until Ctrl-C or a signal: the `rhi` command answers it with the shell's code (130, 143), as a live view
        while not STOP_SIGNALS:
            time.sleep(0.2)
        raise KeyboardInterrupt(STOP_SIGNALS[0])  # a signal whose KeyboardInterrupt was lost ends it too
    finally:
        view.close()


def attach_view(cfg, controller, link, *, port: int = 8080, mouse: bool = False, loop_cpu: int | None = None):
    """A `RemoteView` (its own process) of a `rhi run` configuration; give `run` its `telemetry`.

    With `mouse`, the simulated link's hand becomes a `SharedDraggableHand` moved by the browser's gizmo.
    With `loop_cpu` (the control loop's CPU), the view runs on the other CPUs.
    """
    from rhi.control.schedule import schedule_of
    from rhi.viz.remote import RemoteView, SharedDraggableHand

    hand = None
    if mouse:
        if not hasattr(link, "hand"):
            raise InvalidInput("--mouse: only a simulated link (--link sim) has a hand to move")
        hand = link.hand = SharedDraggableHand(cfg.device.m)
    others = None if loop_cpu is None else set(os.sched_getaffinity(0)) - {loop_cpu}
    view = RemoteView(cfg.device, hand=hand, virtual=cfg.virtual, fme=schedule_of(cfg.controller_config.objectives),
                      q0=cfg.sim["q0"], port=port, cpus=others or None)
    print(f"rhi run: view at {view.url}", flush=True)
    return view


def add_commands(sub, floats) -> None:
    """Add `render` and `view` to the `rhi` argument parser's subcommands."""
    r = sub.add_parser("render", help="render a device with MuJoCo's offscreen renderer to a PNG, or a run's log to an "
                                      "MP4 video (MUJOCO_GL)")
    add_device_options(r)
    r.add_argument("--log", help="a run's log (.rhilog or .csv): write its video with the forces and the wall drawn, "
                                 "e.g. rhi render --log run.rhilog -o run.mp4 (device: the log's)")
    r.add_argument("--fps", type=float, default=30.0, help="video frames per second (default: 30)")
    r.add_argument("--q", type=floats, help="configuration [rad] (default: mid-range)")
    r.add_argument("-o", "--out", default="device.png", help="output PNG (default: device.png), or MP4 with --log "
                                                              "(default: the log's name)")
    r.add_argument("--width", type=A.pixels, default=640)
    r.add_argument("--height", type=A.pixels, default=480)
    r.add_argument("--azimuth", type=A.finite, help="camera azimuth [deg]")
    r.add_argument("--elevation", type=A.elevation, help="camera elevation [deg]")
    r.set_defaults(func=_render)
    v = sub.add_parser("view", help="the device live in the browser (viser): replay a log, or simulate it with the "
                                    "mouse as the hand")
    v.add_argument("log", nargs="?", help="a saved log (.rhilog or .csv) to replay; none: a live simulation")
    add_device_options(v, positional=False, default="rhi4")
    v.add_argument("--host", type=A.host, default="127.0.0.1")
    v.add_argument("--port", type=A.port, default=8080)
    v.add_argument("--duration", type=A.duration, default=3600.0, help="live simulation length [s]")
    v.add_argument("--config", help="replay: the run configuration whose environment and desired FME to draw "
                                    "(default: the environment stored in the log)")
    v.add_argument("--q0", type=floats, help="start configuration [rad] (default: mid-range, bent where that is "
                                             "singular: rhi.viz.posed.rest_configuration)")
    v.add_argument("--compare", nargs="+", metavar="DEVICE", help="devices side by side in one page under the same "
                   "hand, e.g. --compare rhi4 phantom (the RHI and its locked NHI)")
    v.set_defaults(func=_view)
