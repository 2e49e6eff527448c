"""Simulated participants: a protocol run end to end without a browser, to power a study before recruiting.

`simulate` walks every participant's trial sequence (`rhi.study.sequence.plan`, adaptive stimuli from
`rhi.study.adaptive`) in order and asks a simulated participant for each answer or run; the rows are those a
session with people writes (`rhi.study.session`), and with ``out`` they are written into participant folders
that `rhi study analyze` reads like any other study. The simulated participants are supplied by the caller:
an `Observer` for discrimination tasks (the §3.5 observer through the simulated devices lives in
`rhi.experiments.ch3`), a `Performer` for path following.

`anova_power`: the power of the one-way ANOVA at Cohen's f (statsmodels' noncentral F), f from group means
and standard deviations (`cohens_f`, e.g. Table 3.3's WF) or from a published F (`f_from_anova`, e.g. §5.5's).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol as Interface

import numpy as np

from rhi.errors import InvalidInput
from rhi.study.adaptive import procedure
from rhi.study.protocol import Protocol
from rhi.study.sequence import plan
from rhi.study.session import Session, answer_row, run_row


class Observer(Interface):
    """A simulated participant of a discrimination task."""

    def answer(self, subject: int, device: str, comparison: float) -> int:
        """1 if participant `subject` (0-based) judges `comparison` stiffer on condition `device`."""
        ...


class Performer(Interface):
    """A simulated participant of a path-following task."""

    def perform(self, subject: int, condition: str, trial: int) -> dict[str, float]:
        """tracking_error [m], effort [J] and completion_time [s] of one run."""
        ...


def subject_name(i: int) -> str:
    """The id of simulated participant `i` (0-based): "S01", "S02", ... (`rhi.analysis.psychophysics.protocol`'s)."""
    return f"S{i + 1:02d}"


def simulate(protocol: Protocol, participants: int, participant: Observer | Performer, *,
             out: str | Path | None = None) -> list[dict[str, Any]]:
    """Every trial of `participants` simulated participants, in order (see the module docstring).

    Args:
        protocol: the study protocol.
        participants: how many (ids "S01", ...; enrolment indices 0, 1, ...).
        participant: an `Observer` (discrimination) or a `Performer` (path following).
        out: a study folder to write participant folders into (None: in memory only).

    Returns:
        The rows (responses.csv columns) of every trial of every participant.

    Raises:
        InvalidInput: fewer than one participant, a participant that does not fit the task, or `out`
            already holding one of the simulated participants.
    """
    if int(participants) != participants or participants < 1:
        raise InvalidInput(f"participants: need a positive integer, got {participants!r}")
    discrimination = protocol.kind == "discrimination_2afc"
    if not hasattr(participant, "answer" if discrimination else "perform"):
        raise InvalidInput(f"participant: a {protocol.kind} task needs an object with "
                           f"{'answer' if discrimination else 'perform'}()")
    adaptive = protocol.stimulus["method"] in ("staircase", "quest")
    rows: list[dict[str, Any]] = []
    for i in range(int(participants)):
        name = subject_name(i)
        session = None
        if out is not None:
            if (Path(out) / name / "participant.json").exists():
                raise InvalidInput(f"out: {Path(out) / name} exists; simulate into an empty study folder")
            session = Session(out, protocol, name, index=i, simulated=True)
        procs = {c: procedure(protocol.stimulus) for c in protocol.condition_names} if adaptive else {}
        for t in plan(protocol, i):
            if not discrimination:
                row = run_row(t, name, participant.perform(i, t.condition, t.index))  # type: ignore[union-attr]
            else:
                adapt = adaptive and not t.training
                pct = procs[t.condition].next() if adapt else float(t.percent)  # type: ignore[arg-type]
                stiffer = participant.answer(i, t.condition, t.reference * (1.0 + pct / 100.0))  # type: ignore
                if adapt:
                    procs[t.condition].update(pct, stiffer)
                row = answer_row(t, name, pct, "first" if bool(stiffer) == t.comparison_first else "second")
            if session is not None:
                session.commit(row)
            rows.append(row)
    return rows


def cohens_f(means: Sequence[float], stds: Sequence[float]) -> float:
    """Cohen's f of equal-sized groups: s.d. of the group means over the pooled within-group s.d."""
    m, s = np.asarray(means, float), np.asarray(stds, float)
    if m.shape != s.shape or m.size < 2 or not (s > 0).all():
        raise InvalidInput(f"means/stds: need two or more groups with positive s.d., got {means}, {stds}")
    return float(np.sqrt(np.mean((m - m.mean()) ** 2)) / np.sqrt(np.mean(s ** 2)))


def anova_power(f: float, groups: int, per_group: int, *, alpha: float = 0.05) -> float:
    """Power of the between-subjects one-way ANOVA at Cohen's f with `groups` groups of `per_group` each."""
    from statsmodels.stats.power import FTestAnovaPower

    if int(per_group) != per_group or per_group < 2 or int(groups) != groups or groups < 2:
        raise InvalidInput(f"groups/per_group: need integers >= 2, got {groups!r}, {per_group!r}")
    if not (np.isfinite(f) and f > 0):
        raise InvalidInput(f"f: need a positive effect size, got {f!r}")
    return float(FTestAnovaPower().power(effect_size=f, nobs=int(groups) * int(per_group), alpha=alpha,
                                         k_groups=int(groups)))


def f_from_anova(F: float, df_between: float, df_within: float) -> float:
    """Cohen's f of a published one-way ANOVA: f² = F df_between / df_within (η² / (1 − η²))."""
    if not (F > 0 and df_between > 0 and df_within > 0):
        raise InvalidInput(f"F/df: need positive values, got {F}, {df_between}, {df_within}")
    return float(np.sqrt(F * df_between / df_within))


__all__ = ["Observer", "Performer", "anova_power", "cohens_f", "f_from_anova", "simulate", "subject_name"]
