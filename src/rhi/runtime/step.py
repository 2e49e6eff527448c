"""The step of one `rhi.runtime.run` tick: a reading in hand → the torque to send (`run`'s ``t_step``).

`ReferenceStep` is the specification, in Python: the handle's x, ẋ and virtual force on the controller's
model (`rhi.sim.loop.Kinematics.render`, where q·q + q̇·q̇ is finite), `Safety.check`, the controller's
`step` with the reading's sensors and the virtual force as sensors["force"] (a raise or a stop is a
fault), `Safety.filter`. `FastStep` computes the same in one compiled call (`rhi.runtime._compiled.step`)
for a `NullSpaceController` on its whole compiled tick with compiled handle kinematics, on a link whose
readings are views of one float array (`packed`, as `UDPLink`'s). Where the safety layer would act — a
rule trips, the controller's kernel does not decide, the torque needs clamping — that kernel stops and
the reference runs the rest of the tick, so every event, reason and torque is the reference's. The safety
state lives in the kernel's vector while it runs the ticks and in the `Safety` object while the reference
does (`last_t` kept current). `make_step` picks one; `why_not` says why a run stays on the reference.
"""

from __future__ import annotations

import math

import numpy as np

from rhi.control.controller import NullSpaceController
from rhi.runtime.safety import _BAD_STATUS, FT_EXEMPT, Safety

nan = math.nan


class ReferenceStep:
    """The step in Python (module docstring).

    Args:
        guard: the run's safety layer.
        kin: the handle's kinematics on the controller's model (`rhi.sim.loop.Kinematics`), or None.
        controller: `step(t, q, dq, sensors) -> tau`.
    """

    #: the run summary's ``step``
    route = "python"

    def __init__(self, guard: Safety, kin, controller) -> None:
        self.guard, self.kin, self.controller = guard, kin, controller
        self.state = getattr(controller, "state", None)
        self.zero = np.zeros(guard.n)
        self.zero_m = np.zeros(0 if kin is None else kin.m)

    def attach(self, link) -> None:
        """The link, once open (its readings' layout)."""

    def __call__(self, r, now: float | None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """τ (n,) to send [N m], ẋ (m,) [m/s] (None: not rendered) and the virtual force (m,) [N] for reading r.

        `now`: the host's time of the check [s] (None: no silence check; `Safety.check`).
        """
        guard, xdot, F_env, tau = self.guard, None, self.zero_m, self.zero
        q, dq = r.q, r.dq
        if self.kin is not None and math.isfinite(float(q @ q + dq @ dq)):
            _, xdot, F_env = self.kin.render(q, dq)
        if guard.check(r, now, xdot):
            tau = self.control(r, F_env)
        return guard.filter(tau, r.t), xdot, F_env

    def control(self, r, F_env: np.ndarray) -> np.ndarray:
        """The controller's torque for a checked reading (before the filter); a raise or a stop trips the guard."""
        sensors = dict(r.sensors)
        sensors["force"] = F_env
        tau, guard, state = self.zero, self.guard, self.state
        try:
            tau = self.controller.step(r.t, r.q, r.dq, sensors)
        except Exception as exc:  # noqa: BLE001 - any controller failure is a fault, not a crash
            guard.trip("controller", f"controller raised {type(exc).__name__} at t={r.t:.4f} s: {exc}")
        if state is not None and state.stopped:
            guard.trip("controller", f"controller stopped: {state.fault}")
        return tau

    def close(self) -> None:
        """At the run's end: the safety state in the `Safety` object."""


def why_not(controller, kin) -> str:
    """Why `FastStep` does not apply to this controller and kinematics ("" where it does; the link: `attach`)."""
    if type(controller) is not NullSpaceController or "step" in controller.__dict__:
        return f"the controller ({type(controller).__name__}) is not a plain NullSpaceController"
    kt = controller._kernel
    if kt is None or not kt.whole_ok:
        return f"the controller's tick is not the whole compiled tick: {controller.route}"
    if any(c.live is not None for _, c in kt.live):
        return "an objective's desired ellipsoid is read in Python each tick"
    if kin is None or kin._compiled is None or (kin.virtual is not None and not kin._fused):
        return "the handle's kinematics or the virtual environment are not compiled"
    return ""


def make_step(guard: Safety, kin, controller) -> ReferenceStep:
    """`FastStep` where `why_not` allows (its kernel loaded now, before a link opens), else `ReferenceStep`."""
    why = why_not(controller, kin)
    if why:
        step = ReferenceStep(guard, kin, controller)
        step.route = f"python: {why}"
        return step
    return FastStep(guard, kin, controller)


class FastStep(ReferenceStep):
    """The step in one compiled call where the safety layer does nothing, else the reference (module docstring)."""

    route = "compiled"

    def __init__(self, guard: Safety, kin, controller) -> None:
        from numba import typeof, types

        from rhi.control.tick import entry_point
        from rhi.jit import KernelRef
        from rhi.runtime._compiled import step as k

        super().__init__(guard, kin, controller)
        self.k, self.kt, self.entry_point = k, controller._kernel, entry_point
        kt, n, m = self.kt, guard.n, kin.m
        cfg = guard.config
        # the safety state (`_pull`), the limits and the output in one vector (`rhi.runtime._compiled.step`)
        at, end = k.limits(n), k.output(n)
        self._sv = np.zeros(end + 1)
        self._lim, self._out = self._sv[at:end], self._sv[end:]
        self._lim[:] = np.concatenate([[cfg.stale_ticks, cfg.frozen_ticks, cfg.frozen_motion, cfg.silence,
                                        cfg.max_age, cfg.max_handle_speed, FT_EXEMPT, _BAD_STATUS],
                                       guard.q_lo, guard.q_hi, guard.max_dq, guard.lo, guard.hi])
        self._kin = kin._compiled[1:]
        self._kout = np.zeros((4, m))
        self._fused = bool(kin._fused)
        wargs = (*kt._chain, False, *kt._mid, kt._x, kt._buf, *kt._out)
        vec = types.float64[::1]
        ref = KernelRef(kt._whole_fn, (types.float64, vec, vec, vec, *(typeof(a) for a in wargs)))
        self._whole = ref
        self._wargs = wargs
        self._own = False  # the kernel's sv holds the safety state (not the `Safety` object)
        self._resets = guard.resets
        self._ft_at, self._width = -1, -1  # where the F/T starts in a reading's array, its length (`attach`)
        # the kernel loaded (or compiled) now, on a reading it leaves to the reference (a bad status)
        self._call = k.step
        self._step(0.0, 0, _BAD_STATUS, nan, nan, nan, np.zeros(2 * n))

    def attach(self, link) -> None:
        """The layout of the link's readings (`packed`: sensor → its slice of the array, after q and q̇), once open."""
        packed, n = getattr(link, "packed", None), self.guard.n
        ft = None if packed is None else packed.get("ft")
        if packed is None or (ft is not None and ft.stop - ft.start != 6) or not set(
                self.controller.required_sensors()) <= set(packed):
            self.route = ("python: the link's readings are not views of one float array (`packed`) with a 6-value "
                          "F/T and the controller's sensors")
            self._width = -1
            return
        self._ft_at = -1 if ft is None else ft.start
        self._width = 2 * n + sum(s.stop - s.start for s in packed.values())

    def _step(self, *reading) -> int:
        args = (*reading, self._ft_at, self._sv, self._kin, self._kout, self._fused, self._wargs, self._whole)
        call = self._call
        code = call(*args)
        if call is self.k.step:  # loaded now: its entry point from here on (the same types every call)
            self._call = self.entry_point(call, args)
        return code

    def __call__(self, r, now: float | None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """As `ReferenceStep.__call__`."""
        g, s, v = self.guard, self.controller.state, r.q.base
        if g.fault is not None or g._estop is not None or s.stopped or v is None or r.dq.base is not v \
                or v.shape[0] != self._width:
            self._release()
            return super().__call__(r, now)
        if (not self._own or g.resets != self._resets) and not self._pull():
            return super().__call__(r, now)
        k, kt = self.k, self.kt
        kt.mirror(s)
        t = float(r.t)
        code = self._step(t, int(r.seq), int(r.status), float(r.age), nan if r.arrival is None else float(r.arrival),
                          nan if now is None else float(now), v)
        if code == k.NONE:
            self._release()
            return super().__call__(r, now)
        if self._sv[k.S_HT]:
            g._last_t = float(self._sv[k.S_T])
        xdot, F_env = self._kout[1].copy(), self._kout[2].copy()
        if code == k.CHECKED:  # (the controller's arrays reloaded from its state where its kernel ran)
            kt._tr_of = kt._ps_of = None
            return g.filter(self.control(r, F_env), t), xdot, F_env
        tau = self.controller._record(t, *kt.settle(t, k.OK, r.q, r.dq, kt._x, kt._buf))
        if code == k.STEPPED:
            return g.filter(tau, t), xdot, F_env
        g.ratio = float(self._out[0])
        return tau, xdot, F_env

    def _pull(self) -> bool:
        """The `Safety` object's state into sv (False: one the kernel cannot hold, e.g. an F/T of another width)."""
        g, sv, n, k = self.guard, self._sv, self.guard.n, self.k
        if g._ft is not None and len(g._ft) != 6:
            return False
        sv[:k.limits(n)] = 0.0
        for slot, has, val in ((k.S_SEQ, k.S_HSEQ, g._last_seq), (k.S_NEW, k.S_HNEW, g._last_new),
                               (k.S_T, k.S_HT, g._last_t)):
            if val is not None:
                sv[slot], sv[has] = val, 1.0
        sv[k.S_SAME], sv[k.S_JSAME], sv[k.S_JT0], sv[k.S_FTSAME] = g._same, g._joints_same, g._joints_t0, g._ft_same
        o = k.N_S
        if g._joints is not None:
            sv[k.S_HJ], sv[o:o + n], sv[o + n:o + 2 * n] = 1.0, g._joints[0], g._joints[1]
        if g._ft is not None:
            sv[k.S_HFT], sv[o + 2 * n:o + 2 * n + 6] = 1.0, g._ft
        if g._ft_q0 is not None:
            sv[k.S_HFTQ0], sv[o + 2 * n + 6:o + 3 * n + 6] = 1.0, g._ft_q0
        self._own, self._resets = True, g.resets
        return True

    def _release(self) -> None:
        """The kernel's safety state (sv) into the `Safety` object (unless it was reset since)."""
        if not self._own:
            return
        self._own = False
        g, n, k = self.guard, self.guard.n, self.k
        if g.resets != self._resets:
            return
        v = self._sv.tolist()
        o = k.N_S
        g._last_seq = int(v[k.S_SEQ]) if v[k.S_HSEQ] else None
        g._last_new = v[k.S_NEW] if v[k.S_HNEW] else None
        g._last_t = v[k.S_T] if v[k.S_HT] else None
        g._same, g._joints_same, g._joints_t0 = int(v[k.S_SAME]), int(v[k.S_JSAME]), v[k.S_JT0]
        g._joints = (v[o:o + n], v[o + n:o + 2 * n]) if v[k.S_HJ] else None
        g._ft = v[o + 2 * n:o + 2 * n + 6] if v[k.S_HFT] else None
        g._ft_same = int(v[k.S_FTSAME])
        g._ft_q0 = v[o + 2 * n + 6:o + 3 * n + 6] if v[k.S_HFTQ0] else None

    close = _release


__all__ = ["FastStep", "ReferenceStep", "make_step", "why_not"]
