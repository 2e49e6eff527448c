"""The device options of the `rhi` commands: a bundled name, or `--urdf`, `--mjcf` or `--description` and the loaders' options.

Every command that takes a device (measure, render, run, view, device-server) takes these options; they
build the table of `rhi.devices.source` (the same keys as a run configuration's ``[device]``).
"""

from __future__ import annotations

import argparse
import re

from rhi.devices.model import Device
from rhi.devices.source import device_from_table
from rhi.errors import InvalidInput, RhiError

SOURCE_EXAMPLE = ("rhi measure --urdf arm.urdf --ee-frame tool0 --q 0,0.5,0,1,0,0.5  "
                  "# or --description so_arm_description/urdf/so101.urdf --inertia fill")


def _numbers(text: str) -> list[float] | float:
    try:
        v = [float(x) for x in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas or spaces, got {text!r}") from None
    if not v:
        raise argparse.ArgumentTypeError("expected at least one number")
    return v[0] if len(v) == 1 else v


def _assign(text: str) -> tuple[str, float]:
    name, eq, value = text.partition("=")
    try:
        if not eq or not name:
            raise ValueError
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected JOINT=VALUE, got {text!r}") from None


def add_device_options(p: argparse.ArgumentParser, *, positional: bool = True, default: str | None = None) -> None:
    """Add the device argument and options to subcommand parser `p`.

    Args:
        p: the subcommand's parser.
        positional: the bundled name is a positional argument (optional when a file source is given);
            else an option ``--device NAME``.
        default: the bundled device without any source option (None: one must be given).
    """
    if positional:
        p.add_argument("device", nargs="?", default=default,
                       help="a bundled device (rhi devices), e.g. rhi4; with --urdf/--mjcf/--description: its name")
    else:
        p.add_argument("--device", default=default, help=f"a bundled device (default: {default}); with "
                       "--urdf/--mjcf/--description: its name")
    g = p.add_argument_group("your robot (instead of a bundled device)")
    src = g.add_mutually_exclusive_group()
    src.add_argument("--urdf", metavar="FILE", help="a URDF or xacro file")
    src.add_argument("--mjcf", metavar="FILE", help="a MuJoCo MJCF file")
    src.add_argument("--description", metavar="ROBOT", help="a robot of an installed description package "
                     "(rhi devices --descriptions), e.g. panda or so_arm_description/urdf/so101.urdf")
    g.add_argument("--ee-frame", metavar="FRAME", help="the end-effector link or frame (required with a source)")
    g.add_argument("--task", metavar="AXES", help="world axes of the position task, e.g. xy (default xyz)")
    g.add_argument("--ee-offset", metavar="X,Y,Z", type=_numbers, help="tool point in the end-effector frame [m]")
    g.add_argument("--lock", metavar="JOINT=VALUE", type=_assign, action="append",
                   help="hold a joint fixed [rad or m] (repeat for more)")
    g.add_argument("--torque-max", metavar="T", type=_numbers, help="actuator limits [N m]: one, or one per motor "
                   "(default: the description's effort limits)")
    g.add_argument("--torque-min", metavar="T", type=_numbers, help="lower actuator limits [N m] (default: -max)")
    g.add_argument("--armature", metavar="I", type=_numbers, help="rotor inertia per motor [kg m²]")
    g.add_argument("--damping", metavar="B", type=_numbers, help="joint viscous friction of the plant [N m s/rad]")
    g.add_argument("--frictionloss", metavar="F", type=_numbers, help="joint dry friction of the plant [N m]")
    g.add_argument("--inertia", choices=("strict", "fill"), help="fill: give point-mass links (zero inertia) a "
                   "small inertia (a solid sphere of water of their mass), with a warning naming them")


def device_table(args: argparse.Namespace) -> dict | None:
    """The `rhi.devices.source` table of the source options given, or None when no source option was."""
    src = {k: getattr(args, k, None) for k in ("urdf", "mjcf", "description")}
    opts = {"ee_frame": args.ee_frame, "task": args.task, "ee_offset": args.ee_offset, "armature": args.armature,
            "torque_min": args.torque_min, "torque_max": args.torque_max, "inertia": args.inertia,
            "lock": dict(args.lock) if args.lock else None}
    if args.damping is not None or args.frictionloss is not None:
        opts["friction"] = {k: v for k, v in (("damping", args.damping), ("frictionloss", args.frictionloss))
                            if v is not None}
    if not any(v is not None for v in src.values()):
        given = [k for k, v in opts.items() if v is not None]
        if given:
            raise InvalidInput(f"--{given[0].replace('_', '-')}: an option of --urdf, --mjcf or --description")
        return None
    return {**src, **opts, "name": args.device}


def device_from_args(args: argparse.Namespace, params: dict | None = None) -> Device:
    """The device the command line names: a bundled device (with design `params`) or a source option's."""
    table = device_table(args)
    if table is None:
        if args.device is None:
            raise InvalidInput("device: give a bundled device (rhi devices) or --urdf, --mjcf or --description")
        table = {"name": args.device, "params": params or None}
    elif params:
        raise InvalidInput("--param: design parameters are for bundled devices")
    try:
        return device_from_table(table, path="device")
    except RhiError as exc:  # device.ee_frame: ... → --ee-frame: ...
        m = re.match(r"device\.(\w+)(.*)", str(exc), re.S)
        if m is None or m.group(1) in ("name", "params"):
            raise
        flag = "--damping/--frictionloss" if m.group(1) == "friction" else "--" + m.group(1).replace("_", "-")
        raise type(exc)(flag + m.group(2)) from None
