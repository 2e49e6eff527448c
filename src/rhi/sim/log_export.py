r"""Logs out: a run log as MCAP (Foxglove, PlotJuggler), Parquet (pandas, polars, MATLAB) or CSV, also while it is written.

`export` writes a `.rhilog` (or a CSV log) in one of the formats of `rhi.sim.log_formats`;
with ``follow=True`` it tails a log still being written: whole rows and events as they appear, until
the writer closes the log (its events file says so), `idle` seconds pass without a new row, or
`stop()` is true. MCAP and Parquet files are complete (readable) once the export returns.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rhi.errors import InvalidInput
from rhi.sim.log import MAGIC, Event, Log, events_path, parse_events, read_header
from rhi.sim.log_formats import FORMATS, SUFFIX, sink, write_log


class LogTail:
    """The rows and events a `.rhilog` gains, read as they are written (whole rows only).

    Args:
        path: the `.rhilog` file.
    """

    def __init__(self, path) -> None:
        self.path = Path(path)
        self.columns, self.meta, self._pos = read_header(self.path)
        self.width = sum(w for _, w in self.columns)
        self._ev = events_path(self.path)
        self._ev_pos = 0
        self.fault: str | None = None
        self.closed = False

    def read(self) -> tuple[np.ndarray, list[Event]]:
        """((k, width) rows and the events written since the last call."""
        size = self.path.stat().st_size
        k = (size - self._pos) // (8 * self.width)
        rows = np.zeros((0, self.width))
        if k > 0:
            with self.path.open("rb") as fh:
                fh.seek(self._pos)
                rows = np.frombuffer(fh.read(8 * self.width * k), dtype="<f8").reshape(k, self.width)
            self._pos += 8 * self.width * k
        events: list[Event] = []
        if self._ev.is_file():
            with self._ev.open("rb") as fh:
                fh.seek(self._ev_pos)
                text = fh.read()
            whole = text[: text.rfind(b"\n") + 1]  # a line still being written waits for the next call
            self._ev_pos += len(whole)
            events, fault, closed = parse_events(whole.decode().splitlines())
            self.fault = fault if fault is not None else self.fault
            self.closed = self.closed or closed
        return rows, events


def export(src, out=None, *, to: str, follow: bool = False, idle: float = 5.0, poll: float = 0.2,
           stop: Callable[[], bool] | None = None, progress: Callable[[int], None] | None = None) -> Path:
    """Export the log at `src` (a `.rhilog`, or a CSV log) to `out` as `to` ("mcap", "parquet", "csv").

    Args:
        src: the log file.
        out: the output file (default: `src` with the format's suffix).
        to: the format.
        follow: keep exporting the rows a writer still appends (a `.rhilog` only) until it closes the log,
            `idle` [s] pass without a new row, or `stop()` is true.
        idle: see `follow` (> 0).
        poll: time between reads when following [s] (> 0).
        stop: see `follow`.
        progress: called with the number of rows exported after each block.

    Returns:
        The output path.

    Raises:
        InvalidInput: no such log, an unknown format, a bad `idle` or `poll`, an unwritable `out` (named).
    """
    if to not in FORMATS:
        raise InvalidInput(f"to: expected one of {', '.join(FORMATS)}, got {to!r}")
    for name, v in (("idle", idle), ("poll", poll)):
        if not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
            raise InvalidInput(f"{name}: must be a finite number of seconds > 0, got {v!r}")
    p = Path(src)
    if not p.is_file():
        raise InvalidInput(f"src: no log file at {str(p)!r}")
    dest = Path(out) if out is not None else p.with_suffix(SUFFIX[to])
    if dest.resolve() == p.resolve():
        raise InvalidInput(f"out: {str(dest)!r} is the log itself")
    with p.open("rb") as fh:
        binary = fh.read(len(MAGIC)) == MAGIC
    if not binary:
        if follow:
            raise InvalidInput(f"follow: only a .rhilog can be followed, {str(p)!r} is a CSV log")
        return write_log(Log.load(p), dest, to)
    tail = LogTail(p)
    w = sink(to, dest, tail.columns, tail.meta)
    done, last = 0, time.monotonic()
    try:
        while True:
            rows, events = tail.read()
            if len(rows) or events:
                w.write(rows, events)
                done += len(rows)
                if progress is not None:
                    progress(done)
            if len(rows):
                last = time.monotonic()
            if not follow or tail.closed or time.monotonic() - last > idle or (stop is not None and stop()):
                break
            time.sleep(poll)
        rows, events = tail.read()  # what came with the close
        w.write(rows, events)
    finally:
        w.close(tail.fault)
    return dest


__all__ = ["LogTail", "export"]
