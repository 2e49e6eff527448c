"""Many ticks of `rhi.sim.simulate` in one compiled call for a run with the motors off (`rhi.control.ZeroTorque`).

`MotorsOffLoop.build` accepts a run of a `ZeroTorque` of the plant's size with a hand that
`rhi.sim._compiled.handle.hand_supported` accepts or none and a physical `Wall` or none, without a virtual
environment, teleoperation or ``record`` hook (`MotorsOffLoop.why_not` says which part is only Python's).
`ticks` then runs a block of ticks per call: the plant's sensors (`rhi.sim._compiled.io.sensors`), zero torque,
a control period of physics steps with the hand and the wall (`rhi.sim._compiled.handle.hand_period`, MuJoCo's
step included) and the log row: the arithmetic of the Python loop, so the log equals it. The Python loop's
scalars but the work stay NaN (`ZeroTorque` has no state). With no controller, no tick is handed to Python; a
plant fault ends the call after the tick's row, as in the Python loop. Timing columns as `rhi.sim._compiled.
fast_loop`'s. Imported by `rhi.sim.loop.simulate`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import numpy as np

from rhi.control.controller import ZeroTorque
from rhi.jit import jit
from rhi.sim._compiled.fast_loop import DONE, FAULT
from rhi.sim._compiled.handle import PERIOD_OK, hand_constants, hand_period, hand_supported
from rhi.sim._compiled.io import log_row, sensors
from rhi.sim.environment import Wall

#: The loop of the last `simulate` run with the motors off, None where it ran in Python (set by `rhi.sim.loop.simulate`).
last: MotorsOffLoop | None = None


@jit
def ticks(count, k0, dt, sub, mj, sens, hand, ctrl, F_hand, st, lay, xv, rows):
    """Run up to `count` ticks with the motors off from tick k0, one log row each (see the module docstring).

    Args:
        count: ticks to run at most (<= len(rows)).
        k0: the first tick's index (the seq column).
        dt: control period [s].
        sub: physics steps per period.
        mj: (mjModel address, mjData address).
        sens: `rhi.sim._compiled.io.sensors`' arguments but its output.
        hand: `hand_period`'s (sd, idx, c, F, xfrc, acc, wn, bad, at).
        ctrl: (n,) MuJoCo's ctrl.
        F_hand: (m,) the hand's force of the last period [N], advanced.
        st: (2,) the session's time [s] and work [J], advanced.
        lay: (5,) int64: where q, work and seq start in a row; then (outputs) ticks run, plant status.
        xv: (2 m,) int64 sensordata indices of the handle's position and velocity.
        rows: (>= count, width) the log rows to write.

    Returns:
        DONE, or FAULT (a plant fault at the last tick run; its status in lay[4]).
    """
    n, m = ctrl.shape[0], F_hand.shape[0]
    sd, idx, c, F, xfrc, acc, wn, bad, at = hand
    read = np.empty(2 * n + 6)
    zero_n, F_env = np.zeros(n), np.zeros(m)
    lay[3], lay[4] = 0, PERIOD_OK
    for j in range(count):
        t = st[0]
        sensors(sens[0], sens[1], sens[2], sens[3], sens[4], sens[5], read)
        ctrl[:] = 0.0
        xfrc[:] = 0.0
        acc[0], acc[2] = st[1], 0.0
        status = hand_period(mj[0], mj[1], sub, t, sd, idx, c, F, xfrc, acc, wn, bad, at)
        st[1] = acc[0]
        if status == PERIOD_OK:
            F_hand[:] = F
        row = rows[j]
        row[0] = t
        log_row(row, lay[0], read, zero_n, sd, xv, F_hand, F_env)
        row[lay[1]] = st[1]
        o = lay[2]
        row[o] = k0 + j
        row[o + 6] = 0.0  # late
        row[o + 7] = 0.0 if status == PERIOD_OK else 1.0
        lay[3] = j + 1
        if status != PERIOD_OK:
            lay[4] = status
            return FAULT
        st[0] = t + dt
    return DONE


class MotorsOffLoop:
    """The compiled ticks of one `simulate` run with the motors off (`build` decides whether they apply).

    Attributes:
        calls: compiled calls made; ticks: ticks they ran.
        recorded: unused (no ``record`` hook); set by `simulate` as for `rhi.sim._compiled.fast_loop.FastLoop`.
    """

    #: the log's ``route`` of a run on this loop
    route = "compiled loop (motors off)"
    #: the controller never stops (`simulate` hands a stopped controller's tick to Python)
    stopped = False

    def __init__(self, sess, columns: list[tuple[str, int]]) -> None:
        plant = sess.plant
        self.sess = sess
        self._sens = (plant._ten, plant._tenv, plant.data.sensordata, plant._R,
                      np.concatenate([plant._const, plant._weight]), plant._ft_adr)
        c = hand_constants(sess.hand, sess.physical, plant.m)
        self._hand = (plant._sd, sess._idx, c, sess._F, plant._xfrc, sess._acc, plant._wnum, sess._badv, sess._at)
        at = dict(zip([name for name, _ in columns], np.cumsum([0] + [width for _, width in columns]).tolist()))
        self._lay = np.array([at["q"], at["work"], at["seq"], 0, 0], dtype=np.int64)
        self._xv = np.concatenate([plant._pos, plant._vel]).astype(np.int64)
        self._st = np.zeros(2)
        self._F_hand = np.zeros(plant.m)
        self.recorded = None
        self.calls = self.ticks = 0

    @staticmethod
    def build(sess, controller, kin, *, virtual, teleop, record, columns) -> MotorsOffLoop | None:
        """The compiled loop for this run (log `columns`), or None where some part of it is only Python's (`why_not`)."""
        if MotorsOffLoop.why_not(sess, controller, kin, virtual=virtual, teleop=teleop, record=record):
            return None
        return MotorsOffLoop(sess, columns)

    @staticmethod
    def why_not(sess, controller, kin, *, virtual, teleop, record) -> str:
        """Why this run is not one this loop computes ("" where it is; see the module)."""
        plant, hand, phys = sess.plant, sess.hand, sess.physical
        if type(controller) is not ZeroTorque:
            return f"the controller is a {type(controller).__name__}, not a ZeroTorque"
        if controller.n != plant.n:
            return "the controller and the plant differ in size"
        if record is not None or virtual is not None or teleop is not None:
            return "a record hook, a virtual environment or teleoperation with the motors off"
        if hand is not None and not hand_supported(hand, phys, plant.m):
            return f"the hand ({type(hand).__name__}) is not one the compiled loop computes"
        if phys is not None and (type(phys) is not Wall or phys.point.shape != (plant.m,)):
            return f"the physical environment ({type(phys).__name__}) is not a Wall"
        return ""

    def run(self, k0: int, rows: np.ndarray) -> tuple[int, int]:
        """Ticks k0, k0 + 1, ... into `rows` (at most all of them): (ticks run, outcome DONE / FAULT).

        On FAULT the session holds its fault (`Session.fault`) and the last row is the tick's.
        """
        sess, st, lay = self.sess, self._st, self._lay
        st[0], st[1] = sess.t, sess.work
        self._F_hand[:] = sess.F_hand
        out = ticks(len(rows), k0, sess.dt, sess.sub, sess._addr, self._sens, self._hand, sess.plant._ctrl,
                    self._F_hand, st, lay, self._xv, rows)
        done = int(lay[3])
        self.calls += 1
        self.ticks += done
        sess.t, sess.work, sess.F_hand = float(st[0]), float(st[1]), self._F_hand.copy()
        if out == FAULT:
            sess._stop(sess._fault(int(lay[4]), float(st[0])))
        return done, out
