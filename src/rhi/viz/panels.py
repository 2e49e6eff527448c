"""The view's side panels as HTML: joint torques against their limits, the ASO and scalings, the safety state."""

from __future__ import annotations

import html
import math

import numpy as np

#: |τ_i| at or above this fraction of its limit counts as saturated (highlighted).
SATURATED = 0.995


def _num(v) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{float(v):.3f}"


def torque_panel(tau: np.ndarray, torque_min: np.ndarray, torque_max: np.ndarray, names: list[str]) -> str:
    """Bars of τ: (n,) [N m] against [torque_min, torque_max], saturated joints in red, with the numbers."""
    rows = []
    for name, t, lo, hi in zip(names, np.asarray(tau, dtype=float), torque_min, torque_max):
        lim = hi if t >= 0 else -lo
        frac = abs(t) / lim if np.isfinite(lim) and lim > 0 else 0.0
        sat = frac >= SATURATED
        color = "#d62728" if sat else "#1f77b4"
        half = 50.0 * min(frac, 1.0)
        left = 50.0 if t >= 0 else 50.0 - half
        rows.append(
            f'<div class="rhi-tau" data-saturated="{int(sat)}" style="display:flex;align-items:center;'
            f'font:12px monospace;margin:2px 0">'
            f'<span style="width:3.5em">{html.escape(name)}</span>'
            f'<span style="position:relative;flex:1;height:12px;background:#eee;border-radius:2px">'
            f'<span style="position:absolute;left:50%;top:0;bottom:0;width:1px;background:#999"></span>'
            f'<span style="position:absolute;left:{left:.1f}%;width:{half:.1f}%;top:1px;bottom:1px;'
            f'background:{color}"></span></span>'
            f'<span style="width:8em;text-align:right;color:{color}">{t:+.3f}/{lim:.2f}</span></div>')
    return '<div id="rhi-torques"><b>joint torques τ [N m] / limit</b>' + "".join(rows) + "</div>"


def _vector(v) -> str:
    v = np.asarray(v, dtype=float)
    if v.size == 0 or not np.all(np.isfinite(v)):
        return "—"
    return f"{np.linalg.norm(v):.2f} ({', '.join(f'{x:+.2f}' for x in v)})"


def state_panel(snap) -> str:
    """Read-outs: the time, hand and environment forces, ASO V, FME activation Ω, scalings α, β, the safety state."""
    g = lambda k: getattr(snap, k, math.nan)  # noqa: E731
    safety = getattr(snap, "safety", "ok")
    fault = getattr(snap, "fault", None)
    ok = safety == "ok" and not fault
    badge = ("#2ca02c", "ok") if ok else ("#d62728", f"fault: {fault or safety}")
    cells = "".join(f"<tr><td>{k}</td><td style='text-align:right'>{_num(v)}</td></tr>"
                    for k, v in (("t [s]", g("t")), ("ASO V", g("V")), ("Ω", g("omega")), ("α", g("alpha")),
                                 ("β", g("beta"))))
    forces = "".join(f"<tr><td>{k}</td><td style='text-align:right'>{_vector(getattr(snap, f, []))}</td></tr>"
                     for k, f in (("|F_h| [N]", "F_hand"), ("|F_env| [N]", "F_env")))
    return (f'<div id="rhi-state" style="font:12px monospace"><table style="width:100%">{cells}{forces}</table>'
            f'<div style="margin-top:4px;padding:3px 6px;border-radius:3px;color:white;background:{badge[0]}">'
            f"safety: {html.escape(badge[1])}</div></div>")


def status_line(text: str) -> str:
    """The run's status ("warming up …", "live", "paused", a fault with its reason) as a coloured line."""
    low = text.lower()
    color = "#d62728" if low.startswith(("fault", "stopped")) else "#2ca02c" if low == "live" else "#ff7f0e"
    return (f'<div id="rhi-status" style="font:12px sans-serif;padding:3px 6px;border-radius:3px;color:white;'
            f'background:{color}">{html.escape(text)}</div>')


def legend(force_scale: float | None, velocity_scale: float | None) -> str:
    """What the colours at the handle mean, with the display scales."""
    fs = "" if force_scale is None else f" (1 N = {1000 * force_scale:.2g} mm)"
    vs = "" if velocity_scale is None else f" (1 rad/s → {1000 * velocity_scale:.3g} mm per m/s)"
    items = [("#3c8ce6", f"velocity ellipsoid JJᵀ{vs}"), ("#eb781e", f"force ellipsoid M̂, eq. 6.9{fs}"),
             ("#28aa50", "desired FME M_des(Ω)"), ("#1e1e1e", "max force along u, LP (null space)"),
             ("#969696", "max force along u, simple scaling"), ("#c81ea0", "hand force F_h"),
             ("#c82828", "environment force / wall, spring, fixture")]
    return '<div style="font:11px sans-serif">' + "".join(
        f'<div><span style="display:inline-block;width:10px;height:10px;background:{c};margin-right:4px">'
        f"</span>{html.escape(t)}</div>" for c, t in items) + "</div>"
