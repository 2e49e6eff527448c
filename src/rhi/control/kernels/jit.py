"""The Numba decorator every rhi.control kernel uses."""

from numba import njit

from rhi import kernel_cache

kernel_cache.install()  # before the decorator: the cache refreshes when any kernel source changes

#: Compiled once per machine (cached on disk); floating-point errors give inf/NaN (checked by the caller), not exceptions.
jit = njit(cache=True, error_model="numpy")
