"""Property-based bad input on the files rhi reads back (issue 24's standard, an adversarial audit).

Hypothesis edits a valid file at a generated key path (derandomized, so the suite is reproducible): the reader must
read it into a consistent object or raise an `rhi.errors` error naming the key path, never a foreign exception.
"""

from __future__ import annotations

import copy
import gzip
import json
import math
import re
import shutil
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
from bad_values import cli_exit, examples
from hypothesis import given, strategies as st

from rhi.errors import RhiError
from rhi.report.fidelity import load_runs
from rhi.study.protocol import load_protocol, parse_protocol, protocol_path, shipped_protocols
from rhi.study.results import responses_of
from rhi.study.sequence import plan
from rhi.study.session import COLUMNS, Session, answer_row, participants

QUICK = json.loads(gzip.decompress((Path(__file__).parent / "data" / "quick_results.json.gz").read_bytes()))[:3]
JSON_VALUES = st.one_of(st.none(), st.booleans(), st.integers(-10, 10), st.floats(), st.text(max_size=4),
                        st.just([]), st.just([1, "a"]), st.just({}), st.just({"k": [None]}))


def _key_paths(d, prefix=()):
    """Every key path of a JSON document (objects and arrays walked; the arrays of figures skipped)."""
    items = d.items() if isinstance(d, dict) else enumerate(d) if isinstance(d, list) else ()
    for k, v in items:
        if k != "arrays":
            yield (*prefix, k)
            yield from _key_paths(v, (*prefix, k))


PATHS = list(_key_paths({"results": QUICK, "meta": {"mode": "quick"}}))


@examples(150)
@given(data=st.data())
def test_fidelity_reads_generated_edits_of_results_json(data, tmp_path_factory):
    """`rhi fidelity` on a results.json with any value at any key path: dossiers, or an error naming the path."""
    doc = {"results": copy.deepcopy(QUICK), "meta": {"mode": "quick"}}
    path = data.draw(st.sampled_from([(), *PATHS]), label="key path")
    value = data.draw(JSON_VALUES, label="value")
    if path:
        node = doc
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
    else:
        doc = value
    run = tmp_path_factory.mktemp("run")
    (run / "results.json").write_text(json.dumps(doc))
    try:
        results, _ = load_runs([run])
    except RhiError as exc:
        named = ".".join(str(k) for k in path[2:-1] if isinstance(k, str))  # e.g. tables.rows
        assert "results.json" in str(exc) and named.split(".")[-1] in str(exc), (path, value, str(exc))
        return
    except Exception as exc:  # noqa: BLE001 - the point of the suite
        pytest.fail(f"{path}={value!r:.60}: foreign {type(exc).__name__}: {exc}")
    for r in results:  # read: every number a finite float or the NaN of a missing one (rhi = null)
        for t in r.tables:
            for row in t.rows:
                assert isinstance(row.ours, float) and isinstance(row.quantity, str), (path, value, row)
                assert row.thesis is None or math.isfinite(row.thesis), (path, value, row)


def test_fidelity_cli_refuses_a_results_json_of_another_form(tmp_path, capsys):
    for text, want in [("[]", "an object with a list 'results'"), ('{"results": 3}', "an object with a list"),
                       ('{"results": [[]]}', "results[0]: expected a table"),
                       ('{"results": [{"name": "x", "title": "t", "tables": [{"title": "a", "rows": [{"quantity": "q"}]}],'
                        ' "notes": []}]}', "results[0].tables[0].rows[0].thesis: missing"),
                       (json.dumps({"results": [{**QUICK[0], "notes": "a"}]}), "results[0].notes")]:
        (tmp_path / "results.json").write_text(text)
        assert cli_exit(["fidelity", str(tmp_path)]) == 2, text
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and want in err[0] and "Traceback" not in err[0], (text, err)


# ------------------------------------------------------------------ study folders edited by hand
@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    """A study folder with one participant and 6 committed trials of the §3.6 protocol (made once per module)."""
    folder = tmp_path_factory.mktemp("study-template")
    s = Session(folder, load_protocol("ch3_stiffness_2afc"), "P01", fields={"handedness": "left"})
    for t in s.plan[:6]:
        s.commit(answer_row(t, "P01", t.percent, "first" if t.index % 2 else "second", response_time=0.8,
                            t_start=1.7e9 + t.index, t_end=1.7e9 + t.index + 0.5))
    return folder


CELL_TEXT = st.one_of(st.sampled_from(["", "nan", "inf", "-1", "2", "1e999", "0x1", "1_0", "first", "x", "P02", "RHI",
                                       "Rehab", "1.5", " 1", "１"]), st.text(max_size=4))


def _edit_study(data, folder: Path) -> str:
    """One generated damage to one file of the participant's folder; its description."""
    which = data.draw(st.sampled_from(["responses.csv", "participant.json", "protocol.toml"]), label="file")
    path = folder / "P01" / which
    text = path.read_text()
    how = data.draw(st.sampled_from(["cut", "value"]), label="how")
    if how == "cut":
        at = data.draw(st.integers(0, len(text)), label="cut at")
        path.write_text(text[:at])
        return f"{which} cut at {at}"
    if which == "responses.csv":
        lines = text.splitlines()
        i = data.draw(st.integers(1, len(lines) - 1), label="line")
        c = data.draw(st.integers(0, len(COLUMNS) - 1), label="column")
        cells = lines[i].split(",")
        cells[c] = data.draw(CELL_TEXT, label="cell")
        lines[i] = ",".join(cells)
        path.write_text("\n".join(lines) + "\n")
        return f"line {i + 1} {COLUMNS[c]}={cells[c]!r}"
    if which == "participant.json":
        meta = json.loads(text)
        key = data.draw(st.sampled_from(sorted(meta)), label="key")
        meta[key] = data.draw(JSON_VALUES, label="value")
        path.write_text(json.dumps(meta))
        return f"participant.json {key}={meta[key]!r}"
    path.write_text(text.replace("50.0", data.draw(st.sampled_from(["nan", "-1", '"x"', "1e400", "[]"]), label="v")))
    return "protocol.toml reference"


@examples(80)
@given(data=st.data())
def test_a_hand_edited_study_folder_is_read_or_refused(data, tmp_path_factory, study):
    """Resuming or analysing a damaged participant folder: consistent rows, or an rhi.errors error naming the file."""
    folder = tmp_path_factory.mktemp("study") / "s"
    shutil.copytree(study, folder)
    what = _edit_study(data, folder)
    try:
        rows = [r for s in participants(folder) for r in s.rows]
    except RhiError as exc:
        assert "P01" in str(exc), (what, str(exc))
        return
    except Exception as exc:  # noqa: BLE001 - the point of the suite
        pytest.fail(f"{what}: foreign {type(exc).__name__}: {exc}")
    for r in rows:
        assert r["subject"] == "P01" and r["training"] in ("0", "1") and r["response"] in ("", "0", "1"), (what, r)
        assert all(math.isfinite(float(r[c])) for c in ("reference", "stimulus", "percent") if r[c]), (what, r)
    try:
        responses_of(rows)
    except RhiError:
        pass
    except Exception as exc:  # noqa: BLE001
        pytest.fail(f"{what}: foreign {type(exc).__name__}: {exc}")


def test_study_folder_damage_names_the_file_and_the_place(tmp_path, study):
    for file, old, new, want in [("participant.json", '"index": 0', '"index": "a"', "participant.json: key 'index'"),
                                 ("participant.json", "{", "[", "participant.json: not JSON"),
                                 ("responses.csv", ",second,1,", ",second,x,", "column 'response': 'x' is not 0, 1"),
                                 ("responses.csv", ",50.0,", ",abc,", "column 'reference'"),
                                 ("responses.csv", ",Rehab,", ",RHI,", "column 'condition': expected 'Rehab'"),
                                 ("protocol.toml", "[", "", "protocol.toml")]:
        folder = tmp_path / file / new
        shutil.copytree(study, folder)
        path = folder / "P01" / file
        assert old in path.read_text(), (file, old)
        path.write_text(path.read_text().replace(old, new, 1))
        with pytest.raises(RhiError, match=re.escape(want)):
            participants(folder)


# ------------------------------------------------------------------ study protocols
PROTOCOLS = {name: tomllib.loads(protocol_path(name).read_text()) for name in shipped_protocols()}
PROTOCOL_PATHS = [(name, path) for name, doc in PROTOCOLS.items() for path in _key_paths(doc)]
TOML_VALUES = st.one_of(st.text(max_size=3), st.booleans(), st.integers(-10**30, 10**30), st.floats(),
                        st.sampled_from([10**12, 1e300, -1e300, [1e300, 1e300], [], {}, [[1.0], [2.0, 3.0]]]),
                        st.lists(st.floats(-1e3, 1e3), max_size=4))


@examples(100)
@given(data=st.data())
def test_study_protocol_with_a_generated_value_at_any_key(data):
    """A protocol with any value at any key path: a Protocol whose plan is made, or an error naming the key path."""
    name, path = data.draw(st.sampled_from(PROTOCOL_PATHS), label="key path")
    value = data.draw(TOML_VALUES, label="value")
    doc = copy.deepcopy(PROTOCOLS[name])
    node = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # an overflow is a silent inf
        try:
            trials = plan(parse_protocol(doc, name=name), 1)
        except RhiError as exc:
            assert str(path[0]) in str(exc), (path, value, str(exc))
            return
        except Exception as exc:  # noqa: BLE001 - the point of the suite
            pytest.fail(f"{name} {path}={value!r:.60}: foreign {type(exc).__name__}: {exc}")
    assert 0 < len(trials) <= 10**6, (path, value)


def test_study_protocol_bounds_and_overflow():
    for path, value, want in [(("stimulus", "repetitions"), 10**12, "stimulus.repetitions"),
                              (("blocks", "training"), 10**30, "blocks.training"),
                              (("fixture", "stiffness"), 1e300, "fixture.stiffness")]:
        doc = copy.deepcopy(PROTOCOLS["ch3_stiffness_2afc"])
        doc.setdefault(path[0], {})[path[1]] = value
        with pytest.raises(RhiError, match=re.escape(want)):
            parse_protocol(doc)
    doc = copy.deepcopy(PROTOCOLS["ch3_stiffness_2afc"])
    doc["fixture"]["direction"] = [1e300, -1e300]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        d = parse_protocol(doc).fixture["direction"]
    assert np.allclose(d / np.linalg.norm(d), [2 ** -0.5, -(2 ** -0.5)])


# ------------------------------------------------------------------ INFO of a device (docs/protocol.md §2)
def _info_packet(body: bytes, n: int = 4, k: int = 7) -> bytes:
    from rhi.runtime import protocol as P

    return P._INFO.pack(P.INFO, P.VERSION, n, k, 0, 1000.0, 0.02, 7) + body


GOOD_INFO = {"device": "rhi4", "sensors": [["x", 2], ["xdot", 2], ["F_hand", 2], ["work", 1]],
             "joint_names": ["a", "b", "c", "d"], "torque_min": [-1.0] * 4, "torque_max": [1, 1, 1, 1], "lockstep": False}
INFO_KEYS = sorted(GOOD_INFO) + ["sensors.0", "sensors.0.0", "sensors.0.1"]


@examples(150)
@given(data=st.data())
def test_device_info_with_generated_descriptions(data):
    """A host reading an INFO with any value at any key (or garbage JSON): its description, or a LinkError."""
    from rhi.errors import LinkError
    from rhi.runtime.protocol import parse_info

    doc = copy.deepcopy(GOOD_INFO)
    key = data.draw(st.sampled_from([*INFO_KEYS, "whole"]), label="key")
    value = data.draw(st.one_of(JSON_VALUES, st.sampled_from([math.inf, -math.inf, 2.5, 2.0, "no", [1.0] * 4,
                                                              ["a"] * 4, [math.nan] * 4])), label="value")
    if key == "whole":
        body = json.dumps(value).encode()
    else:
        node, *rest = key.split(".")
        if rest:
            target = doc[node]
            for r in rest[:-1]:
                target = target[int(r)]
            target[int(rest[-1])] = value
        else:
            doc[node] = value
        body = json.dumps(doc).encode()
    try:
        info = parse_info(_info_packet(body))
    except LinkError:
        return
    except Exception as exc:  # noqa: BLE001 - the point of the suite
        pytest.fail(f"{key}={value!r:.60}: foreign {type(exc).__name__}: {exc}")
    assert all(isinstance(name, str) and type(w) is int and w > 0 for name, w in info["sensors"]), (key, value)
    assert isinstance(info.get("lockstep", False), bool) and isinstance(info.get("device", ""), str), (key, value)
    for t in ("torque_min", "torque_max"):
        assert t not in info or (len(info[t]) == 4 and all(math.isfinite(x) for x in info[t])), (key, value)


def test_device_info_garbage_the_old_parser_let_through():
    from rhi.errors import LinkError
    from rhi.runtime.protocol import parse_info

    for body, want in [(b'{"device": "rhi4", "sensors": [["x", Infinity]]}', "sensors"),
                       (b"[" * 30000 + b"]" * 30000, "not a JSON object"),
                       (json.dumps({**GOOD_INFO, "lockstep": "no"}).encode(), '"lockstep" must be true or false'),
                       (json.dumps({**GOOD_INFO, "sensors": [["x", 2.0], ["xdot", 5.0]]}).encode(), "an integer"),
                       (json.dumps({**GOOD_INFO, "torque_max": [1.0, 2.0]}).encode(), '"torque_max"')]:
        with pytest.raises(LinkError, match=re.escape(want)):
            parse_info(_info_packet(body))
    assert parse_info(_info_packet(json.dumps(GOOD_INFO).encode()))["sensors"][0] == ("x", 2)


# ------------------------------------------------------------------ logs exported to CSV and read back
def _csv_log(path: Path) -> list[str]:
    from rhi.sim.log import LogWriter, layout

    w = LogWriter(layout(4, 2), path.with_suffix(".rhilog"), meta={"device": "rhi4"}, chunk=4)
    for k in range(5):
        row = w.row()
        row[:] = 0.0
        row[0] = k * 1e-3
    w.close()
    from rhi.sim import Log

    Log.load(path.with_suffix(".rhilog")).to_csv(path)
    return path.read_text().splitlines()


@examples(60)
@given(data=st.data())
def test_a_csv_log_with_generated_columns_dropped_is_read_or_refused(data, tmp_path_factory):
    """`Log.load` (and `rhi log export`, `rhi view`) of a CSV missing some columns: a Log, or an error naming the file."""
    from rhi.sim import Log

    path = tmp_path_factory.mktemp("csv") / "log.csv"
    lines = _csv_log(path)
    header = lines[0].split(",")
    keep = sorted(data.draw(st.sets(st.integers(1, len(header) - 1), max_size=len(header) - 1), label="kept"))
    cols = [0, *keep]
    path.write_text("\n".join(",".join(line.split(",")[i] for i in cols) for line in lines) + "\n")
    try:
        log = Log.load(path)
    except RhiError as exc:
        assert str(path) in str(exc), str(exc)
        return
    except Exception as exc:  # noqa: BLE001 - the point of the suite
        pytest.fail(f"columns {[header[i] for i in cols]}: foreign {type(exc).__name__}: {exc}")
    assert len(log.t) == 5


def test_log_export_of_a_csv_without_the_log_columns(tmp_path, capsys):
    (tmp_path / "two.csv").write_text("t,q0\n0,1\n0.001,2\n")
    assert cli_exit(["log", "export", str(tmp_path / "two.csv"), "--to", "mcap"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no column F_env" in err[0], err
