"""Table 3.3 and §3.6 (mean WF order, one-way ANOVA p, Holm-adjusted paired t-test) against a transcription (issue 23).

The thesis's analysis of the study, from its text, in plain NumPy/SciPy: per subject and device the fitted
cumulative Gaussian's 50 %, 25 % and 75 % points (PSE, LT, UT, §3.6), JND = (UT − LT)/2 (eq. 3.26), WF =
JND/PSE (eq. 3.25); Table 3.3's mean and std over the subjects; the one-way ANOVA on WF by its sums of squares
(F(k − 1, N − k)); the paired-sample t-tests by their differences, p-values adjusted by Holm–Bonferroni
written out (sorted, multiplied by m − i, running maximum, capped at 1).

The inputs are those of `ch3.psychophysics`'s quick run (4 subjects, 6 repetitions, 5 comparisons, η = 0)
on a stimulus table given here (the perceived stiffness through each device is rhi's simulation, not the
thesis's equations; the thesis's per-subject responses are not published): the same responses go through
rhi's fits and analysis and through this transcription, which reads only each fit's psignifit parameters
(threshold, width of the 5–95 % span). Everything agrees to 1e-10; planted differences (JND = UT − LT,
Bonferroni instead of Holm) fail.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rhi.analysis import psychophysics as pp
from rhi.experiments.ch3 import discrimination as disc
from rhi.study.results import fit_conditions

DEVICES = ("RHI", "PHANToM", "Rehab")
QUICK = {"subjects": 4, "repetitions": 6, "comparison_percent": (-35.0, -15.0, 0.0, 15.0, 35.0)}
TOL = 1e-10


def _table() -> dict[str, np.ndarray]:
    """A stimulus table: K̂ per (stiffness, stroke duration), a device-specific gain and offset [N/m]."""
    K = pp.REFERENCE_STIFFNESS * (1.0 + np.asarray(QUICK["comparison_percent"]) / 100.0)
    out = {"stiffness": K, "durations": np.array([0.7, 1.4])}
    for name, (g1, g2, off) in {"RHI": (1.0, 1.02, 0.5), "PHANToM": (0.98, 1.05, 1.0), "Rehab": (0.9, 1.15, 3.0)}.items():
        out[name] = np.stack([g1 * K, g2 * K + off], axis=1)
        out[f"{name}_speed"] = np.ones((K.size, 2))
    return out


@pytest.fixture(scope="module")
def study():
    table = _table()
    responses, _ = disc.simulate_study(table, subjects=QUICK["subjects"], repetitions=QUICK["repetitions"],
                                       comparison_percent=QUICK["comparison_percent"])
    analysis = fit_conditions(responses, conditions=DEVICES, overdispersion=False)
    return table, analysis


def measures(threshold: float, width: float, jnd_halved: bool = True) -> dict[str, float]:
    """PSE, LT, UT, JND (eq. 3.26), WF (eq. 3.25) of a cumulative Gaussian given by psignifit's parameters."""
    sigma = width / (stats.norm.ppf(0.95) - stats.norm.ppf(0.05))  # width: the 5 %–95 % span
    pse, lt, ut = threshold, threshold + sigma * stats.norm.ppf(0.25), threshold + sigma * stats.norm.ppf(0.75)
    jnd = (ut - lt) / 2.0 if jnd_halved else ut - lt
    return {"pse": pse, "lt": lt, "ut": ut, "jnd": jnd, "wf": jnd / pse}


def one_way_anova(groups: list[np.ndarray]) -> tuple[float, float]:
    """(F, p) from the between- and within-group sums of squares."""
    allv = np.concatenate(groups)
    k, n = len(groups), allv.size
    ssb = sum(g.size * (g.mean() - allv.mean()) ** 2 for g in groups)
    ssw = sum(((g - g.mean()) ** 2).sum() for g in groups)
    F = (ssb / (k - 1)) / (ssw / (n - k))
    return float(F), float(stats.f.sf(F, k - 1, n - k))


def paired_p(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sided p of the paired-sample t-test: t = mean(d)/(sd(d)/√n), n − 1 degrees of freedom."""
    d = a - b
    t = d.mean() / (d.std(ddof=1) / np.sqrt(d.size))
    return float(2.0 * stats.t.sf(abs(t), d.size - 1))


def holm(p: list[float]) -> np.ndarray:
    """Holm–Bonferroni: the i-th smallest p times (m − i), running maximum, at most 1."""
    p_arr = np.asarray(p)
    order = np.argsort(p_arr)
    m = p_arr.size
    adj = np.maximum.accumulate(np.minimum(1.0, (m - np.arange(m)) * p_arr[order]))
    out = np.empty(m)
    out[order] = adj
    return out


def test_wf_of_each_fit_is_eqs_3_25_3_26(study):
    _, analysis = study
    assert len(analysis.fits) == QUICK["subjects"] * len(DEVICES)
    for f in analysis.fits:
        mine = measures(f.threshold, f.width)
        for k, v in mine.items():
            assert getattr(f, k) == pytest.approx(v, rel=TOL), (f.subject, f.device, k)
        # planted difference: JND as the whole UT − LT interval
        assert abs(measures(f.threshold, f.width, jnd_halved=False)["wf"] / f.wf - 1.0) > 0.5


def test_table_3_3_and_the_section_3_6_tests_are_the_transcriptions(study):
    table, analysis = study
    wf = {d: np.array([measures(f.threshold, f.width)["wf"] for f in sorted(analysis.fits, key=lambda f: f.subject)
                       if f.device == d]) for d in DEVICES}
    summary = {s.name: s for s in analysis.summary["wf"]}
    for d in DEVICES:
        assert summary[d].mean == pytest.approx(wf[d].mean(), rel=TOL)
        assert summary[d].std == pytest.approx(wf[d].std(ddof=1), rel=TOL)
    F, p = one_way_anova([wf[d] for d in DEVICES])
    assert analysis.anova.statistic == pytest.approx(F, rel=TOL) and analysis.anova.p_value == pytest.approx(p, rel=TOL)
    pairs = [("RHI", "PHANToM"), ("RHI", "Rehab"), ("PHANToM", "Rehab")]
    raw = [paired_p(wf[a], wf[b]) for a, b in pairs]
    adjusted = holm(raw)
    ours = {(t.a, t.b): t.p_adjusted for t in analysis.paired}
    for (a, b), pa in zip(pairs, adjusted):
        assert ours[a, b] == pytest.approx(pa, rel=TOL), (a, b)
    # planted difference: Bonferroni (every p times 3) instead of Holm moves some adjusted p
    assert np.max(np.abs(np.minimum(1.0, 3 * np.asarray(raw)) - adjusted)) > 1e-3
    # the experiment reports these numbers for the same inputs (its own fits of the same responses)
    res = disc.psychophysics(table=table, overdispersion=False, durations=(0.7, 1.4), **QUICK)
    rows = {r.quantity: r.ours for t in res.tables for r in t.rows}
    for d in DEVICES:
        assert rows[f"WF mean, {d}"] == pytest.approx(wf[d].mean(), rel=TOL)
    assert rows["one-way ANOVA on WF: p"] == pytest.approx(p, rel=TOL)
    assert rows["paired t-test on WF RHI vs PHANToM: Holm-adjusted p"] == pytest.approx(adjusted[0], rel=TOL)
    order = sorted(DEVICES, key=lambda d: wf[d].mean())
    assert order == sorted(DEVICES, key=lambda d: summary[d].mean)
