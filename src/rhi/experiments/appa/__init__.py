"""Appendix A: motion distribution by a weighting matrix and force-exertion reconfiguration of the WMM.

Table A.1, Figs. A.5–A.6 and the DM enhancement of §A.4.3 (Figs. A.7, A.9), kinematic control on the plant or
kinematic (`rhi.experiments.appa.kinematic`); Fig. A.8's box push on the MuJoCo plant with a box that slides
on the floor (`rhi.experiments.appa.push`).
"""

from rhi.experiments.appa.kinematic import (
    CM,
    DEG,
    PUSH_LIMITS,
    PUSH_NORM,
    Q0,
    dm_enhancement,
    dm_enhancement_plan,
    dm_run,
    dm_supremum,
    slip_note,
    tracking,
)
from rhi.experiments.appa.push import box_push, box_push_plan

__all__ = ["CM", "DEG", "PUSH_LIMITS", "PUSH_NORM", "Q0", "box_push", "box_push_plan", "dm_enhancement",
           "dm_enhancement_plan", "dm_run", "dm_supremum", "slip_note", "tracking"]
