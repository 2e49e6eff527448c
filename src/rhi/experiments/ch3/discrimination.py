"""Table 3.3, Figs 3.9–3.10: the §3.5 stiffness-discrimination study with simulated subjects and devices.

Physics: for each device, each of the nine stimulus stiffnesses K (50 N/m ± 0, 5, 15,
25, 35 %) and each palpation duration T of a small grid, one simulation: the plant starts
at (0.49, −0.22) m (the RHI at the thesis's optimised configuration projected onto the
point, the NHIs by IK); the controller renders the virtual spring K (a one-sided wall
at the start point along u) plus the virtual fixture (§3.5: 1000 N/m, 5 N s/m across u)
through ``ForceRendering`` (the RHI also runs the ch. 3 VME-matching null-space
controller of `rhi.experiments.ch3.nullspace`); a physical stop 8 cm ahead (§3.5) bounds
the motion; the simulated hand (`MinimumJerkPalpation`) pushes in along u from the start
to 1 cm past the stop with a minimum-jerk reference of duration T and returns.

Perception: the observer estimates the stiffness from what reaches the hand during the
loading phase before the stop, K̂ = Σ F d / Σ d² (least squares through the origin of the
force the hand exerts along u against its displacement d; a spring has no force at zero
displacement, so any offset the device adds — Coulomb and viscous friction, inertia
during acceleration — is attributed to the spring). The device's distortion of K̂ depends
on the palpation speed, which varies from probe to probe.

Trials: the §3.5 protocol (`rhi.analysis.psychophysics.protocol`); on every trial the two
probes of the pair each draw a palpation duration from the grid (independently, uniform),
and the subject perceives K̃ = K̂ (1 + w_s ε), ε ~ N(0, 1) (Weber's law: noise
proportional to the magnitude), and answers "comparison stiffer" when K̃_comparison >
K̃_reference (with lapse probability ``lapse``, a coin flip). Each subject s has an
intrinsic Weber fraction w_s drawn once from N(``weber_mean``, ``weber_sd``) (clipped to
≥ 0.02), the same on every device: the devices differ only through the physics. The
default intrinsic WF, 0.08 ± 0.02, is the *lower* end of the range the thesis cites for
stiffness discrimination (0.08–0.30, [54], [73], [141]): a sensitive observer, so that
device effects are not drowned. It is an input of the model, not fitted to Table 3.3;
with the 2AFC comparison of two noisy percepts the measured WF of a transparent device is
about √2 · 0.674 · w ≈ 0.95 w.

Simulating every one of the 2700 probes would take hours, hence the lookup: one
simulation per (device, K, T), trials drawn from them (documented in the result).
Analysis: psignifit fits per subject and device, PSE, LT, UT, JND (eq. 3.26), WF (eq.
3.25), one-way ANOVA on WF (as the thesis: F(2, 27)), the repeated-measures ANOVA the
within-subject design calls for, and paired t-tests with Holm–Bonferroni (§3.6) and FDR.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from rhi import thesis as T
from rhi.analysis import psychophysics as pp
from rhi.analysis.stats import paired_t_tests
from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
from rhi.design.executors import parallel_map
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.ch3.measures import DEVICE_NAMES
from rhi.experiments.ch3.nullspace import controller, start_configuration
from rhi.experiments.identification import U
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress
from rhi.sim import Fixture, MinimumJerkPalpation, Plant, Wall, compose, simulate, stop
from rhi.study.results import fit_conditions

#: Table 3.3: (mean, std) of WF, JND [N/m], PSE [N/m] per device.
THESIS_TABLE_3_3 = T.TABLE_3_3
#: §3.6: one-way ANOVA on WF, F(2, 27) = 7.36, P = 0.0032.
THESIS_ANOVA = T.ANOVA_3_6
#: §3.6: Holm-adjusted paired t-tests on WF.
THESIS_PAIRED = T.PAIRED_3_6
#: Psychophysics: start point (§3.5), stop distance [m], fixture gains.
START = (0.49, -0.22)
STOP_DISTANCE = 0.08
FIXTURE_STIFFNESS, FIXTURE_DAMPING = 1000.0, 5.0
#: Palpation durations (in-stroke, minimum jerk) [s] of the lookup grid.
DURATIONS = (0.6, 0.9, 1.3, 2.0)


def perceived_stiffness(d: np.ndarray, F: np.ndarray) -> float:
    """K̂ = Σ F d / Σ d²: the stiffness a spring through the origin would need to explain (d, F) [N/m].

    Args:
        d: (N,) displacement into the tissue along u [m] (loading phase, before the stop).
        F: (N,) force the hand exerts along u [N].

    Raises:
        InvalidInput: fewer than 3 samples or no displacement.
    """
    d = np.asarray(d, dtype=float)
    F = np.asarray(F, dtype=float)
    if d.shape != F.shape or d.ndim != 1 or d.size < 3 or not np.any(d != 0):
        raise InvalidInput(f"d/F: need two equal 1-D arrays of >= 3 samples with displacement, "
                           f"got {d.shape}, {F.shape}")
    return float(F @ d / (d @ d))


def _palpation_controller(name: str, dev: Device):
    """The rendering controller: ForceRendering (eq. 7.2 with B^d = 0); the RHI also runs the ch. 3 VME matching."""
    if name == "RHI":
        return controller(dev)
    cfg = ControllerConfig(primary=ForceRendering(damping=0.0, passivity=None), objectives=(), damping=0.0,
                           saturation="none")
    return NullSpaceController(dev, cfg)


def _start_configuration(name: str, dev: Device, x0: np.ndarray) -> np.ndarray:
    if name == "RHI":
        return start_configuration(dev, x0, "thesis")
    return dev.ik(x0, np.full(dev.n, 0.3))


def palpate(
    name: str,
    stiffness: float,
    duration: float,
    *,
    start=START,
    u=U,
    stop_distance: float = STOP_DISTANCE,
    overshoot: float = 0.01,
    hold: float = 0.2,
    hand_stiffness: float = 300.0,
    hand_damping: float = 10.0,
    margin: float = 0.003,
) -> dict[str, np.ndarray | float]:
    """One palpation of a virtual spring through a simulated device (§3.5 set-up).

    The plant starts at rest at `start`; the controller renders a one-sided spring of
    `stiffness` from `start` along u plus the virtual fixture across u; a physical stop
    sits `stop_distance` ahead; a `MinimumJerkPalpation` hand strokes to
    `stop_distance + overshoot` in `duration` seconds and holds for `hold`.

    Args:
        name: "RHI", "PHANToM" or "Rehab".
        stiffness: K of the virtual spring [N/m].
        duration: stroke duration [s].
        start: (m,) start point [m].
        u: (m,) direction.
        stop_distance: distance of the physical stop [m] (§3.5: 8 cm).
        overshoot: how far past the stop the hand's reference goes [m].
        hold: hold time at the end [s].
        hand_stiffness: the hand's impedance stiffness [N/m].
        hand_damping: the hand's impedance damping [N s/m].
        margin: loading samples closer than this to the stop are left out [m].

    Returns:
        dict with "k_hat" (perceived stiffness, `perceived_stiffness` of the loading phase)
        [N/m], "d" [m] and "F" [N] of the loading phase, "peak_speed" [m/s] and "t", "x",
        "F_hand" of the whole run.
    """
    if name not in DEVICE_NAMES:
        raise InvalidInput(f"name: expected one of {list(DEVICE_NAMES)}, got {name!r}")
    if not (math.isfinite(stiffness) and stiffness > 0):
        raise InvalidInput(f"stiffness: must be a positive stiffness in N/m, got {stiffness!r}")
    dev = device(DEVICE_NAMES[name])
    x0 = np.asarray(start, dtype=float)
    uu = np.asarray(u, dtype=float) / np.linalg.norm(u)
    plant = Plant(dev)
    plant.reset(_start_configuration(name, dev, x0))
    hand = MinimumJerkPalpation(x0, uu, stop_distance + overshoot, duration, hand_stiffness, hand_damping)
    virtual = compose(Wall(x0, uu, stiffness), Fixture(x0, uu, FIXTURE_STIFFNESS, FIXTURE_DAMPING))
    log = simulate(plant, _palpation_controller(name, dev), duration=duration + hold, hand=hand, virtual=virtual,
                   physical=stop(x0 + stop_distance * uu, uu))
    if log.fault is not None:
        raise InvalidInput(f"name: the controller of {name} stopped while palpating: {log.fault}")
    d = (log.x - x0) @ uu
    F = log.F_hand @ uu
    k_end = int(np.argmax(d >= stop_distance - margin)) if np.any(d >= stop_distance - margin) else len(d)
    load = np.zeros(len(d), dtype=bool)
    load[:k_end] = True
    load &= d > 0
    return {"k_hat": perceived_stiffness(d[load], F[load]), "d": d[load], "F": F[load],
            "peak_speed": float(np.max(log.xdot @ uu)), "t": log.t, "x": d, "F_hand": F}


def stimulus_table(
    devices: Sequence[str] = tuple(DEVICE_NAMES),
    *,
    reference: float = pp.REFERENCE_STIFFNESS,
    comparison_percent: Sequence[float] = pp.COMPARISON_PERCENT,
    durations: Sequence[float] = DURATIONS,
    progress: Progress | None = None,
) -> dict[str, np.ndarray]:
    """K̂ of every (device, stiffness, stroke duration): the lookup the simulated trials draw from.

    Returns:
        {device: (len(comparison_percent), len(durations)) perceived stiffness [N/m]}, plus
        "stiffness" (k,) [N/m], "durations" (s,) [s] and "{device}_speed" (k, s) peak speeds [m/s].
    """
    K = reference * (1.0 + np.asarray(comparison_percent, dtype=float) / 100.0)
    T = np.asarray(durations, dtype=float)
    out: dict[str, np.ndarray] = {"stiffness": K, "durations": T}
    items = [(name, float(k), float(dur)) for name in devices for k in K for dur in T]
    # independent, deterministic simulations: the default executor runs them in parallel
    res = iter(parallel_map(_palpation_measures, items, progress=progress))
    for name in devices:
        kh = np.empty((K.size, T.size))
        sp = np.empty((K.size, T.size))
        for i in range(K.size):
            for j in range(T.size):
                kh[i, j], sp[i, j] = next(res)
        out[name], out[f"{name}_speed"] = kh, sp
    return out


def _palpation_measures(item: tuple[str, float, float]) -> tuple[float, float]:
    """(K̂ [N/m], peak speed [m/s]) of `palpate(name, stiffness, duration)` for item = (name, stiffness, duration)."""
    r = palpate(*item)
    return float(r["k_hat"]), float(r["peak_speed"])


class WeberObserver:
    """The §3.5 simulated subjects: K̂ of a drawn stroke duration through the device, Weber noise, lapses.

    One observer answers the trials of every subject of a study, in presentation order, from one random
    stream (``default_rng([seed, 1])``): first each subject's intrinsic Weber fraction w_s ~ N(`weber_mean`,
    `weber_sd`) clipped to >= 0.02, then per trial two stroke durations, two normal deviates and, with a lapse
    rate, the lapse draws (see the module docstring). Stiffnesses between the table's are interpolated
    linearly in K per duration (exact at the table's own).

    Args:
        table: `stimulus_table` output.
        subjects: number of subjects.
        reference: reference stiffness [N/m] (must lie in the table's range).
        weber_mean, weber_sd: the intrinsic Weber fractions' distribution.
        lapse: probability of a random answer.
        seed: seed of the stream.
    """

    def __init__(self, table: dict[str, np.ndarray], subjects: int, *, reference: float = pp.REFERENCE_STIFFNESS,
                 weber_mean: float = 0.08, weber_sd: float = 0.02, lapse: float = 0.0, seed: int = 0) -> None:
        if not (weber_mean > 0 and weber_sd >= 0):
            raise InvalidInput(f"weber_mean/weber_sd: need a positive mean and non-negative s.d., "
                               f"got {weber_mean}, {weber_sd}")
        if not (0.0 <= lapse < 1.0):
            raise InvalidInput(f"lapse: must lie in [0, 1), got {lapse!r}")
        if int(subjects) != subjects or subjects < 1:
            raise InvalidInput(f"subjects: need a positive integer, got {subjects!r}")
        self.table, self.reference, self.lapse = table, float(reference), float(lapse)
        self._order = np.argsort(table["stiffness"])
        self._K = np.asarray(table["stiffness"], dtype=float)[self._order]
        self.rng = np.random.default_rng([int(seed), 1])
        self.weber = np.maximum(self.rng.normal(weber_mean, weber_sd, size=int(subjects)), 0.02)

    def _perceived(self, device: str, stiffness: float, j: int) -> float:
        if device not in self.table:
            raise InvalidInput(f"table: no entry for device {device!r}")
        if not self._K[0] - 1e-9 <= stiffness <= self._K[-1] + 1e-9:
            raise InvalidInput(f"stiffness: {stiffness!r} N/m lies outside the table's "
                               f"[{self._K[0]:g}, {self._K[-1]:g}] N/m")
        return float(np.interp(stiffness, self._K, self.table[device][self._order, j]))

    def answer(self, subject: int, device: str, comparison: float) -> int:
        """1 if subject `subject` (0-based) judges `comparison` [N/m] stiffer than the reference on `device`."""
        n_dur = self.table["durations"].size
        j_ref, j_cmp = self.rng.integers(n_dur, size=2)
        w = self.weber[subject]
        e = self.rng.standard_normal(2)
        k_ref = self._perceived(device, self.reference, int(j_ref)) * (1.0 + w * e[0])
        k_cmp = self._perceived(device, comparison, int(j_cmp)) * (1.0 + w * e[1])
        answer = k_cmp > k_ref
        if self.rng.random() < self.lapse:
            answer = self.rng.random() < 0.5
        return int(answer)


def simulate_study(
    table: dict[str, np.ndarray],
    *,
    subjects: int = 10,
    devices: Sequence[str] = tuple(DEVICE_NAMES),
    repetitions: int = pp.REPETITIONS,
    comparison_percent: Sequence[float] = pp.COMPARISON_PERCENT,
    reference: float = pp.REFERENCE_STIFFNESS,
    weber_mean: float = 0.08,
    weber_sd: float = 0.02,
    lapse: float = 0.0,
    seed: int = 0,
) -> tuple[pp.Responses, np.ndarray]:
    """Simulated 2AFC responses of §3.5: the `rhi.analysis.psychophysics.protocol` trials answered by a `WeberObserver`.

    Args:
        table: `stimulus_table` output covering `devices` and `comparison_percent`.
        subjects: number of simulated subjects.
        devices: device names.
        repetitions: presentations per comparison and device (`rhi.analysis.psychophysics.protocol`).
        comparison_percent: comparisons [% of the reference].
        reference: reference stiffness [N/m].
        weber_mean: mean of the subjects' intrinsic Weber fractions w_s.
        weber_sd: their standard deviation.
        lapse: probability of a random answer.
        seed: seed of the protocol order, the subjects, the stroke durations and the noise.

    Returns:
        ``(responses, weber)``: the `Responses` and (subjects,) intrinsic Weber fractions.
    """
    pct = [float(p) for p in comparison_percent]
    K = reference * (1.0 + np.asarray(pct) / 100.0)
    if len(table["stiffness"]) != len(K) or not np.allclose(table["stiffness"], K):
        raise InvalidInput("table: its stiffnesses do not match comparison_percent and reference")
    if 0.0 not in pct:
        raise InvalidInput("comparison_percent: must include 0 (the reference itself is probed)")
    for d in devices:
        if d not in table:
            raise InvalidInput(f"table: no entry for device {d!r}")
    trials = pp.protocol(subjects, devices, reference=reference, comparison_percent=pct,
                         repetitions=repetitions, seed=seed)
    obs = WeberObserver(table, subjects, reference=reference, weber_mean=weber_mean, weber_sd=weber_sd,
                        lapse=lapse, seed=seed)
    index = {name: i for i, name in enumerate(sorted({t.subject for t in trials}))}
    resp = np.array([obs.answer(index[t.subject], t.device, t.comparison) for t in trials], dtype=np.int8)
    return pp.Responses.from_trials(trials, resp), obs.weber


def _summary_of(analysis, measure: str) -> dict[str, tuple[float, float, float]]:
    return {s.name: (s.mean, s.std, s.median) for s in analysis.summary[measure]}


@checked
def psychophysics(
    *,
    subjects: int = 10,
    repetitions: int = pp.REPETITIONS,
    comparison_percent: Sequence[float] = pp.COMPARISON_PERCENT,
    durations: Sequence[float] = DURATIONS,
    weber_mean: float = 0.08,
    weber_sd: float = 0.02,
    lapse: float = 0.0,
    seed: int = 0,
    overdispersion: bool = True,
    table: dict[str, np.ndarray] | None = None,
    progress: Progress | None = None,
) -> Result:
    """Table 3.3, Figs 3.9–3.10: the §3.5 stiffness-discrimination study with simulated subjects and devices.

    See the module docstring for the physics (one simulation per device, stiffness and
    stroke duration), the observer (K̂ through the origin, Weber noise w_s, the same w_s on
    every device) and the analysis (psignifit per subject and device, eqs. 3.25–3.26,
    one-way and repeated-measures ANOVA on WF, paired t-tests with Holm and with FDR).

    Args:
        subjects: simulated subjects (thesis: 10).
        repetitions: presentations per comparison and device (thesis: 10).
        comparison_percent: comparisons [% of 50 N/m] (thesis: 0, ±5, ±15, ±25, ±35).
        durations: stroke durations of the lookup grid [s].
        weber_mean: mean of the subjects' intrinsic Weber fractions (model input, not fitted).
        weber_sd: their standard deviation.
        lapse: lapse rate of the simulated answers.
        seed: seed of everything random.
        overdispersion: psignifit's η (False: about twice as fast).
        table: a precomputed `stimulus_table` (skips the simulations).
        progress: callback(done, total) over simulations, then fits.
    """
    devs = tuple(DEVICE_NAMES)
    n_sim = len(devs) * len(comparison_percent) * len(durations)
    n_fit = subjects * len(devs)
    total = (0 if table is not None else n_sim) + n_fit
    if table is None:
        cb = None if progress is None else (lambda k, n: progress(k, total))
        table = stimulus_table(devs, comparison_percent=comparison_percent, durations=durations, progress=cb)
    responses, weber = simulate_study(table, subjects=subjects, devices=devs, repetitions=repetitions,
                                      comparison_percent=comparison_percent, weber_mean=weber_mean,
                                      weber_sd=weber_sd, lapse=lapse, seed=seed)
    cb = None if progress is None else (lambda k, n: progress(total - n_fit + k, total))
    # independent fits, in parallel on the default executor: the analysis `rhi study analyze` runs
    analysis = fit_conditions(responses, conditions=devs, overdispersion=overdispersion, progress=cb)
    fits = analysis.fits
    fdr = paired_t_tests(analysis.values, correction="fdr_bh")

    rows = []
    units = {"wf": "", "jnd": "N/m", "pse": "N/m"}
    labels = {"wf": "WF", "jnd": "JND", "pse": "PSE"}
    for m in ("wf", "jnd", "pse"):
        summ = _summary_of(analysis, m)
        for d in devs:
            mean, std, _ = summ[d]
            th_mean, th_std = THESIS_TABLE_3_3[m][d]
            rows.append(Row(f"{labels[m]} mean, {d}", th_mean, mean, units[m]))
            rows.append(Row(f"{labels[m]} std, {d}", th_std, std, units[m]))
    stats_rows = [
        Row(f"one-way ANOVA on WF: F({analysis.anova.df_between:g}, {analysis.anova.df_within:g})", THESIS_ANOVA[0],
            analysis.anova.statistic, "", "thesis: F(2, 27) = 7.36"),
        Row("one-way ANOVA on WF: p", THESIS_ANOVA[1], analysis.anova.p_value, ""),
        Row(f"repeated-measures ANOVA on WF: F({analysis.anova_rm.df_between:g}, {analysis.anova_rm.df_within:g})",
            None, analysis.anova_rm.statistic, "", f"p = {analysis.anova_rm.p_value:.3g} (the within-subject design)"),
    ]
    for t, tf in zip(analysis.paired, fdr):
        th = THESIS_PAIRED.get((t.a, t.b), THESIS_PAIRED.get((t.b, t.a)))
        stats_rows.append(Row(f"paired t-test on WF {t.a} vs {t.b}: Holm-adjusted p", th, t.p_adjusted, "",
                              f"t({t.df}) = {t.statistic:.2f}, mean difference {t.mean_difference:+.4f}; "
                              f"FDR-adjusted p = {tf.p_adjusted:.3g}"))
    ref_i = [float(p) for p in comparison_percent].index(0.0)
    phys_rows = []
    for d in devs:
        kh = table[d][ref_i]
        phys_rows.append(Row(f"K̂ of the 50 N/m reference through {d}: mean over stroke durations", None,
                             float(np.mean(kh)), "N/m",
                             f"range {kh.min():.2f}–{kh.max():.2f} N/m over durations "
                             f"{np.round(table['durations'], 2).tolist()} s "
                             f"(peak speeds {np.round(table[f'{d}_speed'][ref_i], 2).tolist()} m/s)"))
        slope = np.polyfit(table["stiffness"], table[d].mean(axis=1), 1)[0]
        phys_rows.append(Row(f"dK̂/dK through {d} (1: transparent)", None, float(slope), ""))
    phys_rows.append(Row("subjects' intrinsic Weber fraction w_s: mean (model input)", None, float(np.mean(weber)), "",
                         f"drawn from N({weber_mean}, {weber_sd}); measured WF of a transparent device ≈ 0.95 w"))

    # Figures: Fig. 3.9 (subject #3, or the last if fewer), Fig. 3.10 (WF and JND per subject and device).
    subj_names = analysis.subjects
    s3 = subj_names[min(2, len(subj_names) - 1)]
    grid = np.linspace(table["stiffness"].min(), table["stiffness"].max(), 201)
    arrays: dict[str, np.ndarray] = {"stiffness_grid": grid, "stiffness": table["stiffness"],
                                     "durations": table["durations"], "weber": weber,
                                     "fig39_subject": np.array(subj_names.index(s3) + 1)}
    for f in fits:
        if f.subject == s3:
            arrays[f"fig39_data_{f.device}"] = f.data
            arrays[f"fig39_curve_{f.device}"] = f.curve(grid)
    arrays["fig39_ideal"] = (grid > pp.REFERENCE_STIFFNESS).astype(float) + 0.5 * (grid == pp.REFERENCE_STIFFNESS)
    for m in ("wf", "jnd", "pse"):
        _, vals = pp.by_device(fits, m, devices=devs)
        arrays[m] = np.array([vals[d] for d in devs])  # (devices RHI, PHANToM, Rehab; subjects S01, ...)
    for d in devs:
        arrays[f"khat_{d}"] = table[d]
        arrays[f"speed_{d}"] = table[f"{d}_speed"]
    order = np.argsort(arrays["wf"].mean(axis=1))
    notes = [
        f"Simulated study: {subjects} subjects × {len(devs)} devices × {len(comparison_percent)} comparisons × "
        f"{repetitions} repetitions; each probe draws one of {len(durations)} stroke durations "
        f"{list(durations)} s and uses the K̂ of that (device, stiffness, duration) simulation "
        f"({n_sim} MuJoCo runs, one per combination, instead of one per probe).",
        f"Observer: K̂ = ΣFd/Σd² over the loading phase; Weber noise w_s ~ N({weber_mean}, {weber_sd}) "
        "per subject, "
        "the same on every device; these are model inputs from the literature range the thesis cites (0.08–0.30), "
        "not fitted to Table 3.3.",
        f"Devices ordered by mean WF: {[devs[i] for i in order]} (thesis: RHI < PHANToM < Rehab).",
        "psignifit 4 (the thesis used 2.5.6), equal-asymptote cumulative Gaussian, thresholds on the lapse-free "
        "sigmoid; the thesis's ANOVA is the between-subjects one (F(2, 27)); the repeated-measures one fits the "
        "design.",
    ]
    return Result(
        "ch3.psychophysics",
        "Table 3.3 / Figs 3.9–3.10: stiffness discrimination through the simulated RHI, PHANToM and Rehab",
        [Table("Table 3.3: mean and std of WF, JND, PSE per device", rows),
         Table("§3.6 statistics on WF", stats_rows),
         Table("What the devices do to the perceived stiffness (simulation)", phys_rows)],
        arrays,
        notes,
    )
