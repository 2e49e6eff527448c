"""The verdict rules of the headline claims, fixed before any number is looked at, and the function applying them.

The five verdicts, best first:

1. *reproduced*: rhi's value equals the thesis's within the thesis's rounding (half a unit of the last
   printed digit, `rhi.thesis`); an ordering or a count holds at every point it is claimed for.
2. *close*: not reproduced, but within `CLOSE_BAND` (5 %) of the thesis's value. Only for quantities whose
   relative difference means something (not an ordering or count, an angle, or a p-value).
3. *direction only*: neither of the above, the claim names an effect (a sign against a baseline: a gain
   above 0 %, a ratio below 100 %, a value above its start) and rhi's effect has the thesis's sign *and*
   at least `EFFECT_FRACTION` (a third) of the thesis's size. An effect is declared only where the sign is
   a finding: not where the method forces it (gradient ascent raises the objective it ascends), not on a
   time or a configuration (`math.isfinite` is no test), not on an ordering (it holds or it does not).
4. *not reproduced*: none of the above.
5. *cannot be reproduced from what the thesis publishes*: the claim's value rests on data the thesis does
   not publish (`UNPUBLISHED_INPUTS`: the responses of its human subjects). One rule for all claims that
   rest on the same inputs: a claim names its inputs (`INPUTS`) and the inputs alone decide this verdict.
   Link inertias are *not* unpublished: the thesis cites their sources ([23] Çavuşoğlu et al. 2002,
   [45] Dyck 2013); rhi's estimates of them are judged like any other number.

The headline verdict is for the literal reading of the thesis. Other readings the text supports stand
beside it in the claim's dossier (`rhi.report.dossiers`), never in its place.
"""

from __future__ import annotations

import dataclasses
import math

from rhi.errors import InvalidInput
from rhi.thesis import ThesisValue

REPRODUCED = "reproduced"
CLOSE = "close"
DIRECTION = "direction only"
NOT_REPRODUCED = "not reproduced"
UNPUBLISHED = "cannot be reproduced from what the thesis publishes"
#: The five verdicts, best first.
VERDICTS = (REPRODUCED, CLOSE, DIRECTION, NOT_REPRODUCED, UNPUBLISHED)
#: A claim whose experiments were not part of this run (e.g. `rhi reproduce --only ch3`).
NOT_RUN = "not run"
#: "close": |rhi − thesis| ≤ CLOSE_BAND · |thesis|.
CLOSE_BAND = 0.05
#: "direction only": rhi's effect is at least this fraction of the thesis's, with the same sign.
EFFECT_FRACTION = 1.0 / 3.0
#: Units on which a relative band means nothing (angles, p-values).
_NO_BAND_UNITS = ("deg", "rad", "p")

#: What a claim's value rests on → (description, published by the thesis).
INPUTS: dict[str, tuple[str, bool]] = {
    "kinematics": ("link lengths, joint limits, torque limits and the stated set-up", True),
    "inertias": ("link masses and inertias (the thesis cites [23] Çavuşoğlu et al. 2002 and [45] Dyck 2013); "
                 "rhi's are the estimates of models/rhi4/README.md", True),
    "plant": ("the simulated plant: inertias, friction and the stated controller gains", True),
    "mobile base": ("the Gen3 arm and the mecanum base with the stated gains; rhi's base slip and noise are "
                    "seeded estimates", True),
    "human subjects": ("the responses of the thesis's human subjects, which it does not publish", False),
}
#: Inputs the thesis does not publish: a claim resting on any of them is "cannot be reproduced ...".
UNPUBLISHED_INPUTS = frozenset(k for k, (_, published) in INPUTS.items() if not published)


@dataclasses.dataclass(frozen=True)
class Effect:
    """A claimed effect: the sign of (value − baseline), e.g. a gain above 0 %, a ratio below 100 %.

    Attributes:
        baseline: the value of no effect, in the claim's unit (0 for a gain in %, 100 for a ratio in %).
        what: the effect in words, e.g. "a gain".
    """

    baseline: float
    what: str

    def holds(self, ours: float, thesis: float) -> bool:
        """Whether rhi's effect has the thesis's sign and at least `EFFECT_FRACTION` of its size."""
        want, got = float(thesis) - self.baseline, float(ours) - self.baseline
        if want == 0 or not math.isfinite(got):
            return False
        return bool(got * want > 0 and abs(got) >= EFFECT_FRACTION * abs(want))


def banded(thesis: ThesisValue) -> bool:
    """Whether the "close" band applies to a thesis value (not to orderings, counts, angles, p-values, zero)."""
    return not thesis.claim and thesis.unit not in _NO_BAND_UNITS and float(thesis) != 0


def judge(thesis: ThesisValue, ours: float, *, effect: Effect | None = None, inputs: tuple[str, ...] = ()) -> str:
    """The verdict of one claim by the rules above.

    Args:
        thesis: the thesis's value (its tolerance is its rounding; a claim value is an ordering or count).
        ours: rhi's value in the same unit (a count of points where an ordering holds, for a count claim).
        effect: the claimed effect, where the sign is a finding.
        inputs: keys of `INPUTS` the thesis's value rests on.

    Raises:
        InvalidInput: an unknown input, or an effect on an ordering or count claim.
    """
    unknown = [k for k in inputs if k not in INPUTS]
    if unknown:
        raise InvalidInput(f"inputs: unknown {unknown}; known: {sorted(INPUTS)}")
    if effect is not None and thesis.claim:
        raise InvalidInput(f"effect: an ordering or count ({thesis.key}) holds or not; it has no effect size")
    if UNPUBLISHED_INPUTS.intersection(inputs):
        return UNPUBLISHED
    if not math.isfinite(ours):
        return NOT_REPRODUCED
    if thesis.within(ours):
        return REPRODUCED
    if banded(thesis) and abs(ours - float(thesis)) <= CLOSE_BAND * abs(float(thesis)) * (1 + 1e-12):
        return CLOSE
    if effect is not None and effect.holds(ours, thesis):
        return DIRECTION
    return NOT_REPRODUCED


def rules_html() -> str:
    """The rules as the report prints them above the headline table."""
    return (
        "<ol class='rules'>"
        "<li><b>reproduced</b>: within the thesis's rounding (half a unit of its last printed digit); an ordering "
        "or count holds at every point it is claimed for.</li>"
        f"<li><b>close</b>: within {CLOSE_BAND:.0%} of the thesis's value (not for orderings, counts, angles, "
        "p-values).</li>"
        "<li><b>direction only</b>: the claimed effect (a sign against a stated baseline) has the thesis's sign "
        "and at least a third of its size. Only where the sign could come out either way: never on "
        "a time, an ordering, or what the method forces (gradient ascent).</li>"
        "<li><b>not reproduced</b>: none of the above.</li>"
        "<li><b>cannot be reproduced from what the thesis publishes</b>: decided by the claim's inputs alone "
        "(the same for every claim on the same inputs): only the responses of human subjects are unpublished. "
        "Link inertias are cited ([23], [45]) and judged like any number.</li></ol>"
        "<p class='note'>Rules fixed before the numbers were looked at; the verdict is for the literal reading. "
        "Other readings the text supports stand beside it in the dossiers below, never in its place.</p>"
    )
