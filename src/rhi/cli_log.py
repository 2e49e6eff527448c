"""The `rhi log` command: export a run log to MCAP, Parquet or CSV (registered by `rhi.cli`)."""

from __future__ import annotations

import argparse
import signal
import sys

_EXAMPLE = """example:
  rhi log export out/run-20260101-120000/run.rhilog --to mcap     # open the .mcap in Foxglove or PlotJuggler
  rhi log export run.rhilog --to parquet -o run.parquet           # pandas.read_parquet / polars.read_parquet
  rhi log export run.rhilog --to mcap --follow                    # while `rhi run` still writes it
"""


def _export(args: argparse.Namespace) -> int:
    from rhi.sim.log_export import export

    stopped = []
    if args.follow:  # Ctrl-C ends the export with a complete file
        signal.signal(signal.SIGINT, lambda *_: stopped.append(True))

    def progress(rows: int) -> None:
        if args.follow and sys.stderr.isatty():
            sys.stderr.write(f"\rrhi log export: {rows} rows")
            sys.stderr.flush()

    out = export(args.log, args.out, to=args.to, follow=args.follow, idle=args.idle, stop=lambda: bool(stopped),
                 progress=progress)
    if args.follow and sys.stderr.isatty():
        sys.stderr.write("\n")
    print(out)
    return 0


def add_commands(sub) -> None:
    """Add `log` (with `log export`) to the `rhi` argument parser's subcommands."""
    lg = sub.add_parser("log", help="work with run logs (.rhilog): export them for other tools",
                        description="Work with run logs (.rhilog) written by `rhi run`, `rhi device-server --log` "
                                    "and rhi.sim.simulate.", epilog=_EXAMPLE,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    lsub = lg.add_subparsers(dest="log_command", required=True)
    e = lsub.add_parser("export", help="export a log to MCAP (Foxglove, PlotJuggler), Parquet (pandas, polars) "
                                       "or CSV (MATLAB, spreadsheets)",
                        description="Export a run log to MCAP (JSON channels: joint state, handle pose, forces, "
                                    "controller, timing, events), Parquet (one column per scalar, units in the "
                                    "column metadata) or CSV.", epilog=_EXAMPLE,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    e.add_argument("log", help="the log (.rhilog, or a CSV written by rhi)")
    e.add_argument("--to", required=True, choices=("mcap", "parquet", "csv"), help="the format")
    e.add_argument("-o", "--out", help="output file (default: the log's path with .mcap, .parquet or .csv)")
    e.add_argument("--follow", action="store_true", help="keep exporting while the log is written, until its "
                   "writer closes it, --idle seconds pass without a new row, or Ctrl-C")
    e.add_argument("--idle", type=float, default=5.0, help="with --follow: stop after this long without a new row "
                   "[s] (default 5)")
    e.set_defaults(func=_export)
