"""Simulation: MuJoCo plants generated from the device descriptions, a simulated hand, environments.

Virtual and physical environments, teleoperation, and the 1 kHz simulation loop.
"""

from rhi.sim.environment import Fixture, Spring, Wall, compose, stop
from rhi.sim.hand import (
    DraggableHand,
    Hand,
    HandPath,
    HandSequence,
    MinimumJerkPalpation,
    PushForce,
    check_path_in_workspace,
    w_path,
)
from rhi.sim.log import Event, Log, LogWriter
from rhi.sim.loop import Session, simulate
from rhi.sim.mjcf import PlantFriction, build_mjcf, plant_spec
from rhi.sim.plant import Plant, PlantUnstable, device_friction
from rhi.sim.probe import Probe
from rhi.sim.telemetry import Telemetry
from rhi.sim.teleop import Teleoperation

__all__ = [
    "Event",
    "DraggableHand",
    "Fixture",
    "Hand",
    "Log",
    "LogWriter",
    "HandPath",
    "HandSequence",
    "MinimumJerkPalpation",
    "Plant",
    "PlantUnstable",
    "PlantFriction",
    "Probe",
    "PushForce",
    "Session",
    "Spring",
    "Teleoperation",
    "Telemetry",
    "Wall",
    "build_mjcf",
    "check_path_in_workspace",
    "compose",
    "device_friction",
    "plant_spec",
    "simulate",
    "stop",
    "w_path",
]
