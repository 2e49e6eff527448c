"""The teleoperated slave of a path-following study (thesis §5.5): the robot whose end effector follows the path.

The participant moves the master (the haptic device of the condition); a simulated slave robot follows it by
unilateral teleoperation (`rhi.sim.Teleoperation`, §5.3): a Cartesian PD toward x_s,des = s x_m + p, with the
slave, its gains and the map (s, p) from the protocol's ``[teleoperation]``. The reference path lies in the
slave's workspace; the master starts where the map sends it onto the path's first point, the slave at that point.
A condition whose controller matches the teleoperation manipulability (eq. 5.11, `TMIMatching`) reads the
live slave's encoders instead of its configuration's fixed slave posture.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rhi.control import ControllerConfig, ObjectiveTerm, TMIMatching
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput, Unreachable
from rhi.runtime.schema import prefixed
from rhi.sim import HandPath, Plant, Teleoperation, w_path


def reference(protocol) -> HandPath:
    """The W path of a path-following task in the slave's frame (`rhi.sim.w_path`), at the task's speed."""
    t = protocol.task
    return w_path(np.asarray(t["center"]), width=t["width"], height=t["height"], speed=t["speed"])


def slave_device(protocol) -> Device:
    """The slave robot of the protocol's ``[teleoperation]``.

    Raises:
        InvalidInput: not a path-following task, or an unknown slave (naming ``teleoperation.slave``).
    """
    tele = protocol.teleoperation
    if tele is None:
        raise InvalidInput(f"protocol: {protocol.name} is a {protocol.kind} task, without a teleoperated slave")
    return prefixed("teleoperation.slave", device, tele["slave"], **tele["slave_params"])


def to_master(protocol, x_slave) -> np.ndarray:
    """The master position (m,) [m] the map sends onto the slave position `x_slave` (m,) [m]: (x_s − p) / s."""
    tele = protocol.teleoperation
    return (np.asarray(x_slave, float) - tele["offset"]) / tele["scale"]


def master_path(protocol) -> HandPath:
    """The reference path mapped into the master's frame (what a hand on the master traces), at speed v / s."""
    ref = reference(protocol)
    return HandPath(to_master(protocol, ref.points), ref.speed / protocol.teleoperation["scale"])


def teleoperation(protocol, slave: Device, *, timestep: float = 0.001) -> Teleoperation:
    """A fresh slave plant at the reference path's first point, following by the protocol's map and gains.

    Raises:
        Unreachable: the path's first point is outside the slave's workspace.
    """
    tele = protocol.teleoperation
    p0 = reference(protocol).points[0]
    try:
        q0 = slave.ik(p0, np.full(slave.n, 0.3))
    except Unreachable:
        raise Unreachable(f"task.center: the path's first point {np.round(p0, 4).tolist()} m is outside the "
                          f"workspace of the slave {slave.name}") from None
    plant = Plant(slave, friction="device", timestep=timestep)
    plant.reset(q0)
    return Teleoperation(plant, kp=tele["kp"], kd=tele["kd"], scale=tele["scale"], offset=tele["offset"])


def live_tmi(cfg: ControllerConfig, tele: Teleoperation) -> ControllerConfig:
    """`cfg` with each `TMIMatching` objective reading the live slave's encoders (the slave must be its model).

    Raises:
        InvalidInput: a TMI objective matching another slave robot than the teleoperated one.
    """
    terms = []
    for i, term in enumerate(cfg.objectives):
        o = term.objective
        if isinstance(o, TMIMatching):
            if o.slave.name != tele.slave.device.name or o.slave.n != tele.slave.device.n:
                raise InvalidInput(f"controller.objectives[{i}].slave: the TMI objective matches {o.slave.name}, but "
                                   f"the teleoperated slave is {tele.slave.device.name} (teleoperation.slave)")
            plant = tele.slave
            o = TMIMatching(o.slave, lambda plant=plant: plant.q, k_q=o.k_q, penalize_slave=o.penalize_slave, H=o.H)
            term = ObjectiveTerm(o, term.gain)
        terms.append(term)
    return dataclasses.replace(cfg, objectives=tuple(terms))


__all__ = ["live_tmi", "master_path", "reference", "slave_device", "teleoperation", "to_master"]
