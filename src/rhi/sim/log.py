r"""Run logs: one row per control tick, streamed to disk in chunks, loadable while the run goes on.

`LogWriter` fills a preallocated chunk of rows and, when it is full, appends it to a file
(or keeps it in memory when no file is given), so a streamed run's memory does not grow
with its length. Safety and other events go to a JSON-lines file beside the log, written
at once, so they survive a crash of the writing process.

File format (``*.rhilog``, little-endian): the 8 bytes ``b"RHILOG1\n"``, a uint64 header
length L, L bytes of UTF-8 JSON (``{"columns": [[name, width], ...], "meta": {...}}``,
padded with spaces to a multiple of 8 bytes), then rows of float64, each the columns'
widths summed. A reader takes the whole rows present (`Log.load`); events are in
``<log>.events.jsonl``, one JSON object per line; the writer's `close` ends that file with
``{"fault": reason}`` after a fault and ``{"closed": rows}`` (a reader following a log still being
written, `rhi.sim.log_export`, stops there). `Log.to_mcap` and `Log.to_parquet` write the log for
Foxglove, PlotJuggler, pandas and polars (`rhi.sim.log_formats`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import struct
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from rhi.errors import InvalidInput
from rhi.sim.log_formats import TIMING, Event, write_log

MAGIC = b"RHILOG1\n"



@dataclasses.dataclass
class Log:
    """What a run recorded, one row per control tick (N ticks).

    Attributes:
        t: (N,) time [s] (the device's clock).
        q, dq: (N, n) motor angles [rad] and velocities [rad/s] (the encoders).
        tau: (N, n) commanded torques [N m] (after the safety layer).
        x, xdot: (N, m) handle position [m] and velocity [m/s] (simulation: MuJoCo's ground truth;
            hardware: NaN unless the device reports them).
        F_hand: (N, m) force the hand applied [N] (simulation only; NaN otherwise).
        F_env: (N, m) virtual-environment force sent to the controller [N].
        ft: (N, 6) F/T sensor (force [N], torque [N m]) in world axes.
        work: (N,) user work W = ∫ F_hᵀ ẋ dt up to each tick (eq. 5.15) [J] (simulation only).
        V, omega, alpha, beta: (N,) controller state (ASO, FME activation, force scaling,
            tertiary scaling); NaN where the controller has no such state.
        E_obs, alpha_pc: (N,) passivity observer energy [J] and controller damping rate [1/s]
            (`rhi.control.passivity`); NaN without a passivity controller.
        slave_x: (N, m_s) slave position [m] in teleoperation, else empty.
        seq: (N,) sequence number of the reading each tick acted on.
        wall, t_read, t_step, t_write, t_tick, late: (N,) timing [s] (see `TIMING`).
        safety: (N,) 0 while no fault is latched, else 1 (zero torque).
        fault: why the run or the controller stopped, if it did.
        events: safety and other events, in order.
        extra: (N, ...) columns a `record` hook of `rhi.sim.simulate` added, by name (kept in memory).
        meta: the run's description from the log file's header (device, task_axes, rate, source, ...).
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    x: np.ndarray
    xdot: np.ndarray
    F_hand: np.ndarray
    F_env: np.ndarray
    ft: np.ndarray
    work: np.ndarray
    V: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    slave_x: np.ndarray
    E_obs: np.ndarray | None = None
    alpha_pc: np.ndarray | None = None
    seq: np.ndarray | None = None
    wall: np.ndarray | None = None
    t_read: np.ndarray | None = None
    t_step: np.ndarray | None = None
    t_write: np.ndarray | None = None
    t_tick: np.ndarray | None = None
    late: np.ndarray | None = None
    safety: np.ndarray | None = None
    fault: str | None = None
    events: list[Event] = dataclasses.field(default_factory=list)
    extra: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    meta: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)

    def columns(self) -> dict[str, np.ndarray]:
        """The per-tick arrays by name, each (N,) or (N, k), the `extra` ones last; empty columns left out."""
        out = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray) and v.size:
                out[f.name] = v
        out.update({k: v for k, v in self.extra.items() if np.asarray(v).size})
        return out

    def to_csv(self, path) -> Path:
        """Write the log as CSV (one column per scalar, header names like q1, x1, F_hand2; `rhi.sim.log_formats`).

        An empty log (no tick) writes the header only.
        """
        return write_log(self, path, "csv")

    def to_mcap(self, path) -> Path:
        """Write the log as MCAP (JSON channels for Foxglove and PlotJuggler; see `rhi.sim.log_formats`)."""
        return write_log(self, path, "mcap")

    def to_parquet(self, path) -> Path:
        """Write the log as Parquet (one float64 column per scalar, units in the column metadata)."""
        return write_log(self, path, "parquet")

    def to_npz(self, path) -> None:
        """Write the log as compressed NPZ (one array per column; `fault` and `events` as JSON strings)."""
        arrays: dict[str, Any] = {k: np.asarray(v) for k, v in self.columns().items()}
        arrays["fault"] = json.dumps(self.fault)
        arrays["events"] = json.dumps([dataclasses.asdict(e) for e in self.events])
        np.savez_compressed(path, **arrays)

    @classmethod
    def load(cls, path) -> Log:
        """Read a streamed log or a CSV written by `to_csv`.

        A ``.rhilog`` is read as the whole rows written so far, memory-mapped.

        Raises:
            InvalidInput: the path does not exist or is not a log (named in the message).
        """
        p = Path(path)
        if not p.is_file():
            raise InvalidInput(f"path: no log file at {str(p)!r}")
        with p.open("rb") as fh:
            head = fh.read(len(MAGIC))
        if head == MAGIC:
            return _load_binary(p)
        return _load_csv(p)


#: The widest column a log header may declare (a bound against damaged headers).
MAX_WIDTH = 4096


def events_path(path: Path) -> Path:
    """The events file beside the `.rhilog` at `path`."""
    return path.with_name(path.name + ".events.jsonl")


def read_header(path: Path) -> tuple[list[tuple[str, int]], dict, int]:
    """(columns [(name, width)], meta, byte offset of the first row) of the `.rhilog` at `path`.

    Raises:
        InvalidInput: the file is not a `.rhilog` or its header is damaged (naming the path).
    """
    size = path.stat().st_size
    with path.open("rb") as fh:
        if fh.read(len(MAGIC)) != MAGIC:
            raise InvalidInput(f"path: {str(path)!r} is not an rhi log (.rhilog)")
        raw = fh.read(8)
        if len(raw) < 8:
            raise InvalidInput(f"path: {str(path)!r} is cut inside its header ({size} bytes)")
        (L,) = struct.unpack("<Q", raw)
        if L > size - len(MAGIC) - 8:
            raise InvalidInput(f"path: {str(path)!r} has a damaged log header (length {L} beyond the file's "
                               f"{size} bytes)")
        try:
            hdr = json.loads(fh.read(L).decode())
            columns = [(c, w) for c, w in hdr["columns"]]
            meta = hdr.get("meta") or {}
        except (ValueError, KeyError, TypeError) as exc:
            raise InvalidInput(f"path: {str(path)!r} has a damaged log header: {exc}") from None
    names = [c for c, _ in columns]
    if (not columns or names[0] != "t" or len(set(names)) != len(names) or not isinstance(meta, dict)
            or not all(isinstance(c, str) and type(w) is int and 1 <= w <= MAX_WIDTH for c, w in columns)):
        raise InvalidInput(f"path: {str(path)!r} has a damaged log header (columns must be distinct [name, width "
                           f"1..{MAX_WIDTH}] pairs starting with t, meta a table)")
    return columns, dict(meta), len(MAGIC) + 8 + L


def parse_events(lines) -> tuple[list[Event], str | None, bool]:
    """(events, the fault line's reason or None, whether the writer closed) from lines of an events file.

    Lines cut by a crash (not JSON) and blank lines are skipped.

    Raises:
        InvalidInput: a JSON line that is not an event (naming its line number).
    """
    events: list[Event] = []
    fault, closed = None, False
    fields = {f.name: f.type for f in dataclasses.fields(Event)}
    for i, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            d = json.loads(line)
        except ValueError:
            continue  # a line cut by a crash
        if isinstance(d, dict) and set(d) == {"fault"} and isinstance(d["fault"], (str, type(None))):
            fault = d["fault"]
        elif isinstance(d, dict) and set(d) == {"closed"}:
            closed = True
        elif (isinstance(d, dict) and set(d) == set(fields) and isinstance(d["kind"], str)
              and isinstance(d["detail"], str) and type(d["tick"]) is int and type(d["t"]) in (int, float)):
            events.append(Event(**d))
        else:
            raise InvalidInput(f"events: line {i} is not an event ({line.strip()[:80]!r})")
    return events, fault, closed


def layout(n: int, m: int, m_slave: int = 0) -> list[tuple[str, int]]:
    """The columns of a log row and their widths for a device with n motors and m task rows."""
    cols = [("t", 1), ("q", n), ("dq", n), ("tau", n), ("x", m), ("xdot", m), ("F_hand", m), ("F_env", m),
            ("ft", 6), ("work", 1), ("V", 1), ("omega", 1), ("alpha", 1), ("beta", 1),
            ("E_obs", 1), ("alpha_pc", 1)]
    if m_slave:
        cols.append(("slave_x", m_slave))
    cols += [("seq", 1)] + [(c, 1) for c in TIMING] + [("safety", 1)]
    return cols


class LogWriter:
    """Streams log rows in chunks to `path` (or keeps them in memory when `path` is None).

    Usage per tick: ``row = w.row()`` (a (width,) float64 view, NaN-filled), assign ``row[w.cols["q"]] = q``,
    and so on; `close` flushes. Memory stays at one chunk when streaming to a file.

    Args:
        columns: [(name, width)] (see `layout`).
        path: the ``.rhilog`` file to write (its events beside it), or None (in memory).
        meta: JSON-serialisable run description stored in the header (device, rate, ...).
        chunk: rows per chunk (flushed to disk when full; 200 rows = 0.2 s at 1 kHz); in memory, the rows
            allocated at a time.
    """

    def __init__(self, columns: list[tuple[str, int]], path=None, *, meta: dict | None = None,
                 chunk: int = 200) -> None:
        if int(chunk) < 1:
            raise InvalidInput(f"chunk: must be >= 1 rows, got {chunk!r}")
        self.columns = [(str(c), int(w)) for c, w in columns]
        self.cols: dict[str, slice | int] = {}
        i = 0
        for c, w in self.columns:
            self.cols[c] = i if w == 1 else slice(i, i + w)
            i += w
        self.width = i
        self.meta = dict(meta or {})
        self.path = None if path is None else Path(path)
        self._chunk = int(chunk)
        self._buf = np.full((self._chunk, self.width), np.nan)
        self._k = 0
        self._chunks: list[np.ndarray] = []
        self.rows = 0
        self.events: list[Event] = []
        self.fault: str | None = None
        self._fh = self._ev = None
        if self.path is not None:
            hdr = json.dumps({"columns": self.columns, "meta": self.meta}).encode()
            hdr += b" " * (-len(hdr) % 8)
            part = self.path.with_name(self.path.name + ".part")
            try:  # the log appears with its whole header, so a reader never finds it half-made
                self.path.parent.mkdir(parents=True, exist_ok=True)
                part.write_bytes(MAGIC + struct.pack("<Q", len(hdr)) + hdr)
                os.replace(part, self.path)
                self._fh = self.path.open("ab")
                self._ev = events_path(self.path).open("w")
            except OSError as exc:
                part.unlink(missing_ok=True)
                raise InvalidInput(f"log: cannot write {str(self.path)!r}: {exc}") from None

    def row(self) -> np.ndarray:
        """The next row to fill: (width,) float64, NaN-filled."""
        self._room()
        r = self._buf[self._k]
        self._k += 1
        self.rows += 1
        return r

    def block(self, count: int) -> np.ndarray:
        """Up to `count` next rows to fill at once: a (r, width) NaN-filled view, 1 <= r <= count (count >= 1).

        The rows belong to the log once `commit` says how many were written (a compiled loop's block).
        """
        self._room()
        return self._buf[self._k: self._k + count]

    def commit(self, rows: int) -> None:
        """The first `rows` rows of the last `block` are written."""
        self._k += rows
        self.rows += rows

    def event(self, t: float, kind: str, detail: str, tick: int = -1) -> Event:
        """Record an event now (written to the events file at once)."""
        e = Event(float(t), str(kind), str(detail), int(tick))
        self.events.append(e)
        if self._ev is not None:
            self._ev.write(json.dumps(dataclasses.asdict(e)) + "\n")
            self._ev.flush()
        return e

    def _room(self) -> None:
        """A next row in the buffer: the full buffer flushed, a new chunk where none is left (in memory)."""
        if self._k == len(self._buf):
            if self._k:
                self._flush()
            if not len(self._buf):
                self._buf = np.full((self._chunk, self.width), np.nan)

    def _flush(self) -> None:
        block = self._buf[: self._k]
        if self._fh is not None:
            self._fh.write(np.ascontiguousarray(block, dtype="<f8").tobytes())
            self._fh.flush()
            self._buf.fill(np.nan)
        else:  # in memory the rows stay where they are; the next go to the rest of the buffer (a new chunk if none)
            self._chunks.append(block)
            self._buf = self._buf[self._k:]
        self._k = 0

    def close(self) -> None:
        """Flush the last partial chunk and close the files (idempotent)."""
        if self._k:
            self._flush()
        if self._fh is not None and self._ev is not None:
            if self.fault is not None:
                self._ev.write(json.dumps({"fault": self.fault}) + "\n")
            self._ev.write(json.dumps({"closed": self.rows}) + "\n")
            self._fh.close()
            self._ev.close()
            self._fh = self._ev = None

    def to_log(self) -> Log:
        """The log written so far (closes the writer first)."""
        self.close()
        if self.path is not None:
            return _load_binary(self.path)
        data = self._chunks[0] if len(self._chunks) == 1 else np.vstack(self._chunks or [np.zeros((0, self.width))])
        log = _from_array(data, self.columns)
        log.events, log.fault, log.meta = list(self.events), self.fault, dict(self.meta)
        return log


def _check_columns(path: Path, columns: list[tuple[str, int]]) -> None:
    """A log file has a column of every field of `Log`.

    Raises:
        InvalidInput: a field without a column (a file rhi did not write, or a damaged one).
    """
    required = {f.name for f in dataclasses.fields(Log)
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING} - {"slave_x"}
    missing = sorted(required - {c for c, _ in columns})
    if missing:
        raise InvalidInput(f"path: {str(path)!r} is not a log rhi wrote, or is damaged: no column {', '.join(missing)}")


def _from_array(data: np.ndarray, columns: list[tuple[str, int]]) -> Log:
    arrays: dict[str, Any] = {}
    i = 0
    for c, w in columns:
        arrays[c] = data[:, i] if w == 1 else data[:, i:i + w]
        i += w
    N = len(data)
    arrays.setdefault("slave_x", np.zeros((0,)))
    if N == 0:
        arrays = {k: np.asarray(v) for k, v in arrays.items()}
    names = {f.name for f in dataclasses.fields(Log)}
    return Log(**{k: v for k, v in arrays.items() if k in names})


def _load_binary(path: Path) -> Log:
    columns, meta, offset = read_header(path)
    _check_columns(path, columns)
    width = sum(w for _, w in columns)
    rows = (path.stat().st_size - offset) // (8 * width)
    data = (np.memmap(path, dtype="<f8", mode="r", offset=offset, shape=(rows, width)) if rows
            else np.zeros((0, width)))
    t = data[:, 0]
    if rows and not (np.isfinite(t).all() and (np.diff(t) >= 0).all()):
        k = int(np.argmax(~np.isfinite(t))) if not np.isfinite(t).all() else int(np.argmax(np.diff(t) < 0)) + 1
        raise InvalidInput(f"path: {str(path)!r} is damaged: its time t is {t[k]!r} at row {k} "
                           f"(after {t[k - 1] if k else None!r}); it must be finite and never run backwards")
    log = _from_array(data, columns)
    log.meta = meta
    ev = events_path(path)
    if ev.is_file():
        try:
            log.events, log.fault, _ = parse_events(ev.read_text(errors="replace").splitlines())
        except InvalidInput as exc:
            raise InvalidInput(f"path: {str(ev)!r}: {exc}") from None
        if log.fault is None:
            faults = [e for e in log.events if e.kind not in ("clamp", "reset", "info")]
            log.fault = faults[0].detail if faults else None
    return log


def _load_csv(path: Path) -> Log:
    try:
        with path.open() as fh:
            names = fh.readline().strip().split(",")
        with warnings.catch_warnings():  # "input contained no data": the check below names the file instead
            warnings.simplefilter("ignore", UserWarning)
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except (ValueError, OSError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"path: {str(path)!r} is neither an rhi log nor a CSV log: {exc}") from None
    if not names or names[0] != "t" or (data.size and data.shape[1] != len(names)):
        raise InvalidInput(f"path: {str(path)!r} is not a CSV written by Log.to_csv (first column must be t)")
    columns: list[tuple[str, int]] = []
    for nm in names:
        base = nm.rstrip("0123456789")
        if columns and base != nm and columns[-1][0] == base:
            columns[-1] = (base, columns[-1][1] + 1)
        else:
            columns.append((base if base != nm else nm, 1))
    # a multi-column field of width 1 (e.g. q1 for n = 1) keeps its matrix shape
    _check_columns(path, columns)
    log = _from_array(data.reshape(-1, len(names)), columns)
    for c, w in columns:
        if w == 1 and c != "t" and c in {"q", "dq", "tau", "x", "xdot", "F_hand", "F_env", "slave_x"}:
            setattr(log, c, getattr(log, c)[:, None])
    return log


def nan_stats(v: np.ndarray) -> dict[str, float]:
    """p50/p99/p99.9/max of the finite values of v (NaN where none)."""
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return {"p50": math.nan, "p99": math.nan, "p99.9": math.nan, "max": math.nan}
    p = np.percentile(v, [50, 99, 99.9])
    return {"p50": float(p[0]), "p99": float(p[1]), "p99.9": float(p[2]), "max": float(v.max())}
