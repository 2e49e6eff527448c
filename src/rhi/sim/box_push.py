"""§A.4.3's box push on the mobile manipulator's MuJoCo plant: a box on the floor, pushed by the end effector.

`BoxPushPlant` is `rhi.sim.mobile.MobilePlant` with three bodies more in its `MjSpec`: a floor that the box
stands on, a `Box` that slides on it with Coulomb friction (x, y, z and yaw free: it slides, it does not tip),
and a pusher tip at the end effector that touches only the box, without friction (the push force is normal
to the box's face). Each arm joint's *total* actuator torque (its position and velocity servo together) is
limited to the joint's torque limit, as one motor drives each joint. Every control period the plant samples
the arm's joint torques (MuJoCo's actuator torques; the arm's gravity is compensated by the plant, so they
are the torques with gravity subtracted, as Fig. A.8 plots them), the box's position and the tip's contact
force. `push_trajectory` is the end-effector reference: hold, then a minimum-jerk push along world x.

Only the box's mass (26 kg) is in the thesis; every other number here is a reading of the experiment
(`rhi.experiments.appa.push` names each with the sentence that allows it).
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from rhi._validate import as_array, scalar
from rhi.devices.model import Device
from rhi.errors import InvalidInput, ModelError
from rhi.sim.geometry import floor_height
from rhi.sim.mobile import MobilePlant, SlipModel, Trajectory

#: The base's velocity servo in the push [N s/m, N m s/rad]: stiff, so that the wheels hold the base against
#: the push's reaction (eq. A.3: pure rolling, the base moves as commanded); 100 N moves it by 1 mm/s.
PUSH_BASE_KV = 1e5


@dataclasses.dataclass(frozen=True)
class Box:
    """The pushed box and the pusher tip.

    Attributes:
        mass: box mass [kg] (thesis: "approximately 26 kg", line 2204).
        friction: Coulomb friction coefficient μ of the box on the floor (not in the thesis).
        depth: box size along the push [m] (not in the thesis).
        width: box size across the push [m] (not in the thesis).
        headroom: box top above the contact point [m] (the tip touches the face, not the edge).
        tip_radius: radius of the pusher sphere at the end effector [m] (the Gen3's tool is not given).
        gap: distance from the tip to the box's face at the start [m].
    """

    mass: float = 26.0
    friction: float = 0.692
    depth: float = 0.5
    width: float = 0.5
    headroom: float = 0.1
    tip_radius: float = 0.02
    gap: float = 0.005

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            scalar(f"box.{f.name}", getattr(self, f.name), positive=True)


def minimum_jerk(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk profile 10s³ − 15s⁴ + 6s⁵ and its first two derivatives in s, for s ∈ [0, 1] (clipped)."""
    s = np.clip(s, 0.0, 1.0)
    return (10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4, 60 * s - 180 * s**2 + 120 * s**3)


def push_trajectory(x0, distance: float, *, start: float, duration: float, hold: float, dt: float) -> Trajectory:
    """Hold x0 until `start`, push by `distance` along world x in `duration` (minimum jerk), hold `hold`.

    Args:
        x0: (3,) end-effector start [m].
        distance: push length [m].
        start: time the push starts [s] (≥ 0).
        duration: push time [s].
        hold: time held at the end [s] (≥ 0).
        dt: sampling period [s].
    """
    x0 = as_array("x0", x0, shape_tail=(3,))
    if x0.ndim != 1:
        raise InvalidInput(f"x0: expected shape (3,), got {x0.shape}")
    d, duration, dt = (scalar(k, v, positive=True) for k, v in (("distance", distance), ("duration", duration), ("dt", dt)))
    start, hold = scalar("start", start, nonnegative=True), scalar("hold", hold, nonnegative=True)
    t = np.arange(int(round((start + duration + hold) / dt)) + 1) * dt
    p, v, a = minimum_jerk((t - start) / duration)
    inside = (t > start) & (t < start + duration)
    x = np.broadcast_to(x0, (t.size, 3)).copy()
    dx, ddx = np.zeros((t.size, 3)), np.zeros((t.size, 3))
    x[:, 0] += d * p
    dx[:, 0] = np.where(inside, d * v / duration, 0.0)
    ddx[:, 0] = np.where(inside, d * a / duration**2, 0.0)
    return Trajectory(t, x, dx, ddx)


class BoxPushPlant(MobilePlant):
    """The wmm plant with a box to push (see the module).

    Args:
        contact: (3,) where the tip's centre is at the start, world frame [m]: the box's face stands
            `box.tip_radius + box.gap` ahead of it along x, its centre line through it.
        box: the box and the tip.
        device: the mobile manipulator (default ``rhi.device("wmm")``).
        slip: base ground model (default `SlipModel.none()`: pure rolling, eq. A.3).
        timestep: physics step [s].
        base_kv: the base's velocity servo gain (default `PUSH_BASE_KV`).
        **gains: the other `rhi.sim.mobile_spec.wmm_spec` gains (arm_kp, arm_kv, armature).

    Attributes:
        floor_z: the floor's height [m] (`rhi.sim.geometry.floor_height` of the drawn base).
        torques: (k, m) arm joint torques sampled at the end of each control period since `reset` [N m].
        box_x: (k, 3) box centre [m], same samples.
        tip_force: (k, 3) force of the tip on the box, world frame [N], same samples.
    """

    def __init__(self, contact, *, box: Box | None = None, device: Device | None = None, slip: SlipModel | None = None,
                 timestep: float = 1e-3, base_kv: float = PUSH_BASE_KV, **gains: float) -> None:
        self.box = box if box is not None else Box()
        if not isinstance(self.box, Box):
            raise InvalidInput(f"box: expected a Box, got {type(self.box).__name__}")
        contact = as_array("contact", contact, shape_tail=(3,))
        if contact.ndim != 1:
            raise InvalidInput(f"contact: expected shape (3,), got {contact.shape}")
        super().__init__(device, slip=slip if slip is not None else SlipModel.none(), timestep=timestep, geometry=None,
                         visual=True, base_kv=base_kv, **gains)
        self.floor_z = floor_height(self.geometry["wheel_radius"])
        if contact[2] - self.box.tip_radius <= self.floor_z:
            raise InvalidInput(f"contact: the tip must be above the floor (z > {self.floor_z:.3f} m), got {contact[2]}")
        self._add_box(contact)
        try:
            self.model = self.spec.compile()
        except ValueError as exc:
            raise ModelError(f"box: MuJoCo rejected the box push plant: {exc}") from None
        self.data = mujoco.MjData(self.model)
        names = self.device.joint_names  # the box's bodies come after the robot's: its addresses are unchanged
        if any(self.model.joint(nm).qposadr[0] != a for nm, a in zip(names, self._qadr)):
            raise ModelError("box: the box moved the robot's joint addresses")
        self._box_body = self.model.body("box").id
        self._tip, self._box_geom = self.model.geom("tip").id, self.model.geom("box").id
        self.torques: list[np.ndarray] = []
        self.box_x: list[np.ndarray] = []
        self.tip_force: list[np.ndarray] = []

    def _add_box(self, contact: np.ndarray) -> None:
        """Floor, box and tip in the spec; collisions: floor–box and tip–box only (contype/conaffinity bits)."""
        b, spec = self.box, self.spec
        spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        for nm in self.device.joint_names[3:]:  # one motor per joint: the servos' sum within the torque limit
            j, i = spec.joint(nm), self.device.joint_names.index(nm)
            j.actfrclimited, j.actfrcrange = mujoco.mjtLimited.mjLIMITED_TRUE, [self.device.torque_min[i],
                                                                                 self.device.torque_max[i]]
        floor = spec.worldbody.add_geom(name="push_floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[4, 4, 0.05],
                                        pos=[0, 0, self.floor_z], rgba=[0, 0, 0, 0])
        floor.contype, floor.conaffinity, floor.friction = 1, 0, [b.friction, 0.005, 1e-4]
        half_h = 0.5 * (contact[2] - self.floor_z + b.headroom)
        face = contact[0] + b.tip_radius + b.gap
        body = spec.worldbody.add_body(name="box", pos=[face + 0.5 * b.depth, contact[1], self.floor_z + half_h])
        body.mass, body.explicitinertial = b.mass, True
        body.ipos = [0, 0, 0]
        body.fullinertia = [b.mass / 12 * (b.width**2 + (2 * half_h) ** 2), b.mass / 12 * (b.depth**2 + (2 * half_h) ** 2),
                            b.mass / 12 * (b.depth**2 + b.width**2), 0, 0, 0]
        for ax, kind in (("x", 0), ("y", 1), ("z", 2)):
            body.add_joint(name=f"box_{ax}", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=np.eye(3)[kind])
        body.add_joint(name="box_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
        g = body.add_geom(name="box", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.5 * b.depth, 0.5 * b.width, half_h],
                          rgba=[0.75, 0.6, 0.4, 1])
        g.contype, g.conaffinity, g.condim, g.mass = 2, 3, 3, 0.0
        g.friction = [b.friction, 0.005, 1e-4]
        ee = spec.body(self.model.body(self.model.site_bodyid[self._site]).name)
        tip = ee.add_geom(name="tip", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[b.tip_radius, 0, 0],
                          pos=self.model.site_pos[self._site].copy(), rgba=[0.9, 0.3, 0.2, 1])
        tip.contype, tip.conaffinity, tip.condim, tip.mass, tip.priority = 2, 0, 1, 0.0, 1  # its condim: frictionless

    def reset(self, q0) -> None:
        """`MobilePlant.reset`, the box back at its start, and the samples emptied."""
        super().reset(q0)
        self.torques, self.box_x, self.tip_force = [], [], []

    def step(self, wheels, q_arm, dq_arm, duration: float) -> None:
        """`MobilePlant.step`, then one sample of the arm torques, the box position and the tip force."""
        super().step(wheels, q_arm, dq_arm, duration)
        d = self.data
        self.torques.append(d.qfrc_actuator[self._vadr[3:]].copy())
        self.box_x.append(d.xpos[self._box_body].copy())
        f, f6 = np.zeros(3), np.zeros(6)
        for i in range(d.ncon):
            c = d.contact[i]
            if {int(c.geom1), int(c.geom2)} == {self._tip, self._box_geom}:
                mujoco.mj_contactForce(self.model, d, i, f6)
                on_geom2 = c.frame.reshape(3, 3).T @ f6[:3]  # the contact force geom1 exerts on geom2, world frame
                f += on_geom2 if int(c.geom2) == self._box_geom else -on_geom2
        self.tip_force.append(f)
