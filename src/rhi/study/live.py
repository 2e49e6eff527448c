"""A participant's session run live: the trial state machine between the pages, the device and the folder.

Discrimination (§3.5): a trial begins (after its rest, if the protocol puts one there) with the first sample
rendered (`phase` "probe_1"); the participant's "next sample" replaces it with the second ("probe_2"); an answer
("first" or "second") ends the trial, which is committed to the participant's folder at once
(`rhi.study.session`), and the next trial's first sample follows. The response time runs from the second
sample's start to the answer. Path following (§5.5): "next" starts a run, "next" again ends it; the participant
drives the master and a simulated slave robot follows it (`rhi.study.slave`); the run's tracking error (of the
slave's end effector), the user's effort (on the master) and the completion time come from its log. The
experimenter may pause (the device loop stops: zero torque), resume (the current probe starts again, on a new
log), abort (the session ends; the same command resumes it at the next uncommitted trial) and write notes. An
optional rest is ended by the participant, a required one by the experimenter.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from rhi.errors import InvalidInput
from rhi.study import slave as sl
from rhi.study.adaptive import procedure, replay
from rhi.study.haptics import Haptics
from rhi.study.session import Session, answer_row, run_row

_MESSAGES = {"ready": "Press Next to begin.", "rest": "Rest. Press Next when you are ready to go on.",
             "long_rest": "Break: the experimenter will continue the session.", "probe_1": "First sample.",
             "probe_2": "Second sample.", "paused": "Paused.", "done": "Thank you: the session is complete.",
             "aborted": "The session was stopped.", "between": "Press Next to start.",
             "running": "Keep the red dot on the blue path: accuracy first, then speed."}  # §5.5's instruction


class StudyRun:
    """The live state of one participant's session (thread-safe; the pages call it from their threads).

    Args:
        session: the participant's opened folder (resumed at its next trial).
        haptics: the device loop.
    """

    def __init__(self, session: Session, haptics: Haptics) -> None:
        self.session, self.haptics = session, haptics
        self.protocol = session.protocol
        self._lock = threading.RLock()
        self.phase = "done" if session.done else "ready"
        self._resume_phase: str | None = None
        self._rested = False
        self.percent: float | None = None
        self._t_start = self._t_second = 0.0
        self._segments: dict[str, int] = {}
        self.notes = 0
        self.fault: str | None = None  # the last fault that paused the session
        self.adaptive = self.protocol.stimulus["method"] in ("staircase", "quest")
        self._procs = {c: replay(procedure(self.protocol.stimulus), session.history(c))
                       for c in self.protocol.condition_names} if self.adaptive else {}
        self.finished = threading.Event()
        if session.done:
            self.finished.set()

    # ------------------------------------------------------------------ helpers
    @property
    def trial(self):
        """The current planned trial (None when done)."""
        k = self.session.next_trial
        return None if k >= len(self.session.plan) else self.session.plan[k]

    def _stiffness(self, which: int) -> float | None:
        t = self.trial
        if t is None or t.reference is None or self.percent is None:
            return None
        comparison = t.reference * (1.0 + self.percent / 100.0)
        first_is_comparison = t.comparison_first
        return comparison if (which == 1) == first_is_comparison else t.reference

    def _start_probe(self, which: str) -> None:
        t = self.trial
        k = self._segments.get(which, 0) + 1
        self._segments[which] = k
        name = which if k == 1 else f"{which}{k}"
        stiff = None if which == "run" else self._stiffness(1 if which == "a" else 2)
        self.haptics.start(t.condition, self.session.trial_log(t.index, name), stiff)

    def _begin_trial(self) -> None:
        """Enter the next trial: its rest, else its first probe (or the wait before a run)."""
        self.haptics.stop()
        t = self.trial
        if t is None:
            self.phase = "done"
            self.finished.set()
            return
        if t.rest and not self._rested:
            self.phase = t.rest
            return
        self._rested = False
        self._segments = {}
        self._t_start = time.time()
        if self.protocol.kind != "discrimination_2afc":
            self.percent, self.phase = None, "between"
            return
        adapt = self.adaptive and not t.training
        self.percent = self._procs[t.condition].next() if adapt else float(t.percent)
        self.phase = "probe_1"
        self._start_probe("a")

    # ------------------------------------------------------------------ participant
    def next(self) -> None:
        """The participant's "next": begin, leave an optional rest, the second sample, or start/end a run.

        Raises:
            InvalidInput: "next" has no meaning now (e.g. during the second sample, or paused).
        """
        with self._lock:
            self._check_fault()
            if self.phase == "ready":
                self._begin_trial()
            elif self.phase == "rest":
                self._rested = True
                self._begin_trial()
            elif self.phase == "probe_1":
                self.haptics.stop()
                self._t_second = time.time()
                self.phase = "probe_2"
                self._start_probe("b")
            elif self.phase == "between":
                self._t_start = time.time()
                self.phase = "running"
                self._start_probe("run")
            elif self.phase == "running":
                if self.haptics.running and not self.haptics.status.get("ticks"):
                    raise InvalidInput("next: the run has not started yet (the device loop is starting)")
                summary = self.haptics.stop()
                self._commit_run(summary)
            else:
                raise InvalidInput(f"next: not available while {self.phase}")

    def answer(self, which: str) -> None:
        """The participant's answer, "first" or "second" (the sample judged stiffer), during the second sample.

        Raises:
            InvalidInput: not during the second sample, or not "first"/"second".
        """
        with self._lock:
            self._check_fault()
            if self.phase != "probe_2":
                raise InvalidInput(f"answer: only after the second sample, not while {self.phase}")
            t_end = time.time()
            row = answer_row(self.trial, self.session.id, float(self.percent), which,  # type: ignore[arg-type]
                             response_time=round(t_end - self._t_second, 4), t_start=round(self._t_start, 4),
                             t_end=round(t_end, 4))
            self.haptics.stop()
            self.session.commit(row)
            if self.adaptive and not self.trial_was_training(row):
                self._procs[row["condition"]].update(row["percent"], row["response"])
            self._begin_trial()

    @staticmethod
    def trial_was_training(row: dict[str, Any]) -> bool:
        """Whether a committed row was a training trial."""
        return bool(row["training"])

    def _commit_run(self, summary: dict[str, Any] | None) -> None:
        from rhi.sim.log import Log

        t = self.trial
        log = Log.load(self.session.trial_log(t.index, "run"))
        self.session.commit(run_row(t, self.session.id, path_measures(self, log), t_start=round(self._t_start, 4),
                                    t_end=round(time.time(), 4)))
        self._begin_trial()

    # ------------------------------------------------------------------ experimenter
    def pause(self) -> None:
        """Stop the device loop (zero torque) and freeze the session."""
        with self._lock:
            if self.phase in ("paused", "done", "aborted"):
                return
            self.haptics.stop()
            self._resume_phase, self.phase = self.phase, "paused"

    def resume(self) -> None:
        """Continue after a pause (the current probe starts again on a new log) or end a required rest."""
        with self._lock:
            if self.phase == "long_rest":
                self._rested = True
                self._begin_trial()
            elif self.phase == "paused":
                self.phase, self._resume_phase, self.fault = self._resume_phase or "ready", None, None
                if self.phase in ("probe_1", "probe_2", "running"):
                    self._start_probe({"probe_1": "a", "probe_2": "b", "running": "run"}[self.phase])

    def abort(self) -> None:
        """End the session now (the trial in progress is not committed; the same command resumes it)."""
        with self._lock:
            self.haptics.stop()
            if self.phase != "done":
                self.phase = "aborted"
            self.finished.set()

    def note(self, text: str) -> None:
        """Store an experimenter's note in the participant's folder."""
        if not str(text).strip():
            raise InvalidInput("note: empty")
        with self._lock:
            self.session.note(text)
            self.notes += 1

    def _check_fault(self) -> None:
        """A probe the device loop ended on a fault (zero torque, logged) pauses the session until resumed."""
        if self.phase in ("probe_1", "probe_2", "running") and not self.haptics.running:
            fault = (self.haptics.last or {}).get("fault")
            if fault:
                self.fault = str(fault)
                self._resume_phase, self.phase = self.phase, "paused"

    # ------------------------------------------------------------------ views
    def participant_view(self) -> dict[str, Any]:
        """What the participant's page shows: only the elements the protocol allows."""
        with self._lock:
            self._check_fault()
            show = self.protocol.display
            ph = self.phase
            v: dict[str, Any] = {"phase": ph, "message": _MESSAGES.get(ph, ""),
                                 "next": "next" in show and ph in ("ready", "rest", "probe_1", "between", "running"),
                                 "answers": "answers" in show and ph == "probe_2"}
            if v["answers"]:
                v["question"] = self.protocol.task["question"]
            if "progress" in show:
                v["progress"] = [self.session.next_trial, len(self.session.plan)]
            if "reference_path" in show:
                v["path"] = reference_path(self.protocol).tolist()
            if "slave" in show:
                v["slave"] = self.haptics.state().get("slave_x")
            if self.haptics.mouse and self.haptics.slave is not None:
                v["hand"] = ph == "running"  # dry run: the pointer on the canvas is the hand
            return v

    def experimenter_view(self) -> dict[str, Any]:
        """Everything the experimenter's page shows: progress, the trial, the device's state and safety."""
        with self._lock:
            self._check_fault()
            t = self.trial
            trial = None if t is None else {
                "index": t.index, "block": t.block, "condition": t.condition, "training": t.training,
                "percent": self.percent, "reference": t.reference, "comparison_first": t.comparison_first,
                "stimulus": None if t.reference is None or self.percent is None else
                t.reference * (1.0 + self.percent / 100.0), "rest": t.rest, "rest_seconds": t.rest_seconds}
            st = dict(self.haptics.status)
            keys = ("condition", "t", "ticks", "missed", "max_torque_ratio", "fault")
            tele = self.protocol.teleoperation
            return {"participant": self.session.id, "protocol": self.protocol.name, "phase": self.phase,
                    "committed": self.session.next_trial, "total": len(self.session.plan), "trial": trial,
                    "device": {k: st.get(k) for k in keys},
                    "state": self.haptics.state(), "running": self.haptics.running, "link": self.haptics.link,
                    "mouse": self.haptics.mouse,
                    "path": None if tele is None else reference_path(self.protocol).tolist(),
                    "teleoperation": None if tele is None else {
                        "slave": tele["slave"], "scale": tele["scale"], "offset": tele["offset"].tolist()},
                    "notes": self.notes, "paused_by_fault": self.fault,
                    "last_fault": (self.haptics.last or {}).get("fault")}


def reference_path(protocol) -> np.ndarray:
    """(k, 2) corners of a path-following task's W path in the slave's frame [m]."""
    return np.asarray(sl.reference(protocol).points)


def path_measures(run: StudyRun, log) -> dict[str, float]:
    """§5.5 measures of a run's log: the slave's tracking error, the user's effort, the completion time.

    tracking_error: the mean distance ‖L_d − L_t‖ of the slave's end effector (the log's ``slave_x``) to the
    reference path [m]; effort: the hand's work on the master W = ∫F_hᵀẋ dt (eq. 5.15, trapezoidal) [J];
    completion_time: the run's duration [s].

    Raises:
        InvalidInput: a log without the slave's positions.
    """
    P = reference_path(run.protocol)
    x = np.asarray(log.slave_x)
    if x.ndim != 2 or x.shape[1] != P.shape[1]:
        raise InvalidInput("log: the run's log holds no slave positions (slave_x); a path-following run needs the "
                           "teleoperated slave")
    seg_a, seg_b = P[:-1], P[1:]
    d = seg_b - seg_a
    s = np.clip(np.einsum("tkj,kj->tk", x[:, None, :] - seg_a[None], d) / np.einsum("kj,kj->k", d, d), 0.0, 1.0)
    dist = np.linalg.norm(x[:, None, :] - (seg_a[None] + s[..., None] * d[None]), axis=-1).min(axis=1)
    m = np.asarray(log.x).shape[1]
    F, v, tt = np.asarray(log.F_hand)[:, :m], np.asarray(log.xdot)[:, :m], np.asarray(log.t)
    power = np.einsum("tj,tj->t", F, v)
    effort = float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(tt))) if len(tt) > 1 else 0.0
    return {"tracking_error": float(dist.mean()) if len(dist) else 0.0, "effort": effort,
            "completion_time": float(tt[-1] - tt[0]) if len(tt) else 0.0}


__all__ = ["StudyRun", "path_measures", "reference_path"]
