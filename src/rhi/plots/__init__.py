"""Matplotlib figures drawn from experiment result objects (no computation here).

Importing or using `rhi.plots` never changes matplotlib's backend: the figures are drawn with
whatever backend is in force (the `rhi` command selects Agg for its own process, where
``MPLBACKEND`` is unset, because it only writes files).
"""
