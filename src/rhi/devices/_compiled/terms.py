"""Compiled kernel behind `Device.terms`: the motor-coordinate and task-space terms of one state.

`task_terms` maps the chain's 6-D frame Jacobian, inertia, gravity and Coriolis matrices
(`rhi.devices._compiled.chain` or Pinocchio, chain coordinates θ = A q + b) to motor coordinates and computes the
task-space dynamics of thesis eq. 5.2 (M_x, J#, C_x, G_x) in one call. Imported on the
first `Device.terms` call, not with `rhi` (Numba's import and, once per machine, the
compilation stay out of ``import rhi``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from llvmlite import ir as llvm_ir
from numba import types
from numba.core import cgutils
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from rhi.jit import jit, stack_empty


@intrinsic
def _shaped(typingctx, x, shape):
    """``shaped(x, shape)`` in compiled code: the contiguous 1-D array x viewed as a C array of `shape`.

    NumPy's ``x.reshape(shape)`` for such an x, without Numba's general reshape (a call of its C helper
    ``numba_attempt_nocopy_reshape`` and the shape's normalisation, each time): a few instructions. `shape` an int
    or a tuple of ints; a size other than x's, or an x with gaps (layout "A"), raises ValueError.
    """
    if not (isinstance(x, types.Array) and x.ndim == 1 and x.layout in "CA"):
        return None
    if isinstance(shape, types.Integer):
        nd = 1
    elif isinstance(shape, types.BaseTuple) and all(isinstance(t, types.Integer) for t in shape.types):  # type: ignore[attr-defined]
        nd = len(shape.types)  # type: ignore[attr-defined]
    else:
        return None
    ret = x.copy(ndim=nd, layout="C")

    def codegen(context, builder, sig, args):
        shape_ty, intp = sig.args[1], context.get_value_type(types.intp)
        if isinstance(shape_ty, types.Integer):
            dims = [context.cast(builder, args[1], shape_ty, types.intp)]
        else:
            dims = [context.cast(builder, builder.extract_value(args[1], i), t, types.intp)
                    for i, t in enumerate(shape_ty.types)]
        src = make_array(sig.args[0])(context, builder, args[0])
        total = llvm_ir.Constant(intp, 1)
        for d in dims:
            total = builder.mul(total, d)
        bad = builder.icmp_signed("!=", total, builder.extract_value(src.shape, 0))
        if sig.args[0].layout != "C":  # contiguous only
            gaps = builder.icmp_signed("!=", builder.extract_value(src.strides, 0), src.itemsize)
            bad = builder.or_(bad, builder.and_(gaps, builder.icmp_signed(">", total, llvm_ir.Constant(intp, 1))))
        with cgutils.if_unlikely(builder, bad):
            context.call_conv.return_user_exc(builder, ValueError, ("cannot reshape array: another size or gaps",))
        strides: list = []
        step = src.itemsize
        for d in reversed(dims):
            strides.insert(0, step)
            step = builder.mul(step, d)
        out = make_array(ret)(context, builder)
        populate_array(out, data=src.data, shape=dims, strides=strides, itemsize=src.itemsize, meminfo=src.meminfo,
                       parent=src.parent)
        return impl_ret_borrowed(context, builder, ret, out._getvalue())

    return ret(x, shape), codegen


shaped: Any = _shaped  # as kernels call it: shaped(x, shape) (the intrinsic takes the typing context first)


@jit
def inv(A):
    """Inverse of a small (k, k) matrix: closed form for k <= 3, Gauss-Jordan otherwise (singular: inf/NaN)."""
    out = np.empty(A.shape)
    inv_to(A, out)
    return out


@jit
def inv_to(A, out):
    """`inv` of A written into `out` (k, k), another array than A."""
    k = A.shape[0]
    if k == 1:
        out[0, 0] = 1.0 / A[0, 0]
    elif k == 2:
        det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        out[0, 0], out[0, 1] = A[1, 1] / det, -A[0, 1] / det
        out[1, 0], out[1, 1] = -A[1, 0] / det, A[0, 0] / det
    elif k == 3:
        c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
        c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
        c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
        det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
        out[0, 0], out[1, 0], out[2, 0] = c00 / det, c01 / det, c02 / det
        out[0, 1] = (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) / det
        out[1, 1] = (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) / det
        out[2, 1] = (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) / det
        out[0, 2] = (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) / det
        out[1, 2] = (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) / det
        out[2, 2] = (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) / det
    else:  # Gauss-Jordan with partial pivoting (no LAPACK call overhead at these sizes)
        W = stack_empty((k, k), np.float64)  # the elimination's work copy of A
        for i in range(k):
            for j in range(k):
                W[i, j] = A[i, j]
        out[:, :] = 0.0
        for i in range(k):
            out[i, i] = 1.0
        for c in range(k):
            p = c
            for r in range(c + 1, k):
                if abs(W[r, c]) > abs(W[p, c]):
                    p = r
            if p != c:
                for j in range(k):
                    W[c, j], W[p, j] = W[p, j], W[c, j]
                    out[c, j], out[p, j] = out[p, j], out[c, j]
            d = 1.0 / W[c, c]
            for j in range(k):
                W[c, j] *= d
                out[c, j] *= d
            for r in range(k):
                if r != c:
                    f = W[r, c]
                    if f != 0.0:
                        for j in range(k):
                            W[r, j] -= f * W[c, j]
                            out[r, j] -= f * out[c, j]


@jit
def mm(A, B):
    """A B for small matrices (loops: faster than a BLAS call at these sizes)."""
    n, k = A.shape
    m = B.shape[1]
    C = np.zeros((n, m))
    for i in range(n):
        for l in range(k):
            a = A[i, l]
            for j in range(m):
                C[i, j] += a * B[l, j]
    return C


@jit
def mv(A, v):
    """A v for a small matrix A (k, n) and v (n,)."""
    k, n = A.shape
    out = np.zeros(k)
    for i in range(k):
        s = 0.0
        for j in range(n):
            s += A[i, j] * v[j]
        out[i] = s
    return out


@jit
def dot(a, b):
    """The dot product a · b of two small vectors."""
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i] * b[i]
    return s


@jit
def finite(v):
    """Whether every entry of the vector v is finite (its squares' sum is: an overflow counts as not finite)."""
    return math.isfinite(dot(v, v))


@jit
def mtv(A, v):
    """Aᵀ v for a small matrix A (k, n) and v (k,)."""
    k, n = A.shape
    out = np.zeros(n)
    for i in range(k):
        vi = v[i]
        for j in range(n):
            out[j] += A[i, j] * vi
    return out


@jit
def task_terms(J6, Mt, gt, Ct, A, rows, armature, supports, identity, fill_lower, dq, out):
    """Motor-coordinate and task-space terms of one state, written into `out` in the order of `rhi.devices.terms.TERMS`.

    Args:
        J6: (6, nθ) frame Jacobian (LOCAL_WORLD_ALIGNED; linear rows first).
        Mt: (nθ, nθ) chain inertia (upper triangle only when fill_lower).
        gt: (nθ,) chain gravity torque.
        Ct: (nθ, nθ) chain Coriolis matrix at θ̇ = A q̇.
        A: (nθ, n) actuation map.
        rows: (m,) task rows of J6.
        armature: (n,) rotor inertia [kg m²].
        supports: (nθ, nθ) bool, [j, k]: chain joint k supports joint j (or is j); every joint one-DoF.
        identity: A is the identity.
        fill_lower: mirror Mt's upper triangle.
        dq: (n,) joint velocities [rad/s].
        out: flat float64 output (`rhi.devices.terms.layout`): J (m, n), ∂J/∂q (m, n, n), M (n, n), g (n,), M⁻¹,
            J M⁻¹ (m, n), M_x (m, m), J# (n, m), G_x (m,), ẋ (m,), J̇ (m, n), C_q (n, n), C_x (m, m).
    """
    nt, n, m = Mt.shape[0], A.shape[1], rows.shape[0]
    # offsets of the terms in out; every term is written there and read back from there (loops with scalar
    # indices, no temporaries per product: an array view or allocation per small product costs more than it)
    oJ = 0
    odJ = oJ + m * n
    oM = odJ + m * n * n
    og = oM + n * n
    oMi = og + n
    oJMi = oMi + n * n
    oL = oJMi + m * n
    oJs = oL + m * m
    oGx = oJs + n * m
    oxd = oGx + m
    oJd = oxd + m
    oCq = oJd + m * n
    oCx = oCq + n * n
    for i in range(m):
        r = rows[i]
        for a in range(n):
            s = 0.0
            for j in range(nt):
                s += A[j, a] * J6[r, j]
            out[oJ + i * n + a] = s
    W = stack_empty((max(n, nt), max(n, nt)), np.float64)  # scratch: Aᵀ X products
    for a in range(n):  # M = Aᵀ M_θ A (+ armature); M_θ's upper triangle alone when fill_lower
        for k in range(nt):
            s = 0.0
            for j in range(nt):
                s += A[j, a] * (Mt[k, j] if fill_lower and j > k else Mt[j, k])
            W[a, k] = s
    for a in range(n):
        for c in range(n):
            s = 0.0
            for k in range(nt):
                s += W[a, k] * A[k, c]
            out[oM + a * n + c] = s
        out[oM + a * n + a] += armature[a]
    gg = 0.0
    for a in range(n):
        s = 0.0
        for j in range(nt):
            s += A[j, a] * gt[j]
        out[og + a] = s
        gg += s * s
    # ∂J_j/∂θ_k = ω_k × v_j when joint k supports joint j, ω_j × v_k otherwise (v, ω: J6's linear, angular rows)
    D = stack_empty((m, nt, nt), np.float64)
    for j in range(nt):
        for k in range(nt):
            w, v = (k, j) if supports[j, k] else (j, k)
            for i in range(m):
                r = rows[i]
                r1, r2 = (r + 1) % 3, (r + 2) % 3
                D[i, j, k] = J6[3 + r1, w] * J6[r2, v] - J6[3 + r2, w] * J6[r1, v]
    if identity:
        for i in range(m):
            for j in range(nt):
                for k in range(nt):
                    out[odJ + (i * n + j) * n + k] = D[i, j, k]
    else:  # J_q = J_θ A: ∂J_q[i, a]/∂q_c = Σ_jk A[j, a] A[k, c] ∂J_θ[i, j]/∂θ_k
        for i in range(m):
            for a in range(n):
                for k in range(nt):
                    s = 0.0
                    for j in range(nt):
                        s += A[j, a] * D[i, j, k]
                    W[a, k] = s
            for a in range(n):
                for c in range(n):
                    s = 0.0
                    for k in range(nt):
                        s += W[a, k] * A[k, c]
                    out[odJ + (i * n + a) * n + c] = s
    Minv = shaped(out[oMi:oMi + n * n], (n, n))
    inv_to(shaped(out[oM:oM + n * n], (n, n)), Minv)
    for i in range(m):  # J M⁻¹
        for c in range(n):
            s = 0.0
            for a in range(n):
                s += out[oJ + i * n + a] * Minv[a, c]
            out[oJMi + i * n + c] = s
    L = stack_empty((m, m), np.float64)  # J M⁻¹ Jᵀ
    for i in range(m):
        for j in range(m):
            s = 0.0
            for c in range(n):
                s += out[oJMi + i * n + c] * out[oJ + j * n + c]
            L[i, j] = s
    Lam = shaped(out[oL:oL + m * m], (m, m))
    inv_to(L, Lam)
    for a in range(n):  # J# = (J M⁻¹)ᵀ Λ
        for j in range(m):
            s = 0.0
            for i in range(m):
                s += out[oJMi + i * n + a] * Lam[i, j]
            out[oJs + a * m + j] = s
    for j in range(m):
        s = 0.0
        if gg != 0.0:
            for a in range(n):
                s += out[oJs + a * m + j] * out[og + a]
        out[oGx + j] = s
        s = 0.0
        for a in range(n):
            s += out[oJ + j * n + a] * dq[a]
        out[oxd + j] = s
    for i in range(m * n):  # J̇ = Σ_c ∂J/∂q_c q̇_c
        s = 0.0
        for c in range(n):
            s += out[odJ + i * n + c] * dq[c]
        out[oJd + i] = s
    for a in range(n):  # C_q = Aᵀ C_θ A
        for k in range(nt):
            s = 0.0
            for j in range(nt):
                s += A[j, a] * Ct[j, k]
            W[a, k] = s
    for a in range(n):
        for c in range(n):
            s = 0.0
            for k in range(nt):
                s += W[a, k] * A[k, c]
            out[oCq + a * n + c] = s
    # C_x = Λ (J M⁻¹ C_q − J̇) J#
    for i in range(m):
        for c in range(n):
            s = 0.0
            for a in range(n):
                s += out[oJMi + i * n + a] * out[oCq + a * n + c]
            W[i, c] = s - out[oJd + i * n + c]
    for i in range(m):
        for j in range(m):
            s = 0.0
            for c in range(n):
                t = 0.0
                for l in range(m):
                    t += Lam[i, l] * W[l, c]
                s += t * out[oJs + c * m + j]
            out[oCx + i * m + j] = s


@jit
def add(x, y):
    """X + y for 1-D arrays (loops: a fraction of the code Numba's array expressions compile to)."""
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = x[i] + y[i]
    return out


@jit
def sub(x, y):
    """X − y for 1-D arrays."""
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = x[i] - y[i]
    return out


@jit
def axpy(s, x, y):
    """The 1-D array s x + y for a scalar s (y − c x is this with s = −c: the same floats)."""
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = s * x[i] + y[i]
    return out


@jit
def assign(dst, src):
    """dst[:] = src for 1-D arrays of one length, as a loop.

    Numba's slice assignment from an array compiles its shape-mismatch error message (string
    formatting): seconds of first-use compilation per kernel tree that this loop avoids.
    """
    for i in range(src.shape[0]):
        dst[i] = src[i]
