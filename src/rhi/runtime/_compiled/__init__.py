"""The runtime's compiled kernels (Numba, private).

`bilateral_loop` (many ticks of `rhi.runtime.bilateral.simulate_bilateral` in one call), `bilateral` (its
Python side: the state in and out, whether a run applies), `tdpa` (the TDPA's port controllers), `step`
(`rhi.runtime.run`'s step in one call). Imported on first use, not with ``import rhi``.
"""
