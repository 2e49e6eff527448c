"""A device process for the UDP tests: the palpation scenario of test_runtime behind `DeviceServer`.

python tests/udp_device.py PORTFILE [--lockstep] [--drop A B] [--reorder T] [--log PATH] [--duration S] [--spin]
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from test_runtime import Q0, _scenario  # noqa: E402

import rhi  # noqa: E402
from rhi.runtime import SimLink  # noqa: E402
from rhi.runtime.server import DeviceServer  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("portfile")
ap.add_argument("--lockstep", action="store_true")
ap.add_argument("--drop", type=float, nargs=2)
ap.add_argument("--reorder", type=float)
ap.add_argument("--log")
ap.add_argument("--duration", type=float)
ap.add_argument("--exit-on-bye", action="store_true")
ap.add_argument("--watchdog", type=float, default=0.02)
ap.add_argument("--spin", action="store_true")
a = ap.parse_args()
dev = rhi.device("rhi4")
plant, ctrl, hand, wall, phys = _scenario(dev)
srv = DeviceServer(SimLink(plant, hand=hand, physical=phys), dev, lockstep=a.lockstep, drop=a.drop,
                   reorder_at=a.reorder, log=a.log, exit_on_bye=a.exit_on_bye, watchdog=a.watchdog, spin=a.spin)
signal.signal(signal.SIGTERM, lambda *_: srv.stop())
Path(a.portfile).write_text(str(srv.port))
print(srv.serve(a.duration), flush=True)
assert np.all(Q0)  # keep the import used
