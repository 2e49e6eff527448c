"""The §3.6 analysis of a whole study: Table 3.3, the ANOVA on WF and the paired tests."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from rhi.analysis.psychophysics.fit import PsychometricFit, by_device, fit_all
from rhi.analysis.psychophysics.trials import Responses
from rhi.analysis.stats import (
    AnovaResult,
    PairedTest,
    Summary,
    describe,
    one_way_anova,
    paired_t_tests,
    repeated_measures_anova,
)


@dataclasses.dataclass(frozen=True)
class StudyAnalysis:
    """The §3.6 analysis of a whole study: Table 3.3, the ANOVA and the paired tests.

    Attributes:
        fits: one `PsychometricFit` per subject and device.
        subjects: subjects present on every device (sorted).
        devices: devices in order.
        measure: the measure tested ("wf" in the thesis).
        summary: ``{measure: [Summary per device]}`` for "wf", "jnd" and "pse" (Table 3.3:
            mean (std); the medians of Fig. 3.10).
        values: ``{device: (n_subjects,) values of measure}`` aligned with ``subjects``.
        anova: between-subjects one-way ANOVA (what the thesis reports, F(2, 27)).
        anova_rm: repeated-measures ANOVA (the within-subject design, F(2, 18)).
        paired: paired t-tests between every pair of devices, adjusted (Holm in §3.6).
    """

    fits: list[PsychometricFit]
    subjects: list[str]
    devices: list[str]
    measure: str
    summary: dict[str, list[Summary]]
    values: dict[str, np.ndarray]
    anova: AnovaResult
    anova_rm: AnovaResult
    paired: list[PairedTest]


def analyse_fits(
    fits: Sequence[PsychometricFit],
    *,
    measure: str = "wf",
    devices: Sequence[str] | None = None,
    correction: str = "holm",
    alternative: str = "two-sided",
    alpha: float = 0.05,
) -> StudyAnalysis:
    """Table 3.3 and the §3.6 tests from per-subject fits.

    Args:
        fits: fits of every subject on every device.
        measure: measure for the ANOVA and t-tests (thesis: "wf").
        devices: device order (default: first appearance).
        correction: p-value adjustment of the paired tests ("holm" in §3.6, "fdr_bh" as Table 5.2).
        alternative: of the paired tests ("two-sided", "less", "greater").
        alpha: family-wise error rate (or FDR).

    Returns:
        `StudyAnalysis`.

    Raises:
        InvalidInput: a subject missing on a device, fewer than two devices or
            subjects, or bad test options.
    """
    fits = list(fits)
    subjects, values = by_device(fits, measure, devices=devices)
    devs = list(values)
    summary = {}
    for m in ("wf", "jnd", "pse"):
        summary[m] = describe(by_device(fits, m, devices=devs)[1])
    return StudyAnalysis(
        fits=fits,
        subjects=subjects,
        devices=devs,
        measure=measure,
        summary=summary,
        values=values,
        anova=one_way_anova(values),
        anova_rm=repeated_measures_anova(values),
        paired=paired_t_tests(values, correction=correction, alternative=alternative, alpha=alpha),
    )


def analyse(
    responses: Responses,
    *,
    measure: str = "wf",
    devices: Sequence[str] | None = None,
    correction: str = "holm",
    **fit_options: Any,
) -> StudyAnalysis:
    """Fit every subject and device, then `analyse_fits` (the whole §3.6 analysis of a study).

    ``rhi.analysis.psychophysics.analyse(from_csv("study.csv"))`` analyses a lab's own experiment.

    Args:
        responses: the study's responses.
        measure: the measure compared (see `analyse_fits`).
        devices: device order (see `analyse_fits`).
        correction: multiple-comparison correction (see `analyse_fits`).
        **fit_options: keyword options of `fit_psychometric`.
    """
    return analyse_fits(fit_all(responses, **fit_options), measure=measure, devices=devices, correction=correction)
