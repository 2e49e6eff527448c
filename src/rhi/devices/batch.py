"""Batch kinematics and dynamics: x, J, ∂J/∂q, M and g for many configurations at once.

Spatial algebra built from a Pinocchio model's joint placements, axes and inertias, for
kinematic trees of one-DoF revolute and prismatic joints (every bundled device, Panda,
UR5, Kinova Gen3, mobile bases on prismatic joints, ...). It computes what `Device.fk`,
`jacobian`, `jacobian_derivative`, `mass_matrix` and `gravity` compute with Pinocchio one
configuration at a time, equal to ~1e-14 relative and about a hundred times faster than a
loop of Pinocchio calls for 10⁴ configurations: `BatchChain` packs the model's constants
once and the compiled loop of `rhi.devices._compiled.batch` writes every configuration's terms into
batch-first arrays. `Device` calls it for batches of at least `rhi.devices.model.BATCH_MIN`
configurations. With chain coordinates θ = A q + b:

* forward kinematics: R_j = R_p(j) P_j Rot(a_j, θ_j), o_j = o_p(j) + R_p(j) t_j (+ θ_j R_j a_j
  for a prismatic joint); the world joint axis is ω_j = R_j a_j;
* joint spatial axes about the world origin S_j = (ω_j, o_j × ω_j) (revolute) or (0, ω_j) (prismatic);
* Jacobian of the end-effector point p: J_j = S_v,j + S_ω,j × p on the path to the frame;
  J_q = J_θ A (thesis eq. 3.1 with the transmission map of §3.5);
* ∂J_j/∂θ_k = ω_min(j,k) × J_max(j,k) along the path (the Hessian of the position, symmetric);
* composite-rigid-body mass matrix M_jk = S_jᵀ I^c_k S_k for j supporting k, with the subtree
  inertia I^c_k about the world origin, plus Pinocchio's armature; M_q = Aᵀ M_θ A + diag(armature);
* gravity g_j = −S_jᵀ (h_j × g₀, m_j g₀) from the subtree mass m_j and first moment h_j.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from rhi._validate import float_array
from rhi.errors import InvalidInput, ModelError

_AXIS = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
_EPS = 1e-14  # model constants this close to 0 or ±1 are taken as exact


# --------------------------------------------------------------- the model
def joint_axis(jm) -> tuple[bool, np.ndarray] | None:
    """(revolute?, unit axis in the joint frame) of a one-DoF joint model, None if not supported."""
    name = jm.shortname()
    if jm.nq != 1 or jm.nv != 1:
        return None
    if name in ("JointModelRX", "JointModelRY", "JointModelRZ"):
        return True, np.array(_AXIS[name[-1]])
    if name in ("JointModelPX", "JointModelPY", "JointModelPZ"):
        return False, np.array(_AXIS[name[-1]])
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        a = np.asarray(jm.extract().axis, dtype=float)
        return name.startswith("JointModelRevolute"), a / np.linalg.norm(a)
    return None


def supported(model: pin.Model) -> bool:
    """Whether `BatchChain` handles `model`: every joint revolute or prismatic with one DoF."""
    if model.njoints - 1 != model.nv:
        return False
    return all(joint_axis(model.joints[j]) is not None and model.joints[j].idx_v == j - 1
               for j in range(1, model.njoints))


#: per-joint constant columns of `pack`'s float array: placement rotation (9), translation (3),
#: joint axis (3), body mass (1), centre of mass (3), rotational inertia about it (9), armature (1)
_P, _T, _AX, _MASS, _COM, _ROT, _ARM, _WIDTH = 0, 9, 12, 15, 16, 19, 28, 29
#: where a joint's axis starts in `pack`'s rows, for the kernels of other packages (the hand, the mobile base)
AXIS_COLUMN = _AX


def pack(model: pin.Model, frame_id: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The constants of the compiled chain kernels (`chain_terms`) for a `supported` model and its end-effector frame.

    Raises:
        ModelError: a joint of `model` is not one-DoF revolute or prismatic.

    Returns:
        ints (2 nθ + 1,) int64: parent chain index of each joint (−1: the world), revolute flags,
            then the chain index of the frame's joint (−1: the world);
        joints (nθ, 29) float: per-joint constants in the columns described above (SI units);
        frame (15,) float: frame placement rotation (9) and translation (3) in its joint, gravity g₀ (3) [m/s²].
    """
    nt = model.nv
    ints = np.empty(2 * nt + 1, dtype=np.int64)
    joints = np.empty((nt, _WIDTH))
    for j in range(nt):
        joint = joint_axis(model.joints[j + 1])
        if joint is None:
            raise ModelError(f"model: joint {j + 1} is not a one-DoF revolute/prismatic joint")
        revolute, axis = joint
        ints[j], ints[nt + j] = model.parents[j + 1] - 1, int(revolute)
        pl, inert = model.jointPlacements[j + 1], model.inertias[j + 1]
        joints[j, _P:_T], joints[j, _T:_AX], joints[j, _AX:_MASS] = pl.rotation.ravel(), pl.translation, axis
        joints[j, _MASS], joints[j, _COM:_ROT] = inert.mass, inert.lever
        joints[j, _ROT:_ARM], joints[j, _ARM] = inert.inertia.ravel(), model.armature[j]
    frame = model.frames[frame_id]
    ints[2 * nt] = frame.parentJoint - 1
    consts = np.concatenate([frame.placement.rotation.ravel(), frame.placement.translation, model.gravity.linear])
    return ints, joints, consts


def _exact(a: np.ndarray) -> np.ndarray:
    """A copy of model constants with round-off around 0 and ±1 removed (changes results by ~1e-17).

    The kernel skips products with exact zeros.
    """
    out = np.array(a, dtype=float)
    for v in (0.0, 1.0, -1.0):
        out[np.abs(out - v) < _EPS] = v
    return out


def _z_basis(a: np.ndarray) -> np.ndarray:
    """A rotation U with U e_z = a (exact for the coordinate axes)."""
    if abs(a[2]) > 1.0 - _EPS:
        return np.diag([1.0, math.copysign(1.0, a[2]), math.copysign(1.0, a[2])])
    x = np.cross([0.0, 0.0, 1.0], a) if abs(a[2]) < 0.9 else np.cross([1.0, 0.0, 0.0], a)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(a, x), a])


class BatchChain:
    """Batched kinematics and dynamics of one device (model, end-effector frame, actuation map).

    Args:
        model: Pinocchio model whose joints are all one-DoF revolute or prismatic (`supported`);
            it must not change afterwards.
        frame_id: end-effector frame id in `model`.
        rows: world axes (0: x, 1: y, 2: z) of the position task.
        A: (nθ, n) actuation map, θ = A q + b.
        armature: (n,) rotor inertia added to the diagonal of M_q [kg m²].

    Raises:
        ModelError: a joint of `model` is not supported.
    """

    def __init__(self, model: pin.Model, frame_id: int, *, rows, A: np.ndarray, armature: np.ndarray) -> None:
        if not supported(model):
            raise ModelError("model: batch kinematics needs one-DoF revolute/prismatic joints only")
        nt = model.nv
        A = np.ascontiguousarray(A, dtype=float)
        self.nt, self.n = nt, A.shape[1]
        self.rows = np.asarray(list(rows), dtype=np.int64)
        parent = np.array([model.parents[j] - 1 for j in range(1, nt + 1)], dtype=np.int64)
        axes = [joint_axis(model.joints[j]) for j in range(1, nt + 1)]
        revolute = np.array([ax is not None and ax[0] for ax in axes], dtype=bool)
        U = [_z_basis(ax[1]) for ax in axes if ax is not None]  # internal frames: z along the joint axis
        G, psi, t = np.empty((nt, 3, 3)), np.zeros(nt), np.empty((nt, 3))
        for j in range(nt):
            pl = model.jointPlacements[j + 1]
            Up = U[parent[j]] if parent[j] >= 0 else np.eye(3)
            G[j], t[j] = Up.T @ pl.rotation @ U[j], Up.T @ pl.translation
            if revolute[j] and abs(G[j, 2, 2] - 1.0) < _EPS:  # a rotation about z: fold it into the angle
                psi[j], G[j] = math.atan2(G[j, 1, 0], G[j, 0, 0]), np.eye(3)
        inert = [model.inertias[j] for j in range(1, nt + 1)]
        mass = np.array([I.mass for I in inert], dtype=float)
        lever = np.array([U[j].T @ inert[j].lever for j in range(nt)]).reshape(nt, 3)
        inertia = np.array([U[j].T @ inert[j].inertia @ U[j] for j in range(nt)]).reshape(nt, 3, 3)
        sup = np.zeros((nt, nt), dtype=bool)  # [j, k]: joint j supports joint k (or is k)
        for k in range(1, nt + 1):
            for j in model.supports[k]:
                if j > 0:
                    sup[j - 1, k - 1] = True
        frame = model.frames[frame_id]
        fj = frame.parentJoint - 1
        ft = U[fj].T @ frame.placement.translation if fj >= 0 else np.array(frame.placement.translation)
        self._consts = (
            parent, revolute, _exact(G), psi, _exact(t), mass, _exact(lever), _exact(inertia), sup @ mass,
            np.array(model.armature, dtype=float), int(fj), _exact(ft), _exact(np.array(model.gravity.linear)),
            sup, sup[:, fj].copy() if fj >= 0 else np.zeros(nt, dtype=bool),
            _exact(A), bool(A.shape == (nt, nt) and np.array_equal(A, np.eye(nt))), self.rows,
            np.array(armature, dtype=float),
        )

    def evaluate(self, theta: np.ndarray, what: tuple[str, ...]) -> dict[str, np.ndarray]:
        """The requested terms for a batch of chain configurations.

        Args:
            theta: (..., nθ) chain coordinates θ = A q + b [rad or m].
            what: names among "x" (..., m) [m], "J" (..., m, n) [m/rad], "dJ" (..., m, n, n)
                with [..., i, j, k] = ∂J_ij/∂q_k [m/rad²], "M" (..., n, n) [kg m²] and "g" (..., n) [N m].

        Returns:
            {name: array} in motor coordinates q, batch axes first, C-contiguous.

        Raises:
            InvalidInput: theta is not a finite (..., nθ) array, or a name in `what` is unknown.
        """
        from rhi.devices._compiled.batch import evaluate  # Numba: imported on the first batched call, not with `import rhi`

        if not what or any(k not in TERMS for k in what):
            raise InvalidInput(f"what: expected names among {list(TERMS)}, got {list(what)!r}")
        theta = float_array("theta", theta)
        if theta.ndim == 0 or theta.shape[-1] != self.nt:
            raise InvalidInput(f"theta: expected shape (..., {self.nt}), got {theta.shape}")
        if not np.isfinite(theta).all():  # not rhi._validate.all_finite: its BLAS dot, threaded, stalls on busy cores
            raise InvalidInput("theta: contains NaN or inf")
        lead = theta.shape[:-1]
        th = np.ascontiguousarray(theta).reshape(-1, self.nt)
        B, m, n = th.shape[0], len(self.rows), self.n
        shapes = {"x": (m,), "J": (m, n), "dJ": (m, n, n), "M": (1, n, n), "g": (1, n)}
        out = {k: np.empty((B,) + shape) if k in what else np.empty((0,) * (1 + len(shape)))
               for k, shape in shapes.items()}
        evaluate(*self._consts, th, tuple(k in what for k in shapes), *out.values())
        shapes["M"], shapes["g"] = (n, n), (n,)
        return {k: out[k].reshape(lead + shapes[k]) for k in what}


#: The terms `terms` returns, and the `Device` method that computes each one configuration at a time.
TERMS = {"x": "fk", "J": "jacobian", "dJ": "jacobian_derivative", "M": "mass_matrix", "g": "gravity"}


def terms(device, q, what: tuple[str, ...] = ("J", "dJ", "M", "g")) -> dict[str, np.ndarray]:
    """Several terms of a batch of configurations of a `Device` from one compiled pass.

    `Device.jacobian(Q)`, `jacobian_derivative(Q)`, `mass_matrix(Q)` and `gravity(Q)` each run
    `BatchChain.evaluate` on their own, so asking for all four repeats the forward kinematics four
    times and the composite inertias twice; this runs the pass once. Same numbers as those methods.

    Args:
        device: an `rhi.devices.model.Device`.
        q: (..., n) motor positions [rad or m].
        what: names among "x" (..., m) [m], "J" (..., m, n), "dJ" (..., m, n, n), "M" (..., n, n) [kg m²]
            and "g" (..., n) [N m] (as `BatchChain.evaluate`).

    Returns:
        {name: array}, batch axes first; a device whose joints `rhi.devices.batch` does not support gets the
        `Device` methods' per-configuration results.

    Raises:
        InvalidInput: an unknown term name, or a bad q (named as `Device` does).
    """
    if not what or any(k not in TERMS for k in what):
        raise InvalidInput(f"what: expected names among {list(TERMS)}, got {list(what)!r}")
    th = device.theta(q)
    chain = device._batch
    if chain is None or th.ndim < 2:
        return {k: getattr(device, TERMS[k])(q) for k in what}
    return chain.evaluate(th, tuple(what))
