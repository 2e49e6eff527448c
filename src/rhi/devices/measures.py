"""Every measure of a device at one configuration, at once (what `rhi measure` prints)."""

from __future__ import annotations

import numpy as np

from rhi._validate import as_array, unit_vector
from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.metrics.summary import measure_checked

_MX = "apparent_inertia M_x [kg] (3.12)"
_FME = "force_ellipsoid M̂ (6.9)"
_LP = "max_force (LP, dynamic projector) [N]"


def all_measures(device: Device, q, u=None, *, exact_force: bool = True) -> dict[str, object]:
    """Kinematic, inertial and force measures of `device` at q.

    Args:
        device: the device.
        q: (n,) configuration [rad].
        u: (m,) direction for the directional measures (default: the first task axis).
        exact_force: also solve the force-capability linear program (≈ 1 ms).

    Returns:
        A dict of plain floats/lists, SI units (keys name the quantity and thesis equation).
        At a singular configuration (J of rank < m) "singular" is True, the scalar measures
        keep their limiting values (ρ = 0 along a lost direction, μ = 0, 1/κ = 0) and the
        measures that need a full-rank J (M_x, the force ellipsoid, the LP) are None and
        listed under "undefined (singular J)".
    """
    q = as_array("q", q, shape_tail=(device.n,))
    if q.ndim != 1:
        raise InvalidInput(f"q: expected shape ({device.n},) (one configuration), got {q.shape}")
    u = np.eye(device.m)[0] if u is None else unit_vector("u", u, device.m)
    if u.ndim != 1:
        raise InvalidInput(f"u: expected shape ({device.m},), got {u.shape}")
    th = device._theta(q)
    J = device.jacobian_theta(th)
    lo, hi = device.torque_limits
    lp = exact_force and device.n > device.m
    r = measure_checked(J, device._mass1(th), u, lo, hi, lp=lp)
    undefined = [key for key, value in ((_MX, r.apparent_inertia), (_FME, r.force_ellipsoid)) if value is None]
    out: dict[str, object] = {
        "device": device.name,
        "q": q.tolist(),
        "u": r.u.tolist(),
        "singular": r.rank < device.m,
        "rank J": r.rank,
        "x [m]": device.fk_theta(th).tolist(),
        "within_limits": bool(device._within(q)),
        "J": J.tolist(),
        "velocity_ellipsoid JJᵀ (3.5)": r.velocity_ellipsoid.tolist(),
        "effective_manipulability ρ (3.6)": r.effective_manipulability,
        "effective_inertia Λ [kg] (3.13)": r.effective_inertia,
        _MX: None if r.apparent_inertia is None else r.apparent_inertia.tolist(),
        "manipulability μ (4.7)": r.manipulability,
        "isotropy 1/κ (4.9)": r.isotropy,
        "velocity_transmission σ (4.4)": r.effective_manipulability,
        "reflected_friction λ (4.6)": r.reflected_friction,
        _FME: None if r.force_ellipsoid is None else r.force_ellipsoid.tolist(),
        "directional_manipulability DM [N] (A.8)": r.directional_manipulability,
        "max_force_scaling [N]": r.max_force_scaling,
    }
    if lp:
        out[_LP] = r.max_force
        if r.max_force is None:
            undefined.append(_LP)
    out["undefined (singular J)"] = undefined
    return out
