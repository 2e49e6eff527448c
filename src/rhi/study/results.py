"""A study's numbers from its responses: the §3.6 psychophysics per condition and the §5.5 task measures.

Discrimination (§3.6): the scored 2AFC trials become `rhi.analysis.psychophysics.Responses` (subject,
condition as the device, comparison stimulus, 1 = comparison judged stiffer); one psignifit fit per
participant and condition runs on the default executor (`rhi.design.executors.parallel_map`), then PSE, JND,
WF, the one-way and repeated-measures ANOVA on WF and the paired t-tests with Holm's correction
(`analyse_fits`). Path following (§5.5): per participant and condition the mean tracking error, effort and
completion time of the scored runs; one-way ANOVA over conditions per measure and paired t-tests (FDR, as
Table 5.2).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from rhi.analysis import psychophysics as pp
from rhi.analysis.stats import AnovaResult, PairedTest, Summary, describe, one_way_anova, paired_t_tests
from rhi.design.executors import parallel_map
from rhi.errors import InvalidInput

#: the §5.5 measures of a path-following run, with their units.
TASK_MEASURES = {"tracking_error": "m", "effort": "J", "completion_time": "s"}


def responses_of(rows: Sequence[dict[str, str]]) -> pp.Responses:
    """The scored discrimination trials of responses.csv rows (any participants) as `Responses`.

    Raises:
        InvalidInput: no scored trial with an answer.
    """
    rows = [r for r in rows if r["training"] == "0" and r["response"] != ""]
    if not rows:
        raise InvalidInput("responses: no scored trials with an answer")
    return pp.Responses(subject=np.array([r["subject"] for r in rows], dtype=object),
                        device=np.array([r["condition"] for r in rows], dtype=object),
                        comparison=np.array([float(r["stimulus"]) for r in rows]),
                        response=np.array([int(r["response"]) for r in rows]))


def _fit_group(group: tuple) -> pp.PsychometricFit:
    """`fit_psychometric` of one (comparisons, responses, subject, condition, overdispersion, min_trials) group."""
    x, r, subject, dev, overdispersion, min_trials = group
    return pp.fit_psychometric(x, r, subject=subject, device=dev, overdispersion=overdispersion, min_trials=min_trials)


def fit_conditions(
    responses: pp.Responses,
    *,
    conditions: Sequence[str] | None = None,
    overdispersion: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> pp.StudyAnalysis:
    """Fit psignifit per participant and condition (in parallel), then the §3.6 analysis of WF (Holm).

    Args:
        responses: the scored trials.
        conditions: condition order (default: first appearance).
        overdispersion: psignifit's η (False: about twice as fast).
        progress: callback(done, total) over the fits.
    """
    groups = [(responses.comparison[idx], responses.response[idx], s, d, overdispersion, min(20, len(idx)))
              for (s, d), idx in responses.groups().items()]
    fits = parallel_map(_fit_group, groups, progress=progress)
    return pp.analyse_fits(fits, measure="wf", devices=conditions, correction="holm")


@dataclasses.dataclass(frozen=True)
class TaskAnalysis:
    """The §5.5 analysis: per measure the per-participant means, their summary, the ANOVA and paired tests.

    Attributes:
        subjects: participants with scored runs in every condition (sorted).
        conditions: in order.
        values: {measure: {condition: (subjects,) per-participant means}}.
        summary: {measure: [Summary per condition]} (Table 5.1).
        anova: {measure: one-way ANOVA over conditions} (§5.5: F(2, 21) on the execution time).
        paired: {measure: paired t-tests, FDR-adjusted} (Table 5.2).
    """

    subjects: list[str]
    conditions: list[str]
    values: dict[str, dict[str, np.ndarray]]
    summary: dict[str, list[Summary]]
    anova: dict[str, AnovaResult]
    paired: dict[str, list[PairedTest]]


def analyse_task(rows: Sequence[dict[str, str]], conditions: Sequence[str]) -> TaskAnalysis:
    """The §5.5 measures of path-following rows (see the module docstring).

    Raises:
        InvalidInput: fewer than two participants with scored runs in every condition.
    """
    scored = [r for r in rows if r["training"] == "0" and r["completion_time"] != ""]
    per: dict[tuple[str, str], list[dict[str, str]]] = {}
    for r in scored:
        per.setdefault((r["subject"], r["condition"]), []).append(r)
    subjects = sorted({s for s, _ in per if all((s, c) in per for c in conditions)})
    if len(subjects) < 2:
        raise InvalidInput(f"responses: need two or more participants with scored runs in every condition "
                           f"{list(conditions)}, got {subjects}")
    values = {m: {c: np.array([np.mean([float(r[m]) for r in per[(s, c)]]) for s in subjects]) for c in conditions}
              for m in TASK_MEASURES}
    return TaskAnalysis(subjects=subjects, conditions=list(conditions), values=values,
                        summary={m: describe(v) for m, v in values.items()},
                        anova={m: one_way_anova(v) for m, v in values.items()},
                        paired={m: paired_t_tests(v, correction="fdr_bh") for m, v in values.items()})


__all__ = ["TASK_MEASURES", "TaskAnalysis", "analyse_task", "fit_conditions", "responses_of"]
