"""rhi.analysis: system identification (eqs. 3.24, 6.22), psychophysics (§3.5-3.6) and statistics."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from scipy import stats as sps

from rhi.analysis import psychophysics as P, stats as S, sysid
from rhi.errors import InvalidInput

# Table 6.1 (free, stiff FME) and a Rehab-like heavy device: M [kg], Φ [N s/m].
PLANTS = [(0.036, 0.2953), (0.125, 0.6325), (0.54, 2.0)]
FORCES = np.linspace(0.5, 1.5, 10)  # §3.5/§6.4: constant forces of 0.5-1.5 N, ten trials


def trials(mass, damping, *, duration=0.15, seed=None, **kw):
    """Ten trials with independent noise (seed (seed, i) for trial i)."""
    return [
        sysid.simulate_record(
            mass, damping, f, duration=duration, label=str(i), seed=None if seed is None else (seed, i), **kw
        )
        for i, f in enumerate(FORCES)
    ]


# --------------------------------------------------------------------------- system identification


@pytest.mark.parametrize("mass,damping", PLANTS)
@pytest.mark.parametrize("derivative", ["savgol", "central"])
def test_sysid_noiseless_recovers_mass_and_damping(mass, damping, derivative):
    # Acceptance: within 5 %. The filter is a linear operator applied to both sides of the
    # model, so only the differentiator's truncation error is left; we hold it to 0.1 %.
    res = sysid.identify(trials(mass, damping), derivative=derivative)
    assert res.mass == pytest.approx(mass, rel=1e-3)
    assert res.damping == pytest.approx(damping, rel=1e-3)
    assert res.n_trials == 10
    assert res.residual_rms < 1e-3 * FORCES.min()
    assert res.r_squared > 0.999999


def test_sysid_noisy_intervals_cover_truth_and_state_the_error():
    # 10 µm position noise (encoder-class) and 0.02 N force noise (JR3-class), ten trials.
    mass, damping = 0.07, 0.30
    clean = trials(mass, damping)
    res = sysid.identify(trials(mass, damping, position_noise=1e-5, force_noise=0.02, seed=7))
    assert res.covariance == "cluster" and res.dof == 9
    # The stated error is the actual error's size (one data set: within 4 standard errors) ...
    assert abs(res.mass - mass) < 4 * res.mass_se and abs(res.damping - damping) < 4 * res.damping_se
    assert 0 < res.mass_se < 0.02 * mass and 0 < res.damping_se < 0.05 * damping
    assert res.residual_rms > 10 * sysid.identify(clean).residual_rms  # the noise shows in the fit error
    # ... and over 40 seeded data sets (noise added to the clean trajectories) the 95 %
    # intervals cover the truth at least 34 times (P(fewer) < 1 % for a true 95 % interval).
    rng = np.random.default_rng(2020)
    hits = np.zeros(2, dtype=int)
    for _ in range(40):
        noisy = [
            sysid.Record(
                r.time,
                r.position + 1e-5 * rng.standard_normal(r.time.size),
                r.force + 0.02 * rng.standard_normal(r.time.size),
                r.label,
            )
            for r in clean
        ]
        fit = sysid.identify(noisy)
        hits += [fit.mass_ci[0] <= mass <= fit.mass_ci[1], fit.damping_ci[0] <= damping <= fit.damping_ci[1]]
    assert (hits >= 34).all(), hits
    print(f"sysid 95 % interval coverage over 40 data sets: M {hits[0]}/40, Φ {hits[1]}/40")
    # Ordinary least squares ignores the filter's autocorrelation and is overconfident.
    ols = sysid.identify(noisy, covariance="ols")
    assert ols.mass_se < 0.5 * fit.mass_se


def test_sysid_offset_and_position_range():
    mass, damping, coulomb = 0.125, 0.6325, 0.2
    recs = trials(mass, damping, duration=0.3, offset=coulomb)
    res = sysid.identify(recs, offset=True)
    assert res.offset == pytest.approx(coulomb, rel=1e-3)
    assert res.mass == pytest.approx(mass, rel=1e-3) and res.damping == pytest.approx(damping, rel=1e-3)
    biased = sysid.identify(recs)  # the unmodelled constant force must show up as error
    assert abs(biased.damping - damping) > 0.05 * damping
    # Only samples between 1 and 5 cm along u (as "at the point of interest").
    win = sysid.identify(recs, offset=True, position_range=(0.01, 0.05))
    assert win.n_samples < res.n_samples
    assert win.mass == pytest.approx(mass, rel=1e-3) and win.damping == pytest.approx(damping, rel=1e-3)


def test_lowpass_is_linear_and_zero_phase():
    rng = np.random.default_rng(1)
    x, y = rng.standard_normal((2, 400))
    fx, fy = sysid.lowpass(np.stack([x, y]), sample_rate=1000.0)
    assert np.allclose(sysid.lowpass(2 * x - 3 * y + 1.5, sample_rate=1000.0), 2 * fx - 3 * fy + 1.5, atol=1e-12)
    t = np.arange(2000) / 1000.0
    s = np.sin(2 * np.pi * 2 * t)  # 2 Hz, well inside the 20 Hz pass band: no delay, no attenuation
    assert np.allclose(sysid.lowpass(s, sample_rate=1000.0)[200:-200], s[200:-200], atol=1e-3)
    with pytest.raises(InvalidInput, match="cutoff_hz"):
        sysid.lowpass(s, sample_rate=1000.0, cutoff_hz=600.0)


def test_project_onto_direction():
    rng = np.random.default_rng(3)
    p = rng.standard_normal((3, 50, 2))
    f = rng.standard_normal((3, 50, 2))
    x, F = sysid.project(p, f, [0.0, 2.0])
    assert np.array_equal(x, p[..., 1]) and np.array_equal(F, f[..., 1])
    u = np.array([1.0, 1.0]) / np.sqrt(2)
    x, F = sysid.project(p[0], f[0, :, 0], [3.0, 3.0])
    assert np.allclose(x, p[0] @ u) and np.array_equal(F, f[0, :, 0])
    with pytest.raises(InvalidInput, match="u"):
        sysid.project(p, f, [0.0, 0.0])
    with pytest.raises(InvalidInput, match="forces"):
        sysid.project(p, f[..., :10, :], [0.0, 1.0])


def _write_sysid_csv(path, recs, u):
    u = np.asarray(u, float) / np.linalg.norm(u)
    perp = np.array([-u[1], u[0]])
    lines = ["trial,time,x,y,fx,fy"]
    for r in recs:
        for t, x, f in zip(r.time, r.position, r.force):
            p = 0.5 * perp + x * u + np.array([0.5, 0.1])  # off-axis offset: projection must remove it
            fv = f * u + 0.3 * perp  # a force component normal to u is ignored
            lines.append(f"{r.label},{float(t)!r},{float(p[0])!r},{float(p[1])!r},{float(fv[0])!r},{float(fv[1])!r}")
    path.write_text("\n".join(lines) + "\n")


def test_sysid_from_csv_round_trip(tmp_path):
    recs = trials(0.036, 0.2953)
    path = tmp_path / "sysid.csv"
    _write_sysid_csv(path, recs, [0.0, 1.0])
    loaded = sysid.from_csv(path, u=[0.0, 1.0])
    assert [r.label for r in loaded] == [r.label for r in recs]
    a, b = sysid.identify(loaded), sysid.identify(recs)
    assert a.mass == pytest.approx(b.mass, rel=1e-9) and a.damping == pytest.approx(b.damping, rel=1e-9)
    # A single trial with scalar columns needs no direction.
    one = tmp_path / "one.csv"
    r0 = recs[0]
    rows = "".join(f"{t!r},{x!r},{f!r}\n" for t, x, f in zip(r0.time.tolist(), r0.position.tolist(), r0.force.tolist()))
    one.write_text("Time , Position, Force\n" + rows)
    (r,) = sysid.from_csv(one)
    assert np.array_equal(r.position, recs[0].position)


def _set_field(lines, line_no, column, text):
    """Copy of the CSV lines with field ``column`` (0-based) of file line ``line_no`` replaced."""
    out = list(lines)
    fields = out[line_no - 1].split(",")
    fields[column] = text
    out[line_no - 1] = ",".join(fields)
    return out


@pytest.mark.parametrize(
    "mutate,match",
    [
        (lambda L: [L[0].replace(",fx,fy", ",gx,gy")] + L[1:], r"missing column 'force'"),
        (lambda L: [L[0].replace("time", "t")] + L[1:], r"missing column 'time'"),
        (lambda L: _set_field(L, 6, 2, "nan"), r"line 6, column 'x': non-finite"),
        (lambda L: _set_field(L, 6, 4, "abc"), r"line 6, column 'fx': 'abc' is not a number"),
        (lambda L: _set_field(L, 7, 3, ""), r"line 7, column 'y': '' is not a number"),
        (lambda L: L[:8] + [L[9], L[8]] + L[10:], r"line 10, column 'time': 0.007 does not increase"),
        (lambda L: [L[0]] + L[1:11], r"trial '0' has 10 rows; need at least"),
    ],
)
def test_sysid_from_csv_errors_name_line_and_column(tmp_path, mutate, match):
    recs = trials(0.036, 0.2953)[:2]
    path = tmp_path / "good.csv"
    _write_sysid_csv(path, recs, [0.0, 1.0])
    lines = path.read_text().splitlines()
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(mutate(lines)) + "\n")
    with pytest.raises(InvalidInput, match=match):
        sysid.from_csv(bad, u=[0.0, 1.0])


def test_sysid_input_errors(tmp_path):
    recs = trials(0.036, 0.2953)[:2]
    path = tmp_path / "good.csv"
    _write_sysid_csv(path, recs, [0.0, 1.0])
    with pytest.raises(InvalidInput, match="^u: required"):
        sysid.from_csv(path)
    with pytest.raises(InvalidInput, match="u: expected 2"):
        sysid.from_csv(path, u=[0, 0, 1])
    r = recs[0]
    jitter = r.time + np.where(np.arange(r.time.size) == 20, 3e-4, 0.0)
    uneven = sysid.Record(jitter, r.position, r.force, "j")
    with pytest.raises(InvalidInput, match="'j'.*not uniformly sampled"):
        sysid.identify([uneven])
    fixed = uneven.resampled(1000.0)
    assert fixed.is_uniform()
    with pytest.raises(InvalidInput, match="not independently excited"):
        sysid.identify([sysid.Record(r.time, np.zeros_like(r.time), r.force)])
    with pytest.raises(InvalidInput, match="at least"):
        sysid.Record(r.time[:10], r.position[:10], r.force[:10])
    short = sysid.Record(r.time[:33], r.position[:33], r.force[:33], "s")
    with pytest.raises(InvalidInput, match="only 0 samples selected"):
        sysid.identify([short])  # 33 ms: all of it lies within the default trims
    with pytest.raises(InvalidInput, match="record 's': 33 samples at 1000 Hz are too few"):
        sysid.identify([short], window=31)


# --------------------------------------------------------------------------- psychophysics


def test_protocol_matches_section_3_5():
    trials_ = P.protocol(seed=4)
    assert len(trials_) == 10 * 3 * 9 * 10  # 90 comparisons per device, 270 per subject
    def key(t):
        return t.subject, t.device

    for _, group in itertools.groupby(sorted(trials_, key=key), key=key):
        group = list(group)
        pct, counts = np.unique([t.comparison_percent for t in group], return_counts=True)
        assert np.array_equal(pct, [-35, -25, -15, -5, 0, 5, 15, 25, 35]) and (counts == 10).all()
        assert all(t.comparison == pytest.approx(50.0 * (1 + t.comparison_percent / 100)) for t in group)
        assert len({t.block for t in group}) == 1
    s1 = [t for t in trials_ if t.subject == "S01"]
    assert [t.index for t in s1] == list(range(270))
    # Random order, reproducible, and independent of how many subjects follow.
    assert [t.comparison for t in s1[:90]] != sorted(t.comparison for t in s1[:90])
    assert P.protocol(seed=4) == trials_
    assert P.protocol(2, seed=4) == [t for t in trials_ if t.subject in ("S01", "S02")]
    assert P.protocol(seed=5) != trials_
    with pytest.raises(InvalidInput, match="repetitions"):
        P.protocol(repetitions=0)


@pytest.fixture(scope="module")
def observer_fits():
    """Fits of a known cumulative-Gaussian observer: 10 and 40 repetitions per comparison."""
    truth = {"pse": 51.0, "jnd": 5.5, "lapse": 0.02}
    out = {}
    for reps in (10, 40):
        trials_ = P.protocol(["A"], ["RHI"], repetitions=reps, seed=11)
        resp = P.simulate_responses(trials_, pse=truth["pse"], jnd=truth["jnd"], lapse=truth["lapse"], seed=reps)
        (fit,) = P.fit_all(resp, overdispersion=False)
        out[reps] = fit
    return truth, out


def test_psychometric_fit_recovers_known_pse_and_jnd(observer_fits):
    truth, fits = observer_fits
    for reps, fit in fits.items():
        assert fit.n_trials == 9 * reps
        assert fit.pse_ci[0] <= truth["pse"] <= fit.pse_ci[1], (reps, fit.pse_ci)
        assert fit.jnd_ci[0] <= truth["jnd"] <= fit.jnd_ci[1], (reps, fit.jnd_ci)
        wf = truth["jnd"] / truth["pse"]
        assert fit.wf_ci[0] <= wf <= fit.wf_ci[1]
        # Definitions (eqs. 3.25, 3.26) and ordering of the thresholds.
        assert fit.jnd == pytest.approx((fit.ut - fit.lt) / 2, rel=1e-12)
        assert fit.wf == pytest.approx(fit.jnd / fit.pse, rel=1e-12)
        assert fit.lt < fit.pse < fit.ut and fit.lt_ci[0] < fit.lt_ci[1]
        assert fit.curve([fit.pse])[0] == pytest.approx(0.5, abs=1e-9)  # equal asymptotes
    # Four times the trials: intervals about half as wide.
    width = {r: np.subtract(*fits[r].jnd_ci[::-1]) for r in fits}
    assert width[40] < 0.75 * width[10]
    assert abs(fits[40].pse - truth["pse"]) < 1.5 and abs(fits[40].jnd - truth["jnd"]) < 1.5


def test_fit_equals_a_direct_psignifit_call(observer_fits):
    # Our scipy.special Gaussian must give psignifit's own "norm" fit.
    import psignifit

    _, fits = observer_fits
    ours = fits[10]
    ref = psignifit.psignifit(
        ours.data, sigmoid="norm", experiment_type="equal asymptote", fixed_parameters={"eta": 0.0}, verbose=False
    )
    for name in ("threshold", "width", "lambda"):
        want = ref.parameter_estimate_MAP[name]
        assert ours.result.parameter_estimate_MAP[name] == pytest.approx(want, rel=1e-6, abs=1e-9)
    assert ours.pse == pytest.approx(ref.parameter_estimate_MAP["threshold"], rel=1e-6)
    lt, ut = ref.threshold([0.25, 0.75], unscaled=True, return_ci=False)
    assert ours.jnd == pytest.approx((ut - lt) / 2, rel=1e-6)
    # psignifit's marginal 95 % interval of the threshold is the PSE interval (grid resolution).
    lo, hi = ref.confidence_intervals["threshold"]["0.95"]
    step = np.diff(ref.parameter_values["threshold"][:2])[0]
    assert ours.pse_ci == pytest.approx((lo, hi), abs=step)


def test_lapse_corrected_thresholds(observer_fits):
    _, fits = observer_fits
    fit = fits[40]
    c = np.repeat(fit.data[:, 0], fit.data[:, 2].astype(int))
    r = np.concatenate([np.r_[np.ones(int(k)), np.zeros(int(n - k))] for _, k, n in fit.data])
    raw = P.fit_psychometric(c, r, overdispersion=False, lapse_corrected=False)
    assert raw.lapse > 0
    # Read off the curve with its lapses, the 25/75 % points lie further out.
    assert raw.jnd > fit.jnd and raw.pse == pytest.approx(fit.pse, rel=1e-9)
    assert fit.curve([raw.ut])[0] == pytest.approx(0.75, abs=1e-6)


def test_responses_csv_round_trip_and_table(tmp_path, observer_fits):
    trials_ = P.protocol(["S1", "S2"], ["RHI", "Rehab"], repetitions=2, seed=1)
    resp = P.simulate_responses(trials_, pse=50.0, jnd=6.0, seed=2)
    path = tmp_path / "resp.csv"
    path.write_text(
        "Subject,Device,Comparison,Response,notes\n"
        + "".join(
            f"{s},{d},{float(c)!r},{r},x\n"
            for s, d, c, r in zip(resp.subject, resp.device, resp.comparison, resp.response)
        )
    )
    back = P.from_csv(path)
    assert np.array_equal(back.subject, resp.subject) and np.array_equal(back.response, resp.response)
    assert np.array_equal(back.comparison, resp.comparison) and back.line[0] == 2
    _, fits = observer_fits
    rows = P.results_table(fits.values())
    assert rows[0]["subject"] == "A" and rows[0]["jnd_low"] <= rows[0]["jnd"] <= rows[0]["jnd_high"]
    f = fits[10]
    cells = [("b", "X", 1.0), ("a", "X", 2.0), ("a", "Y", 3.0), ("b", "Y", 4.0)]
    fake = [dataclasses.replace(f, subject=s, device=d, wf=w) for s, d, w in cells]
    subjects, wf = P.by_device(fake)
    assert subjects == ["a", "b"] and np.array_equal(wf["X"], [2.0, 1.0]) and np.array_equal(wf["Y"], [3.0, 4.0])
    with pytest.raises(InvalidInput, match=r"device 'Y' has no fit for subject\(s\) \['b'\]"):
        P.by_device(fake[:3])


def test_study_analysis_from_fits(observer_fits):
    # Table 3.3 layout and the §3.6 tests on fits of 4 subjects x 3 devices (values set by hand).
    _, fits = observer_fits
    f = fits[10]
    wf = {"RHI": [0.10, 0.12, 0.11, 0.09], "PHANToM": [0.12, 0.13, 0.12, 0.10], "Rehab": [0.15, 0.14, 0.16, 0.13]}
    fake = [
        dataclasses.replace(f, subject=f"S{i}", device=d, wf=w, jnd=50 * w, pse=50.0)
        for d, ws in wf.items()
        for i, w in enumerate(ws)
    ]
    study = P.analyse_fits(fake)
    assert study.devices == ["RHI", "PHANToM", "Rehab"] and study.subjects == ["S0", "S1", "S2", "S3"]
    assert [s.mean for s in study.summary["wf"]] == pytest.approx([0.105, 0.1175, 0.145])
    assert study.summary["jnd"][2].std == pytest.approx(50 * np.std(wf["Rehab"], ddof=1))
    assert (study.anova.df_between, study.anova.df_within) == (2, 9)
    assert (study.anova_rm.df_between, study.anova_rm.df_within) == (2, 6)
    assert study.anova.statistic == pytest.approx(sps.f_oneway(*wf.values()).statistic)
    assert [(t.a, t.b, t.correction) for t in study.paired] == [
        ("RHI", "PHANToM", "holm"),
        ("RHI", "Rehab", "holm"),
        ("PHANToM", "Rehab", "holm"),
    ]
    with pytest.raises(InvalidInput, match="no fit for subject"):
        P.analyse_fits(fake[:-1])


@pytest.mark.parametrize(
    "body,match",
    [
        ("subject,device,comparison\nS1,RHI,50\n", r"missing column 'response'"),
        (
            "subject,device,comparison,response\nS1,RHI,50,1\nS1,RHI,55,2\n",
            r"line 3, column 'response': '2' is not 0 or 1",
        ),
        ("subject,device,comparison,response\nS1,RHI,50,yes\n", r"line 2, column 'response'"),
        ("subject,device,comparison,response\nS1,RHI,-5,1\n", r"line 2, column 'comparison'"),
        ("subject,device,comparison,response\nS1,,50,1\n", r"line 2, column 'device': empty"),
    ],
)
def test_responses_csv_errors(tmp_path, body, match):
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(InvalidInput, match=match):
        P.from_csv(path)


def test_too_few_trials_to_fit_names_subject_device_and_line(tmp_path):
    rows = ["subject,device,comparison,response"]
    rows += [f"S1,Rehab,{c},{int(c > 50)}" for c in [40, 60] * 3]
    rows += [f"S1,RHI,{c},{int(c > 50)}" for c in [40, 45, 50, 55, 60] * 6]
    path = tmp_path / "few.csv"
    path.write_text("\n".join(rows) + "\n")
    resp = P.from_csv(path)
    msg = r"subject 'S1' device 'Rehab' has 6 trials at 2 comparison levels.*line 2\)"
    with pytest.raises(InvalidInput, match=msg):
        P.fit_all(resp, overdispersion=False)


# --------------------------------------------------------------------------- statistics


@pytest.fixture(scope="module")
def wf_data():
    """A fixed data set shaped like Table 3.3: 10 subjects x 3 devices (WF)."""
    rng = np.random.default_rng(33)
    subject = rng.normal(0, 0.012, 10)
    return {
        "RHI": 0.111 + subject + rng.normal(0, 0.015, 10),
        "PHANToM": 0.118 + subject + rng.normal(0, 0.015, 10),
        "Rehab": 0.145 + subject + rng.normal(0, 0.015, 10),
    }


def test_one_way_anova_equals_scipy_and_summary(wf_data):
    res = S.one_way_anova(wf_data)
    ref = sps.f_oneway(*wf_data.values())
    assert res.statistic == pytest.approx(ref.statistic, rel=1e-12)
    assert res.p_value == pytest.approx(ref.pvalue, rel=1e-10)
    assert (res.df_between, res.df_within) == (2, 27)  # the thesis's F(2, 27)
    d = S.describe(wf_data)
    summ = S.one_way_anova_from_summary([x.mean for x in d], [x.std for x in d], [x.n for x in d])
    assert summ.statistic == pytest.approx(res.statistic, rel=1e-10)
    assert summ.p_value == pytest.approx(res.p_value, rel=1e-8)
    assert d[0].std == pytest.approx(np.std(wf_data["RHI"], ddof=1))
    assert d[2].median == pytest.approx(np.median(wf_data["Rehab"]))


def test_repeated_measures_anova_against_hand_computation(wf_data):
    res = S.repeated_measures_anova(wf_data)
    Y = np.column_stack(list(wf_data.values()))  # (subjects, conditions)
    n, k = Y.shape
    g = Y.mean()
    ss_cond = n * ((Y.mean(0) - g) ** 2).sum()
    ss_subj = k * ((Y.mean(1) - g) ** 2).sum()
    ss_err = ((Y - g) ** 2).sum() - ss_cond - ss_subj
    F = (ss_cond / (k - 1)) / (ss_err / ((k - 1) * (n - 1)))
    assert (res.df_between, res.df_within) == (2, 18)
    assert res.statistic == pytest.approx(F, rel=1e-10)
    assert res.p_value == pytest.approx(sps.f.sf(F, 2, 18), rel=1e-8)


def test_paired_t_tests_holm_and_fdr_equal_scipy_statsmodels(wf_data):
    from statsmodels.stats.multitest import multipletests

    pairs = list(itertools.combinations(wf_data, 2))
    raw = [sps.ttest_rel(wf_data[a], wf_data[b]) for a, b in pairs]
    for correction in ("holm", "fdr_bh"):
        tests = S.paired_t_tests(wf_data, correction=correction)
        rej, padj, _, _ = multipletests([r.pvalue for r in raw], alpha=0.05, method=correction)
        assert [(t.a, t.b) for t in tests] == pairs
        for t, r, pa, rj in zip(tests, raw, padj, rej):
            assert t.statistic == pytest.approx(r.statistic, rel=1e-12)
            assert t.p_value == pytest.approx(r.pvalue, rel=1e-12)
            assert t.p_adjusted == pytest.approx(pa, rel=1e-12) and t.significant == rj and t.df == 9
    # Table 5.2's one-sided hypotheses "a < b": half the two-sided p where t < 0.
    less = S.paired_t_tests(wf_data, pairs=[("RHI", "Rehab")], alternative="less", correction="fdr_bh")[0]
    assert less.statistic < 0 and less.p_value == pytest.approx(raw[1].pvalue / 2, rel=1e-10)
    assert less.hypothesis == "RHI < Rehab"


def test_adjustments_by_hand():
    p = [0.01, 0.04, 0.03]
    holm, rej = S.adjust(p, correction="holm")
    assert np.allclose(holm, [0.03, 0.06, 0.06]) and rej.tolist() == [True, False, False]
    bh, rej = S.adjust(p, correction="fdr_bh")
    assert np.allclose(bh, [0.03, 0.04, 0.04]) and rej.tolist() == [True, True, True]
    assert np.allclose(S.adjust(p, correction="none")[0], p)


def test_statistics_input_errors(wf_data):
    with pytest.raises(InvalidInput, match="same subjects"):
        S.paired_t_tests({"a": [1, 2, 3], "b": [1, 2]})
    with pytest.raises(InvalidInput, match="unknown group 'Z'"):
        S.paired_t_tests(wf_data, pairs=[("RHI", "Z")])
    with pytest.raises(InvalidInput, match=r"groups\['b'\]: non-finite value at index 1"):
        S.one_way_anova({"a": [1.0, 2.0], "b": [1.0, np.nan]})
    with pytest.raises(InvalidInput, match="correction"):
        S.paired_t_tests(wf_data, correction="sidak_typo")


@pytest.mark.parametrize(
    "means,stds,n,h,reported",
    [
        ((0.111, 0.118, 0.145), (0.019, 0.021, 0.021), 10, 5e-4, (7.36, 2, 27)),  # Table 3.3 WF, §3.6
        ((48.8, 54.3, 62.3), (8.9, 10.4, 10.8), 8, 0.05, (3.57, 2, 21)),  # Table 5.1 time, §5.4
        ((0.207, 0.425, 2.048), (0.047, 0.229, 0.830), 8, 5e-4, (32.63, 2, 21)),  # Table 5.1 effort
        ((105.0, 126.5, 129.2), (60.2, 43.3, 46.3), 8, 0.05, (0.55, 2, 21)),  # Table 5.1 error
    ],
)
def test_thesis_anovas_are_between_subjects_one_way(means, stds, n, h, reported):
    # The thesis's F values follow from its "mean (std)" tables by a between-subjects one-way
    # ANOVA: each reported F lies in the range its tables' rounding (± h) allows, with the
    # reported degrees of freedom (the repeated-measures ANOVA would have df (2, 2(n - 1))).
    F_rep, d1, d2 = reported
    res = S.one_way_anova_from_summary(means, stds, [n] * 3)
    assert (res.df_between, res.df_within) == (d1, d2)
    z = np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=6)))  # corners, edges, centre of the box
    m = np.asarray(means) + h * z[:, :3]
    s = np.asarray(stds) + h * z[:, 3:]
    grand = m.mean(axis=1, keepdims=True)
    F = (n * ((m - grand) ** 2).sum(axis=1) / d1) / ((n - 1) * (s**2).sum(axis=1) / d2)
    assert F[len(F) // 2] == pytest.approx(res.statistic, rel=1e-12)  # the centre: the table as printed
    assert F.min() <= F_rep <= F.max()
