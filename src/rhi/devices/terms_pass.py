"""One pass of `Device.terms`: a device's constant maps and the pass that fills a `DeviceTerms`.

`fast_maps` builds once per device what every pass reuses (`FastMaps`: the task rows, the actuation map's
transpose, the support mask of one-DoF joints, the compiled kernel and its output layout). A pass is then
`compiled_terms` (trees of revolute/prismatic joints: `rhi.devices._compiled.chain` computes Pinocchio's
terms too; other chains of one-DoF joints: Pinocchio, then `rhi.devices._compiled.terms.task_terms` writes
every term, the task-space dynamics included, into one buffer) or `pinocchio_terms` (a joint that is not
one-DoF: Pinocchio's algorithms, the task-space dynamics on first access).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from rhi.devices.terms import DeviceModel, DeviceTerms, layout

#: one-DoF joints whose kinematic Hessian has the closed form used by `Device.terms`
ONE_DOF_JOINT = re.compile(r"JointModel(R[XYZ]|P[XYZ]|RevoluteUnaligned|PrismaticUnaligned|Helical\w*)$")

@dataclasses.dataclass(frozen=True)
class FastMaps:
    """Constant maps and flags of `Device.terms` (built once per device by `fast_maps`)."""

    rows: slice | np.ndarray
    offset: bool
    identity: bool
    At: np.ndarray
    armature: np.ndarray
    tril: tuple[np.ndarray, np.ndarray]
    crba_symmetric: bool
    rows_idx: np.ndarray  # (m,) int64 task rows of the 6-D frame Jacobian
    supports: np.ndarray | None  # (nθ, nθ) bool: chain joint k supports joint j (or is j); None: not all one-DoF
    kernel: Callable | None  # _compiled.chain.chain_terms (with `chain`), else _compiled.terms.task_terms, else None
    chain: tuple[np.ndarray, ...] | None  # rhi.devices.batch.pack constants: trees of revolute/prismatic joints
    layout: dict[str, tuple[int, int, tuple[int, ...]]]  # where each term lies in the kernel's output
    position_layout: dict[str, tuple[int, int, tuple[int, ...]]]  # the same without the velocity terms
    size: int  # length of the kernel's output



def fast_maps(model: pin.Model, frame_id: int, A: np.ndarray, b: np.ndarray, armature: np.ndarray,
              rows: list[int]) -> FastMaps:
    """The constant maps and flags of `Device.terms` for a chain model with actuation map θ = A q + b.

    Args:
        model: Pinocchio model of the chain (nv = nθ).
        frame_id: end-effector frame id in `model`.
        A: (nθ, n) actuation map.
        b: (nθ,) actuation offset.
        armature: (n,) rotor inertia [kg m²].
        rows: world-axis indices of the task coordinates (m of them).
    """
    nt, n, m = model.nv, A.shape[1], len(rows)
    rows_idx = slice(rows[0], rows[-1] + 1) if rows == list(range(rows[0], rows[-1] + 1)) else np.array(rows)
    data = model.createData()
    th = np.random.default_rng(0).uniform(-1.0, 1.0, nt)
    Mt = pin.crba(model, data, th)
    mask = hessian_mask(model)
    from rhi.devices import batch  # Numba: imported on the first `Device.terms`, not with `import rhi`
    from rhi.devices._compiled import chain as chain_kernel, terms as terms_kernel

    where, _, size = layout(n, m)
    chain = batch.pack(model, frame_id) if mask is not None and batch.supported(model) else None
    return FastMaps(
        rows=rows_idx,
        offset=bool(np.any(b != 0)),
        identity=A.shape == (nt, nt) and bool(np.array_equal(A, np.eye(nt))),
        At=np.ascontiguousarray(A.T),
        armature=np.diag(armature),
        tril=np.tril_indices(nt, -1),
        crba_symmetric=bool(np.array_equal(Mt, Mt.T)) and bool(np.any(np.tril(Mt, -1) != 0) or nt == 1),
        rows_idx=np.array(rows, dtype=np.int64),
        supports=mask,
        kernel=None if mask is None else chain_kernel.chain_terms if chain is not None else terms_kernel.task_terms,
        chain=chain,
        layout=where,
        position_layout={k: v for k, v in where.items() if k not in ("xdot", "Jdot", "C", "Cx")},
        size=size,
    )


def compiled_terms(device: DeviceModel, fast: FastMaps, kernel: Callable, q: np.ndarray, dq: np.ndarray | None,
                   th: np.ndarray) -> DeviceTerms:
    """Every term of one state, the task-space dynamics included, from compiled kernels.

    Trees of revolute/prismatic joints (``fast.chain``): one `rhi.devices._compiled.chain.chain_terms` call
    computes Pinocchio's terms too; other one-DoF joints: Pinocchio's algorithms, then
    `rhi.devices._compiled.terms.task_terms`.

    Args:
        device: the device.
        fast: its `FastMaps`.
        kernel: ``fast.kernel``.
        q: (n,) joint positions [rad or m].
        dq: (n,) joint velocities [rad/s], or None.
        th: (nθ,) chain coordinates θ = A q + b.
    """
    v = np.zeros(device.n) if dq is None else np.ascontiguousarray(dq, dtype=float)
    buf = np.empty(fast.size)
    if fast.chain is not None:
        x = np.empty(fast.rows_idx.shape[0])
        kernel(*fast.chain, th, device.A, fast.rows_idx, device.armature, fast.supports, fast.identity, v, x, buf)
    else:
        model, data, fid = device.model, device.data, device.ee_frame_id
        pin.computeJointJacobians(model, data, th)
        J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        x = data.oMf[fid].translation[fast.rows].copy()
        Ct = pin.computeCoriolisMatrix(model, data, th, device.A.dot(v))
        kernel(J6, pin.crba(model, data, th), pin.computeGeneralizedGravity(model, data, th), Ct, device.A,
                    fast.rows_idx, device.armature, fast.supports, fast.identity, not fast.crba_symmetric, v, buf)
    return DeviceTerms.from_buffer(device, q, dq, x, th, buf, fast.position_layout if dq is None else fast.layout)



def pinocchio_terms(device: DeviceModel, fast: FastMaps, q: np.ndarray, dq: np.ndarray | None,
                    th: np.ndarray) -> DeviceTerms:
    """The eager terms of one state from Pinocchio's algorithms (a chain with a joint that is not one-DoF).

    One `computeJointJacobians` (forward kinematics + joint Jacobians), the frame Jacobian, `crba` and
    `computeGeneralizedGravity`; ∂J/∂q from `jacobian_derivative_theta`.

    Args:
        device: the device.
        fast: its `FastMaps`.
        q: (n,) joint positions [rad or m].
        dq: (n,) joint velocities [rad/s], or None.
        th: (nθ,) chain coordinates θ = A q + b.
    """
    model, data, fid = device.model, device.data, device.ee_frame_id
    pin.computeJointJacobians(model, data, th)
    J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    x = data.oMf[fid].translation[fast.rows].copy()
    Mt = pin.crba(model, data, th)
    if not fast.crba_symmetric:
        il = fast.tril
        Mt[il] = Mt.T[il]  # this Pinocchio fills only the upper triangle
    gt = pin.computeGeneralizedGravity(model, data, th)
    if fast.identity:
        J = J6[fast.rows].copy()
        M = Mt + fast.armature
        g = gt.copy()
    else:
        At = fast.At
        J = J6[fast.rows].dot(device.A)
        M = At.dot(Mt).dot(device.A) + fast.armature
        g = At.dot(gt)
    return DeviceTerms(device, q, dq, x=x, J=J, dJ=device.jacobian_derivative_theta(th), M=M, g=g, theta=th)


def hessian_mask(model: pin.Model) -> np.ndarray | None:
    """(nθ, nθ) bool, [j, k]: joint k supports joint j (or is j); None if a joint is not one-DoF."""
    if model.njoints - 1 != model.nv:
        return None
    vidx = {}
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        if jm.nv != 1 or jm.nq != 1 or not ONE_DOF_JOINT.match(jm.shortname()):
            return None
        vidx[jid] = jm.idx_v
    mask = np.zeros((model.nv, model.nv), bool)
    for jid, j in vidx.items():
        for kid in model.supports[jid]:
            if kid in vidx:
                mask[j, vidx[kid]] = True
    return mask


__all__ = ["ONE_DOF_JOINT", "FastMaps", "compiled_terms", "fast_maps", "hessian_mask", "pinocchio_terms"]
