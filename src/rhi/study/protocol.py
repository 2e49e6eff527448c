"""Study protocols: a TOML file describing a user study, read and checked once (`load_protocol`).

A protocol holds these tables (the shipped files in ``rhi/study/protocols/`` are commented examples,
`shipped_protocols()` lists them); unknown keys, values of the wrong type, impossible stimulus ranges and
undeclared participant fields raise `InvalidInput` naming the key path:

- ``description``, ``seed`` (the study's seed; participant i's randomisation is seeded by (seed, i)).
- ``[task]``: ``kind`` = "discrimination_2afc" (probe A, signal, probe B, answer: thesis §3.5) with
  ``question``, ``probe_time`` [s] (the longest a probe may last), ``stroke_time`` [s] (the simulated hand's);
  or "path_following" (§5.5) with ``time_limit`` [s] and the W path (``center``, ``width``, ``height`` [m]).
- ``[stimulus]``: ``method`` = "constant" (the method of constant stimuli: ``reference``,
  ``comparisons_percent``, ``repetitions``), "staircase" (transformed up-down: ``start_percent``,
  ``step_percent``, ``down``, ``up``, ``trials``, ``min_percent``, ``max_percent``), "quest" (QUEST+ over
  the equal-asymptote cumulative Gaussian: ``trials``, ``min_percent``, ``max_percent``, ``step_percent``,
  ``lapse``) or "none" (a task without stimuli: ``repetitions`` per condition).
- ``[[conditions]]``: ``name``, ``device`` (a bundled device), ``config`` (a run configuration: the
  controller), ``params`` (the device's design parameters), ``description``.
- ``[order]``: ``conditions`` = "random" | "fixed" (per participant), ``pair`` = "random" |
  "reference_first" (which sample of a pair comes first).
- ``[blocks]``: ``rest_every`` (an optional rest before every such trial), ``rest_seconds``,
  ``long_rest_every``, ``long_rest_seconds`` (a required rest), ``training`` (unscored trials per condition).
- ``[fixture]`` (a virtual fixture holding the handle on a line: ``point``, ``direction`` [m],
  ``stiffness`` [N/m], ``damping`` [N s/m]) and ``[obstacle]`` (a physical stop ``distance`` [m] along it).
- ``[teleoperation]`` (path following only; the §5.4 set-up when absent): the simulated slave robot that follows
  the master, ``slave`` (a bundled device, "rehab_slave"), ``slave_params``, its Cartesian PD ``kp`` [N/m] and
  ``kd`` [N s/m], and the master→slave map x_s,des = ``scale`` x_m + ``offset`` [m] (`rhi.sim.Teleoperation`);
  the reference path lies in the slave's workspace.
- ``[display]``: ``participant``: what the participant's page shows, out of `PARTICIPANT_ELEMENTS`.
- ``[participant]``: ``fields`` (name = "integer" | "number" | "text" | a list of choices) and ``required``
  (names among them): nothing else about a participant is stored.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from rhi.errors import InvalidInput
from rhi.runtime import schema as S

#: what a participant's page may show.
PARTICIPANT_ELEMENTS = ("next", "answers", "progress", "rest", "reference_path", "slave")
_TASK_ELEMENTS = {"discrimination_2afc": ("next", "answers", "progress", "rest"),
                  "path_following": ("next", "progress", "rest", "reference_path", "slave")}

_pos, _nonneg = S.number(low=0.0, strict=True), S.number(low=0.0)
_pct = S.number()
_stiff, _damp = S.number(low=0.0, high=1e6), S.number(low=0.0, high=1e4)  # of a rendered environment [N/m, N s/m]
_count = S.integer(low=1, high=10_000)  # repetitions, trials: a session of a person (and of plausible memory)
_R = S.REQUIRED


def _strings(path: str, v) -> tuple[str, ...]:
    if not isinstance(v, list):
        raise InvalidInput(f"{path}: expected a list of strings, got {v!r}")
    return tuple(S.string(f"{path}[{i}]", x) for i, x in enumerate(v))


def _field_type(path: str, v) -> str | tuple[str, ...]:
    if isinstance(v, list):
        if not v:
            raise InvalidInput(f"{path}: expected a non-empty list of choices, got []")
        return _strings(path, v)
    return str(S.choice("integer", "number", "text")(path, v))


def _fields(path: str, v) -> dict[str, str | tuple[str, ...]]:
    if not isinstance(v, dict):
        raise InvalidInput(f"{path}: expected a table of field names and types, got {v!r}")
    return {k: _field_type(f"{path}.{k}", x) for k, x in v.items()}


_TASK = S.tagged("kind", {
    "discrimination_2afc": {"question": (S.string, "Which sample was stiffer?"), "probe_time": (_pos, 30.0),
                            "stroke_time": (_pos, 1.0)},
    "path_following": {"time_limit": (_pos, 120.0), "center": (S.vector(), [0.49, -0.18]),
                       "width": (_pos, 0.08), "height": (_pos, 0.04), "speed": (_pos, 0.02)},
})
_REF = {"reference": (_pos, 50.0), "unit": (S.string, "N/m")}
_STIMULUS = S.tagged("method", {
    "constant": {**_REF, "comparisons_percent": (S.vector(), _R), "repetitions": (_count, _R)},
    "staircase": {**_REF, "start_percent": (_pct, _R), "step_percent": (_pos, _R), "down": (S.integer(low=1), 2),
                  "up": (S.integer(low=1), 1), "trials": (_count, _R), "min_percent": (_pct, _R),
                  "max_percent": (_pct, _R)},
    "quest": {**_REF, "trials": (_count, _R), "min_percent": (_pct, _R), "max_percent": (_pct, _R),
              "step_percent": (_pos, 2.5), "lapse": (S.number(low=0.0), 0.02)},
    "none": {"repetitions": (_count, _R)},
})
_CONDITION = {"name": (S.string, _R), "device": (S.string, _R), "config": (S.string, None),
              "params": (S.numbers_table, {}), "description": (S.string, "")}
_ROOT = {
    "description": (S.string, ""),
    "seed": (S.integer(low=0), 0),
    "task": (_TASK, _R),
    "stimulus": (_STIMULUS, _R),
    "conditions": (S.tables(S.table(_CONDITION)), _R),
    "order": (S.table({"conditions": (S.choice("random", "fixed"), "random"),
                       "pair": (S.choice("random", "reference_first"), "random")}), {}),
    "blocks": (S.table({"rest_every": (S.integer(low=0), 0), "rest_seconds": (_nonneg, 600.0),
                        "long_rest_every": (S.integer(low=0), 0), "long_rest_seconds": (_nonneg, 3600.0),
                        "training": (S.integer(low=0, high=10_000), 0)}), {}),
    "fixture": (S.table({"point": (S.vector(), _R), "direction": (S.vector(), _R), "stiffness": (_stiff, 1000.0),
                         "damping": (_damp, 5.0)}), None),
    "obstacle": (S.table({"distance": (_pos, _R), "stiffness": (_stiff, 2.0e4), "damping": (_damp, 50.0)}), None),
    "teleoperation": (S.table({"slave": (S.string, "rehab_slave"), "slave_params": (S.numbers_table, {}),
                               "kp": (_nonneg, 2000.0), "kd": (_nonneg, 60.0), "scale": (_pos, 1.0),
                               "offset": (S.vector(), None)}), {}),
    "display": (S.table({"participant": (_strings, _R)}), _R),
    "participant": (S.table({"fields": (_fields, {}), "required": (_strings, [])}), {}),
}


@dataclasses.dataclass(frozen=True)
class Condition:
    """One condition of a study: a device under a controller (a run configuration).

    Attributes:
        name: the condition's name (a column of the responses, e.g. "RHI").
        device: bundled device name (e.g. "rhi4"); params: its design parameters.
        config: run configuration (`rhi.runtime.config`) of the controller, or None (rendering only).
        description: one line.
    """

    name: str
    device: str
    config: str | None
    params: dict[str, float]
    description: str


@dataclasses.dataclass(frozen=True, eq=False)
class Protocol:
    """A checked study protocol (see the module docstring for the keys).

    Attributes:
        name: the file's stem; source: its path; text: the file's text (copied into every participant's folder).
        description, seed: as in the file.
        task, stimulus, order, blocks, fixture, obstacle: the checked tables (dicts, SI units; fixture and
            obstacle None where absent).
        teleoperation: the slave's table of a path-following task (defaults filled in, ``offset`` (m,)), else None.
        conditions: the conditions in file order.
        display: the elements the participant's page shows.
        fields: declared participant fields {name: "integer" | "number" | "text" | choices}; required: names.
    """

    name: str
    source: str
    text: str
    description: str
    seed: int
    task: dict[str, Any]
    stimulus: dict[str, Any]
    conditions: tuple[Condition, ...]
    order: dict[str, str]
    blocks: dict[str, Any]
    fixture: dict[str, Any] | None
    obstacle: dict[str, Any] | None
    teleoperation: dict[str, Any] | None
    display: tuple[str, ...]
    fields: dict[str, str | tuple[str, ...]]
    required: tuple[str, ...]

    @property
    def kind(self) -> str:
        """The task: "discrimination_2afc" or "path_following"."""
        return str(self.task["kind"])

    @property
    def condition_names(self) -> list[str]:
        """Condition names in file order."""
        return [c.name for c in self.conditions]

    def condition(self, name: str) -> Condition:
        """The condition called `name`.

        Raises:
            InvalidInput: no such condition.
        """
        for c in self.conditions:
            if c.name == name:
                return c
        raise InvalidInput(f"condition: {name!r} is not one of {self.condition_names}")

    def participant_record(self, values: dict[str, Any], *, simulated: bool = False) -> dict[str, Any]:
        """Check a participant's fields against the declared ones; return them converted.

        Args:
            values: {field: value} (strings from a command line or a form are converted).
            simulated: a simulated participant (required fields may be absent).

        Raises:
            InvalidInput: an undeclared field, a missing required one, or a value of the wrong type, naming
                ``participant.<field>``.
        """
        out: dict[str, Any] = {}
        for k, v in values.items():
            path = f"participant.{k}"
            kind = self.fields.get(k)
            if kind is None:
                raise InvalidInput(f"{path}: not a declared participant field (declared: {sorted(self.fields)}); "
                                   "only declared fields are stored")
            out[k] = _convert(path, kind, v)
        missing = [] if simulated else [k for k in self.required if k not in out]
        if missing:
            raise InvalidInput(f"participant.{missing[0]}: required by the protocol, not given")
        return out


def _convert(path: str, kind: str | tuple[str, ...], v: Any) -> Any:
    if isinstance(kind, tuple):
        if str(v) not in kind:
            raise InvalidInput(f"{path}: expected one of {list(kind)}, got {v!r}")
        return str(v)
    if kind == "text":
        return str(v)
    try:
        x = float(v) if kind == "number" else int(str(v))
    except (TypeError, ValueError):
        raise InvalidInput(f"{path}: expected {'a number' if kind == 'number' else 'an integer'}, got {v!r}") from None
    if isinstance(x, float) and not math.isfinite(x):
        raise InvalidInput(f"{path}: expected a finite number, got {v!r}")
    return x


def _check_stimulus(st: dict) -> None:
    m = st["method"]
    if m == "constant":
        pct = st["comparisons_percent"]
        for i, p in enumerate(pct):
            if p <= -100.0:
                raise InvalidInput(f"stimulus.comparisons_percent[{i}]: {p:g} % gives a stiffness <= 0 "
                                   "(impossible stimulus)")
        if len(set(pct.tolist())) != len(pct):
            raise InvalidInput(f"stimulus.comparisons_percent: duplicate values in {pct.tolist()}")
    elif m in ("staircase", "quest"):
        lo, hi = st["min_percent"], st["max_percent"]
        if lo <= -100.0:
            raise InvalidInput(f"stimulus.min_percent: {lo:g} % gives a stiffness <= 0 (impossible stimulus)")
        if hi <= lo:
            raise InvalidInput(f"stimulus.max_percent: {hi:g} % must exceed min_percent ({lo:g} %)")
        if m == "staircase" and not lo <= st["start_percent"] <= hi:
            raise InvalidInput(f"stimulus.start_percent: {st['start_percent']:g} % lies outside "
                               f"[{lo:g}, {hi:g}] %")
        if m == "quest":
            if st["step_percent"] > hi - lo:
                raise InvalidInput(f"stimulus.step_percent: {st['step_percent']:g} % is wider than the range")
            if st["lapse"] >= 0.5:
                raise InvalidInput(f"stimulus.lapse: must be < 0.5, got {st['lapse']:g}")


def _teleoperation(kind: str, d: dict, given: bool) -> dict[str, Any] | None:
    """The `[teleoperation]` table of a path-following task (its defaults when absent), None for the others."""
    if kind != "path_following":
        if given:
            raise InvalidInput(f"teleoperation: a {kind} task has no teleoperated slave")
        return None
    tele = dict(d["teleoperation"])
    m = len(d["task"]["center"])
    off = np.zeros(m) if tele["offset"] is None else tele["offset"]
    if off.shape != (m,):
        raise InvalidInput(f"teleoperation.offset: expected {m} values (the length of task.center), got {off.tolist()}")
    tele["offset"] = off
    return tele


def parse_protocol(data: dict, *, name: str = "protocol", source: str = "<dict>", text: str = "") -> Protocol:
    """A `Protocol` from a parsed TOML document.

    Raises:
        InvalidInput: an unknown key, a value of the wrong type, an impossible stimulus range, a stimulus method
            the task cannot use, duplicate conditions, a page element the task has not, or a required participant
            field that is not declared -- each naming its key path.
    """
    d = S.parse("", data, _ROOT)
    kind = d["task"]["kind"]
    st = d["stimulus"]
    if (kind == "path_following") != (st["method"] == "none"):
        raise InvalidInput(f"stimulus.method: {st['method']!r} does not fit the task {kind!r} "
                           "(path following has no stimuli: method = \"none\"; discrimination needs one)")
    _check_stimulus(st)
    conds = tuple(Condition(**c) for c in d["conditions"])
    if not conds:
        raise InvalidInput("conditions: need at least one condition")
    names = [c.name for c in conds]
    for i, n in enumerate(names):
        if not n or n in names[:i]:
            raise InvalidInput(f"conditions[{i}].name: {n!r} is empty or repeated")
    for i, el in enumerate(d["display"]["participant"]):
        if el not in _TASK_ELEMENTS[kind]:
            raise InvalidInput(f"display.participant[{i}]: {el!r} is not shown in a {kind} task "
                               f"(allowed: {list(_TASK_ELEMENTS[kind])})")
    fields = d["participant"]["fields"]
    for i, r in enumerate(d["participant"]["required"]):
        if r not in fields:
            raise InvalidInput(f"participant.required[{i}]: {r!r} is not a declared field (participant.fields)")
    fx, ob = d["fixture"], d["obstacle"]
    if ob is not None and fx is None:
        raise InvalidInput("obstacle: needs a [fixture] (the obstacle sits along its direction)")
    if kind == "discrimination_2afc" and fx is None:
        raise InvalidInput("fixture: a discrimination task needs a [fixture] (the line the samples are probed along)")
    if fx is not None:
        if fx["point"].shape != fx["direction"].shape:
            raise InvalidInput("fixture.direction: must have the length of fixture.point")
        if not np.abs(fx["direction"]).max() > 0:
            raise InvalidInput("fixture.direction: must be non-zero")
        fx["direction"] = fx["direction"] / np.abs(fx["direction"]).max()  # its norm cannot overflow (e.g. 1e300)
    return Protocol(name=name, source=source, text=text, description=d["description"], seed=d["seed"],
                    task=d["task"], stimulus=st, conditions=conds, order=d["order"], blocks=d["blocks"],
                    fixture=fx, obstacle=ob, teleoperation=_teleoperation(kind, d, "teleoperation" in data),
                    display=tuple(d["display"]["participant"]), fields=fields,
                    required=tuple(d["participant"]["required"]))


def shipped_protocols() -> list[str]:
    """Names of the protocols shipped with rhi (``rhi study run NAME``)."""
    folder = resources.files("rhi.study") / "protocols"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def protocol_path(protocol: str | Path) -> Path:
    """The file of `protocol`: a TOML path or the name of a shipped protocol.

    Raises:
        InvalidInput: neither exists.
    """
    p = Path(protocol)
    if p.is_file():
        return p
    stem = str(protocol).removesuffix(".toml")
    if p.name == str(protocol) and stem in shipped_protocols():
        return Path(str(resources.files("rhi.study") / "protocols" / f"{stem}.toml"))
    raise InvalidInput(f"protocol: no file {str(protocol)!r} and no shipped protocol of that name "
                       f"(shipped: {', '.join(shipped_protocols())})")


def load_protocol(protocol: str | Path) -> Protocol:
    """Read and check a protocol from a TOML file or by the name of a shipped one (see `parse_protocol`)."""
    p = protocol_path(protocol)
    try:
        text = p.read_text(encoding="utf-8")
        data = tomllib.loads(text)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InvalidInput(f"protocol: cannot read {str(p)!r} as TOML ({exc})") from None
    return parse_protocol(data, name=p.stem, source=str(p), text=text)


__all__ = ["PARTICIPANT_ELEMENTS", "Condition", "Protocol", "load_protocol", "parse_protocol", "protocol_path",
           "shipped_protocols"]
