"""The device layer's compiled kernels (Numba, private).

`terms` (the task-space terms of one state and the small dense linear algebra every kernel shares),
`chain` (the chain's kinematics and dynamics), `batch` (batched kinematics). Imported on first use,
not with ``import rhi``.
"""
