"""The runtime over the UDP device protocol on loopback, for one second of device time.

A `DeviceServer` (the device side of docs/protocol.md; here the MuJoCo plant and a simulated hand,
as ``rhi device-server`` serves it) runs in a thread; the host runs the chapter-7 controller through a
`UDPLink` with `rhi.runtime.run`, behind the safety layer. In lock-step mode the run is exactly the
in-process simulation: the torques equal `rhi.sim.simulate`'s to 1e-9 N m.

Run: ``python examples/udp_runtime.py``. Needs the ``sim`` extra (MuJoCo).

Expected output (tests/test_examples.py checks every value to the tolerance given)::

    ticks = 1000 +- 0
    fault = 0 +- 0
    lost_datagrams = 0 +- 0
    max_torque_difference_to_simulate = 0.0 +- 1e-9
"""

import threading

import numpy as np

import rhi
from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
from rhi.runtime import SimLink, run
from rhi.runtime.server import DeviceServer
from rhi.runtime.udp import UDPLink
from rhi.sim import Hand, HandPath, Plant, Wall, simulate, stop

dev = rhi.device("rhi4")
Q0 = np.array([-0.63, 0.25, 0.28, 0.09])  # [rad]


def scenario():
    """Plant at Q0, the ch. 7 controller, a hand pushing 5 cm along +y, a 1000 N/m wall and a rigid stop."""
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    ctrl = NullSpaceController(dev, ControllerConfig(primary=ForceRendering(passivity=None), saturation="ascm"))
    hand = Hand(HandPath([x0, x0 + [0, 0.05]], speed=0.05))
    wall = Wall(x0 + [0, 0.01], normal=[0, 1], stiffness=1000.0)
    return plant, ctrl, hand, wall, stop(x0 + [0, 0.03], [0, 1])


# the device side: port 0 = any free port; lock-step = one reading per command (deterministic)
plant, _, hand, _, physical = scenario()
server = DeviceServer(SimLink(plant, hand=hand, physical=physical), dev, lockstep=True, exit_on_bye=True,
                      watchdog=2.0)
device_thread = threading.Thread(target=server.serve, daemon=True)
device_thread.start()

# the host side: the controller and the rendered wall, paced by the device (realtime=False)
_, ctrl, _, wall, _ = scenario()
link = UDPLink("127.0.0.1", server.port, timeout=1.0)
result = run(link, ctrl, duration=1.0, virtual=wall, realtime=False)
device_thread.join(timeout=10)

# the same scenario in one process
plant, ctrl, hand, wall, physical = scenario()
ref = simulate(plant, ctrl, duration=1.0, hand=hand, virtual=wall, physical=physical)

print(f"ticks = {result.summary['ticks']}")
print(f"fault = {0 if result.fault is None else 1}")
print(f"lost_datagrams = {link.stats['lost']}")
print(f"max_torque_difference_to_simulate = {np.abs(result.log.tau - ref.tau).max():.2e}")
