"""The HTML report of a reproduction run.

It opens with the headline claims (`rhi.report.headline`, claims in `rhi.report.claims`) and a table
of contents, then one section per experiment: tables thesis ± tolerance | rhi | difference | note
(`rhi.report.tables`), figures, notes. Numbers go to `results.json`, arrays to `results.npz`.
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
from rhi.report import headline
from rhi.report.claims import CLAIMS
from rhi.report.tables import audit, summary, table_html

STYLE = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;font-size:14px}
th{background:#f3f3f3}tr.ok td:nth-child(3){background:#e6f6e6}tr.off td:nth-child(3){background:#fdf0dc}
tr.fail td:nth-child(3){background:#f8d7d7}td.src{font-size:12px;color:#666}
table.headline tr.ok td.verdict{background:#e6f6e6}table.headline tr.dir td.verdict{background:#eef3d9}
table.headline tr.off td.verdict{background:#fdf0dc}table.headline tr.na td.verdict{background:#eee}
img{max-width:100%;border:1px solid #eee;margin:.5em 0}.note{color:#555;font-size:14px}nav li{font-size:14px}
"""


def write_report(
    results: list[tuple[str, Result, dict[str, Figure | Callable[[], Figure] | Path]]],
    out: str | Path,
    *,
    title: str = "rhi reproduction of Torabiparizi (2020)",
    meta: dict | None = None,
) -> Path:
    """Write `out/report.html`, `out/results.json` (numbers), `out/results.npz` (arrays), a CSV per table, a PNG per figure.

    Args:
        results: (chapter, result, {figure name: figure, a zero-argument function drawing it, or the path of its
            PNG already drawn into out/figures}) triples.
        out: output directory (created).
        title: the report's title.
        meta: run information printed at the top and stored in the JSON.

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
    verdicts = headline.evaluate(CLAIMS, done)
    problems, counts = audit(done), summary(done)
    payload["headline"] = [{"where": v.claim.where, "claim": v.claim.claim, "thesis": v.thesis_text, "rhi": v.ours,
                            "verdict": v.verdict, "reason": v.reason, "experiment": v.claim.experiments[0]}
                           for v in verdicts]
    payload["summary"], payload["problems"] = counts, problems
    meta_html = "".join(f"<li>{html.escape(str(k))}: {html.escape(str(v))}</li>" for k, v in (meta or {}).items())
    n = headline.counts(verdicts)
    verdict_line = "; ".join(f"{k}: {n[k]}" for k in (*headline.VERDICTS, headline.NOT_RUN) if n[k])
    count_line = ", ".join(f"{k}: {v}" for k, v in counts.items())
    page = (
        f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
        f"<style>{STYLE}</style></head><body><h1>{html.escape(title)}</h1><ul>{meta_html}</ul>"
        f"<h2 id='headline'>Headline claims</h2><p class='note'>{html.escape(verdict_line)}. Reproduced: within the "
        "thesis's rounding; in direction only: the sign or order holds, the size does not; cannot be reproduced: the "
        "thesis's value rests on data it does not publish. Each claim links to its experiment.</p>"
        + headline.to_html(verdicts)
        + f"<h2>Contents</h2><nav><ol><li><a href='#headline'>Headline claims</a></li>{''.join(toc)}</ol></nav>"
        f"<p class='note'>Rows: {html.escape(count_line)}. Green: within the thesis's rounding (the tolerance "
        "column); amber: outside it, the note says why; red: an acceptance bound not met. Relative differences only "
        "where they mean something (not on p-values, angles, counts or values near 0).</p>"
        + (f"<p class='note'>Report problems: {html.escape('; '.join(problems))}</p>" if problems else "")
        + "\n".join(sections)
        + "</body></html>"
    )
    (out / "results.json").write_text(json.dumps(payload, indent=1, allow_nan=False))
    np.savez_compressed(out / "results.npz", **arrays)
    path = out / "report.html"
    path.write_text(page)
    return path
