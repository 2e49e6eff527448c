"""The torque of each source in a fast controller's tick: the compiled twin of the reference's ``parts``.

`TickSources` splits the torque of the tick a `NullSpaceController` has just run through its whole
compiled tick (`rhi.control.tick.KernelTick.whole`) into the sources `rhi.control.reference.reference_tick`
names (task, gravity, allocation, damping, barrier, tank damper, each objective, box clip), with
`rhi.control._compiled.sources.split`: the same definitions in projector form, equal to the reference to
rounding. A tick the controller ran through the reference (its fallback) fills ``ctrl.sources`` itself.
"""

from __future__ import annotations

import numpy as np

from rhi.control._compiled import P_CLIPPED
from rhi.control._compiled.sources import OK, split
from rhi.control._compiled.tank import TK_DAMPING, TK_GATE, TK_ON, TK_SCALE, TK_THETA
from rhi.control.controller import NullSpaceController
from rhi.control.tick import KernelTick, compiled_form

#: The sources before the objectives, in `reference_tick`'s order; "box clip" follows the objectives.
FIXED = ("task", "gravity", "allocation", "damping", "barrier", "tank damper")


class TickSources:
    """The torque by source of a controller's last whole compiled tick.

    Args:
        ctrl: a fast `NullSpaceController` (``reason`` says whether its ticks can be split here).

    Attributes:
        names: the sources, in `reference_tick`'s order.
        reason: why this controller's ticks are not split here ("" where they are).
    """

    def __init__(self, ctrl: NullSpaceController) -> None:
        self.ctrl = ctrl
        self.names = [*FIXED, *(f"objective {i}: {type(obj).__name__}" for i, (_, obj) in enumerate(ctrl.objectives)),
                      "box clip"]
        kt = ctrl._kernel
        why = []
        if kt is None or not kt.whole_ok:
            why.append("the controller's tick is not the whole compiled tick")
        elif kt._scheduled or kt._prm[P_CLIPPED] != 0.0 or kt.live:
            why.append("a scheduled objective, a Jacobian objective (TMI, manipulability) or null_space='clipped'")
        self.reason = "; ".join(why)
        if self.reason or kt is None:
            return
        static = vme = 0
        slots = []
        for _, obj in ctrl.objectives:  # the order `KernelTick` files them in: VME terms, static FME terms
            c = compiled_form(obj, ctrl.device)
            if c is not None and c.kind == "vme":
                slots.append(-1 - vme)
                vme += 1
            else:
                slots.append(static)
                static += 1
        self._kt: KernelTick = kt
        self._slot = np.array([s if s >= 0 else static + (-1 - s) for s in slots], dtype=np.int64)
        self._out = np.zeros((len(self.names), ctrl.device.n))

    def __call__(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray | None:
        """The last tick's torque by source (len(names), n) [N m] (a buffer the next call reuses); None: undecided.

        Call it right after ``ctrl.step(t, q, dq, ...)`` ran a whole compiled tick (its terms, forces and the
        tank's λ, μ are read from the kernel's buffers).
        """
        ctrl, kt = self.ctrl, self._kt
        buf = kt._buf
        last = ctrl.device.__dict__.get("_last_terms")  # the snapshot the whole tick read instead (`KernelTick.whole`)
        if last is not None and last[1]._buf is not None and last[0] == (q.tobytes(), dq.tobytes()):
            buf = last[1]._buf
        tank = kt._tank
        status = split(q, dq, buf, kt._at, kt._F[0], kt._F[1], ctrl.lo, ctrl.hi, kt._prm, kt._obj, kt._vme,
                       kt._vme_gain, float(tank[TK_ON]), float(tank[TK_SCALE]), float(tank[TK_DAMPING]),
                       float(tank[TK_THETA]) if tank[TK_GATE] != 0.0 else 1.0, self._slot, self._out)
        return self._out if status == OK else None


__all__ = ["FIXED", "TickSources"]
