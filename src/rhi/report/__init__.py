"""The HTML report of a reproduction run.

It opens with the tally of verdicts, the verdict rules (`rhi.report.rules`) and the headline claims grouped
by chapter (`rhi.report.headline`, claims in `rhi.report.claims`), then the dossiers of the claims not
reproduced (`rhi.report.dossiers`, data in `rhi.report.readings`) and a table of contents, then one
section per experiment: tables thesis as printed | rhi | difference | note (`rhi.report.tables`), figures,
notes; the run's metadata last, collapsed. Numbers go to `results.json`, arrays to `results.npz`.
"""

from __future__ import annotations

import csv
import html
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result
from rhi.report import dossiers, headline
from rhi.report.claims import CLAIMS
from rhi.report.fidelity import fidelity_header
from rhi.report.readings import DOSSIERS
from rhi.report.rules import rules_html
from rhi.report.tables import audit, summary, table_html

STYLE = """
body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;font-size:14px}
th{background:#f3f3f3}tr.ok td:nth-child(3){background:#e6f6e6}tr.off td:nth-child(3){background:#fdf0dc}
tr.fail td:nth-child(3){background:#f8d7d7}td.src{font-size:12px;color:#666}
.v-ok{--v:#8fd18f}.v-close{--v:#9cc9f0}.v-dir{--v:#ffd966}.v-off{--v:#f08c8c}.v-na{--v:#c9b8e8}.v-run{--v:#f4f4f4}
table.headline td.verdict{background:var(--v);font-weight:600}table.headline tr.chapter th{text-align:left;
background:#e4e4e4}table.headline td.reason{font-size:12px;color:#444;max-width:420px}
.tally{display:flex;gap:8px;margin:1em 0}.tally-cell{flex:1;background:var(--v);padding:10px;border-radius:6px;
text-align:center;font-size:14px}.tally-cell b{font-size:26px}section.dossier{border-left:4px solid #ccc;
padding-left:1em;margin:1em 0}ol.rules li{font-size:14px;margin:2px 0}
img{max-width:100%;border:1px solid #eee;margin:.5em 0}.note{color:#555;font-size:14px}nav li{font-size:14px}
details{margin:2em 0;font-size:13px}
"""


def write_report(
    results: list[tuple[str, Result, dict[str, Figure | Callable[[], Figure] | Path]]],
    out: str | Path,
    *,
    title: str = "rhi reproduction of Torabiparizi (2020)",
    meta: dict | None = None,
    thesis: bool = True,
) -> Path:
    """Write out/report.html, results.json, results.npz, fidelity.md (dossiers), a CSV per table and a PNG per figure.

    Args:
        results: (chapter, result, {figure name: figure, a zero-argument function drawing it, or the path of its
            PNG already drawn into out/figures}) triples.
        out: output directory (created).
        title: the report's title.
        meta: run information, printed in a collapsed block at the end and stored in the JSON.
        thesis: judge the thesis's headline claims (with their dossiers and fidelity.md); False for a report
            that is not a reproduction (e.g. `rhi study analyze`).

    Returns:
        Path of report.html.
    """
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "tables").mkdir(exist_ok=True)
    sections: list[str] = []
    toc: list[str] = []
    payload: dict[str, Any] = {"meta": meta or {}, "results": []}
    arrays: dict[str, Any] = {}
    for chapter, res, figs in results:
        anchor = headline.anchor(res.name)
        toc.append(f"<li><a href='#{anchor}'>{html.escape(chapter)} — {html.escape(res.title)}</a></li>")
        parts = [f"<h2 id='{anchor}'>{html.escape(chapter)} — {html.escape(res.title)}</h2>"]
        for t_i, table in enumerate(res.tables):
            parts.append(table_html(table))
            with open(out / "tables" / f"{res.name}.{t_i}.csv", "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["quantity", "thesis", "tolerance", "bound", "rhi", "difference", "within", "unit", "source",
                            "note"])
                for r in table.rows:
                    w.writerow([r.quantity, None if r.thesis is None else float(r.thesis), r.tol, r.bound, r.ours,
                                r.difference, r.within, r.unit, r.source, r.note])
        for name, fig in figs.items():
            path = out / "figures" / f"{res.name}.{name}.png"
            if isinstance(fig, Path):
                path = fig
            else:
                fig = fig() if callable(fig) else fig  # drawn here, so one figure is open at a time
                fig.savefig(path, dpi=110, bbox_inches="tight")
                plt.close(fig)
            parts.append(f"<img src='figures/{path.name}' alt='{html.escape(name)}'>")
        parts += [f"<p class='note'>{html.escape(n)}</p>" for n in res.notes]
        sections.append("\n".join(parts))
        payload["results"].append({"chapter": chapter, **res.to_json(arrays=False)})
        arrays.update({f"{res.name}/{k}": np.asarray(v) for k, v in res.arrays.items()})
    done = [r for _, r, _ in results]
    verdicts = headline.evaluate(CLAIMS, done) if thesis else []
    cases = dossiers.evaluate(verdicts, DOSSIERS, done)
    problems = audit(done) + [f"no dossier for the claim not reproduced {m}"
                              for m in dossiers.missing_dossiers(verdicts, DOSSIERS)] + [
        f"headline claim {v.claim.where} ({v.claim.claim}): {v.reason}" for v in verdicts
        if v.verdict == headline.NOT_RUN and v.reason.startswith("missing")]
    counts = summary(done)
    payload["headline"] = [{"where": v.claim.where, "claim": v.claim.claim, "key": v.claim.key,
                            "thesis": v.thesis_text, "rhi": v.ours, "rhi_text": v.ours_text, "verdict": v.verdict,
                            "reason": v.reason, "experiment": v.claim.experiments[0]} for v in verdicts]
    payload["dossiers"] = [{"key": c.verdict.claim.key, "conclusion": c.conclusion,
                            "readings": [{"name": rd.name, "rhi": x, "verdict": vd} for rd, x, vd in c.readings]}
                           for c in cases]
    payload["summary"], payload["problems"] = counts, problems
    meta_html = "".join(f"<li>{html.escape(str(k))}: {html.escape(str(v))}</li>" for k, v in (meta or {}).items())
    count_line = ", ".join(f"{k}: {v}" for k, v in counts.items())
    page = (
        f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
        f"<style>{STYLE}</style></head><body><h1>{html.escape(title)}</h1>"
        + (f"<h2 id='headline'>Headline claims</h2>{headline.tally_html(verdicts)}"
           f"<details open><summary>Verdict rules</summary>{rules_html()}</details>"
           + headline.to_html(verdicts, frozenset(c.verdict.claim.key for c in cases))
           + f"<h2 id='dossiers'>Dossiers of the claims not reproduced</h2>{dossiers.to_html(cases)}"
           if thesis else "")
        + "<h2>Contents</h2><nav><ol>"
        + ("<li><a href='#headline'>Headline claims</a></li><li><a href='#dossiers'>Dossiers</a></li>" if thesis else "")
        + f"{''.join(toc)}<li><a href='#meta'>Run metadata</a></li></ol></nav>"
        f"<p class='note'>Rows: {html.escape(count_line)}. Green: within the thesis's rounding (the thesis column "
        "prints the number as the thesis printed it); amber: outside it, the note says why; red: an acceptance bound "
        "not met. Relative differences only where they mean something (not on p-values, angles, counts or values "
        "near 0).</p>"
        + (f"<p class='note'>Report problems: {html.escape('; '.join(problems))}</p>" if problems else "")
        + "\n".join(sections)
        + f"<details id='meta'><summary>Run metadata</summary><ul>{meta_html}</ul></details>"
        + "</body></html>"
    )
    (out / "results.json").write_text(json.dumps(payload, indent=1, allow_nan=False))
    np.savez_compressed(out / "results.npz", **arrays)
    if thesis:
        (out / "fidelity.md").write_text(dossiers.to_markdown(cases, fidelity_header(verdicts, meta)))
    path = out / "report.html"
    path.write_text(page)
    return path

