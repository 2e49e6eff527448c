r"""Log formats: a run log's rows as MCAP (Foxglove, PlotJuggler), Parquet (pandas, polars, MATLAB) or CSV.

MCAP (`mcap`): JSON messages with JSON schemas, zstd-compressed chunks; each message's log time is the
row's device time ``t`` in ns (negative or non-finite times at 0), and every message carries ``t`` [s]
exactly. One channel per group of columns, one message per tick:

- ``/rhi/joint_state`` (``rhi.JointState``): ``q`` [rad], ``dq`` [rad/s], ``tau`` [N m] per motor;
- ``/rhi/handle`` (``rhi.Handle``): ``x`` [m], ``xdot`` [m/s] in the task rows;
- ``/rhi/handle_pose`` (``foxglove.PoseInFrame``, frame ``world``): the handle position on the device's
  task axes (the header's ``task_axes``, else x, y, z in order; a device with more than 3 rows has none);
- ``/rhi/forces`` (``rhi.Forces``): ``F_hand``, ``F_env`` [N], ``ft`` (force [N], torque [N m]);
- ``/rhi/controller`` (``rhi.Controller``): ``V``, ``omega``, ``alpha``, ``beta``, ``E_obs`` [J],
  ``alpha_pc`` [1/s], ``work`` [J], ``safety``;
- ``/rhi/timing`` (``rhi.Timing``): ``seq`` and the timing columns [s];
- ``/rhi/slave`` (``rhi.Slave``): ``slave_x`` [m]; ``/rhi/extra`` (``rhi.Extra``): any other column;
- ``/rhi/events`` (``foxglove.Log``, Foxglove's Log panel): one message per event, ``name`` its kind,
  ``message`` its sentence, ``line`` its tick, level ERROR for a fault, WARNING for a clamp, INFO otherwise.

Vector columns are JSON arrays, scalar columns numbers; NaN and ±inf are ``null`` (``t`` too), so every message is
strict JSON and validates against its channel's schema; the ``foxglove.*`` channels also against Foxglove's own
schemas of those names (tests/test_log_export.py). The header's run
description is the MCAP metadata record ``rhi`` (``meta``, ``fault`` as JSON).

Parquet (`pyarrow`, zstd): one float64 column per scalar, named as `Log.to_csv` names them (``q1`` … ``qn``,
``x1``, ``ft6``, ``t``), each field's metadata ``unit`` and ``description``; the file's key-value metadata
(`pyarrow.parquet.read_metadata(path).metadata`) holds ``rhi.meta``, ``rhi.events`` and ``rhi.fault`` (JSON), and
``PANDAS_ATTRS``, so that ``pandas.read_parquet(path).attrs["units"]`` maps each column to its unit (pandas keeps
no field metadata). polars reads the same float64 columns (its schema has no units).

The writers take blocks of rows as they come (`rhi.sim.log_export` follows a log still being written).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

import numpy as np

from rhi.errors import InvalidInput


@dataclasses.dataclass
class Event:
    """Something that happened during a run (a safety fault, a clamp, an e-stop, a reset).

    Attributes:
        t: device time [s] of the tick it happened at.
        kind: short machine-readable name (e.g. "stale", "torque_limit", "estop").
        detail: one human-readable sentence.
        tick: tick index.
    """

    t: float
    kind: str
    detail: str
    tick: int = -1

class Recorded(Protocol):
    """What `write_log` reads of a run log (`rhi.sim.Log` is one)."""

    fault: str | None
    events: list[Event]
    meta: dict

    def columns(self) -> dict[str, np.ndarray]:
        """The log's columns by name, each (N, ...)."""
        ...


#: Per-tick timing columns [s]: wall time since the run's start, read, controller step,
#: write, whole tick, and how late the tick started against its absolute deadline.
TIMING = ("wall", "t_read", "t_step", "t_write", "t_tick", "late")

FORMATS = ("mcap", "parquet", "csv")
SUFFIX = {"mcap": ".mcap", "parquet": ".parquet", "csv": ".csv"}

#: Unit and meaning of each column (a vector column's unit holds for each of its entries; ``ft`` per entry).
COLUMNS: dict[str, tuple[str | tuple[str, ...], str]] = {
    "t": ("s", "device time"),
    "q": ("rad", "motor angles (m for a prismatic motor)"),
    "dq": ("rad/s", "motor velocities (m/s for a prismatic motor)"),
    "tau": ("N m", "commanded motor torques after the safety layer (N for a prismatic motor)"),
    "x": ("m", "handle position in the task rows"),
    "xdot": ("m/s", "handle velocity in the task rows"),
    "F_hand": ("N", "force the hand applied (simulation only)"),
    "F_env": ("N", "virtual-environment force sent to the controller"),
    "ft": (("N", "N", "N", "N m", "N m", "N m"), "F/T sensor, force then torque, world axes"),
    "work": ("J", "user work up to the tick (thesis eq. 5.15)"),
    "V": ("1", "actuator saturation objective (ASO)"),
    "omega": ("1", "FME activation"),
    "alpha": ("1", "force scaling"),
    "beta": ("1", "tertiary scaling"),
    "E_obs": ("J", "passivity observer energy"),
    "alpha_pc": ("1/s", "passivity controller damping rate"),
    "slave_x": ("m", "slave position"),
    "seq": ("1", "sequence number of the reading the tick acted on"),
    "safety": ("1", "1 while a safety fault is latched (zero torque), else 0"),
    "wall": ("s", "wall time since the run's start"),
    "t_read": ("s", "time to read the device"),
    "t_step": ("s", "time of the controller step"),
    "t_write": ("s", "time to write the command"),
    "t_tick": ("s", "time of the whole tick"),
    "late": ("s", "how late the tick started against its deadline"),
}
VECTORS = frozenset({"q", "dq", "tau", "x", "xdot", "F_hand", "F_env", "ft", "slave_x"})
_GROUPS = {
    "joint_state": ("JointState", ("q", "dq", "tau")),
    "handle": ("Handle", ("x", "xdot")),
    "forces": ("Forces", ("F_hand", "F_env", "ft")),
    "controller": ("Controller", ("V", "omega", "alpha", "beta", "E_obs", "alpha_pc", "work", "safety")),
    "timing": ("Timing", ("seq", *TIMING)),
    "slave": ("Slave", ("slave_x",)),
}
_TIME = {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
         "description": "log time: the device time t"}
_NUMBER = {"type": ["number", "null"]}
#: compact (an MCAP message per tick) and strict: NaN or ±inf would make a message that JSON readers (Foxglove) refuse
_dumps = json.JSONEncoder(separators=(",", ":"), check_circular=False, allow_nan=False).encode
_LEVEL = {"clamp": 3, "info": 2, "reset": 2}  # foxglove.Log levels: 2 INFO, 3 WARNING, 4 ERROR (the rest: faults)


def scalar_names(name: str, width: int) -> list[str]:
    """The scalar names of a column as `Log.to_csv` writes them: ``name`` for width 1, else name1 … name<width>."""
    return [name] if width == 1 else [f"{name}{i + 1}" for i in range(width)]


def unit(name: str, i: int = 0) -> str:
    """The unit of entry `i` of column `name` ("" for a column rhi does not know, e.g. a `record` hook's)."""
    u = COLUMNS.get(name, ("", ""))[0]
    return u[i] if isinstance(u, tuple) else u


# ------------------------------------------------------------------------------------------ sinks
class _Sink:
    """Writes blocks of log rows (and events) to one file; `close` completes it."""

    def __init__(self, path: Path, columns: list[tuple[str, int]], meta: dict) -> None:
        self.path, self.columns, self.meta = path, columns, meta
        self.at: dict[str, slice] = {}
        i = 0
        for c, w in columns:
            self.at[c] = slice(i, i + w)
            i += w
        self.events: list[Event] = []

    def write(self, rows: np.ndarray, events: Sequence[Event]) -> None:
        raise NotImplementedError

    def close(self, fault: str | None) -> None:
        raise NotImplementedError


def _finite(values: list[float]) -> list[float | None]:
    return [v if math.isfinite(v) else None for v in values]


def _ns(t: float) -> int:
    return int(round(t * 1e9)) if math.isfinite(t) and t > 0 else 0


class _McapSink(_Sink):
    def __init__(self, path: Path, columns: list[tuple[str, int]], meta: dict) -> None:
        super().__init__(path, columns, meta)
        from mcap.writer import CompressionType, Writer

        from rhi import __version__

        self._fh = path.open("wb")
        self._w = Writer(self._fh, compression=CompressionType.ZSTD)
        self._w.start(profile="", library=f"rhi {__version__}")
        self._channels: list[tuple[int, list[tuple[str, slice, bool]]]] = []
        self._seq: dict[int, int] = {}
        names = [c for c, _ in columns]
        claimed = {"t"}
        for topic, (schema, cols) in _GROUPS.items():
            present = [c for c in cols if c in self.at]
            claimed.update(present)
            if present:
                self._channels.append((self._channel(f"/rhi/{topic}", f"rhi.{schema}", present), self._fields(present)))
        extra = [c for c in names if c not in claimed]
        if extra:
            self._channels.append((self._channel("/rhi/extra", "rhi.Extra", extra), self._fields(extra)))
        self._pose = None
        m = self.at["x"].stop - self.at["x"].start if "x" in self.at else 0
        axes = meta.get("task_axes") or "xyz"[:m]
        if m and isinstance(axes, str) and len(axes) == m <= 3 and set(axes) <= set("xyz"):
            self._pose = (self._pose_channel(), [("xyz".index(a), self.at["x"].start + i) for i, a in enumerate(axes)])
        self._events = self._register("/rhi/events", "foxglove.Log", _FOXGLOVE_LOG)

    def _fields(self, cols: list[str]) -> list[tuple[str, slice, bool]]:
        return [(c, self.at[c], c in VECTORS or self.at[c].stop - self.at[c].start != 1) for c in cols]

    def _register(self, topic: str, schema_name: str, schema: dict) -> int:
        sid = self._w.register_schema(name=schema_name, encoding="jsonschema", data=json.dumps(schema).encode())
        cid = self._w.register_channel(topic=topic, message_encoding="json", schema_id=sid)
        self._seq[cid] = 0
        return cid

    def _channel(self, topic: str, schema_name: str, cols: list[str]) -> int:
        props: dict = {"timestamp": _TIME, "t": {**_NUMBER, "description": "device time [s]"}}
        for c in cols:
            u, what = COLUMNS.get(c, ("", f"column {c}"))
            desc = f"{what} [{', '.join(u) if isinstance(u, tuple) else u}]" if u else what
            vec = c in VECTORS or self.at[c].stop - self.at[c].start != 1
            props[c] = {"type": "array", "items": _NUMBER, "description": desc} if vec else {**_NUMBER, "description": desc}
        return self._register(topic, schema_name, {"title": schema_name, "type": "object", "properties": props})

    def _pose_channel(self) -> int:
        xyz = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
        schema = {"title": "foxglove.PoseInFrame", "type": "object", "properties": {
            "timestamp": _TIME, "frame_id": {"type": "string"},
            "pose": {"type": "object", "properties": {
                "position": {**xyz, "description": "handle position [m]"},
                "orientation": {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}}}}}
        return self._register("/rhi/handle_pose", "foxglove.PoseInFrame", schema)

    def _add(self, cid: int, ns: int, msg: dict) -> None:
        self._w.add_message(cid, log_time=ns, publish_time=ns, data=_dumps(msg).encode(), sequence=self._seq[cid])
        self._seq[cid] += 1

    def write(self, rows: np.ndarray, events: Sequence[Event]) -> None:
        t_at = self.at["t"].start
        for row in rows.tolist():
            t = row[t_at]
            ns = _ns(t)
            stamp = {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}
            t_json = t if math.isfinite(t) else None
            for cid, fields in self._channels:
                msg: dict = {"timestamp": stamp, "t": t_json}
                for c, sl, vec in fields:
                    v = _finite(row[sl])
                    msg[c] = v if vec else v[0]
                self._add(cid, ns, msg)
            if self._pose is not None:
                cid, idx = self._pose
                p = [0.0, 0.0, 0.0]
                for k, j in idx:
                    p[k] = row[j] if math.isfinite(row[j]) else 0.0
                self._add(cid, ns, {"timestamp": stamp, "frame_id": "world", "pose": {
                    "position": dict(zip("xyz", p)), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}})
        for e in events:
            ns = _ns(e.t)
            self._add(self._events, ns, {"timestamp": {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000},
                                         "level": _LEVEL.get(e.kind, 4), "message": e.detail, "name": e.kind,
                                         "file": "", "line": max(e.tick, 0), "t": e.t if math.isfinite(e.t) else None,
                                         "tick": e.tick})

    def close(self, fault: str | None) -> None:
        self._w.add_metadata("rhi", {"meta": json.dumps(self.meta), "fault": json.dumps(fault)})
        self._w.finish()
        self._fh.close()


_FOXGLOVE_LOG = {"title": "foxglove.Log", "type": "object", "properties": {
    "timestamp": _TIME, "level": {"type": "integer", "description": "2 INFO, 3 WARNING, 4 ERROR"},
    "message": {"type": "string"}, "name": {"type": "string", "description": "event kind"},
    "file": {"type": "string"}, "line": {"type": "integer", "description": "tick"},
    "t": {**_NUMBER, "description": "device time [s]"}, "tick": {"type": "integer"}}}


class _ParquetSink(_Sink):
    def __init__(self, path: Path, columns: list[tuple[str, int]], meta: dict, batch: int = 100_000) -> None:
        super().__init__(path, columns, meta)
        import pyarrow as pa
        import pyarrow.parquet as pq

        fields, units = [], {}
        for c, w in columns:
            what = COLUMNS.get(c, ("", f"column {c}"))[1]
            for i, name in enumerate(scalar_names(c, w)):
                fields.append(pa.field(name, pa.float64(), metadata={"unit": unit(c, i), "description": what}))
                units[name] = unit(c, i)
        self._pa = pa
        # pandas drops the fields' metadata but reads PANDAS_ATTRS into DataFrame.attrs: the units reach it there
        self.schema = pa.schema(fields, metadata={"rhi.meta": json.dumps(meta),
                                                  "PANDAS_ATTRS": json.dumps({"units": units})})
        self._w = pq.ParquetWriter(str(path), self.schema, compression="zstd")
        self._rows: list[np.ndarray] = []
        self._n, self._batch = 0, batch

    def write(self, rows: np.ndarray, events: Sequence[Event]) -> None:
        self.events.extend(events)
        if len(rows):
            self._rows.append(np.array(rows, dtype=float))
            self._n += len(rows)
        if self._n >= self._batch:
            self._flush()

    def _flush(self) -> None:
        if self._n:
            data = np.vstack(self._rows)
            self._w.write_table(self._pa.Table.from_arrays([self._pa.array(data[:, j]) for j in range(data.shape[1])],
                                                           schema=self.schema))
        self._rows, self._n = [], 0

    def close(self, fault: str | None) -> None:
        self._flush()
        self._w.add_key_value_metadata({"rhi.events": json.dumps([dataclasses.asdict(e) for e in self.events]),
                                        "rhi.fault": json.dumps(fault)})
        self._w.close()


class _CsvSink(_Sink):
    def __init__(self, path: Path, columns: list[tuple[str, int]], meta: dict) -> None:
        super().__init__(path, columns, meta)
        names = [s for c, w in columns for s in scalar_names(c, w)] or ["t"]
        self._fh = path.open("w")
        self._fh.write(",".join(names) + "\n")

    def write(self, rows: np.ndarray, events: Sequence[Event]) -> None:
        if len(rows):
            np.savetxt(self._fh, rows, delimiter=",")
            self._fh.flush()

    def close(self, fault: str | None) -> None:
        self._fh.close()


_SINKS: dict[str, type[_Sink]] = {"mcap": _McapSink, "parquet": _ParquetSink, "csv": _CsvSink}


def _sink(to: str, path: Path, columns: list[tuple[str, int]], meta: dict) -> _Sink:
    if to not in _SINKS:
        raise InvalidInput(f"to: expected one of {', '.join(FORMATS)}, got {to!r}")
    try:
        return _SINKS[to](path, columns, meta)
    except OSError as exc:
        raise InvalidInput(f"out: cannot write {str(path)!r}: {exc}") from None


# ------------------------------------------------------------------------------------------ front doors
def write_log(log: Recorded, path, to: str) -> Path:
    """Write `log` (all its columns, events and fault) to `path` as `to` ("mcap", "parquet" or "csv")."""
    cols = [(name, int(np.prod(np.shape(v)[1:], dtype=int))) for name, v in log.columns().items()]
    out = Path(path)
    sink = _sink(to, out, cols, dict(log.meta))
    data = (np.hstack([np.asarray(v, dtype=float).reshape(len(v), -1) for v in log.columns().values()]) if cols
            else np.zeros((0, 0)))
    sink.write(data, log.events)
    sink.close(log.fault)
    return out


def sink(to: str, path: Path, columns: list[tuple[str, int]], meta: dict) -> _Sink:
    """A writer of `to` at `path` for rows of `columns` [(name, width)]: ``write(rows, events)``, ``close(fault)``.

    Raises:
        InvalidInput: an unknown format (`to`) or a path that cannot be written (`out`).
    """
    return _sink(to, path, columns, meta)


__all__ = ["COLUMNS", "FORMATS", "SUFFIX", "TIMING", "Event", "Recorded", "scalar_names", "sink", "unit", "write_log"]
