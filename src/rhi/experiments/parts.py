"""Experiments made of independent parts: the cases of one experiment run one after another or side by side.

An experiment whose cases do not depend on each other (the passivity cases, the W-trajectory
scenarios) describes them as a `Plan`: its `Part` s, each a picklable call that returns plain
data, and a `merge` that turns their outputs, in order, into the experiment's `Result`. The
experiment function itself runs the plan in this process (`run_plan`); `rhi reproduce` runs the
parts of a plan in separate worker processes and merges them, with the same result.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

from rhi.errors import InvalidInput
from rhi.experiments.result import Result

#: A progress callback: progress(done, total), in ticks or items.
Progress = Callable[[int, int], None]


@dataclasses.dataclass(frozen=True)
class Part:
    """One independent case of an experiment.

    Attributes:
        label: short name of the case, e.g. "objectives" (unique within its plan).
        run: ``run(progress=callback or None) -> output``; picklable (a module-level function or a
            `functools.partial` of one) so that a worker process can run it.
        work: its size in progress units (e.g. control ticks), for the progress of the whole plan.
    """

    label: str
    run: Callable[..., Any]
    work: int = 1


@dataclasses.dataclass(frozen=True)
class Plan:
    """The parts of an experiment and how their outputs make its result.

    Attributes:
        parts: the independent cases, in the order `merge` expects their outputs.
        merge: ``merge(outputs) -> Result`` with outputs[i] the output of parts[i]; picklable.
    """

    parts: Sequence[Part]
    merge: Callable[[list[Any]], Result]

    def __post_init__(self) -> None:
        labels = [p.label for p in self.parts]
        if not labels or len(set(labels)) != len(labels):
            raise InvalidInput(f"parts: expected at least one part, with distinct labels; got {labels!r}")


def run_plan(plan: Plan, progress: Progress | None = None) -> Result:
    """Run the parts of `plan` one after another in this process and merge their outputs.

    Args:
        plan: the experiment's plan.
        progress: callback(done, total) over all parts, in the parts' `work` units.
    """
    total, done, outputs = sum(p.work for p in plan.parts), 0, []
    for p in plan.parts:
        cb = None if progress is None else (lambda k, n, off=done: progress(off + k, total))
        outputs.append(p.run(progress=cb))
        done += p.work
    return plan.merge(outputs)


__all__ = ["Part", "Plan", "run_plan"]
