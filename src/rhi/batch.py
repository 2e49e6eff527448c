"""Batch kinematics and dynamics: x, J, ∂J/∂q, M and g for many configurations at once.

Vectorized spatial algebra built from a Pinocchio model's joint placements, axes and
inertias, for kinematic trees of one-DoF revolute and prismatic joints (every bundled
device, Panda, UR5, Kinova Gen3, mobile bases on prismatic joints, ...). It computes what
`Device.fk`, `jacobian`, `jacobian_derivative`, `mass_matrix` and `gravity` compute with
Pinocchio one configuration at a time, equal to ~1e-15 relative, tens of times faster for
10⁴ configurations. `Device` calls it for every batched input.

Every scalar is either a Python float (a constant of the model) or a (B,) array over the
batch, and every vector a 3-tuple of them: products with constant zeros and ones are
skipped, so planar devices cost a fraction of spatial ones, and every NumPy operation is
one contiguous loop over B values (no tiny stacked matrix products). Each joint gets an
internal frame F_j = R_j U_j whose z axis is the joint axis a_j (U_j constant), so a
revolute joint is a rotation about z by θ_j + ψ_j, ψ_j folding any z-rotation of its
placement. With chain coordinates θ = A q + b:

* forward kinematics: F_j = F_p(j) G_j Rot_z(θ_j + ψ_j), o_j = o_p(j) + F_p(j) t_j (+ θ_j F_j e_z
  for a prismatic joint); the world joint axis is ω_j = F_j e_z;
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
from typing import Any

import numpy as np
import pinocchio as pin

from rhi.errors import InvalidInput, ModelError

_AXIS = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
CHUNK = 8192  # configurations per pass: (B,) work arrays stay small enough for the allocator's heap
_EPS = 1e-14  # model constants this close to 0 or ±1 are taken as exact (changes results by ~1e-17)


# ------------------------------------------------------- scalar / vector algebra
def _c(v: float) -> float:
    """A model constant with round-off around 0 and ±1 removed."""
    v = float(v)
    for exact in (0.0, 1.0, -1.0):
        if abs(v - exact) < _EPS:
            return exact
    return v


def _zero(a) -> bool:
    return isinstance(a, float) and a == 0.0


def _mul(a, b):
    if _zero(a) or _zero(b):
        return 0.0
    if isinstance(a, float):
        return b if a == 1.0 else (-b if a == -1.0 else a * b)
    if isinstance(b, float):
        return a if b == 1.0 else (-a if b == -1.0 else a * b)
    return a * b


def _add(a, b):
    if _zero(a):
        return b
    if _zero(b):
        return a
    return a + b


def _sub(a, b):
    if _zero(b):
        return a
    if _zero(a):
        return -b
    return a - b


def _lin(coef, xs):
    """Σ coef_i x_i."""
    out = 0.0
    for c, x in zip(coef, xs):
        out = _add(out, _mul(c, x))
    return out


def _vadd(u, v):
    return tuple(_add(a, b) for a, b in zip(u, v))


def _vsub(u, v):
    return tuple(_sub(a, b) for a, b in zip(u, v))


def _vscale(s, u):
    return tuple(_mul(s, a) for a in u)


def _cross_i(u, v, i: int):
    """Component i of u × v."""
    y, z = (i + 1) % 3, (i + 2) % 3
    return _sub(_mul(u[y], v[z]), _mul(u[z], v[y]))


def _cross(u, v):
    return tuple(_cross_i(u, v, i) for i in range(3))


def _dot(u, v):
    return _lin(u, v)


def _matvec(F, x):
    """F x for F given by its 3 columns and a constant x (3,)."""
    return tuple(_lin(x, (F[0][r], F[1][r], F[2][r])) for r in range(3))


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


def _z_basis(a: np.ndarray) -> np.ndarray:
    """A rotation U with U e_z = a (exact for the coordinate axes)."""
    if abs(a[2]) > 1.0 - _EPS:
        return np.diag([1.0, math.copysign(1.0, a[2]), math.copysign(1.0, a[2])])
    x = np.cross([0.0, 0.0, 1.0], a) if abs(a[2]) < 0.9 else np.cross([1.0, 0.0, 0.0], a)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(a, x), a])


class BatchChain:
    """Vectorized kinematics and dynamics of one device (model, end-effector frame, actuation map).

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
        self.nt, self.n, self.rows = nt, A.shape[1], list(rows)
        self.A = [[_c(v) for v in row] for row in np.asarray(A, dtype=float)]
        self.armature_q = [float(v) for v in armature]
        self.armature_t = [float(v) for v in model.armature]
        self.parent = [model.parents[j] - 1 for j in range(1, nt + 1)]
        self.revolute, U = [], []
        for j in range(nt):
            axis = joint_axis(model.joints[j + 1])
            if axis is None:  # supported() checked every joint
                raise ModelError(f"model: joint {j + 1} is not a one-DoF revolute/prismatic joint")
            rev, a = axis
            self.revolute.append(rev)
            U.append(_z_basis(a))
        self.G: list[Any] = []
        self.psi: list[float] = []
        self.t: list[Any] = []
        for j in range(nt):
            pl = model.jointPlacements[j + 1]
            Up = U[self.parent[j]] if self.parent[j] >= 0 else np.eye(3)
            G = Up.T @ pl.rotation @ U[j]
            psi = 0.0
            if self.revolute[j] and abs(G[2, 2] - 1.0) < _EPS:  # a rotation about z: fold it into the angle
                psi, G = math.atan2(G[1, 0], G[0, 0]), None
            self.psi.append(psi)
            self.G.append(None if G is None or np.allclose(G, np.eye(3), atol=_EPS, rtol=0) else
                          [[_c(v) for v in row] for row in G])
            self.t.append([_c(v) for v in Up.T @ pl.translation])
        # T[k][i]: joint k supports joint i (body i belongs to the subtree of k)
        self.supports = [[False] * nt for _ in range(nt)]
        for i in range(1, nt + 1):
            for k in model.supports[i]:
                if k > 0:
                    self.supports[k - 1][i - 1] = True
        inert = [model.inertias[j] for j in range(1, nt + 1)]
        self.mass = [float(I.mass) for I in inert]
        self.lever = [[_c(v) for v in U[j].T @ inert[j].lever] for j in range(nt)]
        self.inertia = [[[_c(v) for v in row] for row in U[j].T @ inert[j].inertia @ U[j]] for j in range(nt)]
        self.mass_c = [sum(self.mass[i] for i in range(nt) if self.supports[k][i]) for k in range(nt)]
        self.g0 = tuple(_c(v) for v in model.gravity.linear)
        frame = model.frames[frame_id]
        f = self.fparent = frame.parentJoint - 1
        self.ft = [_c(v) for v in (U[f].T @ frame.placement.translation if f >= 0 else frame.placement.translation)]
        self.path = [j for j in range(nt) if f >= 0 and self.supports[j][f]]

    # ---------------------------------------------------------------- public
    def evaluate(self, theta: np.ndarray, what: tuple[str, ...]) -> dict[str, np.ndarray]:
        """The requested terms for a batch of chain configurations.

        Args:
            theta: (..., nθ) chain coordinates θ = A q + b [rad or m].
            what: names among "x" (..., m) [m], "J" (..., m, n) [m/rad], "dJ" (..., m, n, n)
                with [..., i, j, k] = ∂J_ij/∂q_k [m/rad²], "M" (..., n, n) [kg m²] and "g" (..., n) [N m].

        Returns:
            {name: array} in motor coordinates q, batch axes first.
        """
        lead = theta.shape[:-1]
        th = theta.reshape(-1, self.nt)
        B = th.shape[0]
        m, n = len(self.rows), self.n
        shapes = {"x": (m,), "J": (m, n), "dJ": (m, n, n), "M": (n, n), "g": (n,)}
        out = {k: np.empty(shapes[k] + (B,)) for k in what}
        for s in range(0, B, CHUNK):
            self._chunk(np.ascontiguousarray(th[s:s + CHUNK].T), what, {k: v[..., s:s + CHUNK] for k, v in out.items()})
        return {k: np.moveaxis(v, -1, 0).reshape(lead + shapes[k]) for k, v in out.items()}

    # ------------------------------------------------------------- internals
    def _chunk(self, th: np.ndarray, what, out: dict[str, np.ndarray]) -> None:
        """Write the terms for th: (nθ, B) into out[name]: (..., B)."""
        F, o = self._forward(th)
        nt = self.nt
        S_w = [F[j][2] if self.revolute[j] else (0.0, 0.0, 0.0) for j in range(nt)]
        S_v = [_cross(o[j], F[j][2]) if self.revolute[j] else F[j][2] for j in range(nt)]
        if {"x", "J", "dJ"} & set(what):
            f = self.fparent
            p = _vadd(o[f], _matvec(F[f], self.ft)) if f >= 0 else (0.0, 0.0, 0.0)
            if "x" in what:
                for r, i in enumerate(self.rows):
                    out["x"][r] = p[i]
            Jp = {j: _vadd(S_v[j], _cross(S_w[j], p)) for j in self.path}
            if "J" in what:
                self._map_cols(out["J"], [[Jp[j][i] if j in Jp else 0.0 for j in range(nt)] for i in self.rows])
            if "dJ" in what:
                self._hessian(out["dJ"], S_w, Jp)
        if "M" in what or "g" in what:
            hc, Ic = self._composite(F, o, "M" in what)
            if "g" in what:
                g = [-_add(_dot(S_w[j], _cross(hc[j], self.g0)), _mul(self.mass_c[j], _dot(S_v[j], self.g0)))
                     for j in range(nt)]
                self._map_cols(out["g"][None], [g])
            if "M" in what:
                self._mass(out["M"], S_w, S_v, hc, Ic)

    def _forward(self, th: np.ndarray):
        """Internal frames F_j (3 columns, each a vector) and joint origins o_j (vectors) of every joint."""
        nt = self.nt
        ident = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
        zero = (0.0, 0.0, 0.0)
        F: list[Any] = [None] * nt
        o: list[Any] = [None] * nt
        for j in range(nt):
            p = self.parent[j]
            Fp, op = (F[p], o[p]) if p >= 0 else (ident, zero)
            Q = Fp if self.G[j] is None else tuple(_matvec(Fp, [self.G[j][r][k] for r in range(3)]) for k in range(3))
            oj = _vadd(op, _matvec(Fp, self.t[j]))
            if self.revolute[j]:
                ang = th[j] + self.psi[j] if self.psi[j] else th[j]
                c, s = np.cos(ang), np.sin(ang)
                F[j] = (_vadd(_vscale(c, Q[0]), _vscale(s, Q[1])), _vsub(_vscale(c, Q[1]), _vscale(s, Q[0])), Q[2])
            else:
                F[j] = Q
                oj = _vadd(oj, _vscale(th[j], Q[2]))
            o[j] = oj
        return F, o

    def _composite(self, F, o, inertia: bool):
        """Subtree first moments h_k [kg m] and, if asked, inertias about the world origin (3 × 3 nested) [kg m²]."""
        nt = self.nt
        h: list[Any] = [None] * nt
        Iw: list[Any] = [None] * nt
        for j in range(nt):
            c = _vadd(o[j], _matvec(F[j], self.lever[j]))
            mc = _vscale(self.mass[j], c)
            h[j] = mc
            if inertia:  # F I Fᵀ + m (|c|² E − c cᵀ), upper triangle
                FI = [_matvec(F[j], [self.inertia[j][a][b] for a in range(3)]) for b in range(3)]  # columns of F I
                d = _dot(mc, c)
                Iw[j] = {(x, y): _sub(_add(_lin([F[j][b][y] for b in range(3)], [FI[b][x] for b in range(3)]),
                                           d if x == y else 0.0), _mul(mc[x], c[y]))
                         for x in range(3) for y in range(x, 3)}
        for j in reversed(range(nt)):  # children come after their parent in Pinocchio's order
            p = self.parent[j]
            if p >= 0:
                h[p] = _vadd(h[p], h[j])
                if inertia:
                    Iw[p] = {k: _add(v, Iw[j][k]) for k, v in Iw[p].items()}
        return h, Iw

    def _mass(self, out: np.ndarray, S_w, S_v, hc, Ic) -> None:
        """M_q into out: (n, n, B), composite-rigid-body algorithm in world coordinates."""
        nt = self.nt
        M = [[0.0] * nt for _ in range(nt)]
        for k in range(nt):
            I = Ic[k]
            Iw = tuple(_lin([I[min(x, y), max(x, y)] for y in range(3)], S_w[k]) if not all(_zero(v) for v in S_w[k])
                       else 0.0 for x in range(3))
            H = _vadd(Iw, _cross(hc[k], S_v[k]))  # angular momentum about O per unit q̇_k
            L = _vadd(_vscale(self.mass_c[k], S_v[k]), _cross(S_w[k], hc[k]))  # linear momentum per unit q̇_k
            for j in range(nt):
                if self.supports[j][k]:
                    M[j][k] = M[k][j] = _add(_dot(S_w[j], H), _dot(S_v[j], L))
            M[k][k] = _add(M[k][k], self.armature_t[k])
        A = self.A
        for a in range(self.n):
            for c in range(a, self.n):
                v = 0.0
                for j in range(nt):
                    if not _zero(A[j][a]):
                        v = _add(v, _mul(A[j][a], _lin([A[k][c] for k in range(nt)], M[j])))
                if a == c:
                    v = _add(v, self.armature_q[a])
                out[a, c] = v
                if c != a:
                    out[c, a] = out[a, c]

    def _map_cols(self, out: np.ndarray, rows_theta) -> None:
        """out[r, a] = Σ_j X[r][j] A[j][a] for X given per row as a list of nθ scalars."""
        for r, X in enumerate(rows_theta):
            for a in range(self.n):
                out[r, a] = _lin([self.A[j][a] for j in range(self.nt)], X)

    def _hessian(self, out: np.ndarray, S_w, Jp) -> None:
        """∂J/∂q into out: (m, n, n, B) from ∂J_j/∂θ_k = ω_min(j,k) × J_max(j,k) along the path."""
        nt, path, A = self.nt, self.path, self.A
        for r, i in enumerate(self.rows):
            H = [[0.0] * nt for _ in range(nt)]
            for u, j in enumerate(path):
                for k in path[u:]:
                    H[j][k] = H[k][j] = _cross_i(S_w[j], Jp[k], i)
            for a in range(self.n):
                HA = [_lin([A[j][a] for j in range(nt)], [H[j][k] for j in range(nt)]) for k in range(nt)]
                for c in range(self.n):
                    out[r, a, c] = _lin([A[k][c] for k in range(nt)], HA)


#: The terms `terms` returns, and the `Device` method that computes each one configuration at a time.
TERMS = {"x": "fk", "J": "jacobian", "dJ": "jacobian_derivative", "M": "mass_matrix", "g": "gravity"}


def terms(device, q, what: tuple[str, ...] = ("J", "dJ", "M", "g")) -> dict[str, np.ndarray]:
    """Several terms of a batch of configurations of a `Device` from one vectorized pass.

    `Device.jacobian(Q)`, `jacobian_derivative(Q)`, `mass_matrix(Q)` and `gravity(Q)` each run
    `BatchChain.evaluate` on their own, so asking for all four repeats the forward kinematics four
    times and the composite inertias twice; this runs the pass once. Same numbers as those methods.

    Args:
        device: an `rhi.device.Device`.
        q: (..., n) motor positions [rad or m].
        what: names among "x" (..., m) [m], "J" (..., m, n), "dJ" (..., m, n, n), "M" (..., n, n) [kg m²]
            and "g" (..., n) [N m] (as `BatchChain.evaluate`).

    Returns:
        {name: array}, batch axes first; a device whose joints `rhi.batch` does not support gets the
        `Device` methods' per-configuration results.

    Raises:
        InvalidInput: an unknown term name, or a bad q (named as `Device` does).
    """
    unknown = [k for k in what if k not in TERMS]
    if unknown or not what:
        raise InvalidInput(f"what: expected names among {list(TERMS)}, got {list(what)!r}")
    th = device.theta(q)
    chain = device._batch
    if chain is None or th.ndim < 2:
        return {k: getattr(device, TERMS[k])(q) for k in what}
    return chain.evaluate(th, tuple(what))
