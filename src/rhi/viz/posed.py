"""`Posed`: a device's MuJoCo model (with its visual geometry) placed at a configuration, for drawing.

Serial and parallel devices use the plant of `rhi.sim.Plant` (chain coordinates θ = A q + b);
a mobile manipulator (coordinates starting with the base pose x_b, y_b, θ_b) uses
`rhi.sim.mobile.MobilePlant`. Only the kinematics are evaluated (`mj_kinematics`), never the
dynamics.
"""

from __future__ import annotations

import mujoco
import numpy as np

from rhi._validate import as_array
from rhi.devices.mobile_base import BASE_JOINTS
from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.sim.geometry import joint_axis
from rhi.sim.mobile import MobilePlant
from rhi.sim.plant import Plant

#: the smallest σ_min/σ_max of the Jacobian a start pose may have (`rest_configuration`)
WELL_CONDITIONED = 0.1
#: a parallelogram's crank as a fraction of the link it parallels (`Posed.linkages`)
CRANK = 0.3
#: the floor's distance under the device's lowest point where the model has no floor of its own [m]
FLOOR_GAP = 0.02


def parallelograms(device: Device) -> list[tuple[int, int]]:
    """Chain joints (p, j) whose link j is driven through a parallelogram from joint p's axis.

    The actuation map says so: θ_p = q_a and θ_j = q_b − q_a with parallel hinge axes, so the motor b sets
    link j's absolute angle from the base (thesis §3.5: the Quanser arm and the PHANToM 1.5A of the rhi4).
    A chain that branches at p models its linkage itself and is left out.
    """
    model, A = device.model, np.asarray(device.A, dtype=float)
    out = []
    for j in range(2, model.njoints):
        p = int(model.parents[j])
        if p == 0 or list(model.parents).count(p) != 1:
            continue
        rp, rj = A[model.joints[p].idx_v], A[model.joints[j].idx_v]
        a = np.flatnonzero(rp)
        if len(a) != 1 or rp[a[0]] != 1.0 or rj[a[0]] != -1.0 or np.count_nonzero(rj) != 2 or rj.sum() != 0.0:
            continue
        (kp, ap), (kj, aj) = joint_axis(model.joints[p]), joint_axis(model.joints[j])
        if kp == kj == "hinge" and abs(abs(float(ap @ (model.jointPlacements[j].rotation @ aj))) - 1.0) < 1e-9:
            out.append((p, j))
    return out


def rest_configuration(device: Device) -> np.ndarray:
    """A documented, non-singular start pose: (n,) [rad or m].

    Mid-range motor coordinates (0 for unbounded ones). Where that pose is singular or nearly so
    (σ_min/σ_max of J below 0.1: a stretched serial arm such as planar3r or gen3 at zero), each joint
    is bent by alternating ±0.4 rad (then ±0.8 rad), kept 10 % inside its range: the first such pose
    that is well conditioned, else the best one tried.
    """
    lo, hi = device.joint_limits
    ok = np.isfinite(lo) & np.isfinite(hi)
    lo0, hi0 = np.where(ok, lo, 0.0), np.where(ok, hi, 0.0)
    mid = 0.5 * (lo0 + hi0)
    inner_lo = np.where(ok, lo0 + 0.1 * (hi0 - lo0), -np.inf)
    inner_hi = np.where(ok, hi0 - 0.1 * (hi0 - lo0), np.inf)
    alt = np.where(np.arange(device.n) % 2 == 0, 1.0, -1.0)
    best, best_c = mid, -1.0
    for q in (mid, *(np.clip(mid + a * alt, inner_lo, inner_hi) for a in (0.4, -0.4, 0.8, -0.8))):
        s = np.linalg.svd(device.jacobian(q), compute_uv=False)
        c = float(s[-1] / s[0]) if s[0] > 0 else 0.0
        if c >= WELL_CONDITIONED:
            return q
        if c > best_c:
            best, best_c = q, c
    return best


class Posed:
    """A device's drawable MuJoCo model.

    Args:
        device: the device to draw.
        collision: give the geometry contacts (drawn the same).

    Attributes:
        model, data: MuJoCo model and data (the data holds the pose of the last `set`).
        device: the device.
    """

    def __init__(self, device: Device, *, collision: bool = False) -> None:
        self.device = device
        if tuple(device.joint_names[:3]) == BASE_JOINTS:
            plant: Plant | MobilePlant = MobilePlant(device)
            self._qadr = np.array([plant.model.joint(nm).qposadr[0] for nm in device.joint_names])
            self._A = self._b = None
        else:
            plant = Plant(device, friction=None, collision=collision)
            moving = np.any(device.A != 0, axis=1)
            self._A, self._b = device.A[moving], device.b[moving]
        self.model, self.data = plant.model, plant.data
        self.handle = self.model.body("handle").id
        self._links = self._parallelogram_links()

    def _parallelogram_links(self) -> list[tuple[int, int, np.ndarray]]:
        """Per parallelogram: MuJoCo bodies of joints p and j, and the crank (3,) in j's frame [m].

        The crank is `CRANK` of link p long and points away from link j.
        """
        dev, m, d = self.device, self.model, self.data
        mujoco.mj_kinematics(m, d)
        out = []
        for p, j in parallelograms(dev):
            bp, bj = (m.body(f"b_{dev.model.names[i]}").id for i in (p, j))
            children = [i for i in range(1, dev.model.njoints) if dev.model.parents[i] == j]
            end = m.body(f"b_{dev.model.names[children[0]]}").id if children else self.handle
            O, P, C = d.xpos[bp], d.xpos[bj], d.xpos[end]
            along = d.xmat[bj].reshape(3, 3).T @ (C - P) / float(np.linalg.norm(C - P))
            out.append((bp, bj, -CRANK * float(np.linalg.norm(P - O)) * along))
        return out

    def linkages(self) -> np.ndarray:
        """The parallelograms' links the serial chain leaves out, at the current pose: (k, 2, 3) segments [m].

        Per parallelogram (`parallelograms`), three: the crank at joint p (turning with link j), the coupler
        from its tip parallel to link p, and link j's rear extension to the coupler's end.
        """
        d, out = self.data, []
        for bp, bj, crank in self._links:
            O, P = d.xpos[bp], d.xpos[bj]
            c = d.xmat[bj].reshape(3, 3) @ crank
            out += [(O, O + c), (O + c, P + c), (P, P + c)]
        return np.array(out, dtype=float).reshape(-1, 2, 3)

    def set(self, q) -> None:
        """Place the device at motor coordinates q: (n,) [rad or m] (kinematics only)."""
        q = as_array("q", q, shape_tail=(self.device.n,))
        if q.ndim != 1:
            raise InvalidInput(f"q: expected shape ({self.device.n},), got {q.shape}")
        if self._A is not None:
            self.data.qpos[:] = self._A @ q + self._b
        else:
            self.data.qpos[self._qadr] = q
        mujoco.mj_kinematics(self.model, self.data)

    def floor(self, lowest: float | None = None) -> float:
        """Height of the floor the device stands on [m]: the model's own plane, else `FLOOR_GAP` under `lowest`.

        Args:
            lowest: z of the lowest point to stand under [m] (default: the drawn geometry's at the current pose).
        """
        m = self.model
        planes = np.flatnonzero(m.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
        if planes.size:
            return float(np.min(self.data.geom_xpos[planes, 2]))
        return (float(self.bounds()[0][2]) if lowest is None else float(lowest)) - FLOOR_GAP

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned box of the drawn geometry at the current pose (floor planes left out): (3,), (3,) [m]."""
        m, d = self.model, self.data
        keep = m.geom_type != mujoco.mjtGeom.mjGEOM_PLANE
        c, r = d.geom_xpos[keep], m.geom_rbound[keep][:, None]
        return (c - r).min(axis=0), (c + r).max(axis=0)
