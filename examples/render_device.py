"""An offscreen picture of the 4-DoF RHI at the thesis's optimised configuration (MuJoCo, MjSpec geometry).

The device stands on a light-grey checker floor; its links are coloured and its joints dark.

The picture is written as PNG. On a machine without a display MuJoCo needs ``MUJOCO_GL=egl`` or
``MUJOCO_GL=osmesa`` (rhi selects one where it is installed and ``MUJOCO_GL`` is unset); without any
OpenGL backend the example says so and stops (the test suite then skips it).

Run: ``python examples/render_device.py [OUT.png]``. Needs the ``sim`` extra (MuJoCo).

Expected output (tests/test_examples.py checks every value to the tolerance given)::

    height = 300 +- 0
    width = 400 +- 0
    channels = 3 +- 0
    device_pixels_percent = 3.1 +- 1.5
"""

import sys
import tempfile
from pathlib import Path

import rhi
from rhi.viz.render import RenderUnavailable, render, save_png

dev = rhi.device("rhi4")
try:
    image = render(dev, [0.125, 0.022, 0.298, 0.175], width=400, height=300)  # (300, 400, 3) uint8
except RenderUnavailable as exc:
    print(f"skipped: {exc}")
    sys.exit(0)
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp()) / "rhi4.png"
save_png(image, out)

rgb = image.astype(int)
device = (rgb.max(axis=-1) - rgb.min(axis=-1) > 40) | (rgb.max(axis=-1) < 90)  # coloured or dark: not the grey floor
print(f"height = {image.shape[0]}")
print(f"width = {image.shape[1]}")
print(f"channels = {image.shape[2]}")
print(f"device_pixels_percent = {100 * device.mean():.1f}")
