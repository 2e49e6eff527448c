"""Every measure of a device at one configuration, at once (what `rhi measure` prints)."""

from __future__ import annotations

import numpy as np

from rhi import metrics
from rhi._validate import as_array, unit_vector
from rhi.devices.model import Device
from rhi.errors import Singular


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
    u = np.eye(device.m)[0] if u is None else unit_vector("u", u, device.m)
    J = device.jacobian(q)
    M = device.mass_matrix(q)
    lo, hi = device.torque_limits
    tmax = np.maximum(np.abs(lo), np.abs(hi))
    vme = metrics.velocity_ellipsoid(J)
    rank = int(np.linalg.matrix_rank(J))
    undefined: list[str] = []

    def full_rank(key: str, fn):
        try:
            return fn()
        except Singular:
            undefined.append(key)
            return None

    out: dict[str, object] = {
        "device": device.name,
        "q": q.tolist(),
        "u": u.tolist(),
        "singular": rank < device.m,
        "rank J": rank,
        "x [m]": device.fk(q).tolist(),
        "within_limits": bool(device.within_limits(q)),
        "J": J.tolist(),
        "velocity_ellipsoid JJᵀ (3.5)": vme.tolist(),
        "effective_manipulability ρ (3.6)": float(metrics.effective_manipulability(J, u)),
        "effective_inertia Λ [kg] (3.13)": float(metrics.effective_inertia(J, M, u)),
        "apparent_inertia M_x [kg] (3.12)": full_rank(
            "apparent_inertia M_x [kg] (3.12)", lambda: metrics.apparent_inertia(J, M).tolist()),
        "manipulability μ (4.7)": float(metrics.manipulability(J)),
        "isotropy 1/κ (4.9)": float(metrics.isotropy(J)),
        "velocity_transmission σ (4.4)": float(metrics.velocity_transmission(J, u)),
        "reflected_friction λ (4.6)": float(metrics.reflected_friction(J, u)),
        "force_ellipsoid M̂ (6.9)": full_rank("force_ellipsoid M̂ (6.9)", lambda: metrics.force_ellipsoid(J, tmax).tolist()),
        "directional_manipulability DM [N] (A.8)": float(metrics.directional_manipulability(J, u, tmax)),
        "max_force_scaling [N]": float(metrics.max_force_scaling(J, u, torque_min=lo, torque_max=hi)),
    }
    if exact_force and device.n > device.m:
        key = "max_force (LP, dynamic projector) [N]"
        out[key] = full_rank(key, lambda: float(
            metrics.max_force(J, u, torque_min=lo, torque_max=hi, projector="dynamic", M=M)))
    out["undefined (singular J)"] = undefined
    return out
