"""The `rhi identify` command: joint friction and M_x of a device through the runtime (registered by `rhi.cli`).

It runs `rhi.analysis.sysid.on_device.identify_device` over `--link` and writes, into `--out`:
``identify.rhilog`` (the run), ``identification.json`` (values, intervals, R², residual RMS, the programme as run)
and ``friction.toml`` (the ``[plant]`` table of a ``device.toml``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tomllib
from pathlib import Path

from rhi import cli_args as A
from rhi._validate import writable_file
from rhi.cli_device import add_device_options, device_table
from rhi.cli_link import NO_CONTROLLER, Status, add_realtime, link as link_from
from rhi.errors import InvalidInput

_EXAMPLE = """example:
  rhi device-server rhi4 --q0 1.2566,0.3754,-0.0983,0.8113 --port 5005 &   # or your device's own server
  rhi identify rhi4 --link udp://127.0.0.1:5005 --config ch6_fme_aso --out out/ident
  rhi identify rhi4 --link sim --config ch6_fme_aso --trials 5          # the simulated plant, in this process
"""


def _identify(args: argparse.Namespace) -> int:
    import numpy as np

    from rhi.analysis.sysid.excitation import Programme
    from rhi.analysis.sysid.on_device import identify_device
    from rhi.runtime.config import load_config, parse_config
    from rhi.runtime.simlink import SimLink
    from rhi.sim import Plant

    table = device_table(args)
    name = args.device if table is None else None
    if args.config is not None:
        cfg = load_config(args.config, device_name=name, device=table, defaults=NO_CONTROLLER)
    elif table is None and args.device is None:
        raise InvalidInput("device: give a bundled device (rhi devices) or --urdf, --mjcf or --description")
    else:
        cfg = parse_config(NO_CONTROLLER, name="identify", device_name=name, device=table)
    dev = cfg.device
    u = np.asarray(args.direction, dtype=float).reshape(-1)
    if u.shape != (dev.m,) or not np.linalg.norm(u) > 0:
        raise InvalidInput(f"--direction: expected {dev.m} numbers, not all zero, for {dev.name}'s task "
                           f"({''.join(dev.task_axes)}), got {args.direction}")
    q0 = args.q0
    if q0 is None and args.config is not None and "q0" in tomllib.loads(Path(cfg.source).read_text()).get("sim", {}):
        q0 = cfg.sim["q0"]  # the configuration's start is the hold configuration
    if q0 is not None and np.asarray(q0, dtype=float).reshape(-1).shape != (dev.n,):
        raise InvalidInput(f"--q0: expected {dev.n} numbers for {dev.name}, got {q0}")
    try:
        programme = Programme(trials=args.trials, seed=args.seed)
    except InvalidInput as exc:
        raise InvalidInput(f"--{exc}") from None
    rate = args.rate or cfg.rate
    out = Path(args.out) if args.out else Path("out") / time.strftime("identify-%Y%m%d-%H%M%S")
    for name in ("identify.rhilog", "identification.json", "friction.toml"):
        writable_file("--out", out / name)
    if args.link == "sim":  # the configuration's plant (its friction, start), without its hand or world
        s = cfg.sim
        plant = Plant(dev, friction=s["friction"], timestep=s["timestep"], handle_mass=s["handle_mass"])
        plant.reset(s["q0"], s["dq0"])
        link = SimLink(plant, rate=rate)
    else:
        link = link_from(args.link, rate, cfg, args.realtime, args.spin, args.device_name, args.takeover)
    print(f"rhi identify: {dev.name} over {args.link} at {rate:g} Hz: joint friction (each motor in turn), then "
          f"{args.trials} pushes along u = {u.tolist()}", flush=True)
    status = Status(sys.stderr, None)
    try:
        res = identify_device(link, dev, u=u, q0=q0, programme=programme, rate=rate, safety=cfg.safety,
                              realtime=args.realtime, log=out / "identify.rhilog", progress=status, cpu=args.cpu,
                              priority=args.priority, spin=args.spin, cpu_latency=args.cpu_latency)
    finally:
        status.close()
    (out / "identification.json").write_text(json.dumps(res.to_dict(), indent=1, default=float))
    (out / "friction.toml").write_text(res.friction_toml())
    f, m = res.friction, res.inertia
    print("motor  damping [N m s/rad] (95 % CI)        Coulomb [N m] (95 % CI)          R²      RMS [N m]")
    for i in range(len(f.damping)):
        print(f"{i + 1:5d}  {f.damping[i]:9.4g} ({f.damping_ci[i][0]:.4g}, {f.damping_ci[i][1]:.4g})"
              f"{'':6}{f.frictionloss[i]:9.4g} ({f.frictionloss_ci[i][0]:.4g}, {f.frictionloss_ci[i][1]:.4g})"
              f"{'':6}{f.r2[i]:.4f}  {f.residual_rms[i]:.3g}")
    print(f"M_x along u: {m.mass:.5g} kg (95 % CI {m.mass_ci[0]:.5g} to {m.mass_ci[1]:.5g}; model Λ eq. 3.13 "
          f"{res.lambda_model:.5g} kg), Φ {m.damping:.4g} N s/m, c {m.offset:.4g} N, R² {m.r_squared:.5f}, "
          f"residual RMS {m.residual_rms:.3g} N over {m.n_trials} pushes")
    print(f"written: {out / 'identification.json'}, {out / 'friction.toml'}, {out / 'identify.rhilog'}")
    return 0


def add_commands(sub) -> None:
    """Add `identify` to the `rhi` argument parser's subcommands."""
    p = sub.add_parser("identify", help="identify joint friction and the apparent inertia M_x of a device through the "
                       "runtime and its safety layer",
                       description="Run the thesis's identification experiments on a real or simulated device, behind "
                                   "the safety layer: each motor in turn sweeps its room at three speeds while the "
                                   "others are held (viscous + Coulomb friction per motor, the model's M, C and g "
                                   "removed), then pushes from rest along u (M_x, Φ, c of eq. 3.24; Tables 3.2 and "
                                   "6.1). Writes identification.json (values, 95 %% intervals, R², residual RMS), "
                                   "friction.toml (a device.toml [plant] table) and the run's log into --out.",
                       epilog=_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_device_options(p)
    p.add_argument("--link", default="sim", help="sim (the configuration's simulated plant, without its hand), "
                   "udp://HOST:PORT (a device server) or an installed plugin's scheme (rhi.links)")
    p.add_argument("--config", help="a run configuration (TOML file or shipped name): its device, rate, [safety] "
                   "and [sim] (plant friction; its q0 is the hold configuration)")
    p.add_argument("--q0", type=A.floats, help="hold configuration [rad] (default: the configuration's [sim] q0, "
                   "else the nearest to where the device is that is 0.1 rad inside every limit)")
    p.add_argument("--direction", type=A.floats, default=[0.0, 1.0], help="push direction u in the task's axes "
                   "(default 0,1: the thesis's)")
    p.add_argument("--trials", type=A.count, default=10, help="pushes pooled for M_x (default 10, the thesis's)")
    p.add_argument("--seed", type=int, default=0, help="seed of the push forces (default 0)")
    p.add_argument("--rate", type=A.rate, help="control rate [Hz] (default: the configuration's, else 1000)")
    p.add_argument("--out", help="output folder (default out/identify-<timestamp>)")
    p.add_argument("--device-name", help="accept a device whose INFO calls it this (default: the device's name)")
    p.add_argument("--takeover", action="store_true", help="take the device over from another host's session")
    p.add_argument("--realtime", action=argparse.BooleanOptionalAction, default=True,
                   help="pace ticks on the wall clock (default); --no-realtime: as fast as the link answers "
                        "(a lock-step device server)")
    add_realtime(p, "the control loop")
    p.set_defaults(func=_identify)
