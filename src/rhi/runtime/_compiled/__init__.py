"""The runtime's compiled kernels (Numba, private).

`bilateral_loop` (many ticks of `rhi.runtime.bilateral.simulate_bilateral` in one call). Imported on first use,
not with ``import rhi``.
"""
