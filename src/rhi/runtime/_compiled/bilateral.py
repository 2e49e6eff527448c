"""`BilateralLoop`: the Python side of the compiled bilateral loop (`rhi.runtime._compiled.bilateral_loop`).

`why_not` decides whether a `rhi.runtime.bilateral.simulate_bilateral` run is one the kernels compute (else
the run stays on the Python loop, the reference, and its `BilateralLog.route` says why); `run` hands the
Python state (`Master`, `Slave`, both sessions, the metered tissue, the controller's state) to the kernels,
runs ticks until the end, a fault or a tick only Python decides, and writes the state and the log back, so
the Python loop continues from there. Imported by `simulate_bilateral`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import weakref
from typing import Any

import numpy as np
from numba import typeof, types

from rhi.control._compiled import whole as _whole
from rhi.control.controller import NullSpaceController
from rhi.devices.terms import layout
from rhi.jit import KernelRef
from rhi.runtime._compiled import bilateral_loop as bl
from rhi.runtime._compiled.tdpa import settings
from rhi.sim._compiled.handle import PERIOD_UNSTABLE, hand_supported
from rhi.sim.environment import Wall
from rhi.sim.plant import unstable

#: Each controller's whole tick as `ticks` calls it (ready = True), by its `KernelTick`.
_refs: weakref.WeakKeyDictionary[Any, KernelRef] = weakref.WeakKeyDictionary()


class BilateralLoop:
    """The compiled ticks of one `simulate_bilateral` run (`why_not` says whether they apply).

    Args:
        ms, ss: the master's and the slave's `rhi.sim.loop.Session`.
        controller: the master's `NullSpaceController`.
        tissue: the slave's tissue `Wall`.
        forward, backward: the channel's `ChannelConfig`s.
        passivity: the TDPA's settings, or None.
        gains: (K_p [N/m], K_d [N s/m]) of the slave.
        N: ticks of the run.

    Attributes:
        ends: (master end, slave end), `rhi.runtime.channel.ScheduledEnd`s on the run's schedule.
        calls: compiled calls made; ticks: ticks they ran (the Python loop ran the others).
    """

    #: the `BilateralLog.route` of a run on this loop
    route = "compiled loop (bilateral)"

    def __init__(self, ms, ss, controller, tissue, forward, backward, passivity, gains, N: int) -> None:
        from rhi.runtime.channel import ScheduledEnd, schedule

        mp, sp, kt = ms.plant, ss.plant, controller._kernel
        m, dt = mp.m, ms.dt
        self.ms, self.ss, self.ctrl, self.kt = ms, ss, controller, kt
        fwd, bwd = np.zeros((N, m + 1)), np.zeros((N, m + 1))
        vis_f, vis_b = schedule(forward, dt, N), schedule(backward, dt, N, lag=1)
        self.ends = (ScheduledEnd(fwd, bwd, vis_b), ScheduledEnd(bwd, fwd, vis_f))
        self._chan = (fwd, bwd, vis_f, vis_b)
        self._cfg = settings(passivity)
        wargs = (*kt._chain, True, *kt._mid, kt._x, kt._buf, *kt._out)
        self._whole = _refs.get(kt)
        if self._whole is None or self._whole.kernel is not kt._whole_fn:  # typed once per controller (its arrays)
            vec = types.float64[::1]
            self._whole = _refs[kt] = KernelRef(kt._whole_fn, (types.float64, vec, vec, vec, *(typeof(a) for a in wargs)))
        self._wargs = wargs
        self._cs = (kt._tr, kt._pc, kt._pc_pos, kt._pc_eff, kt._tau, kt._sat, kt._res, kt._tank, kt._tank_q, kt._tank_e)

        def sens(p):
            return (p._ten, p._tenv, p.data.sensordata, p._R, np.concatenate([p._const, p._weight]), p._ft_adr)

        def chain(dev):
            f = dev._fast_maps
            return (*f.chain, dev.A, dev.b, f.rows_idx, dev.armature, f.supports, f.identity)

        dm, ds = controller.device, sp.device
        self._mst = (ms._addr, ms.sub, sens(mp), (mp._sd, ms._idx, ms._compiled(ms.hand, None)[1], ms._F, mp._xfrc,
                                                  ms._acc, mp._wnum, ms._badv, ms._at),
                     mp._ctrl, chain(dm), layout(dm.n, m)[1], kt._x, kt._buf)  # the terms the whole tick reads (ready)
        wall = np.array([*tissue.point, *tissue.normal, tissue.stiffness, tissue.damping], dtype=float)
        self._slv = (ss._addr, ss.sub, sens(sp), sp._ctrl, sp._xfrc, sp._sd, ss._idx, wall, sp._wnum, ss._badv,
                     chain(ds), layout(ds.n, m)[1], np.empty(m), np.empty(ds._fast_maps.size),
                     np.array(ds.task_rows, dtype=np.int64), np.asarray(ds.torque_min, dtype=float),
                     np.asarray(ds.torque_max, dtype=float), np.array(gains, dtype=float))
        self._st, self._vec = np.zeros(bl.N_ST), np.zeros((bl.N_V, m))
        self._lay = np.array([0, 0, 0, 0, int("ft" in controller._sensors)], dtype=np.int64)
        self.calls = self.ticks = 0

    @staticmethod
    def why_not(plain: bool, controller, ms, ss, tissue) -> str:
        """Why this run is not one the compiled loop computes ("" where it is; see the module).

        plain: the sides are `rhi.runtime.bilateral.Master` and `Slave` themselves (not subclasses).
        """
        mp, sp = ms.plant, ss.plant
        if not plain:
            return "the master or the slave is a subclass"
        if type(controller) is not NullSpaceController or "step" in controller.__dict__:
            return f"the master's controller ({type(controller).__name__}) is not a plain NullSpaceController"
        if controller._kernel is None or not controller._kernel.whole_ok:
            return f"the controller's tick is not the whole compiled tick: {controller.route}"
        if not set(controller._sensors) <= {"force", "ft"}:
            return "the primary law reads sensors other than force and ft"
        dm, ds, m = controller.device, sp.device, mp.m
        if (dm.n, dm.m) != (mp.n, m) or ds.m != m or m != 2:
            return "the devices' sizes differ from the plants' or are not two task axes"
        if dm._fast_maps.chain is None or ds._fast_maps.chain is None:
            return "a device's chain is not one the compiled kinematics handle"
        if not hand_supported(ms.hand, None, m):
            return f"the hand ({type(ms.hand).__name__}) is not one the compiled loop computes"
        if type(tissue) is not Wall or tissue.point.shape != (m,):
            return f"the tissue ({type(tissue).__name__}) is not a Wall"
        return ""

    def run(self, k0: int, mst, slv, metered, log, tmi_every: int) -> tuple[int, str | None]:
        """Ticks k0, k0 + 1, ... into `log` (`BilateralLog`) until the end, a fault or a tick for Python.

        The Python state (`Master` mst, `Slave` slv, the sessions, the metered tissue, the controller) is read
        before and written after, so the caller's Python tick continues from it. Returns (the next tick, the
        fault that ended the run or None). The TMI of every `tmi_every`-th tick is computed here.
        """
        ms, ss, ctrl, kt = self.ms, self.ss, self.ctrl, self.kt
        st, vec, N = self._st, self._vec, len(log.t)
        s = ctrl.state
        ps = None if ctrl._pc is None else ctrl._pc.state
        pm, pv = mst.port, slv.port
        st[:bl.PM] = (ms.t, ss.t, ms.work, metered.work, float(metered._last is not None), float(mst._held is not None),
                   float(slv._x_s0 is not None), float(slv._x_m0 is not None), float(s.stopped), s.V, s.omega,
                   s.alpha, s.beta, 0.0, 0.0, 0.0, 0.0, 0.0 if ps is None else ps.dissipated, s.E_obs, s.alpha_pc)
        st[bl.PM:] = (pm.E_in, pm.E_out, pm.dissipated, pm.gain, pm.deficit, pv.E_in, pv.E_out, pv.dissipated, pv.gain,
                   pv.deficit)
        z = np.zeros(vec.shape[1])
        held = mst._held or (z, z)
        last = metered._last or (z, z)
        vec[:] = (held[0], held[1], mst.force, mst.received, _or(slv._x_s0, z), _or(slv.x_d, z), _or(slv._x_m0, z),
                  slv.F_e, slv.drift, last[0], last[1], ms.F_hand)
        before = None
        if not s.stopped:
            before = kt._load_transition(s)
            kt._load_passivity(ps)
            kt._load_tank(s)
        if s.saturated is not None:
            kt._sat[:] = s.saturated
        if ps is not None:
            kt._pc[_whole.PC_SCALE] = ps.scale
        m, n, n_s = vec.shape[1], ms.plant.n, ss.plant.n
        rows = np.empty((N - k0, 1 + 7 * m + 8 + n + n_s))
        lay = self._lay
        bl.ticks(N - k0, k0, ms.dt, self._mst, self._slv, self._chan, self._cfg, self._wargs, self._cs, self._whole, st,
              vec, lay, rows)
        done, out = int(lay[bl.L_DONE]), int(lay[bl.L_OUT])
        self.calls += 1
        self.ticks += done
        self._store(st, vec, mst, slv, metered, ps, before)
        mst.end.k = slv.end.k = k0 + done - 1
        self._log(log, k0, rows[:done], tmi_every)
        fault = None
        if out == bl.FAULT_M:
            fault = ms._stop(ms._fault(int(lay[bl.L_STATUS]), float(log.t[k0 + done - 1])))
        elif out == bl.FAULT_S:
            t = float(st[bl.S_TS]) + int(lay[bl.L_STEP]) * ss.plant.timestep
            fault = ss._stop(str(unstable(t)) if int(lay[bl.L_STATUS]) == PERIOD_UNSTABLE else
                             f"hand/environment: non-finite force {vec[bl.V_MF].tolist()} on the handle at t={t:.4f} s")
        return k0 + done, fault

    def _store(self, st, vec, mst, slv, metered, ps, before) -> None:
        """The Python state after a call (see `run`)."""
        from rhi.runtime.tdpa import PortEnergy

        ms, ss, s, kt = self.ms, self.ss, self.ctrl.state, self.kt
        v = st.tolist()
        ms.t, ss.t, ms.work, metered.work = v[bl.S_TM], v[bl.S_TS], v[bl.S_WORK], v[bl.S_WENV]
        mst.port, slv.port = PortEnergy(*v[bl.PM:bl.PM + 5]), PortEnergy(*v[bl.PS:bl.PS + 5])
        if v[bl.S_MET]:
            metered._last = (vec[bl.V_MX].copy(), vec[bl.V_MF].copy())
        if v[bl.S_HELD]:
            mst._held = (vec[bl.V_HX].copy(), vec[bl.V_HF].copy())
        mst.force, mst.received, ms.F_hand = vec[bl.V_FORCE].copy(), vec[bl.V_RECV].copy(), vec[bl.V_FHAND].copy()
        if v[bl.S_XS0]:
            slv._x_s0, slv.x_d = vec[bl.V_XS0].copy(), vec[bl.V_XD].copy()
        if v[bl.S_XM0]:
            slv._x_m0 = vec[bl.V_XM0].copy()
        slv.F_e, slv.drift = vec[bl.V_FE].copy(), vec[bl.V_DRIFT].copy()
        if not s.stopped:
            kt._store_transition(s, before)
            if v[bl.S_TICKS]:
                s.t, s.alpha, s.beta, s.V, s.omega = v[bl.S_TLAST], v[bl.S_ALPHA], v[bl.S_BETA], v[bl.S_V], v[bl.S_OMEGA]
                s.saturated, s.clipped, s.tau = kt._sat.copy(), bool(v[bl.S_CLIP]), kt._tau.copy()
                s.ticks += int(v[bl.S_TICKS])
                kt._store_tank(s)
            if v[bl.S_PC] and ps is not None:
                kt._store_passivity(s, ps, v[bl.S_TLAST], v[bl.S_DISS])

    def _log(self, log, k0: int, rows: np.ndarray, every: int) -> None:
        """The rows of a call into the log's arrays from tick k0 on, and the TMI of its ticks that compute one."""
        from rhi.metrics import tmi

        m, n = self._vec.shape[1], self.ms.plant.n
        k1, o = k0 + len(rows), 0
        for name, wide in bl.COLUMNS:
            a = getattr(log, name)
            a[k0:k1] = rows[:, o:o + m] if wide else rows[:, o]
            o += m if wide else 1
        dm, ds = self.ctrl.device, self.ss.plant.device
        at = np.arange(-(-k0 // every) * every, k1, every)
        if len(at):  # one batch of Jacobians and TMIs (equal to the Python loop's one at a time)
            r = rows[at - k0]
            log.tmi[at] = tmi(dm.jacobian(r[:, o:o + n]), ds.jacobian(r[:, o + n:]))


def _or(v, z: np.ndarray) -> np.ndarray:
    """v, or z where v is None."""
    return z if v is None else v
