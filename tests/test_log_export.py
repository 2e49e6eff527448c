"""Logs out (rhi.sim.log_export): MCAP and Parquet read back with their own readers equal the .rhilog, also while written."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest

import rhi
from rhi.cli import main
from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
from rhi.errors import InvalidInput
from rhi.runtime import SimLink, run
from rhi.runtime.inject import Inject
from rhi.sim import Hand, HandPath, Log, LogWriter, Plant, Wall
from rhi.sim.log import layout
from rhi.sim.log_export import export
from rhi.sim.log_formats import scalar_names

mcap_reader = pytest.importorskip("mcap.reader")
pq = pytest.importorskip("pyarrow.parquet")

Q0 = np.array([-0.63, 0.25, 0.28, 0.09])
VECTORS = {"q", "dq", "tau", "x", "xdot", "F_hand", "F_env", "ft", "slave_x"}


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    """A 0.3 s run of rhi4 against a wall whose F/T sensor reads NaN from 0.25 s: a fault, events, NaN cells."""
    dev = rhi.device("rhi4")
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    ctrl = NullSpaceController(dev, ControllerConfig(primary=ForceRendering(), saturation="ascm"))
    link = Inject(SimLink(plant, hand=Hand(HandPath([x0, x0 + [0, 0.05]], speed=0.05))), nan=(0.25, 1.0))
    path = tmp_path_factory.mktemp("log") / "run.rhilog"
    res = run(link, ctrl, duration=0.3, virtual=Wall(x0 + [0, 0.01], normal=[0, 1], stiffness=1000.0), log=path,
              realtime=False)
    assert res.fault is not None  # the NaN reading latched a fault
    return path, Log.load(path)


def _mcap(path):
    """{topic: (schema name, schema, [message dicts], [log times])} and the metadata of an MCAP file."""
    topics: dict = {}
    with open(path, "rb") as fh:
        reader = mcap_reader.make_reader(fh)
        for schema, channel, msg in reader.iter_messages():
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
            entry = topics.setdefault(channel.topic, (schema.name, json.loads(schema.data), [], []))
            entry[2].append(json.loads(msg.data))
            entry[3].append(msg.log_time)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    return topics, meta


def _nan(values):
    return np.array([np.nan if v is None else v for v in values], dtype=float) if isinstance(values, list) \
        else np.nan if values is None else float(values)


def _assert_mcap_equals(path, log):
    topics, meta = _mcap(path)
    seen = set()
    for _topic, (_name, schema, msgs, times) in topics.items():
        if _topic in ("/rhi/events", "/rhi/handle_pose"):
            continue
        assert len(msgs) == len(log)
        np.testing.assert_array_equal([m["t"] for m in msgs], log.t)
        np.testing.assert_array_equal(times, np.round(log.t * 1e9).astype(np.int64))
        for col in set(msgs[0]) - {"timestamp", "t"}:
            got = np.array([_nan(m[col]) for m in msgs])
            want = getattr(log, col)
            np.testing.assert_array_equal(got, want, err_msg=col)
            assert schema["properties"][col]["description"]
            seen.add(col)
    assert seen == set(log.columns()) - {"t"}  # every column is in some channel
    ev = topics["/rhi/events"]
    assert ev[0] == "foxglove.Log"
    assert [(m["t"], m["name"], m["message"], m["tick"]) for m in ev[2]] == \
        [(e.t, e.kind, e.detail, e.tick) for e in log.events]
    name, _, poses, _ = topics["/rhi/handle_pose"]
    assert name == "foxglove.PoseInFrame"  # rhi4's task is "xy": z is 0
    np.testing.assert_array_equal([[p["pose"]["position"][a] for a in "xy"] for p in poses], log.x)
    assert all(p["pose"]["position"]["z"] == 0.0 for p in poses)
    assert json.loads(meta["rhi"]["fault"]) == log.fault
    assert json.loads(meta["rhi"]["meta"])["device"] == "rhi4"


def test_mcap_read_back_equals_the_rhilog(logged, tmp_path, capsys):
    path, log = logged
    assert len(log.events) and np.isnan(log.ft).any()  # events and NaN cells are exported too
    out = tmp_path / "run.mcap"
    assert main(["log", "export", str(path), "--to", "mcap", "-o", str(out)]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    _assert_mcap_equals(out, log)
    topics, _ = _mcap(out)
    assert {"/rhi/joint_state", "/rhi/handle", "/rhi/forces", "/rhi/controller", "/rhi/timing"} <= set(topics)
    assert topics["/rhi/joint_state"][1]["properties"]["tau"]["description"].endswith("[N m]")
    log.to_mcap(tmp_path / "again.mcap")  # the Log method writes the same messages
    _assert_mcap_equals(tmp_path / "again.mcap", log)


#: Foxglove's message schemas of the names the export uses (docs.foxglove.dev, "Message schemas": Log, PoseInFrame),
#: transcribed with every field required: Foxglove's panels read all of them.
_TIME = {"type": "object", "required": ["sec", "nsec"], "properties": {
    "sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}}
_XYZ = {"type": "object", "required": list("xyz"), "properties": {k: {"type": "number"} for k in "xyz"}}
FOXGLOVE = {
    "foxglove.Log": {"type": "object", "required": ["timestamp", "level", "message", "name", "file", "line"],
                     "properties": {"timestamp": _TIME, "level": {"oneOf": [{"const": k} for k in range(6)]},
                                    "message": {"type": "string"}, "name": {"type": "string"},
                                    "file": {"type": "string"}, "line": {"type": "integer", "minimum": 0}}},
    "foxglove.PoseInFrame": {"type": "object", "required": ["timestamp", "frame_id", "pose"], "properties": {
        "timestamp": _TIME, "frame_id": {"type": "string"},
        "pose": {"type": "object", "required": ["position", "orientation"], "properties": {
            "position": _XYZ, "orientation": {"type": "object", "required": list("xyzw"),
                                              "properties": {k: {"type": "number"} for k in "xyzw"}}}}}},
}


def _strict(text):
    """JSON as Foxglove's and PlotJuggler's parsers take it: NaN and ±Infinity are not JSON."""
    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def test_mcap_messages_validate_against_their_schemas_and_foxglove(logged, tmp_path):
    """Every message is strict JSON, valid against its channel's schema (foxglove.* ones against Foxglove's too).

    Log times ascend per channel and equal each message's timestamp.
    """
    jsonschema = pytest.importorskip("jsonschema")
    _, log = logged
    out = log.to_mcap(tmp_path / "run.mcap")
    counts: dict = {}
    with open(out, "rb") as fh:
        reader = mcap_reader.make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count > 0
        validators = {}
        for sid, schema in summary.schemas.items():
            assert schema.encoding == "jsonschema"
            declared = _strict(schema.data)
            jsonschema.Draft202012Validator.check_schema(declared)
            validators[sid] = [jsonschema.Draft202012Validator(declared)]
            if schema.name.startswith("foxglove."):
                validators[sid].append(jsonschema.Draft202012Validator(FOXGLOVE[schema.name]))
        last: dict = {}
        for schema, channel, msg in reader.iter_messages(log_time_order=False):
            assert channel.message_encoding == "json"
            body = _strict(msg.data)
            for v in validators[schema.id]:
                v.validate(body)
            stamp = body["timestamp"]
            assert stamp["sec"] * 1_000_000_000 + stamp["nsec"] == msg.log_time == msg.publish_time
            assert msg.log_time >= last.get(channel.topic, 0)
            last[channel.topic] = msg.log_time
            counts[schema.name] = counts.get(schema.name, 0) + 1
    assert counts["foxglove.PoseInFrame"] == len(log) and counts["foxglove.Log"] == len(log.events)
    assert counts["rhi.JointState"] == len(log)
    # a non-finite device time is null, never NaN (a NaN would make the message unreadable in Foxglove)
    bad = Log.load(logged[0])
    bad.t = bad.t.copy()
    bad.t[3] = np.nan
    topics, _ = _mcap(bad.to_mcap(tmp_path / "nan_t.mcap"))
    assert [m["t"] for m in topics["/rhi/joint_state"][2]].count(None) == 1  # (its log time is 0: read first)


def test_parquet_and_csv_load_in_pandas_as_float64_with_units(logged, tmp_path):
    pd = pytest.importorskip("pandas")
    path, log = logged
    frame = pd.read_parquet(log.to_parquet(tmp_path / "run.parquet"))
    assert all(str(d) == "float64" for d in frame.dtypes)
    units = frame.attrs["units"]
    assert list(units) == list(frame.columns)
    assert (units["t"], units["q1"], units["dq4"], units["tau2"], units["x1"], units["ft1"], units["ft6"]) == \
        ("s", "rad", "rad/s", "N m", "m", "N", "N m")
    assert main(["log", "export", str(path), "--to", "csv", "-o", str(tmp_path / "run.csv")]) == 0
    csv = pd.read_csv(tmp_path / "run.csv")
    assert list(csv.columns) == list(frame.columns) and all(str(d) == "float64" for d in csv.dtypes)
    np.testing.assert_array_equal(csv["tau3"].to_numpy(), log.tau[:, 2])


def test_parquet_read_back_equals_the_rhilog(logged, tmp_path):
    path, log = logged
    out = log.to_parquet(tmp_path / "run.parquet")
    table = pq.read_table(out)
    for name, v in log.columns().items():
        v = np.asarray(v).reshape(len(log), -1)
        for i, col in enumerate(scalar_names(name, v.shape[1])):
            np.testing.assert_array_equal(table.column(col).to_numpy(), v[:, i], err_msg=col)
    assert table.num_columns == sum(np.asarray(v).reshape(len(log), -1).shape[1] for v in log.columns().values())
    schema = pq.read_schema(out)
    assert schema.field("tau1").metadata[b"unit"] == b"N m"
    assert schema.field("ft4").metadata[b"unit"] == b"N m" and schema.field("ft1").metadata[b"unit"] == b"N"
    assert schema.field("q2").metadata[b"unit"] == b"rad" and schema.field("t").metadata[b"unit"] == b"s"
    md = pq.read_metadata(out).metadata
    assert json.loads(md[b"rhi.fault"]) == log.fault
    assert [e["kind"] for e in json.loads(md[b"rhi.events"])] == [e.kind for e in log.events]
    assert json.loads(md[b"rhi.meta"])["task_axes"] == "xy"
    pd = pytest.importorskip("pandas")
    frame = pd.read_parquet(out)
    np.testing.assert_array_equal(frame["q3"].to_numpy(), log.q[:, 2])
    assert main(["log", "export", str(path), "--to", "parquet", "-o", str(tmp_path / "cli.parquet")]) == 0
    cli = pq.read_table(tmp_path / "cli.parquet")  # from the file: the same columns (in the file's order)
    assert sorted(cli.column_names) == sorted(table.column_names)
    for col in table.column_names:
        np.testing.assert_array_equal(cli.column(col).to_numpy(), table.column(col).to_numpy(), err_msg=col)


def test_csv_export_loads_back(logged, tmp_path):
    path, log = logged
    assert main(["log", "export", str(path), "--to", "csv"]) == 0  # default: beside the log
    back = Log.load(path.with_suffix(".csv"))
    for name in ("t", "q", "tau", "ft", "V"):
        np.testing.assert_array_equal(getattr(back, name), getattr(log, name))


def test_follow_exports_a_log_still_being_written(tmp_path):
    path = tmp_path / "live.rhilog"
    cols = layout(2, 2)
    w = LogWriter(cols, path, meta={"device": "two", "task_axes": "xz"}, chunk=7)
    rng = np.random.default_rng(3)
    first = threading.Event()

    def write():
        for k in range(60):
            row = w.row()
            row[:] = rng.normal(size=w.width)
            row[w.cols["t"]] = 1e-3 * k
            if k == 30:
                w.event(1e-3 * k, "clamp", "torque clamped", k)
            if k == 20:
                first.set()
            time.sleep(0.002)
        w.close()

    th = threading.Thread(target=write)
    th.start()
    first.wait(5)
    out = export(path, tmp_path / "live.mcap", to="mcap", follow=True, poll=0.005, idle=30.0)
    th.join()
    log = Log.load(path)
    assert len(log) == 60 and len(log.events) == 1
    _assert_follow(out, log)


def _assert_follow(out, log):
    topics, _ = _mcap(out)
    js = topics["/rhi/joint_state"][2]
    np.testing.assert_array_equal([m["q"] for m in js], log.q)
    np.testing.assert_array_equal([m["t"] for m in js], log.t)
    assert [m["name"] for m in topics["/rhi/events"][2]] == ["clamp"]
    poses = topics["/rhi/handle_pose"][2]  # task "xz": the handle's second row is z
    np.testing.assert_array_equal([[p["pose"]["position"][a] for a in "xz"] for p in poses], log.x)


def test_follow_stops_when_idle_and_bad_input(tmp_path, capsys):
    path = tmp_path / "crashed.rhilog"
    w = LogWriter(layout(1, 1), path, chunk=2)
    for k in range(5):
        w.row()[0] = k
    w._flush()  # a writer that died without closing: the export stops after `idle`
    t0 = time.monotonic()
    out = export(path, to="parquet", follow=True, idle=0.2, poll=0.01)
    assert time.monotonic() - t0 < 5
    np.testing.assert_array_equal(pq.read_table(out).column("t").to_numpy(), np.arange(5.0))
    for kw, key in (({"to": "hdf5"}, "to"), ({"to": "mcap", "idle": 0}, "idle"), ({"to": "mcap", "poll": np.nan}, "poll")):
        with pytest.raises(InvalidInput, match=key):
            export(path, **kw)
    with pytest.raises(InvalidInput, match="src"):
        export(tmp_path / "none.rhilog", to="mcap")
    with pytest.raises(InvalidInput, match="out"):
        export(path, path, to="csv")
    assert main(["log", "export", str(tmp_path / "none.rhilog"), "--to", "mcap"]) == 2
    assert "no log file" in capsys.readouterr().err


def test_in_memory_writer_keeps_every_row_across_chunks_blocks_and_a_second_close():
    w = LogWriter(layout(1, 1), chunk=3)  # in memory: rows stay in their chunk, no copy
    for k in range(4):  # rows 0-3: a full chunk, then one row of the next
        w.row()[0] = k
    rows = w.block(5)  # the rest of that chunk (2 rows)
    assert len(rows) == 2
    rows[:, 0] = [4, 5]
    w.commit(2)
    w.row()[0] = 6  # a new chunk
    np.testing.assert_array_equal(w.to_log().t, np.arange(7.0))
    w.row()[0] = 7  # after closing: the next rows join the log at the next close
    np.testing.assert_array_equal(w.to_log().t, np.arange(8.0))
    assert len(LogWriter(layout(1, 1)).to_log().t) == 0
