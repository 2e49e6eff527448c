"""Stiffness discrimination: the protocol of thesis §3.5 and the psychometric analysis of §3.6.

Protocol (§3.5): two-alternative forced choice (2AFC) by the method of constant
stimuli. On every trial the subject probes a reference virtual spring (50 N/m)
and a comparison spring and says which is stiffer. Nine comparisons, -35, -25,
-15, -5, 0, +5, +15, +25, +35 % of the reference, ten repetitions each, in
random order, for each haptic interface (RHI, PHANToM, Rehab): 90 trials per
device and subject.

Analysis (§3.6): the "positive fraction" is the proportion of trials on which
the *comparison* was judged stiffer. A psychometric function is fitted to it per
subject and device (the thesis used psignifit 2.5.6 for MATLAB; we use
psignifit 4, its successor), and from it

    PSE = x(50 %),  UT = x(75 %),  LT = x(25 %),
    JND = (UT − LT) / 2                                   (thesis eq. 3.26)
    WF  = JND / PSE                                       (thesis eq. 3.25)

Why a yes/no-type ("equal asymptote") fit and not psignifit's "2AFC": in
psignifit, "2AFC" means the response is *correct/incorrect* and the function
rises from a guess rate of 1/2 to 1 as the signal grows. Here the response is
"comparison stiffer", which runs from 0 (comparison much softer) through 1/2
(at the PSE) to 1 (comparison much stiffer): the full 0-1 range, like a yes/no
task, with the 25/50/75 % points the thesis reads off. Its asymptotes are lapses
(pressing the wrong answer by mistake), equally likely at both ends, so the
lower asymptote γ and the upper lapse λ are tied (psignifit's
``experiment_type="equal asymptote"``), which also keeps the 50 % point of the
fitted curve at its threshold parameter. ``experiment_type="yes/no"`` (γ and λ
free) is available.

Thresholds are read off the lapse-free sigmoid F by default (``lapse_corrected=
True``): lapses say nothing about sensitivity, and psignifit 2.5.6 defined its
thresholds ("cuts") on F too. Confidence intervals of PSE, LT, UT, JND and WF are
percentiles of psignifit's posterior over its parameter grid (JND and WF depend
on the threshold and the width jointly, so they are computed point by point on
the grid and weighted by the posterior mass), not psignifit's own
``Result.threshold`` intervals, which combine the interval ends of each
parameter and are documented as upper bounds only.

Measured with `simulate_responses` (observers with PSE ~ N(50, 1.5) N/m, JND
uniform in 4-8 N/m, lapse 0.02, the 90 trials of §3.5): with η fixed at 0
(``overdispersion=False``, 150 observers) the 95 % intervals covered the true PSE
in 96 % and the true JND and WF in 99 % of fits (conservative), JND error
-0.05 ± 1.8 N/m; with η estimated (40 observers) 95 %, 97.5 % and 97.5 %.
"""

from rhi.analysis.psychophysics.csv_responses import from_csv
from rhi.analysis.psychophysics.fit import (
    PsychometricFit,
    by_device,
    fit_all,
    fit_psychometric,
    results_table,
)
from rhi.analysis.psychophysics.study import StudyAnalysis, analyse, analyse_fits
from rhi.analysis.psychophysics.trials import (
    COMPARISON_PERCENT,
    DEVICES,
    MEASURES,
    REFERENCE_STIFFNESS,
    REPETITIONS,
    Z75,
    Responses,
    Trial,
    pool,
    protocol,
    simulate_responses,
)

__all__ = ["COMPARISON_PERCENT", "DEVICES", "MEASURES", "REFERENCE_STIFFNESS", "REPETITIONS", "Z75", "PsychometricFit",
           "Responses", "StudyAnalysis", "Trial", "analyse", "analyse_fits", "by_device", "fit_all", "fit_psychometric",
           "from_csv", "pool", "protocol", "results_table", "simulate_responses"]
