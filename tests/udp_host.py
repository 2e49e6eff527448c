"""A control-host process for the UDP tests: the palpation controller over UDPLink, in real time.

python tests/udp_host.py PORT DURATION
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from test_runtime import _scenario  # noqa: E402

import rhi  # noqa: E402
from rhi.runtime import SafetyConfig, run  # noqa: E402
from rhi.runtime.udp import UDPLink  # noqa: E402

dev = rhi.device("rhi4")
plant, ctrl, hand, wall, phys = _scenario(dev)
started = []


def progress(status):  # called from inside the loop: the host is really running
    if not started:
        started.append(print("host: running", flush=True))


res = run(UDPLink("127.0.0.1", int(sys.argv[1]), timeout=4e-4), ctrl, duration=float(sys.argv[2]), virtual=wall,
          safety=SafetyConfig(stale_ticks=20, silence=0.1, max_age=0.2, range_margin=0.3), progress=progress)
print("host:", res.fault, flush=True)
