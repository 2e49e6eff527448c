"""The report: thesis values in one module, tolerances, notes on every miss, the headline claims."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

from rhi import thesis as T
from rhi.errors import InvalidInput
from rhi.experiments import ch3, ch7
from rhi.experiments.result import Result, Row, Table
from rhi.report import headline, write_report
from rhi.report.claims import CLAIMS
from rhi.report.tables import audit, summary


def test_tolerance_is_the_thesis_rounding():
    assert T.get("table3_1.rho.RHI.0").tol == pytest.approx(0.0005)
    assert T.THETA_Z["C1"].tol == pytest.approx(0.5)
    assert T.PAIRED_3_6["RHI", "Rehab"].tol == pytest.approx(5e-6)
    assert T.ANOVA_5["effort"][1].tol == pytest.approx(5e-10)
    assert T.TABLE_4_1["C2"]["theta_z"] == 0 and T.TABLE_4_1["C2"]["theta_z"].tol == 0.5
    assert T.GAIN_7_5.within(73.4) and not T.GAIN_7_5.within(73.6)


def test_thesis_values_are_registered_floats():
    v = T.TABLE_3_1_RHO["RHI"][0]
    assert isinstance(v, float) and T.is_registered(v) and v.source.startswith("Table 3.1")
    assert pickle.loads(pickle.dumps(v)) is v  # process pools get the registered value back
    assert not T.is_registered(v * 1.0) and not T.is_registered(0.371)
    with pytest.raises(InvalidInput, match="key"):
        T.get("table9_9")
    # relative differences are meaningless on p-values, angles and claims
    assert not T.ANOVA_3_6[1].relative and not T.THETA_Z["C2"].relative and not T.EFFORT_ORDER.relative
    assert T.GAIN_6_4.relative


def test_derived_values_propagate_the_rounding():
    assert float(T.MEAN_TME_S1) == pytest.approx(0.1034 / 0.847)
    assert float(T.ERROR_REDUCTION_B[0]) == pytest.approx(100 * (1 - 2.44 / 6.65), abs=T.ERROR_REDUCTION_B[0].tol)
    assert float(T.ERROR_REDUCTION_B[1]) == pytest.approx(100 * (1 - 1.82 / 2.72), abs=T.ERROR_REDUCTION_B[1].tol)
    assert float(T.BASE_TIME_REDUCTION_B) == pytest.approx(100 * (1 - 12.08 / 80), abs=T.BASE_TIME_REDUCTION_B.tol)
    lo = (0.125 - 0.0005) / (0.036 + 0.0005)
    assert float(T.MX_RATIO_6_1) - T.MX_RATIO_6_1.tol == pytest.approx(lo, rel=0.01)


def test_row_tolerance_bounds_and_relative():
    r = Row("ρ", T.TABLE_3_1_RHO["RHI"][0], 0.3712, "m/s")
    assert r.within and r.tol == pytest.approx(5e-4) and r.source == "table3_1.rho.RHI.0"
    assert Row("ρ", T.TABLE_3_1_RHO["RHI"][0], 0.372, "m/s").within is False
    assert Row("p", T.ANOVA_3_6[1], 0.5).relative is None  # no relative difference on a p-value
    b = Row("drift", 0.5, 0.7, "mm", bound="max")
    assert b.within is False and b.relative is None and b.source is None
    assert Row("drift", 0.5, 0.3, "mm", bound="max").within
    with pytest.raises(InvalidInput, match="bound"):
        Row("x", 1.0, 1.0, bound="above")


def _result(rows):
    return Result("test.x", "test", [Table("t", rows)])


def test_audit_flags_unregistered_numbers_and_unexplained_misses():
    ok = Row("ρ", T.TABLE_3_1_RHO["RHI"][0], 0.3711, "m/s")
    assert audit([_result([ok])]) == []
    assert "not a value of rhi.thesis" in audit([_result([Row("ρ", 0.371, 0.3711, "m/s")])])[0]
    # outside the tolerance: the group explanation of rhi.report.explain counts as its note ...
    assert audit([_result([Row("ρ", T.TABLE_3_1_RHO["RHI"][0], 0.40, "m/s")])]) == []
    # ... and a row whose thesis value has no explanation must carry its own note
    lone = T.ThesisValue("1.5", "test.lone", "m", "nowhere")  # not registered either
    problems = audit([_result([Row("x", lone, 2.0, "m")])])
    assert len(problems) == 2 and "not a value" in problems[0] and "without a note" in problems[1]
    assert len(audit([_result([Row("x", lone, 2.0, "m", "because")])])) == 1


def test_experiments_take_thesis_numbers_from_the_module():
    """Fast experiments: every thesis column is a registered value and every miss has a note."""
    results = [ch3.table_3_1(), ch7.example_3dof(steps=41)]
    assert audit(results) == []
    n = summary(results)
    assert n["thesis values"] >= 20 and n["within tolerance"] + n["outside tolerance"] == n["thesis values"]


def test_headline_claims_are_complete_and_well_formed():
    assert len(CLAIMS) >= 35
    where = {c.where for c in CLAIMS}
    for needed in ("Table 3.1", "Table 3.3", "§4.4", "Table 4.1", "§5.4.1", "Fig. 5.6", "§6.4", "Table 6.1",
                   "Fig. 7.1", "§7.5", "Table A.1", "§A.4.3", "§B.4.2", "App. B"):
        assert needed in where, needed
    for c in CLAIMS:
        assert T.is_registered(c.thesis) and c.reason and c.experiments


def test_headline_verdicts_on_a_partial_run():
    results = [ch3.table_3_1(), ch7.example_3dof(steps=101)]
    verdicts = headline.evaluate(CLAIMS, results)
    assert len(verdicts) == len(CLAIMS)
    ran = [v for v in verdicts if v.verdict != headline.NOT_RUN]
    assert len(ran) >= 6
    for v in ran:
        assert v.verdict in headline.VERDICTS
        assert v.reason.strip() and "{" not in v.reason
    by = {v.claim.claim: v for v in ran}
    assert by["ρ_RHI > ρ_PHANToM, ρ_Rehab at both points"].verdict == headline.REPRODUCED
    assert by["simple scaling gives 12 % less force than ASCM"].verdict in headline.VERDICTS
    # link inertias are cited by the thesis, not unpublished: Λ is judged on its number
    assert by["Λ_RHI = 0.0576 kg at (0.49, −0.22)"].verdict != headline.UNPUBLISHED
    text = headline.to_text(verdicts)
    assert "reproduced" in text and "not run" in text


def test_report_has_headline_contents_and_npz(tmp_path):
    res = ch3.table_3_1()
    path = write_report([("ch3", res, {})], tmp_path)
    page = path.read_text()
    assert page.index("Headline claims") < page.index("Contents") < page.index("Effective manipulability")
    assert f"id='{headline.anchor(res.name)}'" in page and "<td>0.0576</td>" in page  # as the thesis printed it
    assert page.index("class='tally'") < page.index("Verdict rules") < page.index("class='headline'")
    assert page.index("Contents") < page.index("Run metadata")
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["problems"] == [] and data["headline"] and data["results"][0]["arrays"] == {}
    assert data["results"][0]["tables"][0]["rows"][0]["tolerance"] == pytest.approx(5e-4)
    npz = np.load(tmp_path / "results.npz")
    assert set(npz.files) == {f"{res.name}/{k}" for k in res.arrays}


def test_split_experiment_in_parallel_equals_one_after_the_other(tmp_path, monkeypatch):
    """An experiment with parts (beyond.passivity's cases) reports the same run in two workers as in this process.

    The parts' times are recorded, and order the next run's queue.
    """
    import dataclasses

    from rhi.experiments.beyond.passivity import passivity, passivity_plan
    from rhi.experiments.parts import Plan, run_plan
    from rhi.report import reproduce as rep
    from rhi.report.warmup import GROUPS

    kw = {"duration": 0.3, "stiff_duration": 0.2, "speed": 0.03, "cases": ("objectives", "objectives_pc")}
    step = next(s for s in rep.STEPS if s.name == "beyond.passivity")
    monkeypatch.setattr(rep, "STEPS", [dataclasses.replace(step, quick=kw)])
    plan = passivity_plan(**kw)
    assert [p.label for p in plan.parts] == ["objectives", "objectives_pc", "stiff_objectives", "stiff_objectives_pc"]
    seen = []
    assert run_plan(plan, lambda k, n: seen.append((k, n))).arrays.keys() == passivity(**kw).arrays.keys()
    assert seen[-1] == (1000, 1000) and all(a <= b for (a, _), (b, _) in zip(seen, seen[1:]))
    out = {}
    for jobs in (1, 2):
        rep.reproduce(tmp_path / str(jobs), quick=True, jobs=jobs)
        out[jobs] = json.loads((tmp_path / str(jobs) / "results.json").read_text())
    assert out[1]["results"] == out[2]["results"]
    assert np.array_equal(np.load(tmp_path / "1" / "results.npz")["beyond.passivity/objectives_pc_W"],
                          np.load(tmp_path / "2" / "results.npz")["beyond.passivity/objectives_pc_W"])
    tasks = out[2]["meta"]["seconds_per_task"]
    assert out[1]["meta"]["warmup_seconds"] == {}  # one process: nothing to share
    assert set(out[2]["meta"]["warmup_seconds"]) == set(GROUPS)  # once, before the workers ran
    assert set(tasks) == {f"beyond.passivity[{k}]" for k in ("objectives", "objectives_pc", "stiff_objectives",
                                                             "stiff_objectives_pc", "merge")}
    assert sorted(p.name for p in (tmp_path / "2" / "figures").iterdir()) == \
        sorted(p.name for p in (tmp_path / "1" / "figures").iterdir())
    assert rep._previous_times(tmp_path / "2", "quick")["beyond.passivity[objectives]"] == tasks[
        "beyond.passivity[objectives]"]
    with pytest.raises(InvalidInput, match="parts"):
        Plan([], lambda outputs: None)


def test_packaged_timings_order_a_first_run():
    """A first run (no results.json in out/) orders its queue by the packaged reference times of its mode."""
    from rhi.report import reproduce as rep

    for mode in ("quick", "full"):
        times = rep._previous_times(rep.TIMINGS.parent / "no such folder", mode)
        assert {s.name for s in rep.STEPS} <= set(times) and all(v >= 0 for v in times.values())
    full, quick = (rep._previous_times(rep.TIMINGS.parent / "no such folder", m) for m in ("full", "quick"))
    assert sum(full[s.name] for s in rep.STEPS) > sum(quick[s.name] for s in rep.STEPS)  # each mode its own


def test_a_failed_reproduction_ends_with_one_line_naming_the_step(tmp_path, monkeypatch, capsys):
    """A failing experiment: `rhi experiment` exits 2 with one line naming it and saying that re-running resumes."""
    import dataclasses

    from rhi.cli import main
    from rhi.report import reproduce as rep

    step = next(s for s in rep.STEPS if s.name == "ch7.example_3dof")
    monkeypatch.setattr(rep, "STEPS", [dataclasses.replace(step, quick={"steps": -1})])
    assert main(["experiment", "ch7.example_3dof", "--quick", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rhi: error: reproduce: ch7.example_3dof failed (")
    assert "re-running the same command resumes" in err[0]
    assert "Traceback" in (tmp_path / "o" / "reproduce-error.log").read_text()
    with pytest.raises(InvalidInput, match="out: cannot write into /proc/rhi"):  # refused before anything runs
        rep.reproduce("/proc/rhi/out", quick=True, experiment="ch7.example_3dof")


def test_fidelity_judges_a_written_run_again(tmp_path, capsys):
    """`rhi fidelity out` reads results.json back (thesis values by key) and gives the report's verdicts."""
    from rhi.cli import main
    from rhi.report.fidelity import load_runs

    res = ch3.table_3_1()
    write_report([("ch3", res, {})], tmp_path)
    data = json.loads((tmp_path / "results.json").read_text())
    loaded, meta = load_runs([tmp_path])
    again = headline.evaluate(CLAIMS, loaded)
    assert [(v.verdict, v.ours) for v in again] == [(h["verdict"], h["rhi"]) for h in data["headline"]]
    assert T.is_registered(loaded[0].tables[0].rows[0].thesis) and meta["chapters"] == "ch3"
    out = tmp_path / "fidelity.md"
    assert main(["fidelity", str(tmp_path), "--to", str(out)]) == 0
    assert "reproduced" in capsys.readouterr().out and out.read_text().startswith("# Fidelity")
    assert "## Table 3.1" in out.read_text()  # Λ_RHI is not reproduced with rhi's inertias: its dossier
    assert main(["fidelity", str(tmp_path / "nowhere")]) == 2  # an error naming the folder, no traceback
