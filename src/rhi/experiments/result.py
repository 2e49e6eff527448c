"""Result objects of the thesis experiments: numbers beside the thesis's, arrays for figures."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from rhi.errors import InvalidInput
from rhi.thesis import ThesisValue


@dataclasses.dataclass(frozen=True)
class Row:
    """One reproduced quantity: the thesis value, ours, and their difference.

    Attributes:
        quantity: what is compared, e.g. "ρ RHI at (0.49, -0.22)".
        thesis: the thesis's value (None where the thesis gives none).
        ours: our value.
        unit: SI unit ("" for dimensionless).
        note: why they differ, where they do (required where ours is outside the tolerance).
        tolerance: explicit tolerance [unit]; default: the thesis value's own (its rounding, `rhi.thesis`).
        bound: "max" or "min" where `thesis` is an acceptance bound (ours ≤ or ≥ it), not a value to equal.

    A thesis number must be a `rhi.thesis.ThesisValue` (the one module of thesis values); a plain
    float in `thesis` is allowed only as a `bound` of rhi's own.
    """

    quantity: str
    thesis: float | None
    ours: float
    unit: str = ""
    note: str = ""
    tolerance: float | None = None
    bound: str | None = None

    def __post_init__(self) -> None:
        if self.bound not in (None, "max", "min"):
            raise InvalidInput(f"bound: expected None, 'max' or 'min', got {self.bound!r}")
        if self.bound is not None and self.thesis is None:
            raise InvalidInput("thesis: a bound row needs its bound in `thesis`")

    @property
    def source(self) -> str | None:
        """Key of the thesis value in `rhi.thesis` (None for bounds of rhi's own and rows without one)."""
        return self.thesis.key if isinstance(self.thesis, ThesisValue) else None

    @property
    def tol(self) -> float | None:
        """Tolerance [unit]: explicit, else the thesis value's rounding, else 0 for a bound."""
        if self.tolerance is not None:
            return self.tolerance
        if isinstance(self.thesis, ThesisValue):
            return self.thesis.tol
        return 0.0 if self.bound is not None else None

    @property
    def within(self) -> bool | None:
        """Whether ours matches the thesis within the tolerance (or satisfies the bound); None without one."""
        tol = self.tol
        if self.thesis is None or tol is None:
            return None
        if not math.isfinite(self.ours):
            return False
        slack = tol * (1 + 1e-9) + 1e-15
        if self.bound == "max":
            return bool(self.ours <= self.thesis + slack)
        if self.bound == "min":
            return bool(self.ours >= self.thesis - slack)
        return bool(abs(self.ours - self.thesis) <= slack)

    @property
    def difference(self) -> float | None:
        """Ours − thesis."""
        return None if self.thesis is None else self.ours - self.thesis

    @property
    def relative(self) -> float | None:
        """(ours − thesis)/|thesis|; None where it means nothing (bounds, p-values, angles, orderings, ≈ 0)."""
        if self.thesis is None or self.thesis == 0 or self.bound is not None:
            return None
        if isinstance(self.thesis, ThesisValue) and not self.thesis.relative:
            return None
        return (self.ours - self.thesis) / abs(self.thesis)


@dataclasses.dataclass(frozen=True)
class Table:
    """A thesis table (or a set of reported numbers) side by side with ours."""

    title: str
    rows: list[Row]


@dataclasses.dataclass
class Result:
    """What an experiment returns: tables of numbers, arrays for figures, notes.

    Attributes:
        name: experiment id, e.g. "ch3.table_3_1".
        title: human title.
        tables: thesis-vs-rhi tables.
        arrays: named arrays (figures are drawn from these by `rhi.plots`).
        notes: explanations of differences and of choices the thesis leaves open.
    """

    name: str
    title: str
    tables: list[Table] = dataclasses.field(default_factory=list)
    arrays: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    notes: list[str] = dataclasses.field(default_factory=list)

    def to_json(self, *, arrays: bool = True) -> dict[str, Any]:
        """JSON-serialisable dict of every number (arrays as nested lists unless `arrays` is False)."""

        def clean(v: Any) -> Any:
            if isinstance(v, float) and not math.isfinite(v):
                return None
            return v

        return {
            "name": self.name,
            "title": self.title,
            "tables": [
                {
                    "title": t.title,
                    "rows": [
                        {
                            "quantity": r.quantity,
                            "thesis": None if r.thesis is None else float(r.thesis),
                            "rhi": clean(float(r.ours)),
                            "difference": clean(r.difference),
                            "relative": clean(r.relative),
                            "tolerance": r.tol,
                            "bound": r.bound,
                            "within": r.within,
                            "source": r.source,
                            "unit": r.unit,
                            "note": r.note,
                        }
                        for r in t.rows
                    ],
                }
                for t in self.tables
            ],
            "arrays": {k: _jsonable(v) for k, v in self.arrays.items()} if arrays else {},
            "notes": self.notes,
        }


def result_from_json(d: Any, path: str = "result") -> Result:
    """A `Result` back from its `Result.to_json(arrays=False)` form (thesis values by their `rhi.thesis` key).

    Keys the form derives (difference, relative, within, arrays, ...) are not read.

    Raises:
        InvalidInput: a missing key or a value of the wrong type (named by its key path under `path`, e.g.
            ``result.tables[0].rows[2].rhi``) or a thesis key `rhi.thesis` does not know.
    """
    from rhi import thesis as T
    from rhi.runtime import schema as S  # deferred: rhi.runtime costs a second to import

    r = _result_form()(path, d)
    tables = []
    for i, t in enumerate(r["tables"]):
        rows = []
        for j, row in enumerate(t["rows"]):
            where = f"{path}.tables[{i}].rows[{j}]"
            thesis = S.prefixed(f"{where}.source", T.get, row["source"]) if row["source"] else row["thesis"]
            own_tol = isinstance(thesis, ThesisValue) and row["tolerance"] == thesis.tol
            rows.append(S.prefixed(where, Row, row["quantity"], thesis, math.nan if row["rhi"] is None else row["rhi"],
                                   row["unit"], row["note"], None if own_tol or row["bound"] else row["tolerance"],
                                   row["bound"]))
        tables.append(Table(t["title"], rows))
    return Result(r["name"], r["title"], tables, {}, list(r["notes"]))


def _result_form() -> Callable[[str, Any], Any]:
    """The check of a result's JSON form (`rhi.runtime.schema`): the keys it reads, their types."""
    from rhi.runtime import schema as S

    def read(spec: S.Spec) -> S.Check:  # a table; the keys `Result.to_json` derives are not read
        def check(path: str, d: Any) -> dict:
            if not isinstance(d, dict):
                raise InvalidInput(f"{path}: expected a table, got {d!r:.80}")
            return S.parse(path, {k: v for k, v in d.items() if k in spec}, spec)

        return check

    def notes(path: str, v: Any) -> list[str]:
        if not isinstance(v, list):
            raise InvalidInput(f"{path}: expected a list of strings, got {v!r:.80}")
        return [S.string(f"{path}[{i}]", x) for i, x in enumerate(v)]

    number = S.optional(S.number())
    row = {"quantity": (S.string, S.REQUIRED), "thesis": (number, S.REQUIRED), "rhi": (number, S.REQUIRED),
           "unit": (S.string, S.REQUIRED), "note": (S.string, S.REQUIRED),
           "tolerance": (S.optional(S.number(low=0.0)), S.REQUIRED),
           "bound": (S.optional(S.choice("max", "min")), S.REQUIRED), "source": (S.optional(S.string), S.REQUIRED)}
    table = {"title": (S.string, S.REQUIRED), "rows": (S.tables(read(row)), S.REQUIRED)}
    return read({"name": (S.string, S.REQUIRED), "title": (S.string, S.REQUIRED),
                 "tables": (S.tables(read(table)), S.REQUIRED), "notes": (notes, S.REQUIRED)})


def _jsonable(v: np.ndarray) -> Any:
    """Array as nested lists with None where it is not finite (JSON has no NaN)."""
    a = np.asarray(v)
    if a.dtype.kind in "biu":
        return a.tolist()
    return np.where(np.isfinite(a), a.astype(object), np.array(None, dtype=object)).tolist()
