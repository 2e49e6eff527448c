"""The `rhi` command: list devices, measure a configuration, run one experiment, reproduce the thesis."""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np

from rhi import __version__, cli_args as A, cli_help, plugins
from rhi._lifetime import STOP_SIGNALS
from rhi._validate import parent_made, writable_file
from rhi.cli_device import add_device_options, device_from_args, device_table
from rhi.cli_identify import add_commands as add_identify_command
from rhi.cli_link import NO_CONTROLLER, Status as _Status, add_realtime as _add_realtime, link as _link
from rhi.cli_log import add_commands as add_log_commands
from rhi.cli_study import add_commands as add_study_commands
from rhi.cli_warmup import add_commands as add_warmup_command
from rhi.devices.measures import all_measures
from rhi.devices.model import available_devices, device
from rhi.errors import InvalidInput, RhiError
from rhi.viz.cli import add_commands


def _param(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}") from None


def _devices(args: argparse.Namespace) -> int:
    if args.descriptions:
        from rhi.devices.loaders import available_descriptions

        found = available_descriptions()
        if not found:
            print("no description package installed (pip install example-robot-data)")
        for name, path in found.items():
            print(f"{name:<60} {path}")
        return 0
    print(f"{'name':<12} {'n':>2} {'task':<5} parameters")
    bundled = available_devices()
    for name in bundled + [n for n in plugins.names("rhi.devices") if n not in bundled]:  # then the plugins'
        where = "" if name in bundled else f"plugin: {plugins.provider('rhi.devices', name)}"
        try:
            d = device(name)
        except RhiError as exc:  # a broken plugin is listed, with why
            print(f"{name:<12} {'?':>2} {'?':<5} {where}: {exc}")
            continue
        params = ", ".join(f"{k}={v:g}" for k, v in d.params.items())
        print(f"{name:<12} {d.n:>2} {d.task_axes:<5} {params or where}")
    return 0


def _measure(args: argparse.Namespace) -> int:
    dev = device_from_args(args, dict(args.param or []))
    res = all_measures(dev, args.q, args.u)
    if args.json:
        print(json.dumps(res, indent=1))
        return 0
    for k, v in res.items():
        if isinstance(v, list):
            v = np.array2string(np.asarray(v), precision=5, suppress_small=True).replace("\n", "\n" + " " * 46)
        elif isinstance(v, float):
            v = f"{v:.6g}"
        elif v is None:
            v = "— (undefined: J is singular)"
        print(f"{k:<45} {v}")
    return 0


def _reproduce(args: argparse.Namespace) -> int:
    from rhi.design.executors import configure

    name = getattr(args, "name", None)
    out = args.out or (str(Path("out") / name) if name else "out")
    # first: a bad executor argument (a Ray address where nothing answers) fails before the experiments load
    configure(executor=args.executor, address=args.address, workers=args.workers,
              checkpoint_dir=str(Path(out) / "checkpoints" / ("quick" if args.quick else "full")))  # one problem per file
    from rhi.report.reproduce import reproduce
    from rhi.report.steps import describe

    if getattr(args, "list", False) or (args.command == "experiment" and not args.name):
        print("\n".join(f"{name:<34} {what}" for name, what in describe()))
        return 0
    path, results = reproduce(out, only=getattr(args, "only", None), quick=args.quick, experiment=name,
                              jobs=getattr(args, "jobs", None))
    for res in results:
        for table in res.tables:
            print(f"\n{res.name}: {table.title}")
            for r in table.rows:
                th = "—" if r.thesis is None else f"{r.thesis:.4g}"
                rel = "" if r.relative is None else f"({100 * r.relative:+.1f} %)"
                print(f"  {r.quantity:<55} thesis {th:>9}   rhi {r.ours:>9.4g} {r.unit:<4} {rel}")
    print(f"\nreport: {path}\nnumbers: {path.parent / 'results.json'}\narrays: {path.parent / 'results.npz'}")
    return 0


def _fidelity(args: argparse.Namespace) -> int:
    from rhi.report.fidelity import rejudge

    text, tally = rejudge(args.runs)
    if args.to:
        Path(args.to).write_text(text)
    print(tally if args.to else text)
    return 0


def _device_server(args: argparse.Namespace) -> int:
    from rhi.runtime import SimLink
    from rhi.runtime.server import DeviceServer
    from rhi.sim import Plant

    if args.config is not None:  # the device side of a run configuration: its [sim] start, hand and world
        cfg = _config(args, defaults=NO_CONTROLLER)
        dev, link = cfg.device, cfg.sim_link(rate=args.rate)
        if args.q0 is not None:
            link.plant.reset(args.q0)
    else:
        dev = device_from_args(args)
        plant = Plant(dev)
        lo, hi = dev.joint_limits
        plant.reset(args.q0 if args.q0 is not None else np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), 0.0))
        link = SimLink(plant, rate=args.rate)
    srv = DeviceServer(link, dev, host=args.host, port=args.port,
                       watchdog=args.watchdog_ms * 1e-3, lockstep=args.lockstep, log=args.log, cpu=args.cpu,
                       priority=args.priority, spin=args.spin, cpu_latency=args.cpu_latency)
    signal.signal(signal.SIGTERM, lambda *_: srv.stop())
    signal.signal(signal.SIGINT, lambda *_: srv.stop())
    print(f"rhi device-server: {dev.name} (simulated, {args.rate:g} Hz) on udp://{args.host}:{srv.port}, "
          f"watchdog {args.watchdog_ms:g} ms{', lockstep' if args.lockstep else ''}", flush=True)
    stats = srv.serve(args.duration)
    print(json.dumps(stats), flush=True)
    return 0


def _config(args: argparse.Namespace, defaults: dict | None = None):
    """The run configuration of `--config`, on the device of the command line (a name or a source option)."""
    from rhi.runtime.config import load_config

    table = device_table(args)
    return load_config(args.config, device_name=args.device if table is None else None, device=table,
                       defaults=defaults)


# ------------------------------------------------------------------------------------------ rhi run
def _run(args: argparse.Namespace) -> int:
    from rhi.runtime import run

    if args.mouse and not args.view:
        raise InvalidInput("--mouse: the mouse moves the hand in the browser view; add --view")
    cfg = _config(args)
    rate = args.rate or cfg.rate
    duration = args.duration if args.duration is not None else cfg.duration
    link = _link(args.link, rate, cfg, args.realtime, args.spin, args.device_name, args.takeover)
    out = Path("out") / time.strftime("run-%Y%m%d-%H%M%S")
    log_path = Path(args.log) if args.log else out / "run.rhilog"
    summary_path = Path(args.summary) if args.summary else (log_path.parent if args.log else out) / "summary.json"
    writable_file("--log", log_path)  # before the run, not at its end
    writable_file("--summary", summary_path)
    about = {"name": cfg.name, "source": cfg.source, "device": cfg.device.name, "link": args.link}
    parent_made(summary_path).write_text(json.dumps({"config": about, "log": str(log_path), "running": True}, indent=1))
    print(f"rhi run: {cfg.name} on {cfg.device.name} over {args.link} at {rate:g} Hz, "
          f"{'until Ctrl-C' if duration is None else f'{duration:g} s'}"
          f"{'' if args.realtime else ' (as fast as possible)'}", flush=True)
    status = _Status(sys.stderr, duration)
    ctrl = cfg.controller()
    view = None
    if args.view:
        from rhi.viz.cli import attach_view

        view = attach_view(cfg, ctrl, link, port=args.view_port, mouse=args.mouse, loop_cpu=args.cpu)
    def once(safety, left, path=log_path):
        return run(link, ctrl, rate=rate, duration=left, safety=safety, log=path, virtual=cfg.virtual,
                   realtime=args.realtime, progress=status, telemetry=None if view is None else view.telemetry,
                   cpu=args.cpu, priority=args.priority, spin=args.spin, cpu_latency=args.cpu_latency)

    try:
        if view is None:
            res = once(cfg.safety, duration)
        else:  # faults shown in the page and reset there, pause and resume: one log per run
            from rhi.viz.session import supervise

            def restart() -> None:
                nonlocal link
                link = _link(args.link, rate, cfg, args.realtime, args.spin)
                if args.mouse:
                    view.hand.target = None
                    link.hand = view.hand
                ctrl.reset()

            runs = [0]

            def supervised(guard, left):
                runs[0] += 1
                k = runs[0]
                return once(guard, left, log_path if k == 1 else log_path.with_suffix(f".{k}.rhilog"))

            results = supervise(supervised, view.commands, cfg.device, restart, config=cfg.safety,
                                duration=duration, say=lambda line: print(line, file=sys.stderr, flush=True))
            res = results[-1]
            if len(results) > 1:
                print(f"rhi run: {len(results)} runs under the view; the last one's log and summary follow",
                      flush=True)
                log_path = log_path.with_suffix(f".{len(results)}.rhilog")
    finally:
        status.close()
        if view is not None:
            view.close()
    s = res.summary
    s["config"] = about
    s["log"] = str(log_path)
    if hasattr(link, "stats"):
        s["link_stats"] = dict(link.stats)
    summary_path.write_text(json.dumps(s, indent=1, default=float))
    us = lambda d: f"p50 {1e6 * d['p50']:.0f}  p99 {1e6 * d['p99']:.0f}  max {1e6 * d['max']:.0f} µs"  # noqa: E731
    print(f"{s['ticks']} ticks in {s['duration']:.2f} s ({s['rate_reached']:.1f} Hz reached of {rate:g}); "
          f"missed deadlines {s['missed']} ({s['missed_pct']:.3f} %); device readings skipped {s['skipped_readings']} "
          f"({s['skipped_readings_pct']:.3f} %); tick {us(s['tick'])}; torques clamped {s['clamped']}")
    if math.isfinite(s["round_trip"]["max"]):
        print(f"round-trip age {us(s['round_trip'])}")
    print(f"log: {log_path}\nsummary: {summary_path}")
    if res.fault is not None:
        print(f"rhi run: fault ({s['fault_kind']}): {res.fault}", file=sys.stderr)
    return res.exit_code


def _add_run(sub) -> None:
    shipped = sorted(p.stem for p in (Path(__file__).parent / "runtime" / "configs").glob("*.toml"))  # no heavy import
    r = sub.add_parser("run", help="run a controller described by a configuration file on a device, in real time")
    add_device_options(r)
    r.add_argument("--link", default="sim", help="sim (the configuration's simulated device), udp://HOST:PORT "
                   "(a device server, e.g. `rhi device-server`) or an installed plugin's scheme (rhi.links)")
    r.add_argument("--config", required=True,
                   help=f"a TOML file or a shipped configuration: {', '.join(shipped)}")
    r.add_argument("--duration", type=A.duration, help="run time [s] (default: the configuration's, else until Ctrl-C)")
    r.add_argument("--rate", type=A.rate, help="control rate [Hz] (default: the configuration's, else 1000)")
    r.add_argument("--log", help="streamed log (.rhilog; default out/run-<timestamp>/run.rhilog)")
    r.add_argument("--summary", help="JSON summary (default: summary.json beside the log)")
    r.add_argument("--device-name", help="accept a device whose INFO calls it this (default: the configuration's "
                   "device name)")
    r.add_argument("--takeover", action="store_true", help="take the device over from another host's active session")
    r.add_argument("--realtime", action=argparse.BooleanOptionalAction, default=True,
                   help="pace ticks on the wall clock (default); --no-realtime runs as fast as possible")
    r.add_argument("--fast", dest="realtime", action="store_false", help="same as --no-realtime")
    r.add_argument("--view", action="store_true", help="watch the run live in the browser (viser)")
    r.add_argument("--view-port", type=A.port, default=8080, help="port of the browser view (default: 8080)")
    r.add_argument("--mouse", action="store_true", help="with --view and the sim link: the mouse is the hand "
                   "(drag the gizmo at the handle) instead of the configuration's hand")
    _add_realtime(r, "the control loop")
    r.set_defaults(func=_run)


_NEGATIVE = re.compile(r"^-(\d|\.\d)")


def _join_negative(argv: list[str]) -> list[str]:
    """`--q -0.5,0.2` → `--q=-0.5,0.2` (argparse takes a leading '-' for an option)."""
    out: list[str] = []
    for tok in argv:
        if out and out[-1].startswith("--") and "=" not in out[-1] and _NEGATIVE.match(tok):
            out[-1] = f"{out[-1]}={tok}"
        else:
            out.append(tok)
    return out


_EXTRAS = {"mujoco": "sim", "psignifit": "analysis", "statsmodels": "analysis", "matplotlib": "plots", "viser": "view",
           "mcap": "logs", "pyarrow": "logs", "PIL": "sim"}
"""The optional dependencies and the extra that installs each (pyproject.toml)."""
_NEEDS_ALL = ("reproduce", "experiment", "fidelity")
"""Commands that need every extra: their error names rhi[all] at once, not one missing extra after another."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `rhi` command."""
    os.environ.setdefault("MPLBACKEND", "Agg")  # this process only writes figures to files
    p = A.Parser(prog="rhi", description=__doc__)
    p.add_argument("--version", action="version", version=f"rhi {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    ds = sub.add_parser("devices", help="list the bundled devices")
    ds.add_argument("--descriptions", action="store_true", help="list the robots of the installed description "
                    "packages instead (each works as --description NAME)")
    ds.set_defaults(func=_devices)
    m = sub.add_parser("measure", help="print every measure of a device at a configuration")
    add_device_options(m)
    m.add_argument("--q", type=A.floats, required=True, help="configuration [rad], e.g. 0.125,0.022,0.298,0.175")
    m.add_argument("--u", type=A.floats, help="direction for directional measures, e.g. 0,1")
    m.add_argument("--param", type=_param, action="append", help="design parameter NAME=VALUE, e.g. d2=0.1405")
    m.add_argument("--json", action="store_true", help="print JSON")
    m.set_defaults(func=_measure)
    r = sub.add_parser("reproduce", help="reproduce the thesis's computational tables and figures into a report")
    r.add_argument("--only", help="one chapter, e.g. ch3")
    r.add_argument("--jobs", type=A.count, help="experiments run at once, each in its own process (default: CPU count; "
                   "1: one after the other, with per-experiment progress bars)")
    e = sub.add_parser("experiment", help="run one experiment: PNG figures, CSV/JSON numbers, thesis beside ours")
    e.add_argument("name", nargs="?", help="experiment id (its result's name), e.g. ch7.example_3dof (none: list them)")
    e.add_argument("--list", action="store_true", help="list the experiments")
    for q in (r, e):
        q.add_argument("--quick", action="store_true", help="reduced resolution (seconds)")
        q.add_argument("--out", help="output directory (default: out, or out/<experiment> for one experiment)")
        q.add_argument("--executor", choices=("local", "serial", "ray"), default="local",
                       help="where design evaluations run: local process pool (default), this process, or Ray")
        q.add_argument("--address", help="Ray cluster address for --executor ray (default: start a local instance)")
        q.add_argument("--workers", type=A.count, help="processes of the local pool (default: CPU count)")
        q.set_defaults(func=_reproduce)
    f = sub.add_parser("fidelity", help="judge the headline claims of reproduction runs again and write their dossiers")
    f.add_argument("runs", nargs="+", help="output folders of `rhi reproduce` (their results.json; later ones win)")
    f.add_argument("--to", help="write the dossiers' Markdown here (e.g. docs/fidelity.md) instead of printing it")
    f.set_defaults(func=_fidelity)
    d = sub.add_parser("device-server", help="serve a simulated device over UDP (the protocol of docs/protocol.md)")
    add_device_options(d)
    d.add_argument("--port", type=A.port, default=5005, help="UDP port (0: any free port; default 5005)")
    d.add_argument("--host", type=A.host, default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    d.add_argument("--rate", type=A.rate, default=1000.0, help="device rate [Hz] (default 1000)")
    d.add_argument("--watchdog-ms", type=A.watchdog_ms, default=20.0, help="zero torque after this long without a command")
    d.add_argument("--lockstep", action="store_true", help="wait for each command (bit-exact simulation)")
    d.add_argument("--config", help="a run configuration whose [sim] start, hand and physical world the device uses")
    d.add_argument("--q0", type=A.floats, help="start configuration [rad] (default: the configuration's, else mid-range)")
    d.add_argument("--log", help="device-side log (.rhilog)")
    d.add_argument("--duration", type=A.duration, help="stop after this much device time [s]")
    _add_realtime(d, "the device loop")
    d.set_defaults(func=_device_server)
    _add_run(sub)
    add_commands(sub, A.floats)
    add_log_commands(sub)
    add_study_commands(sub)
    add_warmup_command(sub)
    add_identify_command(sub)
    cli_help.finish(p)
    args = p.parse_args(_join_negative(sys.argv[1:] if argv is None else list(argv)))
    previous = _interrupt_on_signals()
    try:
        return args.func(args)
    except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM or SIGHUP outside a run's loop (which makes them an e-stop)
        name = str(exc) or "SIGINT"
        print(f"rhi: stopped by {name}", file=sys.stderr)
        return 128 + int(getattr(signal, name, signal.SIGINT))
    except RhiError as exc:
        print(f"rhi: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        extra = _EXTRAS.get((exc.name or "").split(".")[0])
        if extra is None:
            raise
        need = "'rhi[all]'" if args.command in _NEEDS_ALL else f"'rhi[{extra}]' (or 'rhi[all]')"  # all at once
        print(f"rhi: error: this command needs {exc.name}: pip install {need}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        STOP_SIGNALS.clear()


def _interrupt_on_signals() -> dict:
    """SIGTERM and SIGHUP stop the command as Ctrl-C does (its cleanup runs); {signal: previous handler}."""
    def interrupt(num, _frame):
        STOP_SIGNALS.append(signal.Signals(num).name)  # kept where the KeyboardInterrupt is lost (rhi._lifetime)
        raise KeyboardInterrupt(signal.Signals(num).name)

    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.signal(sig, interrupt) for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)) if sig}


if __name__ == "__main__":
    sys.exit(main())
