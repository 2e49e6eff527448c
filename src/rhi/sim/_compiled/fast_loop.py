"""Many ticks of `rhi.sim.simulate` in one compiled call, for the runs it computes exactly.

`FastLoop.build` accepts a run whose every part the kernels know: a `NullSpaceController` whose
whole tick runs compiled (`KernelTick.whole_ok`; a TMI objective's slave ellipsoid read from the run's own
teleoperated slave), a hand that `rhi.sim._compiled.handle.hand_supported` accepts or none, a physical `Wall`
or none, a virtual `Wall`, `Fixture`, a `compose` of them or none, a `rhi.sim.Teleoperation` or none, and
no ``record`` hook or a `rhi.sim.Probe`. `ticks` then runs up to a block
of ticks per call: the plant's sensors (`rhi.sim._compiled.io.sensors`), the handle's kinematics and
the virtual environment (`rhi.sim._compiled.handle.handle_state`), the slave's torque and ellipsoid
(`rhi.sim._compiled.slave.slave_torque`), the controller's input checks and whole tick (the controller's own
kernel of `rhi.control._compiled.whole.whole_for`, passed as a `rhi.jit.KernelRef`: the loop is compiled once
for every set of parts), the torque and a control period of physics steps with the hand and the
physical wall (`rhi.sim._compiled.handle.hand_period`, MuJoCo's step by `rhi.sim.mjc`), the slave's period
(`rhi.sim._compiled.slave.slave_period`), the log row and the probe's snapshot row (`SNAPSHOT`).

The arithmetic is that of the Python loop, so the log and the controller's state equal it. A tick the
compiled loop does not decide — a non-finite reading, a non-finite torque, the kernel's FALLBACK or
SINGULAR, a stopped controller not logged yet, a non-finite slave torque — ends the call *before* that tick
with the controller's state as it was; the caller runs that tick in Python and resumes. A plant fault
(non-finite handle force, diverged physics) ends it *after* the tick's row, as the Python loop does; a
diverged slave ends it without the row, and `FastLoop.run` raises the error `Plant.step` raises.

Timing columns of compiled rows: ``t_tick`` the call's average per tick, ``wall`` interpolated from
the call's start, ``t_read``, ``t_step`` and ``t_write`` NaN (not measured per tick), ``late`` 0.
Imported by `rhi.sim.loop.simulate`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import math
import weakref
from typing import Any

import numpy as np
from numba import typeof, types

from rhi.control._compiled import intent as _intent, tank as _tank, whole as _whole
from rhi.control._compiled.whole import B
from rhi.control.controller import NullSpaceController
from rhi.control.intent_control import IntentController
from rhi.devices._compiled.terms import assign, finite
from rhi.devices.terms import layout
from rhi.jit import KernelRef, jit
from rhi.sim._compiled.handle import (
    PERIOD_OK,
    hand_constants,
    hand_period,
    hand_supported,
    handle_state,
)
from rhi.sim._compiled.io import log_row, sensors
from rhi.sim._compiled.slave import slave_period, slave_torque
from rhi.sim.environment import Wall
from rhi.sim.plant import unstable
from rhi.sim.probe import Probe, Recorded
from rhi.sim.teleop import Teleoperation

#: How a call of `ticks` ended: every tick ran; the next tick is the Python loop's; a plant fault at the last
#: tick; the slave diverged at the tick after the last (its physics step in lay[L_STATUS]).
DONE, PYTHON, FAULT, SLAVE = 0, 1, 2, 3
#: (state name, its columns' width as a function of (n, n_s, m_i)), m_i: m with an intent estimator, else -1.
SNAPSHOT = (("held", lambda n, ns, mi: n), ("pc_scale", lambda n, ns, mi: 1), ("tank", lambda n, ns, mi: 1),
            ("tank_scale", lambda n, ns, mi: 1), ("tank_damping", lambda n, ns, mi: 1), ("slave_q", lambda n, ns, mi: ns),
            ("intent", lambda n, ns, mi: mi + 1))

#: Slots of the float state vector `st`: the session's time [s], work [J] and the last tick's logged
#: controller values (V, Ω, α, β, E_obs, α_pc), the stopped flag, Σ dissipated [J], the last controller
#: tick's time and clipped flag, the controller ticks and passivity ticks of the call.
S_T, S_WORK, S_V, S_OMEGA, S_ALPHA, S_BETA, S_EOBS, S_APC, S_STOPPED, S_DISS, S_TLAST, S_CLIP, S_TICKS, S_PC = range(14)
N_ST = 14
#: Slots of the int vector `lay`: where q and work start in a row, where seq starts, the virtual wall flag,
#: whether the law reads sensors["force"], sensors["ft"]; then (outputs) ticks run, outcome, plant status; then
#: (inputs) the teleoperation flag, where slave_x starts in a row, whether to write snapshot rows.
L_Q, L_WORK, L_SEQ, L_VIRTUAL, L_FORCE, L_FT, L_DONE, L_OUT, L_STATUS, L_TELE, L_SLAVE, L_SNAP, L_INTENT = range(13)

#: The compiled loop of the last `simulate` run, None where it ran in Python (set by `rhi.sim.loop.simulate`).
last: FastLoop | None = None
#: Each controller's whole tick as `ticks` calls it, by its `KernelTick` (whose arguments are the same arrays every call).
_refs: weakref.WeakKeyDictionary[Any, KernelRef] = weakref.WeakKeyDictionary()


@jit
def ticks(count, k0, dt, sub, mj, sens, kin, hand, ctrl, F_hand, wargs, cs, st, lay, xv, rows, tele, intent, snap,
          whole):
    """Run up to `count` ticks of the simulation loop from tick k0, one log row each (see the module docstring).

    Args:
        count: ticks to run at most (<= len(rows)).
        k0: the first tick's index (the seq column).
        dt: control period [s].
        sub: physics steps per period.
        mj: (mjModel address, mjData address).
        sens: `rhi.sim._compiled.io.sensors`' arguments but its output.
        kin: (ints, joints, fc) of `handle_state` with the virtual wall's constants (`rhi.sim.loop.Kinematics`).
        hand: `hand_period`'s (sd, idx, c, F, xfrc, acc, wn, bad, at).
        ctrl: (n,) MuJoCo's ctrl.
        F_hand: (m,) the hand's force of the last period [N], advanced.
        wargs: the whole tick's arguments after (t, q, dq, force) (`whole_args`).
        cs: the controller's arrays among them: FME transition tr, passivity vector, port position and
            effort, torque, held joints, result, the null-space energy tank's vector, q and efforts (`KernelTick`).
        st: (N_ST,) float state (S_* slots), advanced.
        lay: (9,) int64 layout and outcome (L_* slots).
        xv: (2 m,) int64 sensordata indices of the handle's position and velocity.
        rows: (>= count, width) the log rows to write.
        tele: the slave's (mj, sub, `slave_torque`'s arguments before x_master, ˢM (m, m), τ_s (n_s,), ctrl,
            applied force, sensordata, (m,) int64 position indices, warnings, bad, (k,) int64 slots of ˢM in the
            objective vector, the objective vector) (`FastLoop`; a stand-in where lay[L_TELE] is 0).
        intent: the intent estimator's (kind, settings, table, knots, state, posterior) of
            `rhi.control._compiled.intent.update`, (m,) int64 F/T rows of the task axes, (k,) int64 slots of
            the desired ellipsoids of u in the objective vector and (k, 2) their axes (`CompiledObjective.axes`)
            (a stand-in where lay[L_INTENT] is 0).
        snap: (>= count, width) the snapshot rows (`SNAPSHOT`) to write where lay[L_SNAP].
        whole: the controller's whole tick (`rhi.control._compiled.whole.whole_for`'s kernel, a `rhi.jit.KernelRef`).
    """
    n, m = ctrl.shape[0], F_hand.shape[0]
    tr, pc, pc_pos, pc_eff, tau, sat, res, tank, tank_q, tank_e = cs
    ist, ip = intent[4], intent[5]
    # scratch, and the state before a tick (restored where the tick is Python's)
    own = (np.empty(2 * n + 6), np.empty((3, m)), np.empty((2, m)), np.zeros(m), np.zeros(n), np.empty(m),
           np.empty((m, m)), ist.copy(), ip.copy(), tr.copy(), pc.copy(), pc_pos.copy(), pc_eff.copy(), tau.copy(),
           sat.copy(), tank.copy(), tank_q.copy(), tank_e.copy())
    # every array outlives the call (`own` is passed along to keep it): no reference counting of them within it
    _ticks(count, k0, dt, sub, mj, B(sens), B(kin), B(hand), B(ctrl), B(F_hand), B(wargs), B(cs), B(st), B(lay), B(xv),
           B(rows), B(tele), B(intent), B(snap), whole, B(own), own)


@jit
def _ticks(count, k0, dt, sub, mj, sens, kin, hand, ctrl, F_hand, wargs, cs, st, lay, xv, rows, tele, intent, snap,
           whole, scratch, keep):
    """`ticks`' loop on its arguments and `scratch` (`keep`: the owner of scratch, unused)."""
    n, m = ctrl.shape[0], F_hand.shape[0]
    tr, pc, pc_pos, pc_eff, tau, sat, res, tank, tank_q, tank_e = cs
    sd, idx, c, F, xfrc, acc, wn, bad, at = hand
    mj_s, sub_s, pd, M_s, tau_s, ctrl_s, xfrc_s, sd_s, pos_s, wn_s, bad_s, slots, obj = tele
    n_s = tau_s.shape[0]
    kind, iprm, table, knots, ist, ip, irows, islots, axes = intent
    read, kout, kx, F_env, zero_n, Fi, Di, ist0, ip0, tr0, pc0, pos0, eff0, tau0, sat0, tk0, tq0, te0 = scratch
    lay[L_DONE], lay[L_OUT], lay[L_STATUS] = 0, DONE, PERIOD_OK
    for j in range(count):
        t = st[S_T]
        sensors(sens[0], sens[1], sens[2], sens[3], sens[4], sens[5], read)
        q, dq, ft = read[:n], read[n:2 * n], read[2 * n:]
        if lay[L_VIRTUAL] != 0:
            handle_state(kin[0], kin[1], kin[2], q, dq, kout)
            assign(F_env, kout[2])
        if lay[L_TELE] != 0 or lay[L_INTENT] != 0:  # the handle's x and ẋ on the controller's model
            if lay[L_VIRTUAL] != 0:
                kx[0], kx[1] = kout[0], kout[1]
            else:
                handle_state(kin[0], kin[1], kin[2], q, dq, kx)
        if lay[L_TELE] != 0:  # the slave follows the master's x of this tick (its torque now: its state is the tick's)
            if not finite(kx[0]) or not slave_torque(*pd, kx[0], tau_s, M_s):
                lay[L_OUT] = PYTHON
                return
            for o in slots:
                for i in range(m):
                    for k in range(m):
                        obj[o + i * m + k] = M_s[i, k]
        if lay[L_INTENT] != 0:  # `IntentController.step`: the estimate from F_h and ẋ, then its objectives' M(u)
            assign(ist0, ist)
            assign(ip0, ip)
            for i in range(m):
                Fi[i] = ft[irows[i]]
            _intent.update(kind, iprm, table, knots, ist, ip, Fi, kx[1], t)
            for k in range(islots.shape[0]):
                _intent.desired(ist[:m], axes[k, 0], axes[k, 1], Di)
                for i in range(m):
                    for r in range(m):
                        obj[islots[k] + i * m + r] = Di[i, r]
        cmd = zero_n
        if st[S_STOPPED] == 0.0:
            # the controller's input checks: a tick that fails one is the Python loop's
            if not (finite(q) and finite(dq)) or (lay[L_FORCE] != 0 and not finite(F_env)) or (
                    lay[L_FT] != 0 and not finite(ft)):
                ist[:], ip[:] = ist0, ip0
                lay[L_OUT] = PYTHON
                return
            # the controller's state before the tick: loops (a slice assignment's broadcasting code costs more)
            assign(tr0, tr)
            assign(pc0, pc)
            assign(pos0, pc_pos)
            assign(eff0, pc_eff)
            assign(tau0, tau)
            assign(sat0, sat)
            assign(tk0, tank)
            assign(tq0, tank_q)
            for r in range(te0.shape[0]):
                assign(te0[r], tank_e[r])
            status = whole(t, q, dq, F_env, *wargs)
            if status != _whole.OK or res[_whole.R_DONE] == 0.0 or not finite(tau):  # the state as before the tick
                tr[:], pc[:], pc_pos[:], pc_eff[:], tau[:], sat[:] = tr0, pc0, pos0, eff0, tau0, sat0
                tank[:], tank_q[:], tank_e[:] = tk0, tq0, te0
                ist[:], ip[:] = ist0, ip0
                lay[L_OUT] = PYTHON
                return
            st[S_ALPHA], st[S_BETA] = res[_whole.R_ALPHA], res[_whole.R_BETA]
            st[S_V], st[S_OMEGA] = res[_whole.R_V], res[_whole.R_OMEGA]
            st[S_CLIP], st[S_TLAST] = res[_whole.R_CLIPPED], t
            if res[_whole.R_PC] != 0.0:
                st[S_DISS] += pc[_whole.PC_DISSIPATED]
                st[S_EOBS], st[S_APC] = pc[_whole.PC_E], pc[_whole.PC_ALPHA]
                st[S_PC] += 1.0
            st[S_TICKS] += 1.0
            cmd = tau
        assign(ctrl, cmd)
        for i in range(xfrc.shape[0]):
            xfrc[i] = 0.0
        acc[0], acc[2] = st[S_WORK], 0.0
        status = hand_period(mj[0], mj[1], sub, t, sd, idx, c, F, xfrc, acc, wn, bad, at)
        st[S_WORK] = acc[0]
        if status == PERIOD_OK:
            assign(F_hand, F)
            if lay[L_TELE] != 0:
                failed = slave_period(mj_s[0], mj_s[1], sub_s, ctrl_s, xfrc_s, tau_s, wn_s, bad_s)
                if failed >= 0:
                    lay[L_OUT], lay[L_STATUS] = SLAVE, failed
                    return
        row = rows[j]
        row[0] = t
        log_row(row, lay[L_Q], read, cmd, sd, xv, F_hand, F_env)
        if lay[L_TELE] != 0:
            for i in range(m):
                row[lay[L_SLAVE] + i] = sd_s[pos_s[i]]
        if lay[L_SNAP] != 0:
            srow = snap[j]
            for i in range(n):
                srow[i] = 1.0 if sat[i] else 0.0
            srow[n] = pc[_whole.PC_SCALE] if pc[_whole.PC_ON] != 0.0 else math.nan
            on = tank[_tank.TK_ON] != 0.0
            srow[n + 1] = tank[_tank.TK_ENERGY] + tank[_tank.TK_ALLOCATION] if on else math.nan
            srow[n + 2] = tank[_tank.TK_SCALE] if on else math.nan
            srow[n + 3] = tank[_tank.TK_DAMPING] if on else math.nan
            o = n + 4
            if lay[L_TELE] != 0:
                ten, const = pd[0], pd[2]
                for i in range(n_s):
                    srow[o + i] = ten[i] - const[i]
                o += n_s
            if lay[L_INTENT] != 0:
                for i in range(m):
                    srow[o + i] = ist[i]
                srow[o + m] = ist[m + _intent.ST_CONF]
        o = lay[L_WORK]
        row[o], row[o + 1], row[o + 2], row[o + 3] = st[S_WORK], st[S_V], st[S_OMEGA], st[S_ALPHA]
        row[o + 4], row[o + 5], row[o + 6] = st[S_BETA], st[S_EOBS], st[S_APC]
        o = lay[L_SEQ]
        row[o] = k0 + j
        row[o + 6] = 0.0  # late
        row[o + 7] = 0.0 if status == PERIOD_OK else 1.0
        lay[L_DONE] = j + 1
        if status != PERIOD_OK:
            lay[L_OUT], lay[L_STATUS] = FAULT, status
            return
        st[S_T] = t + dt


def _intent_args(intent, kt, m: int) -> tuple:
    """`ticks`' intent argument for an `IntentController` (None: a stand-in of the same types)."""
    ci = None if intent is None else intent.estimator.compiled()
    rows = np.array(intent.device.task_rows if intent is not None else range(m), dtype=np.int64)
    slots = [slot for slot, c in kt.live if intent is not None and c.source is intent.estimator]
    axes = [c.axes for _, c in kt.live if intent is not None and c.source is intent.estimator]
    prm = np.array([0.0 if ci is None else float(ci.settings.get(k, 0.0)) for k in _intent.SETTINGS])
    table = np.zeros((1, m)) if ci is None or ci.table is None else np.ascontiguousarray(ci.table, dtype=float)
    knots = np.zeros(1) if ci is None or ci.knots is None else np.ascontiguousarray(ci.knots, dtype=float)
    p = getattr(intent.estimator, "p", None) if intent is not None else None
    return (0 if ci is None else _intent.KINDS[ci.kind], prm, table, knots, np.zeros(m + 2 + m * m),
            np.zeros(1) if p is None else np.array(p, dtype=float), rows, np.array(slots, dtype=np.int64),
            np.array(axes, dtype=float).reshape(len(axes), 2))


def whole_args(controller) -> tuple:
    """The whole tick's arguments after (t, q, dq, force) (`rhi.control._compiled.whole.whole_for`), as the controller's.

    The controller's own terms buffers (ready = False) and state mirrors: the same arrays every call.
    """
    kt = controller._kernel
    return (*kt._chain, False, *kt._mid, kt._x, kt._buf, *kt._out)


class FastLoop:
    """The compiled ticks of one `simulate` run (`build` decides whether they apply, `why_not` says why not).

    Attributes:
        calls: compiled calls made; ticks: ticks they ran (the Python loop ran the others).
        recorded: where `run` appends the `Probe`'s values of its ticks (`rhi.sim.probe.Recorded`), or None.
    """

    #: the log's ``route`` of a run on this loop
    route = "compiled loop (whole tick)"

    def __init__(self, sess, controller, kin, columns: list[tuple[str, int]], probe: Probe | None = None) -> None:
        self.intent = controller if type(controller) is IntentController else None
        controller = controller.controller if self.intent is not None else controller
        plant, kt = sess.plant, controller._kernel
        self.sess, self.ctrl, self.kt = sess, controller, kt
        m = plant.m
        fused = sess._compiled(sess.hand, sess.physical)  # the session's hand constants (supported: `why_not`)
        c = hand_constants(sess.hand, sess.physical, m) if fused is None else fused[1]
        self._mj = sess._addr
        d = plant.data
        self._sens = (plant._ten, plant._tenv, d.sensordata, plant._R,
                      np.concatenate([plant._const, plant._weight]), plant._ft_adr)
        if kin is not None:
            _, ints, joints, fc = kin._compiled
            self._kin = (ints, joints, fc)
        else:
            self._kin = (np.zeros(1, np.int64), np.zeros((1, 1)), np.zeros(1))
        self._hand = (plant._sd, sess._idx, c, sess._F, plant._xfrc, sess._acc, plant._wnum, sess._badv, sess._at)
        self._wargs = whole_args(controller)
        self._whole = _refs.get(kt)
        if self._whole is None or self._whole.kernel is not kt._whole_fn:  # typed once per controller (its arrays)
            vec = types.float64[::1]  # t, q, dq and the force as `ticks` passes them, then the controller's arguments
            self._whole = _refs[kt] = KernelRef(kt._whole_fn, (types.float64, vec, vec, vec,
                                                               *(typeof(a) for a in self._wargs)))
        self._cs = (kt._tr, kt._pc, kt._pc_pos, kt._pc_eff, kt._tau, kt._sat, kt._res, kt._tank, kt._tank_q,
                    kt._tank_e)
        names = [name for name, _ in columns]
        at = dict(zip(names, np.cumsum([0] + [width for _, width in columns]).tolist()))
        need = set(controller._sensors)
        tele = sess.teleop
        self._lay = np.array([at["q"], at["work"], at["seq"], int(kin is not None and kin._fused), int("force" in need),
                              int("ft" in need), 0, 0, 0, int(tele is not None), at.get("slave_x", 0),
                              int(probe is not None or self.intent is not None), int(self.intent is not None)],
                             dtype=np.int64)
        self._xv = np.concatenate([plant._pos, plant._vel]).astype(np.int64)
        self._st = np.zeros(N_ST)
        self._F_hand = np.zeros(m)
        # the slave's arguments of `ticks` (the master's own arrays as a stand-in without teleoperation: same types)
        sp = plant if tele is None else tele.slave
        sdev = controller.device if tele is None else sp.device
        fast, n_s = sdev._fast_maps, sp.n
        slots = [slot for slot, c in kt.live if tele is not None and c.slave is tele.slave]
        gains = np.zeros(3) if tele is None else np.array([tele.kp, tele.kd, tele.scale])
        R, off = (np.eye(m), np.zeros(m)) if tele is None else (np.ascontiguousarray(tele.R), tele.p.copy())
        pd = (sp._ten, sp._tenv, sp._const, (*fast.chain, sdev.A, sdev.b, fast.rows_idx, sdev.armature, fast.supports,
                                            fast.identity), layout(n_s, m)[1], np.empty(m), np.empty(fast.size), gains,
              R, off)
        self._sub_s = 0 if tele is None else max(1, round(sess.dt / sp.timestep))
        self._tele = ((sp.model._address, sp.data._address), self._sub_s, pd, np.empty((m, m)), np.empty(n_s),
                      sp._ctrl, sp._xfrc, sp._sd, sp._pos.astype(np.int64), sp._wnum, np.array(sp._bad, dtype=np.int64),
                      np.array(slots, dtype=np.int64), kt._obj)
        self.probe = probe
        self.recorded: Recorded | None = None
        self._intent = _intent_args(self.intent, kt, m)
        widths = [w(plant.n, n_s if tele is not None else 0, m if self.intent is not None else -1) for _, w in SNAPSHOT]
        ends = np.cumsum([0, *widths]).tolist()
        self._snap_at = {name: (ends[i], ends[i + 1]) for i, (name, _) in enumerate(SNAPSHOT)}
        self._snap_width = ends[-1]
        self.calls = self.ticks = 0

    @property
    def stopped(self) -> bool:
        """Whether the controller has stopped (`simulate` hands its next tick to Python while that is not logged)."""
        return self.ctrl.state.stopped

    @staticmethod
    def build(sess, controller, kin, *, virtual, teleop, record, columns) -> FastLoop | None:
        """The compiled loop for this run (log `columns`), or None where some part of it is only Python's (`why_not`)."""
        if FastLoop.why_not(sess, controller, kin, virtual=virtual, teleop=teleop, record=record):
            return None
        return FastLoop(sess, controller, kin, columns, record)

    @staticmethod
    def why_not(sess, controller, kin, *, virtual, teleop, record) -> str:
        """Why this run is not one the compiled loop computes ("" where it is; see the module)."""
        if record is not None and not isinstance(record, Probe):
            return "a record hook (not a rhi.sim.Probe)"
        if isinstance(record, Probe) and teleop is None and "slave_q" in record.names.values():
            return "the probe records a slave but the run has no teleoperation"
        intent = controller if type(controller) is IntentController else None
        if intent is not None:
            ci = getattr(intent.estimator, "compiled", None)
            if intent.sensor != "ft" or not callable(ci) or ci() is None or kin is None or kin._compiled is None:
                return (f"the intent estimator ({type(intent.estimator).__name__}) has no compiled form, or the handle's "
                        "compiled kinematics are not there (a virtual environment or teleoperation)")
            controller = intent.controller
        if type(controller) is not NullSpaceController:
            return f"the controller is a {type(controller).__name__}, not a NullSpaceController"
        if controller._kernel is None or not controller._kernel.whole_ok:
            return f"the controller's tick is not the whole compiled tick: {controller.route}"
        if "step" in controller.__dict__:
            return "the controller's step is replaced"
        plant, hand, phys = sess.plant, sess.hand, sess.physical
        m, dev = plant.m, controller.device
        if (dev.n, dev.m) != (plant.n, m):
            return "the controller's device and the plant differ in size"
        if not set(controller._sensors) <= {"force", "ft"}:
            return "the primary law reads sensors other than force and ft"
        if hand is not None and not hand_supported(hand, phys, m):
            return f"the hand ({type(hand).__name__}) is not one the compiled loop computes"
        if phys is not None and (type(phys) is not Wall or phys.point.shape != (m,)):
            return f"the physical environment ({type(phys).__name__}) is not a Wall"
        if virtual is not None and (kin is None or kin._compiled is None or not kin._fused):
            return f"the virtual environment ({type(virtual).__name__}) is not one the compiled loop computes"
        for _, c in controller._kernel.live:
            if c.live is not None and not ((c.slave is not None and c.slave is getattr(teleop, "slave", None)) or (
                    intent is not None and c.source is intent.estimator)):
                return ("an objective's desired ellipsoid is read in Python each tick (not the run's slave or its "
                        "intent estimator)")
        if teleop is not None:
            sp = teleop.slave
            if type(teleop) is not Teleoperation or kin is None or kin._compiled is None:
                return f"the teleoperation ({type(teleop).__name__}) or the master's kinematics are not compiled"
            if sp.device._fast_maps.chain is None or sp.m != m or teleop.R.shape != (m, m):
                return "the slave's chain is not one the compiled kinematics handle, or its task differs in size"
        return ""

    def run(self, k0: int, rows: np.ndarray) -> tuple[int, int]:
        """Ticks k0, k0 + 1, ... into `rows` (at most all of them): (ticks run, outcome DONE / PYTHON / FAULT).

        On FAULT the session holds its fault (`Session.fault`) and the last row is the tick's. The `Probe`'s
        values of the ticks run go to `recorded`.

        Raises:
            PlantUnstable: the teleoperated slave's physics diverged (as `rhi.sim.Plant.step`).
        """
        sess, ctrl, kt = self.sess, self.ctrl, self.kt
        s, st = ctrl.state, self._st
        ps = None if ctrl._pc is None else ctrl._pc.state
        st[:] = (sess.t, sess.work, s.V, s.omega, s.alpha, s.beta, s.E_obs, s.alpha_pc, float(s.stopped),
                 0.0 if ps is None else ps.dissipated, 0.0, 0.0, 0.0, 0.0)
        before = None
        if not s.stopped:
            before = kt._load_transition(s)
            kt._load_passivity(ps)
            kt._load_tank(s)
        self._F_hand[:] = sess.F_hand
        if s.saturated is not None:  # the held set and λ as Python left them: what the probe reads until a tick
            kt._sat[:] = s.saturated
        if ps is not None:
            kt._pc[_whole.PC_SCALE] = ps.scale
        lay = self._lay
        snap = np.empty((len(rows) if lay[L_SNAP] else 1, max(self._snap_width, 1)))  # the probe's or the intent's
        t_slave = None if sess.teleop is None else sess.teleop.slave.data.time
        est = None if self.intent is None else self.intent.estimator
        ist, ip = self._intent[4], self._intent[5]
        if est is not None:  # the estimator's state as Python left it
            m = sess.plant.m
            ist[:m], ist[m], ist[m + 1] = est.u, est.confidence, float(getattr(est, "active", False))
            if getattr(est, "T", None) is not None:
                ist[m + 2:] = np.ravel(est.T)
            if getattr(est, "p", None) is not None:
                ip[:] = est.p
        ticks(len(rows), k0, sess.dt, sess.sub, self._mj, self._sens, self._kin, self._hand, sess.plant._ctrl,
              self._F_hand, self._wargs, self._cs, st, lay, self._xv, rows, self._tele, self._intent, snap,
              self._whole)
        done, out = int(lay[L_DONE]), int(lay[L_OUT])
        if est is not None and self.intent is not None:
            self._store_intent(est, snap[:done], rows[:done, 0])
        if sess.teleop is not None and done:
            sess.slave_x = sess.teleop.slave.x.copy()
        if self.probe is not None and self.recorded is not None and done:
            self.recorded.block(self._probe_values(snap[:done]))
        self.calls += 1
        self.ticks += done
        sess.t, sess.work, sess.F_hand = float(st[S_T]), float(st[S_WORK]), self._F_hand.copy()
        if not s.stopped:
            kt._store_transition(s, before)
            if st[S_TICKS]:
                s.t, s.alpha, s.beta, s.V, s.omega = (float(st[S_TLAST]), float(st[S_ALPHA]), float(st[S_BETA]),
                                                      float(st[S_V]), float(st[S_OMEGA]))
                s.saturated, s.clipped, s.tau = kt._sat.copy(), bool(st[S_CLIP]), kt._tau.copy()
                s.ticks += int(st[S_TICKS])
                kt._store_tank(s)
            if st[S_PC] and ps is not None:
                kt._store_passivity(s, ps, float(st[S_TLAST]), float(st[S_DISS]))
        if out == FAULT:
            sess._stop(sess._fault(int(lay[L_STATUS]), float(st[S_T])))
        if out == SLAVE and t_slave is not None:
            raise unstable(t_slave + (done * self._sub_s + int(lay[L_STATUS])) * sess.teleop.slave.timestep)
        return done, out

    def _store_intent(self, est, snap: np.ndarray, t: np.ndarray) -> None:
        """The estimator's state after the call, and `IntentController.history` of its ticks (t, u, confidence)."""
        m, (lo, _) = self.sess.plant.m, self._snap_at["intent"]
        ist, ip = self._intent[4], self._intent[5]
        if self._intent[0] != _intent.KNOWN:
            est.u, est.confidence = ist[:m].copy(), float(ist[m])
            if hasattr(est, "active"):
                est.active = bool(ist[m + 1])
            if getattr(est, "T", None) is not None:
                est.T = ist[m + 2:].reshape((m, m)).copy()
            if getattr(est, "p", None) is not None:
                est.p = ip.copy()
        u, conf = snap[:, lo:lo + m], snap[:, lo + m].tolist()
        assert self.intent is not None
        self.intent.history.extend((tk, u[r].copy(), conf[r]) for r, tk in enumerate(t.tolist()))

    def _probe_values(self, snap: np.ndarray) -> dict[str, np.ndarray]:
        """The probe's {log name: (k, ...)} from k snapshot rows (bool for "held", a scalar per tick but for "slave_q")."""
        out = {}
        for name, what in self.probe.names.items() if self.probe is not None else ():
            lo, hi = self._snap_at[what]
            a = snap[:, lo:hi]
            out[name] = a != 0.0 if what == "held" else a.copy() if what == "slave_q" else a[:, 0].copy()
        return out
