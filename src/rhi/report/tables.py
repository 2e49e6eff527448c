"""Result tables in the report: thesis as printed, rhi, difference, verdict colour, note; and the audit.

A row is

- *within* when rhi's value equals the thesis value within its tolerance (the thesis's rounding,
  `rhi.thesis`) — green;
- *outside* otherwise — amber, and it must carry a note (the experiment's, or the explanation
  `rhi.report.explain` holds for that thesis value);
- a *bound* when the thesis column is an acceptance bound (≤ / ≥): green when met, red when not,
  never counted as a miss of a thesis value.

Relative differences are printed only where they mean something (`Row.relative`).
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence

from rhi.experiments.result import Result, Row, Table
from rhi.report.explain import explanation
from rhi.thesis import ThesisValue, is_registered, printed


def fmt(v: float | None) -> str:
    """A number for a table cell (— for none or non-finite)."""
    if v is None or not math.isfinite(v):
        return "—"
    a = abs(v)
    return f"{v:.4g}" if 1e-3 <= a < 1e4 or a == 0 else f"{v:.3e}"


def thesis_cell(r: Row) -> str:
    """The thesis column: the number as the thesis printed it (its rounding is the tolerance), or the bound."""
    if r.thesis is None:
        return "—"
    if r.bound is not None:
        return f"{'≤' if r.bound == 'max' else '≥'} {fmt(r.thesis)}"
    if isinstance(r.thesis, ThesisValue):
        text = printed(r.thesis)
        return text if r.tolerance is None else f"{text} (± {r.tolerance:.2g})"
    return fmt(r.thesis)


def difference_cell(r: Row) -> str:
    """The difference rhi − thesis ("0" below floating-point noise, — for a bound)."""
    d = r.difference
    if r.bound is not None or d is None:
        return "—"
    return "0" if abs(d) <= 1e-9 * max(1.0, abs(float(r.thesis or 0.0))) else fmt(d)


def note_of(r: Row) -> str:
    """The row's note, else the explanation of its thesis value where it is outside the tolerance."""
    if r.note:
        return r.note
    return explanation(r) if r.within is False else ""


def row_class(r: Row) -> str:
    """CSS class: ok (within / bound met), off (outside the thesis's rounding), fail (bound not met), '' (no thesis)."""
    w = r.within
    if w is None:
        return ""
    if r.bound is not None:
        return "ok" if w else "fail"
    return "ok" if w else "off"


def table_html(table: Table) -> str:
    """One result table as HTML."""
    head = ("<tr><th>quantity</th><th>thesis (as printed)</th><th>rhi</th><th>difference</th><th>rel.</th><th>unit</th>"
            "<th>source</th><th>note</th></tr>")
    body = []
    for r in table.rows:
        rel = r.relative
        src = r.thesis.source if isinstance(r.thesis, ThesisValue) else ("rhi bound" if r.bound else "")
        body.append(
            f"<tr class='{row_class(r)}'><td>{html.escape(r.quantity)}</td><td>{html.escape(thesis_cell(r))}</td>"
            f"<td>{fmt(r.ours)}</td><td>{difference_cell(r)}</td>"
            f"<td>{'—' if rel is None else f'{100 * rel:+.1f} %'}</td><td>{html.escape(r.unit)}</td>"
            f"<td class='src'>{html.escape(src)}</td><td>{html.escape(note_of(r))}</td></tr>")
    return f"<h3>{html.escape(table.title)}</h3><table>{head}{''.join(body)}</table>"


def audit(results: Sequence[Result]) -> list[str]:
    """Problems of a run's tables, one line each (empty when the report is sound).

    - a thesis column that is neither a registered `rhi.thesis` value nor a bound;
    - a row outside its tolerance with no note (and no explanation for its thesis value).
    """
    problems = []
    for res in results:
        for t in res.tables:
            for r in t.rows:
                where = f"{res.name} / {t.title} / {r.quantity}"
                if r.thesis is not None and r.bound is None and not is_registered(r.thesis):
                    problems.append(f"{where}: thesis number {float(r.thesis):g} is not a value of rhi.thesis")
                if r.within is False and not note_of(r):
                    problems.append(f"{where}: outside the tolerance ({fmt(r.ours)} vs {thesis_cell(r)}) without a note")
    return problems


def summary(results: Sequence[Result]) -> dict[str, int]:
    """Counts of rows: with a thesis value, within its tolerance, outside, bounds met / not met."""
    rows = [r for res in results for t in res.tables for r in t.rows]
    vals = [r for r in rows if r.thesis is not None and r.bound is None]
    bounds = [r for r in rows if r.bound is not None]
    return {"rows": len(rows), "thesis values": len(vals), "within tolerance": sum(r.within is True for r in vals),
            "outside tolerance": sum(r.within is False for r in vals), "bounds met": sum(r.within is True for r in bounds),
            "bounds not met": sum(r.within is False for r in bounds)}
