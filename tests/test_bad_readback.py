"""Property-based bad input on the files rhi reads back (issue 24's standard, an adversarial audit).

Hypothesis edits a valid file at a generated key path (derandomized, so the suite is reproducible): the reader must
read it into a consistent object or raise an `rhi.errors` error naming the key path, never a foreign exception.
"""

from __future__ import annotations

import copy
import gzip
import json
import math
from pathlib import Path

import pytest
from bad_values import examples
from hypothesis import given, strategies as st

from rhi.cli import main
from rhi.errors import RhiError
from rhi.report.fidelity import load_runs

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


def _exit(argv) -> int:
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


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
        assert _exit(["fidelity", str(tmp_path)]) == 2, text
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and want in err[0] and "Traceback" not in err[0], (text, err)
