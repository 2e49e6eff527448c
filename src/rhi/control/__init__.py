"""Control: secondary objectives (cost + analytic gradient) for null-space redundancy resolution."""

from rhi.control.objectives import Objective, VMEMatching

__all__ = ["Objective", "VMEMatching"]
