"""Global performance indices over a sampled workspace: GM, GC (eqs. 4.8, 4.10) and GM_T (eq. 4.18).

The local indices are `rhi.metrics` functions evaluated on the joint-limit-penalized
Jacobian ``J^q`` of eqs. 4.19–4.20 (``k_q=None`` turns the penalty off). Samples the
device cannot reach (failed IK, outside the joint limits) contribute a local index of 0:
a design that does not cover the slave workspace is penalised in proportion to the
uncovered area, and `coverage` reports the reached fraction.
"""

from __future__ import annotations

import numpy as np

from rhi.errors import InvalidInput, Unreachable
from rhi.metrics import global_index, isotropy, manipulability, penalized_jacobian, tmi


def penalize(J: np.ndarray, q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray, k_q: float | None) -> np.ndarray:
    """``J^q`` of eq. 4.19 for J: (N, m, n), q: (N, n); J itself if k_q is None.

    Joints with an infinite range are not penalised.
    """
    if k_q is None:
        return J
    finite = np.isfinite(q_min) & np.isfinite(q_max)
    lo = np.where(finite, q_min, -1.0)
    hi = np.where(finite, q_max, 1.0)
    qq = np.where(finite, np.clip(q, lo, hi), 0.0)
    Jq = penalized_jacobian(J, qq, q_min=lo, q_max=hi, k_q=k_q)
    return np.where(finite[None, None, :], Jq, J)


def _masked_global(values: np.ndarray, ok: np.ndarray, weights: np.ndarray) -> float:
    return float(global_index(np.where(ok, values, 0.0), weights))


def device_indices(J: np.ndarray, ok: np.ndarray, weights: np.ndarray) -> dict[str, float]:
    """GM (eq. 4.8) and GC (eq. 4.10) of one device over the samples.

    Args:
        J: (N, m, n) (penalized) Jacobians at the N samples; rows where ``ok`` is False are ignored.
        ok: (N,) whether the sample was reached.
        weights: (N,) area weights [m²].

    Returns:
        {"GM": ∫μ/∫1, "GC": ∫(1/κ)/∫1, "coverage": reached area fraction}.

    Raises:
        Unreachable: no sample was reached.
    """
    ok = np.asarray(ok, dtype=bool)
    if not ok.any():
        raise Unreachable("workspace: inverse kinematics failed at every workspace sample")
    Jc = np.where(ok[:, None, None], J, 0.0)
    return {
        "GM": _masked_global(manipulability(Jc), ok, weights),
        "GC": _masked_global(isotropy(Jc), ok, weights),
        "coverage": float(np.sum(weights[ok]) / np.sum(weights)),
    }


def teleoperation_index(J_master: np.ndarray, J_slave: np.ndarray, ok: np.ndarray, weights: np.ndarray) -> float:
    """GM_T of eq. 4.18: the workspace mean of the TMI λ (eq. 4.17) of a master–slave pair.

    Args:
        J_master: (N, m, n_M) master Jacobians already in the task frame (H J_M of eq. 4.26).
        J_slave: (N, m, n_S) slave Jacobians.
        ok: (N,) whether both robots reached the sample.
        weights: (N,) area weights [m²].
    """
    ok = np.asarray(ok, dtype=bool)
    if not ok.any():
        raise Unreachable("workspace: inverse kinematics failed at every workspace sample")
    if J_master.shape[:-1] != J_slave.shape[:-1]:
        raise InvalidInput(f"J_master/J_slave: shapes {J_master.shape} and {J_slave.shape} do not match")
    lam = tmi(np.where(ok[:, None, None], J_master, 0.0), np.where(ok[:, None, None], J_slave, 0.0))
    return _masked_global(lam, ok, weights)
