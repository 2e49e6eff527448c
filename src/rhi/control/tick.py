"""The controller's fast tick: one compiled call, or the primary law in Python and the rest compiled.

`KernelTick` holds what does not change between ticks (limits, parameters, the desired VMEs
and FMEs, output buffers). It asks the primary law and each objective for its compiled form
(``compiled(device)``, `rhi.control.compiled`) and recognises no type: objectives whose form the kernels
compute (VME matching and the FME schedule; in the whole tick also static FME matching, the joint-limit
barrier and the Jacobian objectives: TMI matching to a desired read each tick, manipulability) run inside
them; in the composed tick every other objective and the barriers run their own `gradient_at` in Python and
enter as two torque vectors.

`KernelTick.whole` is the whole tick in one call of `rhi.control._compiled.whole` (device terms,
primary law, steps 2–6, the passivity layer) for a device whose chain the compiled kinematics
handle, a primary law with a compiled form and only objectives with one (`KernelTick.whole_ok`;
`KernelTick.reason` says why not);
`KernelTick.__call__` runs steps 2–6 of `rhi.control._compiled.tick` after `Device.terms` and the
primary law's `forces`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

import numpy as np

from rhi.control import _compiled as kernels
from rhi.control._compiled import objectives as _objectives, tank as _tank, whole as _whole
from rhi.control.barrier import limit_rows
from rhi.control.compiled import CompiledLaw, CompiledObjective
from rhi.control.objectives import gradient_function
from rhi.control.settings import ControllerParts, ControllerState
from rhi.control.transition import TransitionState
from rhi.devices.model import DeviceTerms
from rhi.devices.terms import TERMS, layout
from rhi.errors import InvalidInput, Singular

if TYPE_CHECKING:
    from rhi.control.passivity import PassivityState

def _f64(v) -> np.ndarray:
    """V as a C-contiguous float64 array (one compiled specialisation of the kernel)."""
    if type(v) is np.ndarray and v.dtype == np.float64 and v.flags.c_contiguous:
        return v
    return np.ascontiguousarray(v, dtype=np.float64)


def _law_vector(law: CompiledLaw, n: int, m: int) -> np.ndarray:
    """A compiled primary law's settings as `rhi.control._compiled.whole` reads them (LAW_* slots)."""
    head = np.zeros(_whole.N_LAW)
    head[_whole.LAW_KIND] = _LAW_KINDS[law.kind]
    head[_whole.LAW_GAIN] = law.gain
    head[_whole.LAW_CORIOLIS], head[_whole.LAW_GRAVITY] = float(law.coriolis), float(law.gravity)
    x0 = np.zeros(m) if law.x0 is None else law.x0
    head[_whole.LAW_STIFFNESS] = law.stiffness
    normal = np.zeros(m)
    if law.normal is not None:
        head[_whole.LAW_NORMAL], normal = 1.0, law.normal
    viscous, coulomb = np.zeros(n), np.zeros(n)
    if law.viscous is not None and law.coulomb is not None:
        head[_whole.LAW_FRICTION], head[_whole.LAW_VS] = 1.0, law.velocity_scale
        viscous, coulomb = law.viscous, law.coulomb
    return np.concatenate([head, law.damping.ravel(), x0, normal, viscous, coulomb])


_LAW_KINDS = {"force": _whole.FORCE, "spring": _whole.SPRING, "free": _whole.FREE}
_BARRIER_KINDS = {"quadratic": _objectives.QUADRATIC, "inverse": _objectives.INVERSE}


def compiled_form(term, device):
    """``term.compiled(device)`` (a `CompiledLaw` or `CompiledObjective`), None where it has none."""
    fn = getattr(term, "compiled", None)
    return fn(device) if callable(fn) else None


@dataclasses.dataclass(frozen=True, eq=False)
class Fallback:
    """A tick the kernel cannot decide accurately (a held set for the basis form): the reference runs steps 2–6.

    Attributes:
        kin: the device terms of the tick.
        F_render: (m,) the primary law's rendered force [N].
        F_extra: (m,) its unscaled force [N].
    """

    kin: DeviceTerms
    F_render: np.ndarray
    F_extra: np.ndarray


class KernelTick:
    """Steps 2–6 of a `NullSpaceController` tick through `rhi.control._compiled.tick`.

    Args:
        ctrl: the controller (its device, configuration, limits and objectives).
    """

    def __init__(self, ctrl: ControllerParts) -> None:
        cfg, dev = ctrl.config, ctrl.device
        n, m = dev.n, dev.m
        self.ctrl = ctrl
        prm = np.zeros(kernels.N_PARAMS)
        prm[kernels.P_DAMPING] = cfg.damping
        prm[kernels.P_ASO_S] = ctrl.aso_shape
        prm[kernels.P_GRAVITY] = float(cfg.gravity_compensation)
        prm[kernels.P_DYNAMIC] = float(cfg.projector == "dynamic")
        prm[kernels.P_SATURATION] = ctrl.allocation.kernel
        prm[kernels.P_SAFE] = float(ctrl.allocation.safe)
        prm[kernels.P_CLIPPED] = float(cfg.null_space == "clipped")
        self._sch = np.zeros(0)  # the scheduled objective's vector (`rhi.control._compiled.step.schedule_vector`)
        if ctrl.schedule is not None:
            gain, sched = ctrl.schedule
            c = compiled_form(sched, dev)
            if c is None or c.kind != "fme_schedule" or c.stiff is None or c.schedule is None:
                raise InvalidInput(f"objectives: the scheduled objective {type(sched).__name__} has no compiled form "
                                   "(the controller runs it on the reference route)")
            w2 = ctrl.hi**-2.0 if c.w2 is None else np.broadcast_to(c.w2, (n,))
            self._sch = kernels.schedule_vector(gain, _f64(w2), _f64(c.desired), _f64(c.stiff), c.schedule)
        self._scheduled = self._sch.shape[0] != 0
        self._prm = prm
        self._tank = np.zeros(_tank.N_TANK)  # the null-space energy tank's slots, mirrored with `ControllerState.tank`
        self._tank_q, self._tank_e = np.zeros(n), np.zeros((2, n))
        if cfg.tank is not None:
            self._tank[_tank.TK_ON], self._tank[_tank.TK_CAPACITY] = 1.0, cfg.tank.capacity
            self._tank[_tank.TK_GATE], self._tank[_tank.TK_THETA] = float(cfg.tank.allocation == "gate"), 1.0
        vme, gains = [], []
        self._grads = []  # (gain, terms -> ∂ν/∂q) of the objectives computed in Python
        static: list = []  # (gain, w2, M_des) of the static FME-matching terms the whole tick computes
        python = []  # names of the objectives and barriers only Python computes (the whole tick does not apply)
        jac: list = []  # the Jacobian objectives the whole tick computes (`rhi.control._compiled.objectives.pack`)
        live: list = []  # the compiled form of each (its desired of the tick: `live`)
        live_fme: list = []  # (index among the FME terms, compiled form) of those whose desired is `live`
        for gain, obj in ctrl.objectives:
            c = compiled_form(obj, dev)
            if c is not None and c.kind == "vme":
                vme.append(c.desired)
                gains.append(gain)
                continue
            self._grads.append((gain, gradient_function(obj, dev)))
            if c is not None and c.kind == "fme":
                if c.live is not None:
                    live_fme.append((len(static), c))
                static.append((gain, c.w2, c.desired))
            elif c is not None and c.kind in ("vme_live", "manipulability"):
                code = _objectives.JBLD if c.kind == "vme_live" else _objectives.LOG_MU if c.log else _objectives.MU
                D = np.eye(m) if c.desired is None else c.desired  # a live one is written before each tick
                jac.append((code, gain, c.penalty or 0.0, dev.q_min, dev.q_max, D))
                live.append(c)
            else:
                python.append(type(obj).__name__)
        bars = []
        for gain, obj in ctrl.barriers:
            c = compiled_form(obj, dev)
            if c is not None and c.kind == "barrier" and c.barrier is not None:
                shape, margin, weight, hold = c.barrier
                bars.append((gain, _BARRIER_KINDS[shape], margin, weight, hold))
            else:
                python.append(type(obj).__name__)
        self._vme = _f64(np.array(vme).reshape(len(vme), m, m))
        self._vme_gain = _f64(np.array(gains, dtype=float))
        self._barriers = [(gain, gradient_function(obj, dev)) for gain, obj in ctrl.barriers]
        self._flags = kernels.flags(prm, self._sch, self._vme_gain, self._tank)  # the parts of `kernels.tick`
        self._at = layout(n, m)[1]
        self._zero = np.zeros(n)
        self._tau = np.empty(n)
        self._sat = np.zeros(n, bool)
        self._ascm = kernels.ascm_ref(ctrl.lo, ctrl.hi, self._sat)  # `kernels.tick`'s ASCM, by address
        self._tr = np.zeros(4)
        self._tr_of: TransitionState | None = None  # the state object self._tr mirrors
        fast = dev._fast_maps
        compiled_law = compiled_form(cfg.primary, dev)
        why = []
        if fast.chain is None:
            why.append(f"the chain of {dev.name!r} is not one the compiled kinematics handle")
        if compiled_law is None:
            why.append(f"the primary law {type(cfg.primary).__name__} has no compiled form")
        if python:
            why.append(f"no compiled form for {', '.join(sorted(set(python)))} (their gradients run in Python)")
        #: why the whole tick does not apply ("" where it does)
        self.reason = "; ".join(why)
        #: the whole tick runs in `rhi.control._compiled.whole` (`whole_for`)
        self.whole_ok = not why
        self.live: list[tuple[int, CompiledObjective]] = []
        if self.whole_ok:
            law = _law_vector(compiled_law, n, m)
            self._law = law
            rows = limit_rows(dev) if bars else (np.zeros((0, n)), np.zeros(0), np.zeros(0))
            self._obj = _objectives.pack(n, m, static, bars, rows, jac)
            # (slot of D in the objective vector, compiled form) of each Jacobian objective and each FME term
            # with a live desired: `whole` writes D (``live()``, where it has one) before each tick
            self.live = [(_objectives.desired_slot(self._obj, n, m, i), c) for i, c in enumerate(live)]
            self.live += [(_objectives.fme_slot(self._obj, n, m, i), c) for i, c in live_fme]
            self._force = compiled_law.kind == "force"  # reads sensors["force"]
            self._x, self._buf = np.empty(m), np.empty(fast.size)
            chain = (*fast.chain, dev.A, dev.b, fast.rows_idx, dev.armature, fast.supports, fast.identity)
            self._chain: tuple = (*chain, _whole.terms_ref(chain, self._x, self._buf), self._ascm)
            self._no_force = np.zeros(m)
            self._F = np.empty((2, m))
            self._res = np.zeros(_whole.N_RES)
            pas = getattr(cfg.primary, "passivity", None)
            k = n if pas is None or pas.port == "motors" else m
            self._pc = np.zeros(_whole.N_PC)
            if pas is not None:
                self._pc[_whole.PC_ON], self._pc[_whole.PC_MOTORS] = 1.0, float(pas.port == "motors")
                self._pc[_whole.PC_CONTROL] = float(pas.mode)
                self._pc[_whole.PC_ALPHA_MAX] = -1.0 if pas.alpha_max is None else pas.alpha_max
            self._pc_pos, self._pc_eff = np.zeros(k), np.zeros(k)
            self._ps_of: PassivityState | None = None  # the PassivityState the passivity slots mirror
            # the kernel's arguments between `ready` and x, and after buf: the same arrays every tick
            self._mid = (self._at, law, ctrl.lo, ctrl.hi, self._prm, self._tr, self._sch, self._vme, self._vme_gain,
                         self._obj, self._pc, self._pc_pos, self._pc_eff, self._tank, self._tank_q, self._tank_e)
            self._out = (self._F[0], self._F[1], self._tau, self._sat, self._res)
            #: the whole tick compiled for the parts this controller has (`rhi.control._compiled.whole.whole_for`)
            self.parts = _whole.Parts(*self._flags, bool(static or bars or jac), pas is not None)
            self._whole_fn: Callable[..., int] = _whole.whole_for(self.parts)
            # a cold cache: its compile starts now in a child (the first tick then loads it)
            _whole.compile_ahead(self.parts, (0.0, self._zero, self._zero, self._no_force, *self._chain, False, *self._mid,
                                              self._x, self._buf, *self._out))
            # the compiled entry point of `_whole_fn` (`entry_point`), found at the first call, and the dispatcher it is of
            self._call: Callable[..., int] | None = None
            self._call_of: Callable[..., int] | None = None

    def _load_transition(self, s: ControllerState) -> list[float] | None:
        """Mirror the state's FME transition into the kernel's tr (if it changed); tr's values before the tick."""
        if not self._scheduled:
            return None
        tr = self._tr
        if s.transition is not self._tr_of:
            T = s.transition
            tr[:] = (float(T.stiff), T.omega_start, T.t0, T.tf)
        return tr.tolist()

    def _store_transition(self, s: ControllerState, before: list[float] | None) -> None:
        """A new `TransitionState` in the state where the kernel advanced tr."""
        if before is None:
            return
        after = self._tr.tolist()
        if after != before:
            s.transition = TransitionState(after[0] != 0.0, after[1], after[2], after[3])
        self._tr_of = s.transition

    def _load_passivity(self, ps: PassivityState | None) -> None:
        """Mirror a fresh, reset or Python-advanced passivity state into the whole tick's slots."""
        if ps is not None and ps is not self._ps_of:
            pcv = self._pc
            pcv[_whole.PC_E], pcv[_whole.PC_T] = ps.energy, ps.t
            pcv[_whole.PC_PREV] = float(ps.position is not None)
            if ps.position is not None:
                self._pc_pos[:], self._pc_eff[:] = ps.position, ps.effort

    def _store_passivity(self, s: ControllerState, ps: PassivityState, t: float, dissipated: float) -> None:
        """The passivity state after a whole tick at t [s] that ran the layer (Σ dissipated [J] given)."""
        v = self._pc.tolist()
        ps.energy, ps.alpha, ps.scale = v[_whole.PC_E], v[_whole.PC_ALPHA], v[_whole.PC_SCALE]
        ps.dissipated = dissipated
        ps.t, ps.position, ps.effort = t, self._pc_pos.copy(), self._pc_eff.copy()
        s.E_obs, s.alpha_pc = ps.energy, ps.alpha
        self._ps_of = ps

    def _load_tank(self, s: ControllerState) -> None:
        """Mirror the state's null-space energy tank into the kernel's slots (the reference may have advanced it)."""
        ts = s.tank
        if ts is not None:
            v = self._tank
            v[_tank.TK_ENERGY], v[_tank.TK_ALLOCATION] = ts.energy, ts.allocation
            v[_tank.TK_T], v[_tank.TK_PREV] = ts.t, float(ts.position is not None)
            if ts.position is not None and ts.effort is not None:
                self._tank_q[:], self._tank_e[:] = ts.position, ts.effort

    def _store_tank(self, s: ControllerState) -> None:
        """The tank's state after a kernel tick that ran it."""
        ts = s.tank
        if ts is not None:
            v = self._tank.tolist()
            ts.energy, ts.scale, ts.damping, ts.t = v[_tank.TK_ENERGY], v[_tank.TK_SCALE], v[_tank.TK_DAMPING], v[_tank.TK_T]
            ts.allocation, ts.gate = v[_tank.TK_ALLOCATION], v[_tank.TK_THETA]
            ts.position, ts.effort = self._tank_q.copy(), self._tank_e.copy()

    def __call__(self, t: float, kin: DeviceTerms, sensors: Mapping[str, np.ndarray]):
        """One tick: (τ (n,) [N m], α, β, saturated (n,) bool, clipped), or a `Fallback`.

        A `Fallback` where the kernel cannot decide: the reference's basis form then runs the tick.

        Raises:
            Singular: a rank-deficient Jacobian.
        """
        ctrl = self.ctrl
        s = ctrl.state
        F_r, F_x = ctrl.config.primary.forces(t, kin, sensors)
        tau_s = self._zero
        for gain, fn in self._barriers:
            tau_s = tau_s - gain * fn(kin)
        tau_to = self._zero
        for gain, fn in self._grads:
            tau_to = tau_to - gain * fn(kin)
        tr = self._tr
        before = self._load_transition(s)
        buf = kin._buf
        if buf is None:  # terms not from the compiled `Device.terms` (a joint that is not one-DoF)
            buf = np.concatenate([getattr(kin, name).ravel() for name, _ in TERMS[:9]])
        self._load_tank(s)
        status, alpha, beta, V, omega, clipped = kernels.tick(
            t, buf, self._at, _f64(F_r), _f64(F_x), _f64(kin.q), _f64(kin.dq), ctrl.lo, ctrl.hi, self._prm, tr,
            self._sch, self._vme, self._vme_gain, _f64(tau_s), _f64(tau_to),
            self._tank, self._tank_q, self._tank_e, self._tau, self._sat, self._ascm, *self._flags)
        if status != kernels.OK:
            self._tr_of = None  # the kernel may have advanced tr; the state did not
            if status == kernels.SINGULAR:
                raise Singular("J: rank-deficient Jacobian")
            return Fallback(kin, F_r, F_x)
        self._store_transition(s, before)
        self._store_tank(s)
        s.V, s.omega = V, omega
        return self._tau.copy(), alpha, beta, self._sat.copy(), clipped

    def whole(self, t: float, q: np.ndarray, dq: np.ndarray, sensors: Mapping[str, np.ndarray]):
        """One whole tick (`whole_ok`): (τ (n,) [N m] to send, passivity included, α, β, saturated, clipped).

        Where the kernel cannot decide, a `Fallback` instead: the reference then runs steps 2–6 on its
        terms and forces, and the passivity layer after it.

        Args:
            t: time [s].
            q: (n,) joint positions [rad], finite float64.
            dq: (n,) joint velocities [rad/s], finite float64.
            sensors: the law's readings, checked finite by the controller.

        Raises:
            InvalidInput: a force reading of the wrong length.
            Singular: a rank-deficient Jacobian.
        """
        ctrl = self.ctrl
        F = self._no_force
        if self._force:
            F = _f64(sensors["force"])
            if F.shape != self._no_force.shape:
                raise InvalidInput(f"sensors['force']: expected shape {self._no_force.shape}, got {F.shape}")
        self.mirror(ctrl.state)
        q, dq = _f64(q), _f64(dq)
        last = ctrl.device.__dict__.get("_last_terms")  # a loop that read `Device.terms` at this state already
        if last is not None and last[1]._buf is not None and last[0] == (q.tobytes(), dq.tobytes()):
            ready, x, buf = True, last[1].x, last[1]._buf
        else:
            ready, x, buf = False, self._x, self._buf
        fn = self._whole_fn
        call = self._call if self._call is not None and self._call_of is fn else fn
        if call is fn and self.parts.code == kernels.ASCM:  # ASCM compiled here while a child compiles the tick
            self._ascm.resolve()
        status = call(t, q, dq, F, *self._chain, ready, *self._mid, x, buf, *self._out)
        if call is fn and type(t) is float:  # loaded (or compiled) now: its entry point from the next tick on
            self._call, self._call_of = entry_point(fn, (t, q, dq, F, *self._chain, ready, *self._mid, x, buf,
                                                         *self._out)), fn
        return self.settle(t, status, q, dq, x, buf)

    def mirror(self, s: ControllerState) -> None:
        """Before a whole tick: the state into the kernel's arrays where it changed, and the tick's live desireds.

        The FME transition, the passivity layer's and the tank's state, each live desired ellipsoid.
        """
        if self._scheduled and s.transition is not self._tr_of:  # a fresh or replaced state: mirrored into tr
            T = s.transition
            self._tr[:] = (float(T.stiff), T.omega_start, T.t0, T.tf)
            self._tr_of = T
        ps = self.ctrl.passivity
        if ps is not None and ps is not self._ps_of:
            self._load_passivity(ps)
        self._load_tank(s)
        for slot, c in self.live:
            if c.live is not None:
                self._obj[slot:slot + self._F.shape[1] ** 2] = c.live().ravel()

    def settle(self, t: float, status: int, q: np.ndarray, dq: np.ndarray, x: np.ndarray, buf: np.ndarray):
        """After a whole tick at t [s] that returned `status`: the state advanced, and `whole`'s result.

        A `Fallback` (on the terms x, buf at q, q̇) where the kernel did not decide.
        """
        ctrl = self.ctrl
        s, ps = ctrl.state, ctrl.passivity
        alpha, beta, V, omega, clipped, pc_ran, tr_changed = self._res.tolist()[:_whole.R_DONE]
        if status != kernels.OK:
            self._tr_of = self._ps_of = None  # the kernel may have advanced tr; the states did not
            if status == kernels.SINGULAR:
                raise Singular("J: rank-deficient Jacobian")
            dev = ctrl.device
            kin = DeviceTerms.from_buffer(dev, q, dq, x.copy(), dev.A.dot(q) + dev.b, buf.copy(),
                                          dev._fast_maps.layout)
            return Fallback(kin, self._F[0].copy(), self._F[1].copy())
        if tr_changed:
            a0, a1, a2, a3 = self._tr.tolist()
            s.transition = self._tr_of = TransitionState(a0 != 0.0, a1, a2, a3)
        s.V, s.omega = V, omega
        self._store_tank(s)
        if pc_ran and ps is not None:
            self._store_passivity(s, ps, t, ps.dissipated + float(self._pc[_whole.PC_DISSIPATED]))
        return self._tau.copy(), alpha, beta, self._sat.copy(), clipped != 0.0


def entry_point(fn, args: tuple):
    """The compiled entry point of the Numba dispatcher `fn` for the types of `args`, else `fn` itself.

    Calling it skips the dispatcher's per-call type resolution (about a microsecond for the whole tick's
    36 arguments). Only for arguments whose types the caller keeps fixed: the entry point unboxes each
    argument as the type it was compiled for (`KernelTick.whole`: float64 C-contiguous vectors of checked
    shapes, a float time, a bool).
    """
    try:
        cres = fn.overloads.get(tuple(fn.typeof_pyval(a) for a in args))
    except (AttributeError, TypeError, ValueError):  # another Numba's internals: the dispatcher it is
        return fn
    return getattr(cres, "entry_point", None) or fn


__all__ = ["KernelTick", "entry_point"]
