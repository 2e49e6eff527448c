"""Result objects of the thesis experiments: numbers beside the thesis's, arrays for figures."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class Row:
    """One reproduced quantity: the thesis value, ours, and their difference.

    Attributes:
        quantity: what is compared, e.g. "ρ RHI at (0.49, -0.22)".
        thesis: the thesis's value (None where the thesis gives none).
        ours: our value.
        unit: SI unit ("" for dimensionless).
        note: why they differ, where they do.
    """

    quantity: str
    thesis: float | None
    ours: float
    unit: str = ""
    note: str = ""

    @property
    def difference(self) -> float | None:
        """ours − thesis."""
        return None if self.thesis is None else self.ours - self.thesis

    @property
    def relative(self) -> float | None:
        """(ours − thesis)/|thesis|."""
        if self.thesis is None or self.thesis == 0:
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

    def to_json(self) -> dict[str, Any]:
        """JSON-serialisable dict of every number (arrays as nested lists)."""

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
                            "thesis": r.thesis,
                            "rhi": clean(float(r.ours)),
                            "difference": clean(r.difference),
                            "relative": clean(r.relative),
                            "unit": r.unit,
                            "note": r.note,
                        }
                        for r in t.rows
                    ],
                }
                for t in self.tables
            ],
            "arrays": {k: _jsonable(v) for k, v in self.arrays.items()},
            "notes": self.notes,
        }


def _jsonable(v: np.ndarray) -> Any:
    """Array as nested lists with None where it is not finite (JSON has no NaN)."""
    a = np.asarray(v)
    if a.dtype.kind in "biu":
        return a.tolist()
    return np.where(np.isfinite(a), a, None).tolist()
