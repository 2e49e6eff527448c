"""A participant's session data: one folder per participant that survives a crash and resumes at the next trial.

``STUDY_DIR/<participant>/`` holds ``protocol.toml`` (the protocol's text, as run), ``participant.json`` (the
id, the enrolment index that seeds the sequence, the declared fields, nothing else), ``responses.csv`` (one row
per committed trial, `COLUMNS`), ``notes.txt`` (the experimenter's notes, time-stamped) and
``trials/trial-NNNN-<probe>.rhilog`` (the device log of every probe or run).

A trial is committed once, by appending its whole row to ``responses.csv`` and fsync-ing it; a session killed at
any moment reopens with every committed trial and resumes at the first uncommitted one (a row cut short by the
kill is not a committed trial and is dropped; the logs of an interrupted trial are kept beside as
``*.interrupted-K.rhilog``).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import time
import tomllib
from pathlib import Path
from typing import Any

from rhi.errors import InvalidInput
from rhi.runtime.schema import prefixed
from rhi.study.protocol import Protocol, parse_protocol
from rhi.study.sequence import PlannedTrial, plan

#: the columns of responses.csv.
COLUMNS = ("trial", "subject", "block", "condition", "training", "reference", "stimulus", "percent",
           "comparison_first", "answer", "response", "response_time", "t_start", "t_end",
           "tracking_error", "effort", "completion_time")
_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


def _fsync_append(path: Path, text: str, mode: str = "a") -> None:
    with open(path, mode, encoding="utf-8", newline="") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())


def _row_text(row: dict[str, Any]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(["" if row.get(c) is None else row[c] for c in COLUMNS])
    return buf.getvalue()


def _read_text(path: Path) -> str:
    """The text of a file of a participant's folder."""
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"{path}: cannot read it ({exc})") from None


def _read_meta(path: Path) -> dict[str, Any]:
    """participant.json, checked: an object with the protocol's name, the enrolment index and the fields."""
    text = _read_text(path)
    try:
        meta = json.loads(text)
    except ValueError as exc:
        raise InvalidInput(f"{path}: not JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise InvalidInput(f"{path}: expected a JSON object, got {type(meta).__name__}")
    checks = {"protocol": (lambda v: isinstance(v, str), "a string"), "fields": (lambda v: isinstance(v, dict), "an object"),
              "index": (lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0, "an integer >= 0")}
    for key, (ok, want) in checks.items():
        if key not in meta:
            raise InvalidInput(f"{path}: key {key!r} missing")
        if not ok(meta[key]):
            raise InvalidInput(f"{path}: key {key!r}: expected {want}, got {meta[key]!r:.60}")
    return meta


def _stored_protocol(path: Path, text: str, name: str) -> Protocol:
    """The protocol a participant started with (the folder's protocol.toml)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InvalidInput(f"{path}: cannot read it as TOML ({exc})") from None
    return prefixed(str(path), parse_protocol, data, name=name, source=str(path), text=text)


#: what each column of responses.csv holds (a row of `read_responses` is checked against it): a pattern of its text.
_NUMBER = r"|[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?"  # empty, or a finite number as Python writes it
_FORMS = {"trial": r"\d+", "block": r"\d+", "training": r"[01]", "comparison_first": r"|[01]", "response": r"|[01]",
          "answer": r"|first|second", **{c: _NUMBER for c in ("reference", "stimulus", "percent", "response_time",
                                                               "t_start", "t_end", "tracking_error", "effort",
                                                               "completion_time")}}
_ANSWERED = ("reference", "stimulus", "percent", "comparison_first", "answer", "response")
_WANT = {"trial": "an integer", "block": "an integer", "training": "0 or 1", "comparison_first": "0, 1 or empty",
         "response": "0, 1 or empty", "answer": "first, second or empty"}


def read_responses(path: str | Path) -> list[dict[str, str]]:
    """The committed rows of a responses.csv (a last line cut short by a kill is not one).

    Raises:
        InvalidInput: a missing file, a wrong header, or trials out of order (naming the line).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"{path}: cannot read the responses ({exc})") from None
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]  # the uncommitted tail
    rows = list(csv.reader(io.StringIO(text)))
    if not rows or tuple(rows[0]) != COLUMNS:
        raise InvalidInput(f"{path}: line 1 is not the responses header {','.join(COLUMNS)}")
    out: list[dict[str, str]] = []
    for line, r in enumerate(rows[1:], start=2):
        if len(r) != len(COLUMNS) or r[0] != str(len(out)):
            raise InvalidInput(f"{path}, line {line}: expected trial {len(out)} with {len(COLUMNS)} fields, "
                               f"got {r[:1]} with {len(r)}")
        for c, v in zip(COLUMNS, r):
            if c in _FORMS and not re.fullmatch(_FORMS[c], v):
                raise InvalidInput(f"{path}, line {line}, column {c!r}: {v!r} is not {_WANT.get(c, 'a finite number')}")
        row = dict(zip(COLUMNS, r))
        if row["answer"] or row["response"]:  # an answered 2AFC trial (`answer_row`): all of it, and consistent
            empty = [c for c in _ANSWERED if not row[c]]
            if empty:
                raise InvalidInput(f"{path}, line {line}, column {empty[0]!r}: empty in an answered trial")
            if row["response"] != str(int((row["answer"] == "first") == (row["comparison_first"] == "1"))):
                raise InvalidInput(f"{path}, line {line}, column 'response': {row['response']!r} contradicts the "
                                   f"answer {row['answer']!r} (comparison_first {row['comparison_first']})")
        out.append(row)
    return out


def answer_row(trial: PlannedTrial, subject: str, percent: float, answer: str, *, response_time: float | None = None,
               t_start: float | None = None, t_end: float | None = None) -> dict[str, Any]:
    """The responses.csv row of a 2AFC trial.

    Args:
        trial: the planned trial.
        subject: the participant's id.
        percent: the comparison presented [% of the reference].
        answer: "first" or "second" (the sample judged stiffer).
        response_time: from the end of the second probe's start to the answer [s].
        t_start: Unix time of the trial's start [s].
        t_end: Unix time of the answer [s].

    Raises:
        InvalidInput: an answer other than "first" or "second", or a trial without a reference.
    """
    if answer not in ("first", "second"):
        raise InvalidInput(f"answer: expected 'first' or 'second', got {answer!r}")
    if trial.reference is None:
        raise InvalidInput(f"trial: trial {trial.index} has no stimulus to answer")
    stiffer = (answer == "first") == trial.comparison_first
    return {"trial": trial.index, "subject": subject, "block": trial.block, "condition": trial.condition,
            "training": int(trial.training), "reference": trial.reference,
            "stimulus": trial.reference * (1.0 + percent / 100.0), "percent": percent,
            "comparison_first": int(trial.comparison_first), "answer": answer, "response": int(stiffer),
            "response_time": response_time, "t_start": t_start, "t_end": t_end}


def run_row(trial: PlannedTrial, subject: str, measures: dict[str, float], *, t_start: float | None = None,
            t_end: float | None = None) -> dict[str, Any]:
    """The responses.csv row of a path-following run.

    `measures` holds tracking_error [m], effort [J] and completion_time [s].
    """
    return {"trial": trial.index, "subject": subject, "block": trial.block, "condition": trial.condition,
            "training": int(trial.training), "t_start": t_start, "t_end": t_end,
            **{k: float(measures[k]) for k in ("tracking_error", "effort", "completion_time")}}


class Session:
    """A participant's folder, opened to run or resume (see the module docstring).

    Args:
        study_dir: the study's folder (created).
        protocol: the protocol (a new participant) or None (resume: the folder's copy is used).
        participant: the participant's id (letters, digits, ``_.-``).
        fields: the declared participant fields (checked by `Protocol.participant_record`); on resume they
            must equal the stored ones or be omitted.
        index: enrolment index (seeds the sequence); default: the number of participants already in the study.
        simulated: a simulated participant (`rhi.study.simulate`; recorded, required fields may be absent).

    Raises:
        InvalidInput: a bad id, undeclared fields, a protocol that differs from the one the participant started.
    """

    def __init__(self, study_dir: str | Path, protocol: Protocol | None, participant: str, *,
                 fields: dict[str, Any] | None = None, index: int | None = None, simulated: bool = False) -> None:
        if not isinstance(participant, str) or not _ID.match(participant):
            raise InvalidInput(f"participant: {participant!r} is not an id of letters, digits and _.- (max 64)")
        self.study_dir = Path(study_dir)
        self.folder = self.study_dir / participant
        self.id = participant
        meta_path = self.folder / "participant.json"
        if meta_path.exists():
            meta = _read_meta(meta_path)
            stored = self.folder / "protocol.toml"
            text = _read_text(stored)
            if protocol is not None and protocol.text and protocol.text != text:
                raise InvalidInput(f"protocol: differs from the one {participant} started with ({stored}); "
                                   "resume with that one")
            self.protocol = protocol if protocol is not None else _stored_protocol(stored, text, meta["protocol"])
            if fields and self.protocol.participant_record(fields) != meta["fields"]:
                raise InvalidInput(f"fields: differ from those stored for {participant} ({meta_path})")
            if index is not None and index != meta["index"]:
                raise InvalidInput(f"index: {participant} was enrolled as {meta['index']}, got {index}")
            self.index, self.fields = int(meta["index"]), meta["fields"]
        else:
            if protocol is None:
                raise InvalidInput(f"participant: no session of {participant!r} in {self.study_dir} to resume")
            record = protocol.participant_record(fields or {}, simulated=simulated)
            if index is None:
                index = len([p for p in self.study_dir.glob("*/participant.json")]) if self.study_dir.exists() else 0
            if int(index) != index or index < 0:
                raise InvalidInput(f"index: must be an integer >= 0, got {index!r}")
            self.folder.mkdir(parents=True, exist_ok=True)
            (self.folder / "trials").mkdir(exist_ok=True)
            (self.folder / "protocol.toml").write_text(protocol.text or _no_text(protocol), encoding="utf-8")
            # "w": a session killed before participant.json exists left at most a header, never a trial
            _fsync_append(self.folder / "responses.csv", _row_text(dict(zip(COLUMNS, COLUMNS))), mode="w")
            meta = {"id": participant, "protocol": protocol.name, "index": int(index), "seed": [protocol.seed,
                    int(index)], "fields": record, "simulated": simulated, "created": time.time()}
            tmp = meta_path.with_suffix(".tmp")
            tmp.write_text(json.dumps(meta, indent=1), encoding="utf-8")
            os.replace(tmp, meta_path)  # the folder is a participant's once this file exists
            self.protocol, self.index, self.fields = protocol, int(index), record
        self.plan: list[PlannedTrial] = plan(self.protocol, self.index)
        self._truncate_uncommitted()
        self.rows = read_responses(self.folder / "responses.csv")
        self._check_rows()
        self._keep_interrupted()

    # ------------------------------------------------------------------ state
    @property
    def next_trial(self) -> int:
        """Index of the first uncommitted trial (= the number committed)."""
        return len(self.rows)

    @property
    def done(self) -> bool:
        """Every trial committed."""
        return self.next_trial >= len(self.plan)

    def history(self, condition: str) -> list[tuple[float, int]]:
        """(comparison [%], response) of the committed scored trials of `condition` (to replay adaptive methods)."""
        return [(float(r["percent"]), int(r["response"])) for r in self.rows
                if r["condition"] == condition and r["training"] == "0" and r["response"] != ""]

    def trial_log(self, trial: int, probe: str) -> Path:
        """Path of the device log of probe `probe` ("a", "b" or "run") of trial `trial`."""
        return self.folder / "trials" / f"trial-{trial:04d}-{probe}.rhilog"

    # ------------------------------------------------------------------ writing
    def commit(self, row: dict[str, Any]) -> None:
        """Commit the next trial: append its row to responses.csv and fsync (once per trial).

        Raises:
            InvalidInput: the row is not the next trial's, or has an unknown column or a non-finite number.
        """
        if row.get("trial") != self.next_trial or self.done:
            raise InvalidInput(f"trial: expected trial {self.next_trial} of {len(self.plan)}, got {row.get('trial')!r}")
        unknown = sorted(set(row) - set(COLUMNS))
        if unknown:
            raise InvalidInput(f"{unknown[0]}: not a responses column")
        for k, v in row.items():
            if isinstance(v, float) and not math.isfinite(v):
                raise InvalidInput(f"{k}: {v!r} is not a finite number")
        _fsync_append(self.folder / "responses.csv", _row_text(row))
        self.rows.append({c: "" if row.get(c) is None else str(row[c]) for c in COLUMNS})

    def note(self, text: str) -> None:
        """Append an experimenter's note (time-stamped, fsync-ed)."""
        t = time.strftime("%Y-%m-%dT%H:%M:%S")
        _fsync_append(self.folder / "notes.txt", f"{t}\ttrial {self.next_trial}\t{' '.join(str(text).split())}\n")

    def _check_rows(self) -> None:
        """The committed rows are this participant's planned trials (a hand-edited responses.csv is refused)."""
        if len(self.rows) > len(self.plan):
            raise InvalidInput(f"{self.folder / 'responses.csv'}: {len(self.rows)} trials, the plan has {len(self.plan)}")
        for row, t in zip(self.rows, self.plan):
            want = {"subject": self.id, "block": str(t.block), "condition": t.condition, "training": str(int(t.training))}
            for k, v in want.items():
                if row[k] != v:
                    raise InvalidInput(f"{self.folder / 'responses.csv'}, trial {t.index}, column {k!r}: expected {v!r} "
                                       f"(the plan of {self.id}), got {row[k]!r}")

    def _truncate_uncommitted(self) -> None:
        path = self.folder / "responses.csv"
        data = path.read_bytes() if path.is_file() else b""  # no file: read_responses says so
        if data and not data.endswith(b"\n"):
            with open(path, "r+b") as fh:
                fh.truncate(data.rfind(b"\n") + 1)
                fh.flush()
                os.fsync(fh.fileno())

    def _keep_interrupted(self) -> None:
        """Logs of trials not committed (an interrupted one) are renamed, never overwritten."""
        for p in sorted((self.folder / "trials").glob("trial-*.rhilog")):
            m = re.match(r"trial-(\d+)-(\w+)$", p.stem)
            if m and int(m.group(1)) >= self.next_trial:
                k = 1
                while (dest := p.with_name(f"{p.stem}.interrupted-{k}.rhilog")).exists():
                    k += 1
                os.replace(p, dest)
                events = p.with_name(p.name + ".events.jsonl")  # the log's companion (`rhi.sim.log`)
                if events.exists():
                    os.replace(events, dest.with_name(dest.name + ".events.jsonl"))


def _no_text(protocol: Protocol) -> str:
    return Path(protocol.source).read_text(encoding="utf-8")


def participants(study_dir: str | Path) -> list[Session]:
    """Every participant's session of a study folder, by enrolment index.

    Raises:
        InvalidInput: no participant folder in `study_dir`.
    """
    d = Path(study_dir)
    found = sorted(d.glob("*/participant.json")) if d.is_dir() else []
    if not found:
        raise InvalidInput(f"study_dir: no participant folders (with participant.json) in {str(d)!r}")
    sessions = [Session(d, None, p.parent.name) for p in found]
    return sorted(sessions, key=lambda s: s.index)


__all__ = ["COLUMNS", "Session", "answer_row", "participants", "read_responses", "run_row"]
