"""Simulation: MuJoCo plants generated from the device descriptions, a simulated hand,
virtual and physical environments, teleoperation, and the 1 kHz simulation loop."""

from rhi.sim.environment import Fixture, Spring, Wall, compose, stop
from rhi.sim.hand import Hand, Path, PushForce, check_path_in_workspace, w_path
from rhi.sim.loop import Log, simulate
from rhi.sim.mjcf import PlantFriction, build_mjcf
from rhi.sim.plant import Plant, device_friction
from rhi.sim.teleop import Teleoperation

__all__ = [
    "Fixture",
    "Hand",
    "Log",
    "Path",
    "Plant",
    "PlantFriction",
    "PushForce",
    "Spring",
    "Teleoperation",
    "Wall",
    "build_mjcf",
    "check_path_in_workspace",
    "compose",
    "device_friction",
    "simulate",
    "stop",
    "w_path",
]
