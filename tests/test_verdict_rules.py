"""The verdict rules of the headline: each verdict recomputed from its numbers, no direction test that cannot fail.

The independent recomputation below is written from the rules' text (`rhi.report.rules`), not from `judge`.
It runs on the tables of a --quick reproduction of every thesis chapter (tests/data/quick_results.json.gz: the
`results` of the runs' results.json, merged, arrays dropped, gzipped), so every headline claim is judged, and on
a live partial run.
"""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path

import pytest

from rhi import thesis as T
from rhi.errors import InvalidInput
from rhi.experiments import ch3, ch7
from rhi.experiments.result import result_from_json
from rhi.report import dossiers, headline, rules
from rhi.report.claims import CLAIMS
from rhi.report.readings import DOSSIERS

DATA = Path(__file__).parent / "data" / "quick_results.json.gz"


def _quick_results():
    return [result_from_json(r) for r in json.loads(gzip.decompress(DATA.read_bytes()))]


def _expected(c: headline.Claim, ours: float) -> str:
    """The rules, as their text states them."""
    th = c.thesis
    if any(not rules.INPUTS[k][1] for k in c.inputs):
        return rules.UNPUBLISHED
    if not math.isfinite(ours):
        return rules.NOT_REPRODUCED
    if abs(ours - th) <= th.tol * (1 + 1e-9) + 1e-15:
        return rules.REPRODUCED
    if not th.claim and th.unit not in ("deg", "rad", "p") and th != 0 and abs(ours - th) <= 0.05 * abs(th) * (1 + 1e-12):
        return rules.CLOSE
    e = c.effect
    if e is not None:
        want, got = th - e.baseline, ours - e.baseline
        if want * got > 0 and abs(got) >= abs(want) / 3:
            return rules.DIRECTION
    return rules.NOT_REPRODUCED


def _check(verdicts):
    for v in verdicts:
        if v.verdict == headline.NOT_RUN:
            continue
        assert v.verdict == _expected(v.claim, v.ours), (v.claim.where, v.claim.claim, v.ours, v.verdict)
        assert "{" not in v.reason and v.reason.strip()


def test_every_headline_verdict_follows_from_its_numbers():
    verdicts = headline.evaluate(CLAIMS, _quick_results())
    assert all(v.verdict != headline.NOT_RUN for v in verdicts), "the fixture covers every chapter"
    _check(verdicts)
    # reasons restate this run's numbers: every judged claim's reason carries a digit
    assert all(any(ch.isdigit() for ch in v.reason) for v in verdicts)


def test_verdicts_of_a_live_partial_run_follow_from_their_numbers():
    verdicts = headline.evaluate(CLAIMS, [ch3.table_3_1(), ch7.example_3dof(steps=101)])
    assert sum(v.verdict != headline.NOT_RUN for v in verdicts) >= 6
    _check(verdicts)


def test_no_direction_test_that_cannot_fail():
    for c in CLAIMS:
        if c.effect is None:
            continue
        assert isinstance(c.effect, rules.Effect) and not c.thesis.claim
        # no effect (the baseline) and the opposite effect both fail; a third of the thesis's passes
        want = float(c.thesis) - c.effect.baseline
        assert rules.judge(c.thesis, c.effect.baseline, effect=c.effect) == rules.NOT_REPRODUCED, c.claim
        assert rules.judge(c.thesis, c.effect.baseline - want, effect=c.effect) == rules.NOT_REPRODUCED, c.claim
        assert not c.effect.holds(c.effect.baseline + 0.3 * want, c.thesis)
        assert c.effect.holds(c.effect.baseline + 0.34 * want, c.thesis)


def test_one_rule_for_claims_on_the_same_inputs():
    unpublished = {k for k, (_, published) in rules.INPUTS.items() if not published}
    assert unpublished == {"human subjects"}
    for c in CLAIMS:
        # the verdict "cannot be reproduced ..." comes from the inputs alone, whatever the number
        got = rules.judge(c.thesis, float(c.thesis), effect=c.effect, inputs=c.inputs)
        assert (got == rules.UNPUBLISHED) == bool(unpublished & set(c.inputs)), c.claim


def test_rules_examples():
    v = T.GAIN_6_4  # 51 %, printed to the unit
    gain = rules.Effect(0.0, "a gain")
    assert rules.judge(v, 51.4, effect=gain) == rules.REPRODUCED
    assert rules.judge(v, 53.0, effect=gain) == rules.CLOSE
    assert rules.judge(v, 76.7, effect=gain) == rules.DIRECTION  # larger than the thesis: the sign and size hold
    assert rules.judge(v, 20.0, effect=gain) == rules.DIRECTION
    assert rules.judge(v, 16.0, effect=gain) == rules.NOT_REPRODUCED  # below a third
    assert rules.judge(v, -20.0, effect=gain) == rules.NOT_REPRODUCED
    assert rules.judge(v, 51.0, inputs=("human subjects",)) == rules.UNPUBLISHED
    assert rules.judge(T.TABLE_3_2_ORDER, 1.0) == rules.NOT_REPRODUCED  # an ordering at 1 of 2 points
    assert rules.judge(T.THETA_Z["C1"], 88.0) == rules.NOT_REPRODUCED  # no band on angles
    with pytest.raises(InvalidInput, match="effect"):
        rules.judge(T.TABLE_3_2_ORDER, 2.0, effect=gain)
    with pytest.raises(InvalidInput, match="inputs"):
        rules.judge(v, 51.0, inputs=("gut feeling",))


def test_lumped_claims_are_split_and_orderings_print_k_of_n():
    keys = [c.key for c in CLAIMS]
    assert len(keys) == len(set(keys))
    assert "fig3_7.lambda_r" in keys and "fig3_8.rho_r" in keys
    c = next(c for c in CLAIMS if c.key == "table3_2.order")
    v = headline.Verdict(c, 1.0, rules.NOT_REPRODUCED, "r")
    assert v.ours_text == "holds at 1 of 2" and v.thesis_text == "holds at 2 of 2"
    t = next(c for c in CLAIMS if c.key == "sB_4_2.singular_t")
    assert headline.Verdict(t, math.nan, rules.NOT_REPRODUCED, "r").ours_text == "never reached"
    g = next(c for c in CLAIMS if c.key == "table4_1.C2.GM_T")
    assert headline.Verdict(g, 0.06, rules.CLOSE, "r").thesis_text == "0.0590"


def test_every_claim_not_reproduced_has_a_dossier():
    results = _quick_results()
    verdicts = headline.evaluate(CLAIMS, results)
    assert dossiers.missing_dossiers(verdicts, DOSSIERS) == []
    cases = dossiers.evaluate(verdicts, DOSSIERS, results)
    assert len(cases) == sum(v.verdict != rules.REPRODUCED for v in verdicts)
    for case in cases:
        d = case.dossier
        assert d.passage and d.literal and (d.readings or d.missing or d.inconsistent)
        assert case.conclusion
    assert set(DOSSIERS) <= {c.key for c in CLAIMS}, "a dossier for a claim that does not exist"
