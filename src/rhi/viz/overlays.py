"""What the view draws at the handle: ellipsoids, force capability, forces and the rendered environment.

`handle_measures` computes, at a configuration, the velocity ellipsoid JJᵀ (eq. 3.5), the
torque-weighted force ellipsoid M̂ = (J W W Jᵀ)⁻¹ (eq. 6.9), and the largest force along a
direction u by simple scaling (§7.3) and by the LP with null-space torques (eqs. 7.5–7.9),
all from `rhi.metrics`. `Overlays` draws them (and the hand and environment forces, the
desired FME and the virtual environment's wall, spring or fixture) in a viser scene.
Planar devices (m = 2) are drawn in their task plane at the handle's height.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from rhi.devices.model import Device
from rhi.errors import RhiError
from rhi.metrics import force_ellipsoid, max_force, max_force_scaling, velocity_ellipsoid
from rhi.sim.environment import Compose, Fixture, Spring, Wall

_AXES = {"x": 0, "y": 1, "z": 2}
VELOCITY_RGB = (60, 140, 230)
FORCE_RGB = (235, 120, 30)
DESIRED_RGB = (40, 170, 80)
HAND_RGB = (200, 30, 160)
ENV_RGB = (200, 40, 40)
LP_RGB = (30, 30, 30)
SCALING_RGB = (150, 150, 150)


@dataclasses.dataclass
class HandleMeasures:
    """Measures at one configuration (task axes).

    Attributes:
        velocity: (m, m) JJᵀ [(m/s)² per (rad/s)²] (eq. 3.5).
        force: (m, m) M̂ [N²] (eq. 6.9), or None at a singularity.
        u: (m,) unit direction of the force capability.
        f_lp: largest force along u with null-space torques [N] (LP, eq. 7.9), or None when not computed
            or undefined (singular).
        f_scaling: largest force along u by simple scaling [N] (§7.3), NaN where undefined.
    """

    velocity: np.ndarray
    force: np.ndarray | None
    u: np.ndarray
    f_lp: float | None
    f_scaling: float


def handle_measures(device: Device, q: np.ndarray, u: np.ndarray, *, lp: bool = True) -> HandleMeasures:
    """The handle's ellipsoids and force capability along u: (m,) at q: (n,) [rad]."""
    J = device.jacobian(q)
    u = np.asarray(u, dtype=float)
    u = u / np.linalg.norm(u)
    lo, hi = device.torque_limits
    def safe(fn):  # at a singularity a measure is undefined: not drawn
        try:
            return fn()
        except RhiError:
            return None

    F = safe(lambda: force_ellipsoid(J, hi))
    f_s = safe(lambda: float(max_force_scaling(J, u, torque_min=lo, torque_max=hi)))
    f_lp = safe(lambda: float(max_force(J, u, torque_min=lo, torque_max=hi, projector="dynamic",
                                        M=device.mass_matrix(q)))) if lp else None
    return HandleMeasures(velocity_ellipsoid(J), F, u, f_lp, np.nan if f_s is None else f_s)


def ellipsoid_pose(A: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Semi-axes (3,) and orientation wxyz (4,) of the ellipsoid xᵀA⁻¹x <= 1 of a (m, m) PSD A, in 3-D.

    For m = 2 it is an ellipse in the task plane: the third scale is 1, applied to a flat ring.
    """
    w, V = np.linalg.eigh(0.5 * (A + A.T))
    axes = np.sqrt(np.clip(w, 0.0, None))
    R = np.eye(3)
    R[:m, :m] = V
    if np.linalg.det(R) < 0:
        R[:, 0] *= -1
    s = np.ones(3)
    s[:m] = np.maximum(axes, 1e-9)
    return s, _wxyz(R)


def _wxyz(R: np.ndarray) -> np.ndarray:
    q = pin.Quaternion(R)
    return np.array([q.w, q.x, q.y, q.z])


#: the overlay groups a user can switch on and off, with their labels
GROUPS = {"velocity": "velocity ellipsoid", "force": "force ellipsoid", "desired": "desired FME",
          "forces": "hand and environment forces", "capability": "force capability along u",
          "environment": "wall, spring, fixture"}
_ARROW_GROUP = {"F_hand": "forces", "F_env": "forces", "scaling": "capability", "lp": "capability"}


class Overlays:
    """The handle's overlays in a viser scene.

    Args:
        server: the viser server.
        device: the device (its task axes, Jacobian, limits).
        size: the drawn device's size [m] (sets the display scales).
        virtual: the rendered environment (`Wall`, `Spring`, `Fixture`, or a `compose` of them), or None.
        fme: a desired-FME schedule (`rhi.control.FMESchedule`) whose M_des(Ω) is drawn, or None (also a
            scheduled objective without ``desired(omega)``: nothing to draw).

    Attributes:
        force_scale: [m/N] of the force ellipsoid, capability and force arrows: 0.35 of the device's size per the
            largest force seen so far (the capability at the first frame, then any larger hand, environment or
            capability force: rescaled when a force exceeds the reference by 25 %), so arrows stay readable.
        velocity_scale: [s] of the velocity ellipsoid (1 rad/s of joint speed).
        shown: which overlay groups are drawn (`GROUPS`; `show` switches one).
    """

    def __init__(self, server, device: Device, size: float, *, virtual=None, fme=None, root: str = "/overlays") -> None:
        self.server, self.device, self.root = server, device, root
        self.rows = [_AXES[a] for a in device.task_axes]
        self.m = device.m
        self.size = float(size)
        self.virtual, self.fme = virtual, fme if callable(getattr(fme, "desired", None)) else None
        self.force_scale: float | None = None
        self.velocity_scale: float | None = None
        self._f_ref = 0.0  # the force [N] that force_scale draws at 0.35 of the device's size
        self.shown = dict.fromkeys(GROUPS, True)
        self._env_nodes: list = []
        self.vel = self._ellipsoid(f"{root}/velocity", VELOCITY_RGB, 0.25)
        self.frc = self._ellipsoid(f"{root}/force", FORCE_RGB, 0.3)
        self.des = self._ellipsoid(f"{root}/desired", DESIRED_RGB, 0.9, wireframe=True)
        self.des.visible = self.fme is not None
        self._arrows: dict = {}
        self._env_drawn = False
        self._springs: list = []

    def _ellipsoid(self, name: str, rgb, opacity: float, wireframe: bool = False):
        """A unit sphere (spatial tasks) or a unit circle in the task plane (planar tasks), posed and scaled later."""
        if self.m == 3:
            return self.server.scene.add_icosphere(name, radius=1.0, color=rgb, opacity=opacity, wireframe=wireframe,
                                                   subdivisions=3 if not wireframe else 2)
        a = np.linspace(0.0, 2 * np.pi, 65)
        ring = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)]).astype(np.float32)
        return self.server.scene.add_line_segments(name, np.stack([ring[:-1], ring[1:]], axis=1), colors=rgb,
                                                   thickness=2.0 if wireframe else 3.5, thickness_units="screen")

    def _world(self, v: np.ndarray, z: float = 0.0) -> np.ndarray:
        out = np.zeros(3)
        out[2] = z
        out[self.rows] = v
        return out

    def show(self, group: str, on: bool) -> None:
        """Draw (or hide) one overlay group of `GROUPS`."""
        self.shown[group] = bool(on)
        nodes = {"velocity": [self.vel], "force": [self.frc], "desired": [self.des],
                 "environment": self._env_nodes + [c for _, c in self._springs]}.get(group, [])
        nodes += [a for name, a in self._arrows.items() if _ARROW_GROUP[name] == group]
        for node in nodes:
            node.visible = bool(on)
        if group == "desired" and self.fme is None:
            self.des.visible = False

    def _rescale(self, snap, meas: HandleMeasures) -> None:
        """Grow the force scale when a force exceeds the reference by 25 % (never shrinks: no breathing)."""
        seen = [float(meas.f_scaling)] + [float(np.linalg.norm(np.asarray(getattr(snap, k, 0.0), dtype=float)))
                                          for k in ("F_hand", "F_env")]
        f = max((v for v in seen if np.isfinite(v)), default=0.0)
        if self.force_scale is None or f > 1.25 * self._f_ref:
            self._f_ref = f if f > 0 else 1.0
            self.force_scale = 0.35 * self.size / self._f_ref

    def update(self, handle: np.ndarray, snap, meas: HandleMeasures) -> None:
        """Redraw at the handle position (3,) [m] for a telemetry snapshot and the measures at its q."""
        self._rescale(snap, meas)
        if self.velocity_scale is None:
            v_ref = float(np.sqrt(np.max(np.linalg.eigvalsh(meas.velocity))))
            self.velocity_scale = 0.35 * self.size / max(v_ref, 1e-6)
        pos = tuple(handle)
        s, wxyz = ellipsoid_pose(meas.velocity, self.m)
        self.vel.position, self.vel.wxyz, self.vel.scale = pos, tuple(wxyz), tuple(s * self.velocity_scale)
        if meas.force is not None:
            s, wxyz = ellipsoid_pose(meas.force, self.m)
            self.frc.position, self.frc.wxyz, self.frc.scale = pos, tuple(wxyz), tuple(s * self.force_scale)
        frc = meas.force is not None and self.shown["force"]
        if self.frc.visible != frc:  # only on change: viser fades a node in when shown
            self.frc.visible = frc
        if self.fme is not None and np.isfinite(getattr(snap, "omega", np.nan)):
            s, wxyz = ellipsoid_pose(self.fme.desired(float(snap.omega)), self.m)
            self.des.position, self.des.wxyz, self.des.scale = pos, tuple(wxyz), tuple(s * self.force_scale)
        self._draw_arrows(handle, snap, meas)
        if not self._env_drawn and self.virtual is not None:
            self._draw_environment(handle[2])
            self._env_drawn = True
            self.show("environment", self.shown["environment"])
        for rest, coil in self._springs:
            coil.points = np.array([[rest, handle]], dtype=np.float32)

    def _draw_arrows(self, handle: np.ndarray, snap, meas: HandleMeasures) -> None:
        """One arrow node per force, created once and then only moved.

        Viser fades a scene in whenever a node is added, so nothing is re-created per frame.
        """
        k = self.force_scale
        vecs = {"F_hand": (HAND_RGB, getattr(snap, "F_hand", None)), "F_env": (ENV_RGB, getattr(snap, "F_env", None)),
                "scaling": (SCALING_RGB, meas.f_scaling * meas.u if np.isfinite(meas.f_scaling) else None),
                "lp": (LP_RGB, None if meas.f_lp is None else meas.f_lp * meas.u)}
        r = 0.012 * self.size
        for name, (rgb, v) in vecs.items():
            vec3 = None if v is None else k * self._world(np.asarray(v, dtype=float))
            show = vec3 is not None and bool(np.all(np.isfinite(vec3))) and float(np.linalg.norm(vec3)) > 1e-6 \
                and self.shown[_ARROW_GROUP[name]]
            node = self._arrows.get(name)
            if node is None:
                if not show:
                    continue
                node = self._arrows[name] = self.server.scene.add_arrows(
                    f"{self.root}/{name}", np.zeros((1, 2, 3), np.float32), rgb, shaft_radius=0.4 * r,
                    head_radius=r, head_length=3 * r)
            if show:
                node.points = np.array([[handle, handle + vec3]], dtype=np.float32)
            if node.visible != show:
                node.visible = show

    def _draw_environment(self, z: float) -> None:
        parts = self.virtual.parts if isinstance(self.virtual, Compose) else (self.virtual,)
        sc, L = self.server.scene, self.size
        for i, env in enumerate(parts):
            name = f"{self.root}/env{i}"
            if isinstance(env, Wall):
                p, nrm = self._world(env.point, z), self._world(env.normal)
                if self.m == 3:  # a translucent slab
                    self._env_nodes.append(sc.add_box(
                        name, color=ENV_RGB, dimensions=(0.9 * L, 0.9 * L, 0.004 * L), opacity=0.3,
                        position=tuple(p + nrm * 0.002 * L), wxyz=tuple(_plane_pose(nrm))))
                    continue
                # planar: the wall's trace in the task plane, hatched on the environment's side
                along = np.cross([0.0, 0.0, 1.0], nrm)
                ends = [p - 0.45 * L * along, p + 0.45 * L * along]
                marks = [(p + s * along, p + s * along + 0.04 * L * (nrm + 0.6 * along))
                         for s in np.linspace(-0.42 * L, 0.42 * L, 15)]
                self._env_nodes.append(sc.add_line_segments(
                    name, np.array([ends, *marks], dtype=np.float32), colors=ENV_RGB, thickness=3.0,
                    thickness_units="screen"))
            elif isinstance(env, Spring):
                p = self._world(env.point, z)
                self._env_nodes.append(sc.add_icosphere(name, radius=0.03 * L, color=ENV_RGB, position=tuple(p)))
                self._springs.append((p, sc.add_line_segments(f"{name}/coil", np.zeros((1, 2, 3), np.float32),
                                                              colors=ENV_RGB, thickness=0.008 * L)))
            elif isinstance(env, Fixture):
                p, d = self._world(env.point, z), self._world(env.direction)
                pts = np.array([[p - L * d, p + L * d]], dtype=np.float32)
                self._env_nodes.append(sc.add_line_segments(name, pts, colors=ENV_RGB, thickness=0.006 * L))


def _plane_pose(normal: np.ndarray) -> np.ndarray:
    """Orientation wxyz taking z onto `normal`."""
    q = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), normal / np.linalg.norm(normal))
    return np.array([q.w, q.x, q.y, q.z])
