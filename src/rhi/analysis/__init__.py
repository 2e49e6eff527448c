"""Analysis of experiments: system identification, psychophysics and statistics.

- `rhi.analysis.sysid`: apparent mass and viscous friction along a direction from
  position/force records (thesis eqs. 3.24, 6.22; Tables 3.2, 6.1).
- `rhi.analysis.psychophysics`: the 2AFC constant-stimuli protocol of §3.5 and
  psychometric fits with psignifit: PSE, JND, WF (eqs. 3.25, 3.26; Table 3.3).
- `rhi.analysis.stats`: one-way and repeated-measures ANOVA, paired t-tests with
  Holm-Bonferroni (§3.6) or FDR (Table 5.2) adjustment.

The submodules import their heavy dependencies (psignifit, statsmodels) lazily.
"""

from rhi.analysis import psychophysics, stats, sysid

__all__ = ["psychophysics", "stats", "sysid"]
