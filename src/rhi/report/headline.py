"""The headline-claims table: the thesis's main claims, rhi's value for each, a verdict and a reason.

A `Claim` names the thesis value it checks (`rhi.thesis`), the experiments that measure it, how to
read rhi's number from their results (`measure`), when only the direction holds (`direction`), and
one sentence of reason (`reason`, formatted with rhi's measured numbers). `evaluate` turns the claims
of `rhi.report.claims.CLAIMS` and a run's results into `Verdict` rows; `to_html` and `to_text` render them.

Adding a claim (e.g. from another chapter's module)::

    from rhi.report.headline import Claim
    from rhi import thesis as T
    Claim("Fig. 7.1", "simple scaling gives 12 % less force than ASCM", T.SCALING_GAP, ("ch7.example_3dof",),
          measure=lambda r: r("ch7.example_3dof", "peak force deficit of scaling vs ASCM (pseudoinverse"),
          direction=lambda x: x > 0, reason="... {ours:.1f} % ...")

and append it to `rhi.report.claims.CLAIMS`.
"""

from __future__ import annotations

import dataclasses
import html
import math
from collections.abc import Callable, Sequence

from rhi.errors import InvalidInput
from rhi.experiments.result import Result, Row
from rhi.thesis import ThesisValue, is_registered

REPRODUCED = "reproduced"
DIRECTION = "reproduced in direction only"
NOT_REPRODUCED = "not reproduced"
UNPUBLISHED = "cannot be reproduced from what the thesis publishes"
#: The four verdicts a claim can get.
VERDICTS = (REPRODUCED, DIRECTION, NOT_REPRODUCED, UNPUBLISHED)
#: A claim whose experiments were not part of this run (e.g. `rhi reproduce --only ch3`).
NOT_RUN = "not run"


class Lookup:
    """Reads rows of a run's results: ``r(experiment, quantity_prefix)`` → rhi's value; ``r.row(...)`` → the Row."""

    def __init__(self, results: Sequence[Result]):
        self.results = {res.name: res for res in results}

    def row(self, experiment: str, quantity: str) -> Row:
        """The first row of `experiment` whose quantity starts with `quantity`.

        Raises:
            InvalidInput: no such experiment in the results or no such row.
        """
        res = self.results.get(experiment)
        if res is None:
            raise InvalidInput(f"experiment: {experiment!r} is not in the results")
        for table in res.tables:
            for r in table.rows:
                if r.quantity.startswith(quantity):
                    return r
        raise InvalidInput(f"quantity: no row of {experiment!r} starts with {quantity!r}")

    def __call__(self, experiment: str, quantity: str) -> float:
        """Our value of the first row of `experiment` whose quantity starts with `quantity`."""
        return float(self.row(experiment, quantity).ours)


@dataclasses.dataclass(frozen=True)
class Claim:
    """One headline claim of the thesis.

    Attributes:
        where: table, figure or section, e.g. "Table 3.1".
        claim: the claim in a few words, e.g. "ρ_RHI > ρ_PHANToM, ρ_Rehab at both points".
        thesis: the thesis value it rests on (its tolerance decides "reproduced"; a claim value 1 = holds).
        experiments: result names that measure it (the first is the link target).
        measure: rhi's value from the results (a `Lookup`), in the thesis value's unit.
        reason: one sentence on why rhi's value is what it is, `str.format`-ted with ``ours`` and `details`.
        direction: whether rhi's value shows the thesis's direction (a sign, an order); None: no direction.
        unpublished: set where the thesis's value rests on data it does not publish (human subjects,
            hardware it does not specify): the verdict is then "cannot be reproduced ...".
        details: more measured numbers for `reason` (a dict from a `Lookup`).
        shown: the thesis's statement as printed in the table (default: the value and unit).
    """

    where: str
    claim: str
    thesis: ThesisValue
    experiments: tuple[str, ...]
    measure: Callable[[Lookup], float]
    reason: str
    direction: Callable[[float], bool] | None = None
    unpublished: bool = False
    details: Callable[[Lookup], dict] | None = None
    shown: str | None = None

    def __post_init__(self) -> None:
        if not is_registered(self.thesis):
            raise InvalidInput(f"thesis: the value of claim {self.where!r} is not a registered rhi.thesis value")
        if not self.experiments:
            raise InvalidInput("experiments: a claim needs the experiment that measures it")


@dataclasses.dataclass(frozen=True)
class Verdict:
    """A claim evaluated on a run: rhi's value, the verdict, and the reason."""

    claim: Claim
    ours: float | None
    verdict: str
    reason: str

    @property
    def thesis_text(self) -> str:
        """The thesis's statement with its tolerance."""
        c = self.claim
        if c.shown:
            return c.shown
        if c.thesis.claim:
            return "holds" if float(c.thesis) == 1 else f"{float(c.thesis):g}"
        unit = f" {c.thesis.unit}" if c.thesis.unit not in ("", "p") else ""
        tol = f" ± {c.thesis.tol:.2g}" if c.thesis.tol > 0 else ""
        return f"{float(c.thesis):.6g}{tol}{unit}"

    @property
    def ours_text(self) -> str:
        """Our value as text (yes/no for a claim of the thesis)."""
        if self.ours is None or not math.isfinite(self.ours):
            return "—"
        if self.claim.thesis.claim and float(self.claim.thesis) == 1:
            return "holds" if self.ours == 1 else "does not hold"
        unit = f" {self.claim.thesis.unit}" if self.claim.thesis.unit not in ("", "p") else ""
        return f"{self.ours:.4g}{unit}"


def evaluate(claims: Sequence[Claim], results: Sequence[Result]) -> list[Verdict]:
    """Evaluate every claim on a run's results (claims whose experiments did not run get "not run")."""
    look = Lookup(results)
    out = []
    for c in claims:
        if not all(e in look.results for e in c.experiments):
            out.append(Verdict(c, None, NOT_RUN, "its experiment is not part of this run"))
            continue
        ours = float(c.measure(look))
        extra = c.details(look) if c.details is not None else {}
        reason = c.reason.format(ours=ours, **extra)
        if c.unpublished:
            verdict = UNPUBLISHED
        elif c.thesis.within(ours):
            verdict = REPRODUCED
        elif c.direction is not None and math.isfinite(ours) and c.direction(ours):
            verdict = DIRECTION
        else:
            verdict = NOT_REPRODUCED
        out.append(Verdict(c, ours, verdict, reason))
    return out


def anchor(experiment: str) -> str:
    """HTML id of an experiment's section."""
    return "exp-" + experiment.replace(".", "-")


_CLS = {REPRODUCED: "ok", DIRECTION: "dir", NOT_REPRODUCED: "off", UNPUBLISHED: "na", NOT_RUN: "na"}


def to_html(verdicts: Sequence[Verdict]) -> str:
    """The headline table as HTML (each claim linked to its experiment's section)."""
    head = ("<tr><th>#</th><th>where</th><th>claim</th><th>thesis</th><th>rhi</th><th>verdict</th>"
            "<th>reason</th></tr>")
    rows = []
    for i, v in enumerate(verdicts, 1):
        c = v.claim
        rows.append(
            f"<tr class='{_CLS[v.verdict]}'><td>{i}</td><td><a href='#{anchor(c.experiments[0])}'>{html.escape(c.where)}</a>"
            f"</td><td>{html.escape(c.claim)}</td><td>{html.escape(v.thesis_text)}</td><td>{html.escape(v.ours_text)}</td>"
            f"<td class='verdict'>{html.escape(v.verdict)}</td><td>{html.escape(v.reason)}</td></tr>")
    return f"<table class='headline'>{head}{''.join(rows)}</table>"


def counts(verdicts: Sequence[Verdict]) -> dict[str, int]:
    """How many claims got each verdict (and "not run")."""
    return {k: sum(v.verdict == k for v in verdicts) for k in (*VERDICTS, NOT_RUN)}


def to_text(verdicts: Sequence[Verdict], width: int = 110) -> str:
    """The headline table as plain text (printed at the end of `rhi reproduce`)."""
    lines = [f"{'where':<12} {'claim':<52} {'thesis':<18} {'rhi':<14} verdict"]
    for v in verdicts:
        c = v.claim
        lines.append(f"{c.where[:12]:<12} {c.claim[:52]:<52} {v.thesis_text[:18]:<18} {v.ours_text[:14]:<14} {v.verdict}")
    n = counts(verdicts)
    lines.append("; ".join(f"{k}: {n[k]}" for k in (*VERDICTS, NOT_RUN) if n[k]))
    return "\n".join(line[:width + 60] for line in lines)
