"""The dossier of a headline claim not reproduced: the thesis passage, the literal reading, the others, a conclusion.

Every other reading the text supports comes with its sentence and rhi's number under it.

The data (one `Dossier` per claim, by the claim's key) is in `rhi.report.readings`. A reading's number is a
row of an experiment's result (by quantity prefix), so an experiment that computes a new reading only adds a
row; a reading whose row is not in the run reads "not computed in this run". The conclusion follows from
the numbers, in this order: reproduced under the literal reading (then no dossier is shown); reproduced
(or close) under a named reading, where that beats the literal one; inconsistent within the thesis (the
thesis numbers that contradict each other); rests on data the thesis does not publish (named); else the
literal verdict, no reading doing better. The headline verdict stays the literal reading's.
"""

from __future__ import annotations

import dataclasses
import html
import math
from collections.abc import Callable, Sequence

from rhi.errors import InvalidInput
from rhi.report.headline import Lookup, Verdict
from rhi.report.rules import CLOSE, NOT_RUN, REPRODUCED, VERDICTS, judge


@dataclasses.dataclass(frozen=True)
class Reading:
    """One reading of a claim other than the literal one.

    Attributes:
        name: short name, e.g. "plain pseudoinverse J⁺".
        sentence: the thesis sentence (quoted, with its line) that allows it.
        experiment: the experiment whose row holds rhi's number under this reading.
        quantity: the row's quantity prefix.
        transform: turns the row's value into the claim's unit (e.g. a fraction into "holds" = 1.0).
        below: for an ordering, a second row: the value is then 1 where `quantity`'s row is below it, else 0.
        measure: instead of one row, rhi's number from several rows of `experiment` (a `Lookup`).
    """

    name: str
    sentence: str
    experiment: str
    quantity: str
    transform: Callable[[float], float] | None = None
    below: str | None = None
    measure: Callable[[Lookup], float] | None = None

    def value(self, look: Lookup) -> float | None:
        """The number of rhi under this reading, None where this run has no such row."""
        if self.measure is not None:
            try:
                return float(self.measure(look))
            except InvalidInput:
                return None
        rows = (self.quantity,) if self.below is None else (self.quantity, self.below)
        if not all(look.has(self.experiment, q) for q in rows):
            return None
        v = look(self.experiment, self.quantity)
        if self.below is not None:
            v = float(v < look(self.experiment, self.below))
        return self.transform(v) if self.transform is not None else v


@dataclasses.dataclass(frozen=True)
class Dossier:
    """What the thesis says about a claim and how else it can be read.

    Attributes:
        key: the claim's key (its `rhi.thesis` value's key).
        passage: section, equation and figure or table, with the thesis line.
        literal: the literal reading, as the headline measures it.
        readings: the other readings the text supports.
        inconsistent: thesis numbers that contradict each other (with the numbers), where there are;
            ``{0}``, ``{1}``, ... stand for this run's `evidence` values.
        missing: data the thesis does not publish that the value rests on (named), where it does.
        evidence: (experiment, quantity prefix) of rows whose values `inconsistent` quotes.
        checked: how rhi's implementation of the claim's equations was checked against an independent
            transcription of the thesis (the test and its tolerance), where it was.
    """

    key: str
    passage: str
    literal: str
    readings: tuple[Reading, ...] = ()
    inconsistent: str = ""
    missing: str = ""
    evidence: tuple[tuple[str, str], ...] = ()
    checked: str = ""

    def __post_init__(self) -> None:
        if not (self.readings or self.missing or self.inconsistent):
            raise InvalidInput(f"readings: dossier {self.key!r} needs an alternative reading, a missing datum "
                               "or the thesis numbers that contradict each other")


@dataclasses.dataclass(frozen=True)
class Case:
    """A dossier evaluated on a run: the verdict, rhi's number and verdict under each reading, the conclusion."""

    verdict: Verdict
    dossier: Dossier
    readings: tuple[tuple[Reading, float | None, str], ...]
    conclusion: str


def _fmt(v: float | None, verdict: Verdict) -> str:
    if v is None:
        return "not computed in this run"
    if not math.isfinite(v):
        return verdict.claim.absent
    return dataclasses.replace(verdict, ours=v).ours_text


def evaluate(verdicts: Sequence[Verdict], dossiers: dict[str, Dossier], results: Sequence) -> list[Case]:
    """The dossiers of the claims judged and not reproduced in this run (claims without one are skipped)."""
    look = Lookup(results)
    out = []
    for v in verdicts:
        if v.verdict in (REPRODUCED, NOT_RUN) or v.claim.key not in dossiers:
            continue
        d = dossiers[v.claim.key]
        rows = []
        for rd in d.readings:
            x = rd.value(look)
            rows.append((rd, x, "—" if x is None else judge(v.claim.thesis, x, effect=v.claim.effect)))
        quoted = [f"{look(e, q):.4g}" if look.has(e, q) else "(not computed in this run)" for e, q in d.evidence]
        out.append(Case(v, d, tuple(rows), _conclusion(v, d, rows, quoted)))
    return out


def _conclusion(v: Verdict, d: Dossier, rows: list[tuple[Reading, float | None, str]], quoted: list[str]) -> str:
    better = VERDICTS[:VERDICTS.index(v.verdict)] if v.verdict in VERDICTS else ()
    for wanted in (k for k in (REPRODUCED, CLOSE) if k in better):  # a reading counts where it beats the literal
        hits = [rd.name for rd, _, verdict in rows if verdict == wanted]
        if hits:
            return f"{wanted} under the reading “{hits[0]}” (the literal reading: {v.verdict})"
    if d.inconsistent:
        return f"inconsistent within the thesis: {d.inconsistent.format(*quoted)}"
    if d.missing:
        return f"rests on data the thesis does not publish: {d.missing}"
    return f"{v.verdict} under the literal reading; no other reading the text supports does better"


def missing_dossiers(verdicts: Sequence[Verdict], dossiers: dict[str, Dossier]) -> list[str]:
    """Claims judged and not reproduced in this run that have no dossier (for the report's audit)."""
    return [f"{v.claim.where}: {v.claim.claim}" for v in verdicts
            if v.verdict not in (REPRODUCED, NOT_RUN) and v.claim.key not in dossiers]


def to_html(cases: Sequence[Case]) -> str:
    """The dossiers as HTML sections (ids ``dossier-<key>``, linked from the headline table)."""
    parts = []
    for c in cases:
        v, d = c.verdict, c.dossier
        items = "".join(
            f"<tr><td>{html.escape(rd.name)}</td><td class='src'>{html.escape(rd.sentence)}</td>"
            f"<td>{html.escape(_fmt(x, v))}</td><td>{html.escape(verdict)}</td></tr>" for rd, x, verdict in c.readings)
        parts.append(
            f"<section class='dossier' id='dossier-{html.escape(v.claim.key)}'><h3>{html.escape(v.claim.where)} — "
            f"{html.escape(v.claim.claim)}</h3><p><b>Passage</b>: {html.escape(d.passage)}</p>"
            f"<table><tr><th>reading</th><th>what the text says</th><th>rhi</th><th>verdict</th></tr>"
            f"<tr><td><b>literal</b> (the headline)</td><td class='src'>{html.escape(d.literal)}</td>"
            f"<td>{html.escape(v.ours_text)}</td><td>{html.escape(v.verdict)}</td></tr>{items}</table>"
            + (f"<p><b>Not published</b>: {html.escape(d.missing)}</p>" if d.missing and d.missing not in c.conclusion
               else "")
            + (f"<p><b>Implementation checked</b>: {html.escape(d.checked)}</p>" if d.checked else "")
            + f"<p><b>Conclusion</b>: {html.escape(c.conclusion)}</p></section>")
    return "\n".join(parts)


def to_markdown(cases: Sequence[Case], header: str = "") -> str:
    """The dossiers as Markdown (docs/fidelity.md)."""

    def cell(text: str) -> str:
        return text.replace("|", "\\|").replace("\n", " ")

    out = [header] if header else []
    for c in cases:
        v, d = c.verdict, c.dossier
        out += [f"## {v.claim.where} — {v.claim.claim}", "", f"- **Passage**: {d.passage}",
                f"- **Thesis**: {v.thesis_text}; **verdict** (literal reading): {v.verdict}", "",
                "| reading | what the text says | rhi | verdict |", "|---|---|---|---|",
                f"| **literal** (the headline) | {cell(d.literal)} | {cell(v.ours_text)} | {v.verdict} |"]
        out += [f"| {cell(rd.name)} | {cell(rd.sentence)} | {cell(_fmt(x, v))} | {verdict} |"
                for rd, x, verdict in c.readings]
        out += [""] + ([f"- **Not published**: {d.missing}"] if d.missing and d.missing not in c.conclusion else []) + (
            [f"- **Implementation checked**: {d.checked}"] if d.checked else []) + [f"- **Conclusion**: {c.conclusion}", ""]
    return "\n".join(out)
