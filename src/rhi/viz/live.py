"""A live demonstration: a simulated device at 1 kHz in real time, watched and pushed in the browser.

The device (`rhi.sim.Plant` behind `rhi.runtime.SimLink`) runs the thesis's chapter-7
controller — force rendering of a stiff wall, ASO-switched FME matching, ASCM, VME
tertiary objective — in `rhi.runtime.run` on the calling thread; the view runs beside it
in its own process (`RemoteView`) and the user's mouse is the hand (`SharedDraggableHand`): drag the
gizmo into the wall and watch the force ellipsoid, the torque bars saturate and the null-space
reconfiguration.
"""

from __future__ import annotations

import numpy as np

from rhi._validate import as_array
from rhi.control import (
    ControllerConfig,
    FMESchedule,
    ForceRendering,
    NullSpaceController,
    ObjectiveTerm,
    VMEMatching,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.control.schedule import schedule_of
from rhi.devices.mobile_base import BASE_JOINTS
from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.runtime import SafetyConfig, SimLink, run
from rhi.sim import Plant, Wall
from rhi.viz.posed import rest_configuration


def demo_setup(dev: Device, q0=None) -> tuple[Plant, NullSpaceController, Wall, np.ndarray]:
    """Plant at q0 (default: `rest_configuration`), the ch7 controller and a 1000 N/m wall.

    The wall is 1 cm beyond the handle along the task's second axis. Returns (plant, controller, wall, q0).
    """
    if tuple(dev.joint_names[:3]) == BASE_JOINTS:
        raise InvalidInput(f"device: {dev.name} is velocity-commanded (App. A/B); the live demo needs a "
                           "torque-controlled device")
    q0 = rest_configuration(dev) if q0 is None else as_array("q0", q0, shape_tail=(dev.n,))
    if q0.ndim != 1 or np.any(q0 < dev.q_min) or np.any(q0 > dev.q_max):
        raise InvalidInput(f"q0: expected {dev.n} joint coordinates within the joint ranges, got {q0.tolist()}")
    u = np.eye(dev.m)[min(1, dev.m - 1)]
    K, z = fme_shape(dev.jacobian(q0), dev.torque_max, 5.0)
    cfg = ControllerConfig(
        ForceRendering(damping=0.01),
        objectives=(ObjectiveTerm(VMEMatching(tuple(u), 0.01), 0.5),
                    ObjectiveTerm(FMESchedule(desired_fme_free(u, K, z), desired_fme_stiff(u, K, z)), 20.0)),
        damping=0.1,
        saturation="ascm",
    )
    plant = Plant(dev)
    plant.reset(q0)
    return plant, NullSpaceController(dev, cfg), Wall(dev.fk(q0) + 0.01 * u, u, 1000.0), q0


def live(dev: Device, *, duration: float | None = 3600.0, host: str = "127.0.0.1", port: int = 8080,
         on_start=None, q0=None, say=print, safety: SafetyConfig | None = None) -> list:
    """Run the demo in real time with the browser view until `duration` [s] or Ctrl-C (the runtime's e-stop).

    A fault is shown in the page and on the terminal, and the page's reset button restarts the demo
    from q0 with the safety layer re-armed; the page's pause button stops and resumes it
    (`rhi.viz.session.supervise`). The page says "warming up" while the controller's kernels load.

    Args:
        dev: a torque-controlled device (rhi4, planar3r, phantom, gen3, a user URDF...).
        duration: run time [s] over all restarts; None: until Ctrl-C.
        host: the address the view listens on.
        port: the port the view listens on.
        on_start: called with the `RemoteView` once it serves (e.g. to print its address).
        q0: (n,) start configuration [rad] (default: `rest_configuration`, non-singular).
        say: where the session's lines go (faults, resets).
        safety: the safety layer's limits (default: `SafetyConfig(range_margin=0.3)`).

    Returns:
        The runtime's `RunResult` of every run (one per start, pause or reset).
    """
    from rhi.viz.remote import RemoteView, SharedDraggableHand
    from rhi.viz.session import supervise

    plant, ctrl, wall, q0 = demo_setup(dev, q0)
    hand = SharedDraggableHand(dev.m)
    view = RemoteView(dev, hand=hand, virtual=wall, fme=schedule_of(ctrl.config.objectives), q0=q0, host=host, port=port)
    links = [SimLink(plant, hand=hand)]
    try:
        if on_start is not None:
            on_start(view)
        view.commands.set_status("warming up: loading the controller's compiled kernels …")
        say("rhi view: warming up (the first start compiles the kernels: up to a minute or two) …")
        ctrl.warmup()
        say("rhi view: live")

        def restart() -> None:
            hand.target = None
            plant.reset(q0)
            ctrl.reset()
            links[0] = SimLink(plant, hand=hand)

        return supervise(
            lambda guard, left: run(links[0], ctrl, duration=left, virtual=wall, telemetry=view.telemetry,
                                    safety=guard),
            view.commands, dev, restart, config=safety or SafetyConfig(range_margin=0.3), duration=duration, say=say)
    finally:
        view.close()
