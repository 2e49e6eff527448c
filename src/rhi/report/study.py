"""The report of a study with people (`rhi study analyze STUDY_DIR`), in the format of `rhi reproduce`.

`study_result` reads every participant folder of a study (`rhi.study.session.participants`), analyses the scored
trials (`rhi.study.results`: psignifit per participant and condition, PSE, JND, WF, the ANOVAs and the paired
tests with Holm; or the §5.5 measures of a path-following study) and returns a `Result` whose tables set the
thesis's numbers beside the study's where the conditions are the thesis's (Table 3.3, §3.6; Table 5.1, §5.5).
`write_study_report` writes it with the psychometric curves and the per-condition figures through
`rhi.report.write_report`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from rhi import thesis as T
from rhi.errors import InvalidInput
from rhi.experiments.result import Result, Row, Table
from rhi.study.protocol import Protocol
from rhi.study.results import TASK_MEASURES, analyse_task, fit_conditions, responses_of
from rhi.study.session import participants

_LABELS = {"wf": ("WF", ""), "jnd": ("JND", "N/m"), "pse": ("PSE", "N/m")}


def _thesis(table: dict, measure: str, cond: str, i: int):
    pair = table.get(measure, {}).get(cond)
    return None if pair is None else pair[i]


def _discrimination(protocol: Protocol, rows: list[dict[str, str]], overdispersion: bool,
                    progress: Callable[[int, int], None] | None) -> Result:
    conds = protocol.condition_names
    an = fit_conditions(responses_of(rows), conditions=conds, overdispersion=overdispersion, progress=progress)
    unit = protocol.stimulus["unit"]
    measures = []
    for m, (label, u) in _LABELS.items():
        for c, s in zip(an.devices, an.summary[m]):
            u = "" if m == "wf" else unit
            measures.append(Row(f"{label} mean, {c}", _thesis(T.TABLE_3_3, m, c, 0), s.mean, u))
            measures.append(Row(f"{label} std, {c}", _thesis(T.TABLE_3_3, m, c, 1), s.std, u))
    thesis_three = conds == ["RHI", "PHANToM", "Rehab"]
    stats = [
        Row(f"one-way ANOVA on WF: F({an.anova.df_between:g}, {an.anova.df_within:g})",
            T.ANOVA_3_6[0] if thesis_three else None, an.anova.statistic, "", "thesis: F(2, 27) = 7.36"),
        Row("one-way ANOVA on WF: p", T.ANOVA_3_6[1] if thesis_three else None, an.anova.p_value, ""),
        Row(f"repeated-measures ANOVA on WF: F({an.anova_rm.df_between:g}, {an.anova_rm.df_within:g})", None,
            an.anova_rm.statistic, "", f"p = {an.anova_rm.p_value:.3g}"),
    ]
    for t in an.paired:
        th = T.PAIRED_3_6.get((t.a, t.b), T.PAIRED_3_6.get((t.b, t.a))) if thesis_three else None
        stats.append(Row(f"paired t-test on WF {t.a} vs {t.b}: Holm-adjusted p", th, t.p_adjusted, "",
                         f"t({t.df}) = {t.statistic:.2f}, mean difference {t.mean_difference:+.4f}"))
    lo = min(float(f.data[:, 0].min()) for f in an.fits)
    hi = max(float(f.data[:, 0].max()) for f in an.fits)
    grid = np.linspace(lo, hi, 201)
    arrays: dict[str, np.ndarray] = {"conditions": np.array(conds), "curve_grid": grid,
                                     "subjects": np.array(an.subjects)}
    for f in an.fits:
        arrays[f"data/{f.subject}/{f.device}"] = f.data
        arrays[f"curve/{f.subject}/{f.device}"] = f.curve(grid)
        for m in ("pse", "jnd", "wf"):
            arrays[f"fit/{f.subject}/{f.device}/{m}"] = np.array(getattr(f, m))
    for m in ("wf", "jnd", "pse"):
        arrays[f"values/{m}"] = np.array([[getattr(f, m) for s in an.subjects for f in an.fits
                                           if f.subject == s and f.device == c] for c in conds])
    notes = [f"{len(an.subjects)} participants × {len(conds)} conditions; {len(responses_of(rows))} scored trials; "
             "psignifit per participant and condition (equal-asymptote cumulative Gaussian, thresholds on the "
             "lapse-free sigmoid), JND = (UT − LT)/2 (eq. 3.26), WF = JND/PSE (eq. 3.25)."]
    return Result(f"study.{protocol.name}", f"{protocol.description} — psychophysics",
                  [Table("PSE, JND and WF per condition (Table 3.3)", measures), Table("Statistics on WF (§3.6)", stats)],
                  arrays, notes)


def _task(protocol: Protocol, rows: list[dict[str, str]]) -> Result:
    conds = protocol.condition_names
    an = analyse_task(rows, conds)
    out, stats = [], []
    for m, unit in TASK_MEASURES.items():
        for c, s in zip(conds, an.summary[m]):
            out.append(Row(f"{m} mean, {c}", None, s.mean, unit))
            out.append(Row(f"{m} std, {c}", None, s.std, unit))
        a = an.anova[m]
        stats.append(Row(f"one-way ANOVA on {m}: F({a.df_between:g}, {a.df_within:g})", None, a.statistic, "",
                         f"p = {a.p_value:.3g} (thesis, execution time: F(2, 21) = 3.57, p = 0.046)"))
        for t in an.paired[m]:
            stats.append(Row(f"paired t-test on {m} {t.a} vs {t.b}: FDR-adjusted p", None, t.p_adjusted, "",
                             f"t({t.df}) = {t.statistic:.2f}"))
    arrays = {"conditions": np.array(conds), **{f"values/{m}": np.array([an.values[m][c] for c in conds])
                                                for m in TASK_MEASURES}}
    return Result(f"study.{protocol.name}", f"{protocol.description} — task measures",
                  [Table("Task measures per condition (Table 5.1)", out), Table("Statistics (§5.5, Table 5.2)", stats)],
                  arrays, [f"{len(an.subjects)} participants × {len(conds)} conditions; scored runs only."])


def study_result(study_dir: str | Path, *, overdispersion: bool = True,
                 progress: Callable[[int, int], None] | None = None) -> Result:
    """The analysis of every participant of a study folder (see the module docstring).

    Raises:
        InvalidInput: no participants, or participants who ran different protocols.
    """
    sessions = participants(study_dir)
    first = sessions[0].protocol
    for s in sessions[1:]:
        if s.protocol.text != first.text:
            raise InvalidInput(f"study_dir: {s.id} ran another protocol than {sessions[0].id} ({s.folder})")
    rows = [r for s in sessions for r in s.rows]
    if first.kind == "discrimination_2afc":
        return _discrimination(first, rows, overdispersion, progress)
    return _task(first, rows)


def write_study_report(study_dir: str | Path, out: str | Path, *, overdispersion: bool = True,
                       progress: Callable[[int, int], None] | None = None) -> tuple[Path, Result]:
    """Write `study_result` as report.html, results.json, results.npz, tables and figures into `out`."""
    from matplotlib.figure import Figure

    from rhi.plots import study as plots
    from rhi.report import write_report

    res = study_result(study_dir, overdispersion=overdispersion, progress=progress)
    figs: dict[str, Figure | Callable[[], Figure] | Path] = {"by_condition": lambda: plots.by_condition(res)}
    if any(k.startswith("curve/") for k in res.arrays):
        figs["psychometric_curves"] = lambda: plots.psychometric_curves(res)
    path = write_report([("study", res, figs)], out, title=f"rhi study: {res.title}",
                        meta={"study": str(study_dir)}, thesis=False)
    return path, res


__all__ = ["study_result", "write_study_report"]
