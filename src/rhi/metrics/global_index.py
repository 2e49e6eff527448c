"""Workspace-averaged (global) versions of local performance indices."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import as_array
from rhi.errors import InvalidInput
from rhi.metrics._common import FloatArray


def global_index(values: ArrayLike, weights: ArrayLike | None = None) -> FloatArray:
    """Global index ``∫_W v dW / ∫_W dW`` over workspace samples (thesis eqs. 4.8, 4.10, 4.18).

    A weighted mean along axis 0, the weights being the workspace element (area or
    volume) each sample stands for: GM from μ, GC from 1/κ, GM_T from the TMI.

    Args:
        values: (N, ...) local index at N workspace samples, all finite.
        weights: (N,) non-negative sample weights [m² or m³] with a positive sum, or None
            for uniform weights (a regular grid).

    Returns:
        (...) the weighted mean over the samples (a 0-d array for 1-D ``values``).

    Raises:
        InvalidInput: no samples, non-finite values, or weights of the wrong shape,
            with a negative entry or a zero sum.
    """
    v = as_array("values", values, ndim_min=1)
    if v.shape[0] == 0:
        raise InvalidInput("values: no samples (axis 0 has length 0)")
    if weights is None:
        return np.asarray(np.mean(v, axis=0))
    w = as_array("weights", weights, ndim_min=1)
    if w.shape != (v.shape[0],):
        raise InvalidInput(f"weights: expected shape ({v.shape[0]},) to match values, got {w.shape}")
    if np.any(w < 0):
        raise InvalidInput("weights: must be non-negative")
    total = np.sum(w)
    if not total > 0:
        raise InvalidInput("weights: sum to zero")
    return np.asarray(np.tensordot(w, v, axes=(0, 0)) / total)
