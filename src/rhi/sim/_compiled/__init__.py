"""The simulation's compiled kernels (Numba, private).

`io` (sensors and the log row), `handle` (the handle's
kinematics, the virtual environment, a control period of the hand and the physical wall) and `fast_loop`
(many ticks of `rhi.sim.simulate` in one call). Imported on first use, not with ``import rhi``.
"""
