"""The controller's fast tick: the primary law in Python, everything after it in one compiled kernel.

`KernelTick` holds what does not change between ticks (limits, parameters, the desired VMEs
and FMEs, output buffers) and calls `rhi.control.kernels.tick` once per tick with the device
terms of one Pinocchio pass. Objectives the kernel knows (VME matching, the FME schedule)
run inside it; any other objective and the joint-limit barriers run their own
`gradient_at` in Python and enter as two torque vectors.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from rhi.control import kernels
from rhi.control.objectives import EllipsoidMatching, VMEMatching, gradient_function
from rhi.control.transition import TransitionState
from rhi.device import DeviceTerms
from rhi.errors import Singular
from rhi.terms_kernel import TERMS, layout

if TYPE_CHECKING:
    from rhi.control.controller import NullSpaceController

def _f64(v) -> np.ndarray:
    """V as a C-contiguous float64 array (one compiled specialisation of the kernel)."""
    if type(v) is np.ndarray and v.dtype == np.float64 and v.flags.c_contiguous:
        return v
    return np.ascontiguousarray(v, dtype=np.float64)


def _kernel_vme(objective) -> np.ndarray | None:
    """M_des of a VME-matching objective the kernel computes, else None."""
    if isinstance(objective, VMEMatching):
        return objective.desired()
    if isinstance(objective, EllipsoidMatching) and objective.H is None:
        return objective.desired
    return None


class KernelTick:
    """Steps 2–6 of a `NullSpaceController` tick through `rhi.control.kernels.tick`.

    Args:
        ctrl: the controller (its device, configuration, limits and objectives).
    """

    def __init__(self, ctrl: NullSpaceController) -> None:
        cfg, dev = ctrl.config, ctrl.device
        n, m = dev.n, dev.m
        self.ctrl = ctrl
        fme = cfg.fme
        self._fme = fme is not None
        prm = np.zeros(kernels.N_PARAMS)
        prm[kernels.P_DAMPING] = cfg.damping
        prm[kernels.P_ASO_S] = ctrl.aso_shape
        prm[kernels.P_GRAVITY] = float(cfg.gravity_compensation)
        prm[kernels.P_DYNAMIC] = float(cfg.projector == "dynamic")
        prm[kernels.P_SATURATION] = ctrl.allocation.kernel
        prm[kernels.P_SAFE] = float(ctrl.allocation.safe)
        self._free = self._stiff = np.eye(m)
        if fme is not None:
            prm[kernels.P_FME] = 1.0
            prm[kernels.P_FME_GAIN] = fme.gain
            prm[kernels.P_FME_DIST] = fme.distance
            prm[kernels.P_EPS1], prm[kernels.P_EPS2], prm[kernels.P_RHO] = (
                fme.transition.eps1, fme.transition.eps2, fme.transition.rho)
            self._free, self._stiff = _f64(fme.free), _f64(fme.stiff)
        self._prm = prm
        self._w2 = _f64(ctrl.hi**-2.0)
        vme, gains = [], []
        self._grads = []  # (gain, terms -> ∂ν/∂q) of the objectives computed in Python
        for gain, obj in ctrl.objectives:
            D = _kernel_vme(obj)
            if D is None:
                self._grads.append((gain, gradient_function(obj, dev)))
            else:
                vme.append(D)
                gains.append(gain)
        self._vme = _f64(np.array(vme).reshape(len(vme), m, m))
        self._vme_gain = _f64(np.array(gains, dtype=float))
        self._barriers = [(gain, gradient_function(obj, dev)) for gain, obj in ctrl.barriers]
        self._at = layout(n, m)[1]
        self._zero = np.zeros(n)
        self._tau = np.empty(n)
        self._sat = np.zeros(n, bool)
        self._tr = np.zeros(4)
        self._tr_of: TransitionState | None = None  # the state object self._tr mirrors

    def __call__(self, t: float, kin: DeviceTerms, sensors: Mapping[str, np.ndarray]):
        """One tick: (τ (n,) [N m], α, β, saturated (n,) bool, clipped), or (F_render, F_extra).

        The forces come back where the kernel cannot decide: the reference's basis form then runs the tick.

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
        fme = self._fme
        if fme:
            if s.transition is not self._tr_of:
                T = s.transition
                tr[:] = (float(T.stiff), T.omega_start, T.t0, T.tf)
            before = tr.tolist()
        buf = kin._buf
        if buf is None:  # terms not from the compiled `Device.terms` (a joint that is not one-DoF)
            buf = np.concatenate([getattr(kin, name).ravel() for name, _ in TERMS[:9]])
        status, alpha, beta, V, omega, clipped = kernels.tick(
            t, buf, self._at, _f64(F_r), _f64(F_x), _f64(kin.dq), ctrl.lo, ctrl.hi, self._prm, tr,
            self._free, self._stiff, self._w2, self._vme, self._vme_gain, _f64(tau_s), _f64(tau_to),
            self._tau, self._sat)
        if status != kernels.OK:
            self._tr_of = None  # the kernel may have advanced tr; the state did not
            if status == kernels.SINGULAR:
                raise Singular("J: rank-deficient Jacobian")
            return F_r, F_x
        if fme:
            after = tr.tolist()
            if after != before:
                s.transition = TransitionState(after[0] != 0.0, after[1], after[2], after[3])
            self._tr_of = s.transition
        s.V, s.omega = V, omega
        return self._tau.copy(), alpha, beta, self._sat.copy(), clipped


__all__ = ["KernelTick"]
