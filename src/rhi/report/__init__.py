"""The HTML report of a reproduction run: tables thesis | rhi | difference, figures, JSON of every number."""

from __future__ import annotations

import csv
import html
import json
from collections.abc import Callable
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result


def _fmt(v: float | None) -> str:
    if v is None or not np.isfinite(v):
        return "—"
    a = abs(v)
    return f"{v:.4g}" if 1e-3 <= a < 1e4 or a == 0 else f"{v:.3e}"


def _table_html(table) -> str:
    head = "<tr><th>quantity</th><th>thesis</th><th>rhi</th><th>difference</th><th>rel.</th><th>unit</th><th>note</th></tr>"
    body = []
    for r in table.rows:
        rel = r.relative
        cls = "" if rel is None else ("ok" if abs(rel) <= 0.05 else "off")
        body.append(
            f"<tr class='{cls}'><td>{html.escape(r.quantity)}</td><td>{_fmt(r.thesis)}</td><td>{_fmt(r.ours)}</td>"
            f"<td>{_fmt(r.difference)}</td><td>{'—' if rel is None else f'{100 * rel:+.1f} %'}</td>"
            f"<td>{html.escape(r.unit)}</td><td>{html.escape(r.note)}</td></tr>"
        )
    return f"<h3>{html.escape(table.title)}</h3><table>{head}{''.join(body)}</table>"


STYLE = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;font-size:14px}
th{background:#f3f3f3}tr.ok td:nth-child(3){background:#e6f6e6}tr.off td:nth-child(3){background:#fdf0dc}
img{max-width:100%;border:1px solid #eee;margin:.5em 0}.note{color:#555;font-size:14px}
"""


def write_report(
    results: list[tuple[str, Result, dict[str, Figure | Callable[[], Figure]]]],
    out: str | Path,
    *,
    title: str = "rhi reproduction of Torabiparizi (2020)",
    meta: dict | None = None,
) -> Path:
    """Write `out/report.html`, `out/results.json`, one CSV per table and PNG per figure.

    Args:
        results: (chapter, result, {figure name: figure or a zero-argument function drawing it}) triples.
        out: output directory (created).
        meta: run information printed at the top and stored in the JSON.

    Returns:
        Path of report.html.
    """
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "tables").mkdir(exist_ok=True)
    sections, payload = [], {"meta": meta or {}, "results": []}
    for chapter, res, figs in results:
        parts = [f"<h2>{html.escape(chapter)} — {html.escape(res.title)}</h2>"]
        for t_i, table in enumerate(res.tables):
            parts.append(_table_html(table))
            with open(out / "tables" / f"{res.name}.{t_i}.csv", "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["quantity", "thesis", "rhi", "difference", "unit", "note"])
                for r in table.rows:
                    w.writerow([r.quantity, r.thesis, r.ours, r.difference, r.unit, r.note])
        for name, fig in figs.items():
            path = out / "figures" / f"{res.name}.{name}.png"
            fig = fig() if callable(fig) else fig  # drawn here, so one figure is open at a time
            fig.savefig(path, dpi=110, bbox_inches="tight")
            plt.close(fig)
            parts.append(f"<img src='figures/{path.name}' alt='{html.escape(name)}'>")
        parts += [f"<p class='note'>{html.escape(n)}</p>" for n in res.notes]
        sections.append("\n".join(parts))
        payload["results"].append({"chapter": chapter, **res.to_json()})
    meta_html = "".join(f"<li>{html.escape(str(k))}: {html.escape(str(v))}</li>" for k, v in (meta or {}).items())
    page = (
        f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
        f"<style>{STYLE}</style></head><body><h1>{html.escape(title)}</h1><ul>{meta_html}</ul>"
        "<p class='note'>Green: within 5 % of the thesis; amber: further (the note says why).</p>"
        + "\n".join(sections)
        + "</body></html>"
    )
    (out / "results.json").write_text(json.dumps(payload, indent=1, allow_nan=False))
    path = out / "report.html"
    path.write_text(page)
    return path
