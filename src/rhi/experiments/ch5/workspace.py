"""Fig. 5.4: the workspaces of the RHI, the 2-DoF Rehab and the slave."""

from __future__ import annotations

import numpy as np

from rhi import thesis as T
from rhi.errors import InvalidInput, Unreachable
from rhi.experiments.arguments import checked
from rhi.experiments.ch3.measures import workspaces as sample
from rhi.experiments.ch5.setup import Q_FIXED, REHAB_SEED, SLAVE_SEED, devices, w_reference
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import positive
from rhi.sim import check_path_in_workspace


@checked
def workspaces(samples: int = 20000, seed: int = 0, cell: float = 0.02, area_samples: int = 300000) -> Result:
    """Fig. 5.4: workspaces of the RHI, the 2-DoF Rehab and the slave, and the W.

    Uniform samples of each device's joint box, kept where the linear (parallelogram)
    limits hold (`rhi.experiments.ch3.workspaces`). Areas are estimated by counting the
    `cell` × `cell` squares that `area_samples` samples occupy: a lower bound that grows
    with the sample count, slowly for the 4-DoF RHI whose edges are sparsely sampled
    (0.57 / 0.64 / 0.68 m² at 3·10⁴ / 10⁵ / 3·10⁵ samples; the 2-DoF devices converge).

    Args:
        samples: joint-space samples per device kept for the figure.
        seed: random seed.
        cell: grid cell for the area estimate [m].
        area_samples: joint-space samples per device for the area estimate (≥ samples).

    Returns:
        Result "ch5.workspaces" with arrays `workspaces` (3, samples, 2) [m] for RHI, Rehab, slave
        (NaN: rejected sample), `path` (the W's corners) and the table of areas.
    """
    if int(samples) < 1:
        raise InvalidInput(f"samples: must be >= 1, got {samples!r}")
    if int(area_samples) < int(samples):
        raise InvalidInput(f"area_samples: must be >= samples ({samples}), got {area_samples!r}")
    cell = positive("cell", cell)
    devs = devices()
    dense = sample(devs, int(area_samples), seed)
    pts = dense[:, : int(samples)]
    occupied = []
    for P in dense:
        P = P[np.all(np.isfinite(P), axis=1)]
        occupied.append({tuple(c) for c in np.floor(P / cell).astype(int).tolist()})
    area = [len(o) * cell**2 for o in occupied]
    inside = len(occupied[1] & occupied[0]) / max(1, len(occupied[1]))
    path = w_reference()
    reach = {}
    for name, dev in devs.items():
        try:
            check_path_in_workspace(dev, path, q0=dev.ik(path.points[0], {"RHI": Q_FIXED, "Rehab": REHAB_SEED,
                                                                          "slave": SLAVE_SEED}[name]), step=0.01)
            reach[name] = 1.0
        except Unreachable:
            reach[name] = 0.0
    rows = [Row(f"workspace area, {nm}", None, a, "m²",
                f"{cell * 100:g} cm cells occupied by {area_samples} samples (a lower bound)")
            for nm, a in zip(devs, area)]
    rows += [
        Row("RHI workspace larger than the Rehab's (1 = yes)", T.WORKSPACE_LARGER, float(area[0] > area[1]), "",
            "§5.4.1, Fig. 5.4"),
        Row("fraction of the Rehab's cells inside the RHI's", None, inside, "",
            "1 in exact arithmetic: the Rehab is the RHI with q3 = q4 = 0, inside its limits"),
    ]
    rows += [Row(f"W inside the workspace of the {nm} (1 = yes)", T.W_INSIDE, reach[nm], "") for nm in devs]
    return Result("ch5.workspaces", "Fig. 5.4: workspaces of the RHI, the 2-DoF Rehab and the slave",
                  [Table("Fig. 5.4 workspaces", rows)],
                  {"workspaces": pts, "path": path.points},
                  ["The thesis shows Fig. 5.4 as a figure only; the areas are ours.",
                   "workspaces[0], [1], [2]: " + ", ".join(devs) + "."])

