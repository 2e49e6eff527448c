"""Every measure of a device at one configuration (what `rhi measure` prints)."""

from __future__ import annotations

import numpy as np

from rhi import metrics
from rhi._validate import unit_vector
from rhi.device import Device


def measure(device: Device, q, u=None, *, exact_force: bool = True) -> dict[str, object]:
    """Kinematic, inertial and force measures of `device` at q.

    Args:
        device: the device.
        q: (n,) configuration [rad].
        u: (m,) direction for the directional measures (default: the first task axis).
        exact_force: also solve the force-capability linear program (≈ 1 ms).

    Returns:
        A dict of plain floats/lists, SI units (keys name the quantity and thesis equation).
    """
    q = device._q(q)
    u = np.eye(device.m)[0] if u is None else unit_vector("u", u, device.m)
    J = device.jacobian(q)
    M = device.mass_matrix(q)
    lo, hi = device.torque_limits
    tmax = np.maximum(np.abs(lo), np.abs(hi))
    vme = metrics.velocity_ellipsoid(J)
    out: dict[str, object] = {
        "device": device.name,
        "q": q.tolist(),
        "u": u.tolist(),
        "x [m]": device.fk(q).tolist(),
        "within_limits": bool(device.within_limits(q)),
        "J": J.tolist(),
        "velocity_ellipsoid JJᵀ (3.5)": vme.tolist(),
        "effective_manipulability ρ (3.6)": float(metrics.effective_manipulability(J, u)),
        "effective_inertia Λ [kg] (3.13)": float(metrics.effective_inertia(J, M, u)),
        "apparent_inertia M_x [kg] (3.12)": metrics.apparent_inertia(J, M).tolist(),
        "manipulability μ (4.7)": float(metrics.manipulability(J)),
        "isotropy 1/κ (4.9)": float(metrics.isotropy(J)),
        "velocity_transmission σ (4.4)": float(metrics.velocity_transmission(J, u)),
        "reflected_friction λ (4.6)": float(metrics.reflected_friction(J, u)),
        "force_ellipsoid M̂ (6.9)": metrics.force_ellipsoid(J, tmax).tolist(),
        "directional_manipulability DM [N] (A.8)": float(metrics.directional_manipulability(J, u, tmax)),
        "max_force_scaling [N]": float(metrics.max_force_scaling(J, u, torque_min=lo, torque_max=hi)),
    }
    if exact_force and device.n > device.m:
        out["max_force (LP, dynamic projector) [N]"] = float(
            metrics.max_force(J, u, torque_min=lo, torque_max=hi, projector="dynamic", M=M)
        )
    return out
