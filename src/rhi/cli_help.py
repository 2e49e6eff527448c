"""The `rhi` command's help pages: every subcommand's description (its one-line help) and an example.

`finish` walks the parser once it is built: a subcommand without a description gets its help line as one,
and one without an epilog gets its example from `EXAMPLES` (by command path, e.g. "log export").
"""

from __future__ import annotations

import argparse

EXAMPLES: dict[str, str] = {
    "devices": "rhi devices\n  rhi devices --descriptions          # the robots of the installed description packages",
    "measure": "rhi measure rhi4 --q 0.125,0.022,0.298,0.175 --u 0,1\n"
               "  rhi measure --urdf arm.urdf --ee-frame tip --task xy --q 0.3,0.8,0.6 --json",
    "reproduce": "rhi reproduce --quick --only ch3 --out out/ch3",
    "experiment": "rhi experiment --list\n  rhi experiment ch7.example_3dof --quick",
    "fidelity": "rhi fidelity out/full --to docs/fidelity.md",
    "device-server": "rhi device-server rhi4 --config ch7_ascm_tertiary --port 5005",
    "run": "rhi run rhi4 --config ch7_ascm_tertiary --link sim --duration 2\n"
           "  rhi run rhi4 --config ch7_ascm_tertiary --link udp://127.0.0.1:5005 --no-realtime",
    "render": "rhi render gen3 --q 0,0.5,0,1.2,0,0.8,0 -o gen3.png     # headless: MUJOCO_GL=egl or osmesa",
    "view": "rhi view                                  # rhi4 live; drag the gizmo\n"
            "  rhi view out/run-*/run.rhilog --device rhi4   # replay a log",
    "log": "rhi log export out/run-*/run.rhilog --to mcap",
    "log export": "rhi log export run.rhilog --to mcap            # Foxglove, PlotJuggler\n"
                  "  rhi log export run.rhilog --to parquet --follow # while `rhi run` writes it",
    "study": "rhi study simulate ch3_stiffness_2afc --participants 8",
    "study run": "rhi study run ch3_stiffness_2afc --participant P01 --mouse",
    "study simulate": "rhi study simulate ch3_stiffness_2afc --participants 8 --out out/study-sim",
    "study analyze": "rhi study analyze out/study-sim",
    "warmup": "rhi warmup                 # once after installing or updating rhi",
}


def _subparsers(p: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """[(name, help, parser)] of `p`'s subcommands."""
    out = []
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            out += [(name, helps.get(name, ""), sp) for name, sp in action.choices.items()]
    return out


def finish(p: argparse.ArgumentParser, prefix: str = "") -> None:
    """Give every subcommand of `p` (recursively) a description and its `EXAMPLES` entry as an epilog."""
    for name, text, sp in _subparsers(p):
        path = f"{prefix} {name}".strip()
        if not sp.description and text:
            sp.description = text[0].upper() + text[1:] + "."
        if not sp.epilog and path in EXAMPLES:
            sp.epilog = "example:\n  " + EXAMPLES[path]
            sp.formatter_class = argparse.RawDescriptionHelpFormatter
        finish(sp, path)


def subcommands(p: argparse.ArgumentParser, prefix: str = "") -> list[tuple[str, argparse.ArgumentParser]]:
    """Every subcommand of `p`, recursively, as (path, parser), e.g. ("log export", ...)."""
    out = []
    for name, _, sp in _subparsers(p):
        path = f"{prefix} {name}".strip()
        out += [(path, sp), *subcommands(sp, path)]
    return out
