"""The headline-claims table: the thesis's main claims, rhi's value for each, a verdict and a reason.

A `Claim` names the thesis value it checks (`rhi.thesis`), the experiments that measure it, how to
read rhi's number from their results (`measure`), the effect it claims where the sign is a finding
(`effect`), what its value rests on (`inputs`), and one sentence of reason (`reason`, formatted with
rhi's measured numbers). `evaluate` judges the claims of `rhi.report.claims.CLAIMS` on a run's results
by the rules of `rhi.report.rules`; `to_html` and `to_text` render them, grouped by chapter.

Adding a claim (e.g. from another chapter's module)::

    from rhi.report.headline import Claim
    from rhi.report.rules import Effect
    from rhi import thesis as T
    Claim("Fig. 7.1", "simple scaling gives 12 % less force than ASCM", T.SCALING_GAP, ("ch7.example_3dof",),
          measure=lambda r: r("ch7.example_3dof", "peak force deficit of scaling vs ASCM (pseudoinverse"),
          reason="... {ours:.1f} % ...", inputs=("kinematics",), effect=Effect(0.0, "a deficit"))

and append it to `rhi.report.claims.CLAIMS`.
"""

from __future__ import annotations

import dataclasses
import html
import math
from collections.abc import Callable, Sequence

from rhi.errors import InvalidInput
from rhi.experiments.result import Result, Row
from rhi.report.rules import (
    CLOSE,
    DIRECTION,
    NOT_REPRODUCED,
    NOT_RUN,
    REPRODUCED,
    UNPUBLISHED,
    VERDICTS,
    Effect,
    judge,
)
from rhi.thesis import ThesisValue, is_registered, printed

__all__ = ["CLOSE", "DIRECTION", "NOT_REPRODUCED", "NOT_RUN", "REPRODUCED", "UNPUBLISHED", "VERDICTS", "Claim",
           "Lookup", "Verdict", "anchor", "chapter_of", "counts", "evaluate", "to_html", "to_text"]


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

    def has(self, experiment: str, quantity: str) -> bool:
        """Whether the results hold such a row."""
        try:
            self.row(experiment, quantity)
        except InvalidInput:
            return False
        return True


@dataclasses.dataclass(frozen=True)
class Claim:
    """One headline claim of the thesis.

    Attributes:
        where: table, figure or section, e.g. "Table 3.1".
        claim: the claim in a few words, e.g. "ρ_RHI > ρ_PHANToM, ρ_Rehab at both points".
        thesis: the thesis value it rests on (its tolerance decides "reproduced"; for an ordering, the
            number of points it is claimed at, 1 = holds).
        experiments: result names that measure it (the first is the link target).
        measure: rhi's value from the results (a `Lookup`), in the thesis value's unit (for an ordering,
            the number of points where it holds).
        reason: one sentence on what rhi measured, `str.format`-ted with ``ours`` and `details`.
        inputs: keys of `rhi.report.rules.INPUTS` the thesis's value rests on (they alone decide
            "cannot be reproduced ...").
        effect: the claimed effect where its sign is a finding (`rhi.report.rules`), else None.
        details: more measured numbers for `reason` (a dict from a `Lookup`).
        shown: the thesis's statement as printed in the table (default: the value as the thesis printed it).
        absent: how a non-finite value of rhi's reads (e.g. "never reached" for a time).
        variant: where the headline number is one of several variants rhi computes, which one and why.
        points: for an ordering claimed at n points (the thesis value is n), n: rhi's value is then the
            number of points where it holds, shown "k of n".
    """

    where: str
    claim: str
    thesis: ThesisValue
    experiments: tuple[str, ...]
    measure: Callable[[Lookup], float]
    reason: str
    inputs: tuple[str, ...]
    effect: Effect | None = None
    details: Callable[[Lookup], dict] | None = None
    shown: str | None = None
    absent: str = "—"
    variant: str = ""
    points: int | None = None

    def __post_init__(self) -> None:
        if not is_registered(self.thesis):
            raise InvalidInput(f"thesis: the value of claim {self.where!r} is not a registered rhi.thesis value")
        if not self.experiments:
            raise InvalidInput("experiments: a claim needs the experiment that measures it")
        if not self.inputs:
            raise InvalidInput(f"inputs: claim {self.where!r} must name what its value rests on")
        judge(self.thesis, float(self.thesis), effect=self.effect, inputs=self.inputs)  # validates inputs/effect
        if self.points is not None and not (self.thesis.claim and float(self.thesis) == self.points):
            raise InvalidInput(f"points: claim {self.where!r} is an ordering at {self.points} points only if its "
                               "thesis value is that count")

    @property
    def key(self) -> str:
        """The claim's id: its thesis value's key."""
        return self.thesis.key


@dataclasses.dataclass(frozen=True)
class Verdict:
    """A claim evaluated on a run: rhi's value, the verdict, and the reason."""

    claim: Claim
    ours: float | None
    verdict: str
    reason: str

    @property
    def thesis_text(self) -> str:
        """The thesis's statement, its number as the thesis printed it."""
        c = self.claim
        if c.shown:
            return c.shown
        if c.points is not None:
            return f"holds at {c.points} of {c.points}"
        if c.thesis.claim and float(c.thesis) == 1:
            return "holds"
        unit = f" {c.thesis.unit}" if c.thesis.unit not in ("", "p") else ""
        return f"{printed(c.thesis)}{unit}"

    @property
    def ours_text(self) -> str:
        """Our value as text: "holds" / "k of n" for an ordering, `Claim.absent` where not finite."""
        c = self.claim
        if self.ours is None:
            return "—"
        if not math.isfinite(self.ours):
            return c.absent
        if c.points is not None:
            return f"holds at {self.ours:.0f} of {c.points}"
        if c.thesis.claim and float(c.thesis) == 1:
            return "holds" if self.ours == 1 else "does not hold"
        unit = f" {c.thesis.unit}" if c.thesis.unit not in ("", "p") else ""
        return f"{self.ours:.4g}{unit}"


def evaluate(claims: Sequence[Claim], results: Sequence[Result]) -> list[Verdict]:
    """Judge every claim on a run's results (claims whose experiments did not run get "not run")."""
    look = Lookup(results)
    out = []
    for c in claims:
        if not all(e in look.results for e in c.experiments):
            out.append(Verdict(c, None, NOT_RUN, "its experiment is not part of this run"))
            continue
        try:
            ours = float(c.measure(look))
            extra = c.details(look) if c.details is not None else {}
        except InvalidInput as e:  # a row the claim reads is missing: reported, not fatal to the report
            out.append(Verdict(c, None, NOT_RUN, f"missing in this run's results: {e}"))
            continue
        reason = c.reason.format(ours=ours, **extra)
        if c.variant:
            reason = f"{reason} [Variant: {c.variant}]"
        out.append(Verdict(c, ours, judge(c.thesis, ours, effect=c.effect, inputs=c.inputs), reason))
    return out


def anchor(experiment: str) -> str:
    """HTML id of an experiment's section."""
    return "exp-" + experiment.replace(".", "-")


_CHAPTERS = {"ch3": "Chapter 3", "ch4": "Chapter 4", "ch5": "Chapter 5", "ch6": "Chapter 6", "ch7": "Chapter 7",
             "appa": "Appendix A", "appb": "Appendix B"}
#: CSS class of each verdict (colours in `rhi.report.STYLE`).
CLS = {REPRODUCED: "v-ok", CLOSE: "v-close", DIRECTION: "v-dir", NOT_REPRODUCED: "v-off", UNPUBLISHED: "v-na",
       NOT_RUN: "v-run"}


def chapter_of(claim: Claim) -> str:
    """The chapter (or appendix) a claim belongs to, from its experiment's id."""
    ch = claim.experiments[0].split(".")[0]
    return _CHAPTERS.get(ch, ch)


def counts(verdicts: Sequence[Verdict]) -> dict[str, int]:
    """How many claims got each verdict (and "not run")."""
    return {k: sum(v.verdict == k for v in verdicts) for k in (*VERDICTS, NOT_RUN)}


def _tally(verdicts: Sequence[Verdict]) -> str:
    n = counts(verdicts)
    judged = len(verdicts) - n[NOT_RUN]
    return "; ".join(f"{k}: {n[k]} of {judged}" for k in VERDICTS if n[k]) + (
        f" ({n[NOT_RUN]} not run)" if n[NOT_RUN] else "")


def tally_html(verdicts: Sequence[Verdict]) -> str:
    """The tally box that opens the report: one coloured cell per verdict, "k of n" claims judged."""
    n = counts(verdicts)
    judged = len(verdicts) - n[NOT_RUN]
    cells = "".join(f"<div class='tally-cell {CLS[k]}'><b>{n[k]}</b> of {judged}<br>{html.escape(k)}</div>"
                    for k in VERDICTS)
    extra = f"<p class='note'>{n[NOT_RUN]} claims not run (their experiments are not part of this run).</p>" \
        if n[NOT_RUN] else ""
    return f"<div class='tally'>{cells}</div>{extra}"


def to_html(verdicts: Sequence[Verdict], dossier_ids: frozenset[str] = frozenset()) -> str:
    """The headline table as HTML, grouped by chapter with subtotals; claims link to their experiment and dossier."""
    head = "<tr><th>#</th><th>where</th><th>claim</th><th>thesis</th><th>rhi</th><th>verdict</th><th>reason</th></tr>"
    rows, i = [], 0
    groups: dict[str, list[Verdict]] = {}
    for v in verdicts:
        groups.setdefault(chapter_of(v.claim), []).append(v)
    for chapter, vs in groups.items():
        rows.append(f"<tr class='chapter'><th colspan='7'>{html.escape(chapter)} — {html.escape(_tally(vs))}</th></tr>")
        for v in vs:
            i += 1
            c = v.claim
            dossier = (f" <a href='#dossier-{c.key}'>dossier</a>" if c.key in dossier_ids else "")
            rows.append(
                f"<tr class='{CLS[v.verdict]}'><td>{i}</td><td><a href='#{anchor(c.experiments[0])}'>"
                f"{html.escape(c.where)}</a></td><td>{html.escape(c.claim)}</td><td>{html.escape(v.thesis_text)}</td>"
                f"<td>{html.escape(v.ours_text)}</td><td class='verdict'>{html.escape(v.verdict)}{dossier}</td>"
                f"<td class='reason'>{html.escape(v.reason)}</td></tr>")
    return f"<table class='headline'>{head}{''.join(rows)}</table>"


def to_text(verdicts: Sequence[Verdict], width: int = 110) -> str:
    """The headline table as plain text (printed at the end of `rhi reproduce`)."""
    lines = [f"{'where':<12} {'claim':<52} {'thesis':<18} {'rhi':<14} verdict"]
    for v in verdicts:
        c = v.claim
        lines.append(f"{c.where[:12]:<12} {c.claim[:52]:<52} {v.thesis_text[:18]:<18} {v.ours_text[:14]:<14} {v.verdict}")
    lines.append(_tally(verdicts))
    return "\n".join(line[:width + 60] for line in lines)
