"""Tests of rhi.metrics: invariants, thesis numbers, broadcasting and error paths."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import fd_jacobian, random_q

import rhi.metrics as rm
from rhi.errors import InfeasibleLimits, InvalidInput, NotSPD, RhiError, Singular

SEED = 20200101


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(SEED)


def random_spd(rng: np.random.Generator, n: int, batch: tuple[int, ...] = ()) -> np.ndarray:
    A = rng.normal(size=batch + (n, n))
    return A @ np.swapaxes(A, -1, -2) + n * np.eye(n)


def random_unit(rng: np.random.Generator, m: int, batch: tuple[int, ...] = ()) -> np.ndarray:
    u = rng.normal(size=batch + (m,))
    return u / np.linalg.norm(u, axis=-1, keepdims=True)


# --- closed-form Jacobians from the thesis -------------------------------------------

D_RHI4 = (0.254, 0.141, 0.21, 0.181)  # link lengths of the 4-DoF planar RHI [m] (§3.5, §6.4)


def fk_rhi4(q: np.ndarray) -> np.ndarray:
    d1, d2, d3, d4 = D_RHI4
    q1, q2, q3, q4 = q
    return np.array(
        [
            d1 * np.cos(q1) + d2 * np.sin(q2) + d3 * np.cos(q2 + q3) + d4 * np.sin(q2 + q4),
            d1 * np.sin(q1) - d2 * np.cos(q2) + d3 * np.sin(q2 + q3) - d4 * np.cos(q2 + q4),
        ]
    )


def jac_rhi4(q: np.ndarray) -> np.ndarray:
    """Jacobian of the 4-DoF planar RHI (thesis eq. 6.20)."""
    d1, d2, d3, d4 = D_RHI4
    q1, q2, q3, q4 = q
    s, c = np.sin, np.cos
    return np.array(
        [
            [-d1 * s(q1), d2 * c(q2) - d3 * s(q2 + q3) + d4 * c(q2 + q4), -d3 * s(q2 + q3), d4 * c(q2 + q4)],
            [d1 * c(q1), d2 * s(q2) + d3 * c(q2 + q3) + d4 * s(q2 + q4), d3 * c(q2 + q3), d4 * s(q2 + q4)],
        ]
    )


def jac_planar(q: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Jacobian of a planar serial arm with relative joint angles."""
    a = np.cumsum(q)
    J = np.zeros((2, len(q)))
    for i in range(len(q)):
        J[0, i] = -np.sum(lengths[i:] * np.sin(a[i:]))
        J[1, i] = np.sum(lengths[i:] * np.cos(a[i:]))
    return J


def mass_planar_point(q: np.ndarray, lengths: np.ndarray, masses: np.ndarray) -> np.ndarray:
    """Joint-space inertia of a planar arm with point masses at the link midpoints."""
    a = np.cumsum(q)
    n = len(q)
    M = np.zeros((n, n))
    for k in range(n):
        Jc = np.zeros((2, n))
        for i in range(k + 1):
            Jc[0, i] = -np.sum(lengths[i:k] * np.sin(a[i:k])) - 0.5 * lengths[k] * np.sin(a[k])
            Jc[1, i] = np.sum(lengths[i:k] * np.cos(a[i:k])) + 0.5 * lengths[k] * np.cos(a[k])
        M += masses[k] * Jc.T @ Jc
    return M


def test_rhi4_jacobian_matches_forward_kinematics(rng):
    q = rng.uniform(-1, 1, 4)
    h = 1e-6
    fd = np.column_stack([(fk_rhi4(q + h * e) - fk_rhi4(q - h * e)) / (2 * h) for e in np.eye(4)])
    np.testing.assert_allclose(jac_rhi4(q), fd, atol=1e-9)


# --- inverses and projectors -----------------------------------------------------------


def test_weighted_pinv_is_right_inverse_and_matches_formula(rng):
    J = rng.normal(size=(3, 6))
    Q = random_spd(rng, 6)
    Jd = rm.weighted_pinv(J, Q)
    np.testing.assert_allclose(J @ Jd, np.eye(3), atol=1e-12)
    Qi = np.linalg.inv(Q)
    np.testing.assert_allclose(Jd, Qi @ J.T @ np.linalg.inv(J @ Qi @ J.T), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(rm.weighted_pinv(J), np.linalg.pinv(J), atol=1e-12)


def test_weighted_pinv_minimises_weighted_norm(rng):
    J = rng.normal(size=(2, 5))
    Q = random_spd(rng, 5)
    xdot = rng.normal(size=2)
    qd = rm.weighted_pinv(J, Q) @ xdot
    P = rm.velocity_nullspace_projector(J, Q)
    for _ in range(20):  # any other solution qd + P z has a larger Q-norm
        other = qd + P @ rng.normal(size=5)
        np.testing.assert_allclose(J @ other, xdot, atol=1e-12)
        assert other @ Q @ other >= qd @ Q @ qd - 1e-12


@pytest.mark.parametrize("weighted", [False, True])
def test_velocity_nullspace_projector_invariants(rng, weighted):
    J = rng.normal(size=(2, 4))
    Q = random_spd(rng, 4) if weighted else None
    P = rm.velocity_nullspace_projector(J, Q)
    np.testing.assert_allclose(J @ P, 0, atol=1e-12)
    np.testing.assert_allclose(P @ P, P, atol=1e-12)


def test_dynamic_projector_invariants(rng):
    J = rng.normal(size=(2, 4))
    M = random_spd(rng, 4)
    N = rm.nullspace_projector(J, M)
    Jsharp = rm.dynamic_pinv(J, M)
    np.testing.assert_allclose(J @ Jsharp, np.eye(2), atol=1e-12)
    np.testing.assert_allclose(Jsharp, rm.weighted_pinv(J, M), atol=1e-14)
    np.testing.assert_allclose(N @ N, N, atol=1e-12)
    np.testing.assert_allclose(N @ J.T, 0, atol=1e-12)  # task torques pass untouched
    # null-space torques produce no end-effector acceleration / dynamic force
    np.testing.assert_allclose(J @ np.linalg.solve(M, N), 0, atol=1e-12)
    np.testing.assert_allclose(Jsharp.T @ N, 0, atol=1e-12)
    np.testing.assert_allclose(N, (np.eye(4) - Jsharp @ J).T, atol=1e-14)


def test_kinematic_projector_invariants(rng):
    J = rng.normal(size=(3, 5))
    N = rm.nullspace_projector(J)
    np.testing.assert_allclose(N, N.T, atol=1e-14)
    np.testing.assert_allclose(N @ N, N, atol=1e-12)
    np.testing.assert_allclose(J @ N, 0, atol=1e-12)
    np.testing.assert_allclose(N, rm.velocity_nullspace_projector(J), atol=1e-14)


def test_inverses_raise_on_singular_jacobian():
    J = jac_planar(np.array([0.3, 0.0]), np.array([0.3, 0.2]))  # stretched 2R arm
    with pytest.raises(Singular, match="J"):
        rm.weighted_pinv(J)
    with pytest.raises(Singular, match="J"):
        rm.nullspace_projector(J, np.eye(2))
    with pytest.raises(Singular, match="J"):
        rm.weighted_pinv(np.ones((3, 2)))  # fewer columns than rows


def test_inverses_bad_input(rng):
    J = rng.normal(size=(2, 3))
    with pytest.raises(NotSPD, match="Q"):
        rm.weighted_pinv(J, -np.eye(3))
    with pytest.raises(NotSPD, match="M"):
        rm.dynamic_pinv(J, np.array([[1.0, 2.0, 0], [0, 1.0, 0], [0, 0, 1.0]]))
    with pytest.raises(InvalidInput, match="M"):
        rm.dynamic_pinv(J, np.eye(4))
    with pytest.raises(InvalidInput, match="J"):
        rm.weighted_pinv(np.array([1.0, np.nan]))
    with pytest.raises(InvalidInput, match="J"):
        rm.weighted_pinv(np.array([[1.0, np.inf, 0.0], [0.0, 1.0, 0.0]]))


# --- ellipsoids -------------------------------------------------------------------------


def test_effective_manipulability_matches_formula_and_axes(rng):
    J = rng.normal(size=(3, 5))
    u = rng.normal(size=3)
    un = u / np.linalg.norm(u)
    rho = rm.effective_manipulability(J, u)
    np.testing.assert_allclose(rho, (un @ np.linalg.inv(J @ J.T) @ un) ** -0.5, rtol=1e-12)
    np.testing.assert_allclose(rm.effective_manipulability(J, 7.0 * u), rho, rtol=1e-14)
    U, s, _ = np.linalg.svd(J)
    for i in range(3):  # along a principal axis the radius is the semi-axis
        np.testing.assert_allclose(rm.effective_manipulability(J, U[:, i]), s[i], rtol=1e-12)
    np.testing.assert_allclose(rm.velocity_transmission(J, u), rho, rtol=1e-15)


def test_remark_one_adding_base_joints_never_decreases_rho(rng):
    """Thesis Remark I / eq. 3.10: rho_RHI >= rho_NHI for J_RHI = [J_AD, J_NHI]."""
    J_nhi = rng.normal(size=(200, 2, 2))
    J_ad = rng.normal(size=(200, 2, 2))
    J_rhi = np.concatenate([J_ad, J_nhi], axis=-1)
    u = random_unit(rng, 2, (200,))
    assert np.all(rm.effective_manipulability(J_rhi, u) >= rm.effective_manipulability(J_nhi, u) * (1 - 1e-12))


def test_effective_manipulability_at_singularity_is_zero_or_restricted():
    J = jac_planar(np.array([0.4, 0.0]), np.array([0.3, 0.2]))  # stretched: radial motion lost
    radial = np.array([np.cos(0.4), np.sin(0.4)])
    tangential = np.array([-np.sin(0.4), np.cos(0.4)])
    assert rm.effective_manipulability(J, radial) == 0.0
    assert rm.effective_manipulability(J, radial + 0.1 * tangential) == 0.0
    np.testing.assert_allclose(rm.effective_manipulability(J, tangential), np.linalg.norm(J, 2), rtol=1e-12)
    assert rm.manipulability(J) < 1e-15
    assert rm.isotropy(J) < 1e-15


def test_manipulability_and_isotropy(rng):
    J = rng.normal(size=(10, 3, 6))
    s = np.linalg.svd(J, compute_uv=False)
    mu = rm.manipulability(J)
    np.testing.assert_allclose(mu, np.prod(s, axis=-1), rtol=1e-12)
    np.testing.assert_allclose(mu, np.sqrt(np.linalg.det(J @ np.swapaxes(J, -1, -2))), rtol=1e-10)
    iso = rm.isotropy(J)
    np.testing.assert_allclose(iso, s[:, -1] / s[:, 0], rtol=1e-12)
    assert np.all((iso > 0) & (iso <= 1))
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    np.testing.assert_allclose(rm.isotropy(2.5 * R), 1.0, rtol=1e-12)
    assert rm.manipulability(rng.normal(size=(3, 2))) == 0.0  # n < m: flat ellipsoid
    assert rm.isotropy(np.zeros((2, 3))) == 0.0


@pytest.mark.parametrize("n", [2, 3, 4, 7])
def test_two_row_closed_form_svd_matches_lapack(rng, n):
    """The closed-form SVD of planar (two-row) maps gives LAPACK's singular values and directions."""
    from rhi.metrics._common import principal_axes_of_map, singular_values

    B = rng.normal(size=(3000, 2, n))
    B[:800, 1] = B[:800, 0] * rng.normal(size=(800, 1)) + 1e-9 * rng.normal(size=(800, n))  # nearly singular
    B[800:850] = 0.0
    B[850:900, 0] = 0.0  # a zero row (pivoting)
    B[900:950, :, 0] = 0.0
    B[950:1000] *= 1e200  # no overflow in the squares
    B[1000:1050] *= 1e-200
    U0, s0, _ = np.linalg.svd(B)
    s, U = principal_axes_of_map(B)
    scale = np.maximum(s0[:, :1], 1e-300)
    np.testing.assert_allclose(s / scale, s0 / scale, rtol=0, atol=4e-15)
    np.testing.assert_array_equal(singular_values(B), s)
    np.testing.assert_allclose(np.swapaxes(U, -1, -2) @ U, np.broadcast_to(np.eye(2), U.shape), atol=1e-15)
    gap = (s0[:, 0] - s0[:, 1]) / scale[:, 0] > 1e-6  # directions are defined (up to sign)
    np.testing.assert_allclose(np.abs(np.einsum("kij,kij->kj", U, U0))[gap], 1.0, atol=1e-9)
    np.testing.assert_array_equal(U[800:850], np.broadcast_to(np.eye(2), (50, 2, 2)))
    assert rm.manipulability(B[:1, :, :1]).shape == (1,)  # one column: LAPACK path, padded
    np.testing.assert_allclose(principal_axes_of_map(B[2000:2005])[0], s[2000:2005], rtol=1e-14)  # few: LAPACK


@pytest.mark.parametrize("m, n", [(3, 3), (3, 4), (3, 7), (3, 10), (4, 6), (6, 7)])
def test_compiled_jacobi_svd_matches_lapack(rng, m, n):
    """The compiled Jacobi SVD of spatial (3 <= m <= n) maps gives LAPACK's singular values and directions."""
    from rhi.metrics._common import SMALL_BATCH_MIN, inverse_gram, principal_axes_of_map, singular_values

    B = rng.normal(size=(3000, m, n))
    B[:800, -1] = B[:800, 0] * rng.normal(size=(800, 1)) + 1e-9 * rng.normal(size=(800, n))  # nearly singular
    B[800:850] = 0.0
    B[850:900, 0] = 0.0  # a zero row: rank m - 1
    B[900:950, 1] = B[900:950, 0]  # two equal rows: an exactly lost direction
    B[950:1000] *= 1e200  # no overflow in the squares
    B[1000:1050] *= 1e-200
    B[1050:1100] = np.linalg.qr(rng.normal(size=(50, n, n)))[0][:, :m] * 3.0  # equal singular values
    U0, s0, _ = np.linalg.svd(B)
    s, U = principal_axes_of_map(B)
    scale = np.maximum(s0[:, :1], 1e-300)
    np.testing.assert_allclose(s / scale, s0 / scale, rtol=0, atol=4e-15)
    np.testing.assert_array_equal(singular_values(B), s)
    np.testing.assert_allclose(np.swapaxes(U, -1, -2) @ U, np.broadcast_to(np.eye(m), U.shape), atol=1e-14)
    US, Bn = U * (s / scale)[:, None, :], B / scale[:, :, None]
    np.testing.assert_allclose(US @ np.swapaxes(US, -1, -2), Bn @ np.swapaxes(Bn, -1, -2), atol=1e-14)  # U S² Uᵀ = B Bᵀ
    gaps = np.diff(s0, axis=-1) / scale < -1e-6  # each direction is defined (up to sign) between two gaps
    defined = np.concatenate([gaps[:, :1], gaps[:, 1:] & gaps[:, :-1], gaps[:, -1:]], axis=-1)
    np.testing.assert_allclose(np.abs(np.einsum("kij,kij->kj", U, U0[:, :, :m]))[defined], 1.0, atol=1e-9)
    np.testing.assert_array_equal(U[800:850], np.broadcast_to(np.eye(m), (50, m, m)))
    full = np.flatnonzero(s0[:, -1] > 0.01 * s0[:, 0])[-SMALL_BATCH_MIN:]  # well conditioned
    np.testing.assert_allclose(inverse_gram("B", B[full]), np.linalg.inv(B[full] @ np.swapaxes(B[full], -1, -2)),
                               rtol=1e-11)
    with pytest.raises(Singular, match="at batch index"):
        inverse_gram("B", B[800:800 + SMALL_BATCH_MIN])
    u = random_unit(rng, m, (3000,))
    ref = np.array([rm.effective_manipulability(b, v) for b, v in zip(B[1100:1400], u[1100:1400], strict=True)])
    np.testing.assert_allclose(rm.effective_manipulability(B[1100:1400], u[1100:1400]), ref, rtol=1e-12)
    lost = np.eye(m)[0] - np.eye(m)[1]  # Bᵀ(e₀ − e₁) = 0 for two equal rows: no speed along it
    assert rm.effective_manipulability(np.concatenate([B[900:950]] * 2), lost).max() == 0.0


@pytest.mark.parametrize("m, n", [(2, 2), (2, 4), (3, 3), (3, 7), (3, 10), (4, 6)])
def test_triangle_measures_equal_the_svd_route(rng, m, n):
    """ρ and μ of large batches from the Gram–Schmidt triangle equal the SVD's (regular maps) or are the SVD's (others)."""
    from rhi.metrics._common import principal_axes_of_map, radius_along, radius_of_map, singular_values, volume_of_map

    B = rng.normal(size=(2000, m, n))
    B[:300, -1] = B[:300, 0] * rng.normal(size=(300, 1)) + 10.0 ** rng.uniform(-14, -2, (300, 1)) * rng.normal(
        size=(300, n))  # condition numbers from 1e2 to 1e14: both routes
    B[300:350] = 0.0
    B[350:400, 0] = 0.0
    B[400:450, 1] = B[400:450, 0]  # an exactly lost direction
    B[450:500] *= 1e200
    B[500:550] *= 1e-200
    u = random_unit(rng, m, (2000,))
    u[400:425] = (np.eye(m)[0] - np.eye(m)[1]) / np.sqrt(2.0)  # along the lost direction: ρ = 0
    s, U = principal_axes_of_map(B)
    rho, mu = radius_of_map(B, u), volume_of_map(B)
    top = np.where(s[:, 0] > 0, s[:, 0], 1.0)
    np.testing.assert_allclose(rho / top, radius_along(s, U, u) / top, rtol=1e-11, atol=1e-15)
    keep = np.r_[0:450, 550:2000]  # μ of the 1e±200 maps over- or underflows (as the SVD's product)
    ref_mu = singular_values(B[keep]).prod(axis=-1)
    np.testing.assert_allclose(mu[keep] / top[keep]**m, ref_mu / top[keep]**m, rtol=1e-11, atol=1e-15)
    assert rho[400:425].max() == 0.0 and mu[300:350].max() == 0.0
    np.testing.assert_allclose(rm.effective_manipulability(B, u), rho, rtol=1e-14)  # u normalised again
    np.testing.assert_array_equal(rm.manipulability(B), mu)


def test_three_row_closed_form_equals_the_triangle(rng):
    """ρ and μ of three-row maps from the 3×3 Gram by cofactors equal the triangle's where it takes them; it leaves the rest."""
    from rhi.metrics._common import _GRAM_COND_MAX, _TRIANGLE_COND_MAX
    from rhi.metrics._small import gram3_rows, radius_rows

    B = rng.normal(size=(3000, 3, 6)) * 10.0 ** rng.uniform(-3, 3, (3000, 1, 1))
    B[:1000, 2] = B[:1000, 0] + 10.0 ** rng.uniform(-8, 0, (1000, 1)) * rng.normal(size=(1000, 6))
    B[1000:1010] = 0.0
    u = random_unit(rng, 3, (3000,))
    got, ref = [np.empty(3000) for _ in range(2)], [np.empty(3000) for _ in range(2)]
    hard, hard_ref = np.empty(3000, dtype=np.int8), np.empty(3000, dtype=np.int8)
    gram3_rows(B, u, _GRAM_COND_MAX, got[0], got[1], hard)
    radius_rows(B, u, _TRIANGLE_COND_MAX, ref[0], ref[1], hard_ref)
    cond = np.linalg.cond(B)
    assert hard[cond > 1.01 * np.sqrt(_GRAM_COND_MAX)].all() and not hard[cond < 0.3 * np.sqrt(_GRAM_COND_MAX)].any()
    assert hard[1000:1010].all() and 0 < hard.sum() < 3000
    ok = hard == 0
    np.testing.assert_allclose(got[0][ok], ref[0][ok], rtol=1e-12)
    np.testing.assert_allclose(got[1][ok], ref[1][ok], rtol=1e-12)


def test_compiled_whitening_matches_lapack(rng):
    """Λ and M_x of large batches (the compiled Cholesky) equal the per-matrix LAPACK path; bad M raises NotSPD."""
    from rhi.metrics._common import SMALL_BATCH_MIN

    k = 4 * SMALL_BATCH_MIN
    J = rng.normal(size=(k, 3, 7))
    A = rng.normal(size=(k, 7, 7))
    M = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(7)
    u = random_unit(rng, 3, (k,))
    lam = rm.effective_inertia(J, M, u)
    ref = np.array([rm.effective_inertia(*a) for a in zip(J, M, u, strict=True)])
    np.testing.assert_allclose(lam, ref, rtol=1e-12)
    np.testing.assert_allclose(rm.apparent_inertia(J, M), [rm.apparent_inertia(j, mm) for j, mm in zip(J, M, strict=True)],
                               rtol=1e-10)
    np.testing.assert_allclose(rm.effective_inertia(J, M[0], u), [rm.effective_inertia(j, M[0], v) for j, v in
                                                                  zip(J, u, strict=True)], rtol=1e-12)  # M broadcast
    Jz = J.copy()
    Jz[5] = 0.0
    assert rm.effective_inertia(Jz, M, u)[5] == np.inf
    bad = M.copy()
    bad[7, 0, 1] += 1e-3 * np.abs(M[7]).max()
    with pytest.raises(NotSPD, match=r"M: not symmetric at batch index \(7,\)"):
        rm.effective_inertia(J, bad, u)
    bad = M.copy()
    bad[9] = -bad[9]
    with pytest.raises(NotSPD, match="M: not positive definite"):
        rm.effective_inertia(J, bad, u)


@pytest.mark.parametrize("m", [2, 3])
def test_compiled_inertia_near_a_lost_direction(rng, m):
    """Near Jᵀu = 0 the compiled Λ says inf where the per-matrix path does, and equals it elsewhere.

    It solves once, for Jᵀu; ‖B‖_F only where its bound cannot decide (as at Jᵀu = 1e-9, M of condition up to 1e8).
    """
    k, n = 256, 7
    u = random_unit(rng, m, (k,))
    J = rng.normal(size=(k, m, n))
    g = rng.normal(size=(k, n))
    eps = np.repeat([0.0, 1e-16, 1e-9, 1.0], k // 4)  # Jᵀu = eps g: lost, lost by the tolerance, small, regular
    J = J - u[:, :, None] * np.einsum("kr,krn->kn", u, J)[:, None] + eps[:, None, None] * u[:, :, None] * g[:, None]
    V = np.linalg.qr(rng.normal(size=(k, n, n)))[0]
    M = np.einsum("kij,kj,klj->kil", V, 10.0 ** rng.uniform(-4, 4, (k, n)), V)
    M = 0.5 * (M + np.swapaxes(M, -1, -2))
    lam = rm.effective_inertia(J, M, u)
    ref = np.array([rm.effective_inertia(*a) for a in zip(J, M, u, strict=True)])
    assert np.isinf(lam[: k // 2]).all() and np.isinf(ref[: k // 2]).all()
    np.testing.assert_allclose(lam[k // 2:], ref[k // 2:], rtol=1e-4)  # Jᵀu's round-off: 1e-16 / 1e-9 relative
    np.testing.assert_allclose(lam[3 * k // 4:], ref[3 * k // 4:], rtol=1e-7)  # κ(M) 1e8


def test_velocity_transmission_and_reflected_friction(rng):
    """Thesis eqs. 4.4-4.6: sigma * lambda <= 1, with equality along the principal axes."""
    J = rng.normal(size=(2, 3))
    u = random_unit(rng, 2, (50,))
    sig = rm.velocity_transmission(J, u)
    lam = rm.reflected_friction(J, u)
    np.testing.assert_allclose(lam, 1 / np.linalg.norm(u @ J, axis=-1), rtol=1e-12)
    assert np.all(sig * lam <= 1 + 1e-12)
    U = np.linalg.svd(J)[0]
    np.testing.assert_allclose(rm.velocity_transmission(J, U.T) * rm.reflected_friction(J, U.T), 1.0, rtol=1e-12)
    # at a singularity J^T u = 0 for the lost direction: no joint friction is felt
    Js = jac_planar(np.array([0.4, 0.0]), np.array([0.3, 0.2]))
    assert rm.reflected_friction(Js, [np.cos(0.4), np.sin(0.4)]) == np.inf


def test_velocity_ellipsoid_and_axes(rng):
    J = rng.normal(size=(3, 4))
    A = rm.velocity_ellipsoid(J)
    np.testing.assert_allclose(A, J @ J.T, atol=1e-14)
    lengths, V = rm.ellipsoid_axes(A)
    np.testing.assert_allclose(lengths, np.linalg.svd(J, compute_uv=False), rtol=1e-12)
    assert np.all(np.diff(lengths) <= 0)
    np.testing.assert_allclose(V @ np.diag(lengths**2) @ V.T, A, atol=1e-12)
    np.testing.assert_allclose(V.T @ V, np.eye(3), atol=1e-12)
    # a PSD (singular) ellipsoid is allowed, a non-PSD one is not
    np.testing.assert_allclose(rm.ellipsoid_axes(np.diag([4.0, 0.0]))[0], [2.0, 0.0])
    with pytest.raises(NotSPD, match="A"):
        rm.ellipsoid_axes(np.diag([1.0, -1.0]))
    with pytest.raises(NotSPD, match="A"):
        rm.ellipsoid_axes(np.array([[1.0, 0.5], [0.0, 1.0]]))
    with pytest.raises(InvalidInput, match="A"):
        rm.ellipsoid_axes(np.ones((2, 3)))


def test_force_ellipsoid_and_directional_manipulability(rng):
    J = rng.normal(size=(2, 4))
    tmax = np.array([3.0, 3.0, 1.0, 1.0])
    W = np.diag(1 / tmax)
    Mh = rm.force_ellipsoid(J, tmax)
    np.testing.assert_allclose(Mh, np.linalg.inv(J @ W @ W @ J.T), rtol=1e-10)
    np.testing.assert_allclose(rm.force_ellipsoid(J), np.linalg.inv(J @ J.T), rtol=1e-10)
    u = random_unit(rng, 2, (20,))
    dm = rm.directional_manipulability(J, u, tmax)
    np.testing.assert_allclose(dm, np.einsum("ki,ij,kj->k", u, J @ W.T @ W @ J.T, u) ** -0.5, rtol=1e-12)
    # DM is the radius of the torque-weighted FME along u
    np.testing.assert_allclose(dm, np.einsum("ki,ij,kj->k", u, np.linalg.inv(Mh), u) ** -0.5, rtol=1e-10)
    # a force of magnitude DM along u needs torques with |W J^T F| = 1
    np.testing.assert_allclose(np.linalg.norm((dm[:, None] * u) @ J @ W, axis=-1), 1.0, rtol=1e-12)


def test_directional_manipulability_app_a_weights(rng):
    """App. A.4.3 passes W_tau = diag(1,1,1,1,2.5,2.5,2.5): torque_max = 1 / 2.5 for the wrist."""
    J = rng.normal(size=(3, 7))
    u = random_unit(rng, 3)
    W = np.diag([1, 1, 1, 1, 2.5, 2.5, 2.5])
    expected = (u @ J @ W.T @ W @ J.T @ u) ** -0.5
    np.testing.assert_allclose(
        rm.directional_manipulability(J, u, [1, 1, 1, 1, 0.4, 0.4, 0.4]), expected, rtol=1e-12
    )


def test_force_ellipsoid_errors():
    J = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    with pytest.raises(InvalidInput, match="torque_max"):
        rm.force_ellipsoid(J, [1.0, 0.0, 1.0])
    with pytest.raises(InvalidInput, match="torque_max"):
        rm.directional_manipulability(J, [1, 0], [1.0, -1.0, 1.0])
    with pytest.raises(InvalidInput, match="torque_max"):
        rm.force_ellipsoid(J, [1.0, 1.0])
    with pytest.raises(Singular, match="J"):
        rm.force_ellipsoid(np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0]]), 1.0)
    with pytest.raises(InvalidInput, match="u"):
        rm.effective_manipulability(J, [0.0, 0.0])
    with pytest.raises(InvalidInput, match="u"):
        rm.effective_manipulability(J, [1.0, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="u"):
        rm.directional_manipulability(J, [np.nan, 1.0], 1.0)


def test_finite_check_accepts_huge_entries_and_rejects_nan_and_inf():
    J = np.array([[1e200, 0.0, 0.0], [0.0, 1e200, 0.0]])  # squares overflow, entries are finite
    assert rm.isotropy(J) == 1.0
    for bad in (np.inf, -np.inf, np.nan):
        J_bad = J.copy()
        J_bad[1, 2] = bad
        with pytest.raises(InvalidInput, match="J: contains NaN or inf"):
            rm.isotropy(J_bad)
        with pytest.raises(InvalidInput, match="u: contains NaN or inf"):
            rm.effective_manipulability(J, [1.0, bad])

def test_pycapacity_agrees_on_ellipsoid_radii(rng):
    robot = pytest.importorskip("pycapacity.robot")
    J = rng.normal(size=(3, 5))
    tmax = rng.uniform(0.5, 3.0, 5)
    fe = robot.force_ellipsoid(J, tmax)
    np.testing.assert_allclose(
        np.sort(rm.ellipsoid_axes(rm.force_ellipsoid(J, tmax))[0]), np.sort(np.ravel(fe.radii)), rtol=1e-10
    )
    ve = robot.velocity_ellipsoid(J, np.ones(5))
    np.testing.assert_allclose(
        np.sort(rm.ellipsoid_axes(rm.velocity_ellipsoid(J))[0]), np.sort(np.ravel(ve.radii)), rtol=1e-10
    )


def test_rhi4_home_configuration_k_and_zeta():
    """§6.4: with T = [3, 3, 1, 1] N m and mu = 5 at q = 0, K = 123 and zeta = 3.3."""
    Mh = rm.force_ellipsoid(jac_rhi4(np.zeros(4)), [3.0, 3.0, 1.0, 1.0])
    lam = np.linalg.eigvalsh(Mh)
    K = 5 * lam[-1]  # computed 123.016
    zeta = lam[0] / 5  # computed 3.344
    assert K == pytest.approx(123, abs=1)
    assert zeta == pytest.approx(3.3, abs=0.05)


def test_table_3_1_effective_manipulability():
    """Table 3.1 rho along u = [0, 1] (m/s); tolerance +-0.005 as in DESIGN.md.

    Computed: RHI 0.3752 / 0.3870 (thesis 0.371 / 0.387), PHANToM 0.1876 / 0.1668
    (0.188 / 0.167), Rehab 0.2960 / 0.3145 (0.296 / 0.315).
    """
    from scipy.optimize import fsolve

    u = np.array([0.0, 1.0])
    points = [np.array([0.49, -0.22]), np.array([0.49, -0.14])]
    q_rhi = [np.array([0.125, 0.022, 0.298, 0.175]), np.array([0.298, 0.077, 0.413, 0.208])]
    table = {"RHI": (0.371, 0.387), "PHANToM": (0.188, 0.167), "Rehab": (0.296, 0.315)}
    for k, p in enumerate(points):
        np.testing.assert_allclose(fk_rhi4(q_rhi[k]), p, atol=1.5e-3)
        assert rm.effective_manipulability(jac_rhi4(q_rhi[k]), u) == pytest.approx(table["RHI"][k], abs=0.005)
        # PHANToM: q1 = q2 = 0; Rehab: q3 = q4 = 0 (elbow branch of Fig. 3.6)
        q_ph = fsolve(lambda v, p=p: fk_rhi4(np.r_[0.0, 0.0, v]) - p, [0.3, 0.3], xtol=1e-13)
        q_re = fsolve(lambda v, p=p: fk_rhi4(np.r_[v, 0.0, 0.0]) - p, [0.3, 0.3], xtol=1e-13)
        np.testing.assert_allclose(fk_rhi4(np.r_[0.0, 0.0, q_ph]), p, atol=1e-10)
        np.testing.assert_allclose(fk_rhi4(np.r_[q_re, 0.0, 0.0]), p, atol=1e-10)
        rho_ph = rm.effective_manipulability(jac_rhi4(np.r_[0.0, 0.0, q_ph])[:, 2:], u)
        rho_re = rm.effective_manipulability(jac_rhi4(np.r_[q_re, 0.0, 0.0])[:, :2], u)
        assert rho_ph == pytest.approx(table["PHANToM"][k], abs=0.005)
        assert rho_re == pytest.approx(table["Rehab"][k], abs=0.005)


# --- inertia -------------------------------------------------------------------------------


def test_apparent_and_effective_inertia(rng):
    J = rng.normal(size=(2, 4))
    M = random_spd(rng, 4)
    Mx = rm.apparent_inertia(J, M)
    np.testing.assert_allclose(Mx, np.linalg.inv(J @ np.linalg.inv(M) @ J.T), rtol=1e-10)
    u = random_unit(rng, 2, (30,))
    lam = rm.effective_inertia(J, M, u)
    np.testing.assert_allclose(lam, 1 / np.einsum("ki,ij,kj->k", u, np.linalg.inv(Mx), u), rtol=1e-10)
    np.testing.assert_allclose(lam, 1 / np.einsum("ki,ij,kj->k", u, J @ np.linalg.solve(M, J.T), u), rtol=1e-10)


def test_remark_two_adding_base_joints_never_increases_inertia(rng):
    """Thesis Remark II / eq. 3.15: locking the added joints can only raise Lambda."""
    M = random_spd(rng, 4, (100,))
    J = rng.normal(size=(100, 2, 4))
    u = random_unit(rng, 2, (100,))
    lam_rhi = rm.effective_inertia(J, M, u)
    lam_nhi = rm.effective_inertia(J[..., 2:], M[..., 2:, 2:], u)
    assert np.all(lam_rhi <= lam_nhi * (1 + 1e-12))


def test_effective_inertia_singular_and_errors(rng):
    J = jac_planar(np.array([0.4, 0.0]), np.array([0.3, 0.2]))
    M = random_spd(rng, 2)
    assert rm.effective_inertia(J, M, [np.cos(0.4), np.sin(0.4)]) == np.inf
    assert np.isfinite(rm.effective_inertia(J, M, [-np.sin(0.4), np.cos(0.4)]))
    with pytest.raises(Singular, match="J"):
        rm.apparent_inertia(J, M)
    with pytest.raises(NotSPD, match="M"):
        rm.effective_inertia(J, np.array([[1.0, 0.0], [0.0, -1.0]]), [1, 0])
    with pytest.raises(InvalidInput, match="M"):
        rm.apparent_inertia(J, np.eye(3))


# --- SPD divergence and desired ellipsoids ------------------------------------------------


def test_jbld_properties(rng):
    A = random_spd(rng, 3, (5,))
    B = random_spd(rng, 3, (5,))
    assert np.all(np.abs(rm.jbld(A, A)) < 1e-12)
    d = rm.jbld(A, B)
    assert np.all(d > 0)
    np.testing.assert_allclose(d, rm.jbld(B, A), rtol=1e-12)
    expected = (
        np.linalg.slogdet((A + B) / 2)[1] - 0.5 * (np.linalg.slogdet(A)[1] + np.linalg.slogdet(B)[1])
    )
    np.testing.assert_allclose(d, expected, rtol=1e-10)
    X = rng.normal(size=(3, 3))  # affine invariance of the divergence
    np.testing.assert_allclose(rm.jbld(X @ A @ X.T, X @ B @ X.T), d, rtol=1e-8)
    np.testing.assert_allclose(rm.jbld(A, B[0]), [rm.jbld(a, B[0]) for a in A], rtol=1e-12)


def test_jbld_not_spd():
    A = np.eye(2)
    with pytest.raises(NotSPD, match="A"):
        rm.jbld(np.diag([1.0, -1.0]), A)
    with pytest.raises(NotSPD, match="B"):
        rm.jbld(A, np.diag([1.0, 0.0]))
    with pytest.raises(NotSPD, match="B"):
        rm.jbld(A, np.array([[1.0, 0.3], [0.0, 1.0]]))
    with pytest.raises(InvalidInput, match="B"):
        rm.jbld(A, np.eye(3))
    with pytest.raises(InvalidInput, match="A"):
        rm.jbld(np.full((2, 2), np.nan), A)


def test_jbld_spd_equals_jbld_to_the_last_bit(rng):
    """The objectives' unchecked JBLD (closed-form 2 × 2 Cholesky) is `jbld` bit for bit, and still refuses non-SPD."""
    from rhi.metrics.spd import jbld_spd

    for m in (2, 2, 2, 3):
        for _ in range(400):
            X = rng.normal(size=(m, m + 2)) * 10.0 ** rng.uniform(-3, 3)
            Y = rng.normal(size=(m, m + 1))
            A, B = X @ X.T, Y @ Y.T
            assert jbld_spd(A, B) == float(rm.jbld(A, B))
    with pytest.raises(NotSPD, match="B"):
        jbld_spd(np.eye(2), np.diag([1.0, 0.0]))
    with pytest.raises(NotSPD, match="A"):
        jbld_spd(np.full((2, 2), np.nan), np.eye(2))


def test_desired_ellipsoids(rng):
    u = random_unit(rng, 3)
    Md = rm.desired_vme(2.0 * u, 0.01)
    np.testing.assert_allclose(Md @ u, u, atol=1e-14)  # eigenvalue 1 along u (eq. 3.23)
    np.testing.assert_allclose(np.linalg.eigvalsh(Md), [0.01, 0.01, 1.0], atol=1e-14)
    # §6.4: u = [0, 1]; M_Free = diag{123, 3.3} (zeta along u), M_Stiff = diag{3.3, 123}
    np.testing.assert_allclose(rm.desired_fme([0, 1], 3.3, 123), np.diag([123, 3.3]), atol=1e-12)
    np.testing.assert_allclose(rm.desired_fme([0, 1], 123, 3.3), np.diag([3.3, 123]), atol=1e-12)
    assert rm.jbld(rm.desired_fme([0, 1], 3.3, 123), np.diag([123, 3.3])) < 1e-12
    batch = rm.desired_fme(random_unit(rng, 2, (4,)), np.array([1, 2, 3, 4.0]), 0.5)
    assert batch.shape == (4, 2, 2)
    with pytest.raises(InvalidInput, match="beta"):
        rm.desired_vme(u, 0.0)
    with pytest.raises(InvalidInput, match="minor"):
        rm.desired_fme(u, 1.0, -1.0)
    with pytest.raises(InvalidInput, match="u"):
        rm.desired_vme(np.zeros(3), 0.1)


# --- joint-limit penalty ----------------------------------------------------------------------


def test_joint_limit_penalty(rng):
    lo = np.array([-1.0, 0.0, -2.0])
    hi = np.array([1.0, 0.5, 3.0])
    np.testing.assert_allclose(rm.joint_limit_penalty((lo + hi) / 2, q_min=lo, q_max=hi, k_q=5.0), 1.0, rtol=1e-14)
    np.testing.assert_allclose(rm.joint_limit_penalty(lo, q_min=lo, q_max=hi, k_q=5.0), 0.0, atol=1e-15)
    np.testing.assert_allclose(rm.joint_limit_penalty(hi, q_min=lo, q_max=hi, k_q=5.0), 0.0, atol=1e-15)
    q = rng.uniform(lo, hi, size=(100, 3))
    p = rm.joint_limit_penalty(q, q_min=lo, q_max=hi, k_q=2.0)
    assert np.all((p >= 0) & (p <= 1))
    x = -8.0 * (q - lo) * (hi - q) / (hi - lo) ** 2
    np.testing.assert_allclose(p, (1 - np.exp(x)) / (1 - np.exp(-2.0)), rtol=1e-12)
    assert np.all(rm.joint_limit_penalty(hi + 0.1, q_min=lo, q_max=hi, k_q=5.0) == 0.0)  # beyond a limit: clipped
    J = rng.normal(size=(100, 2, 3))
    np.testing.assert_allclose(rm.penalized_jacobian(J, q, q_min=lo, q_max=hi, k_q=2.0), J * p[:, None, :], rtol=1e-14)


def test_joint_limit_penalty_errors():
    with pytest.raises(InfeasibleLimits, match="q_min"):
        rm.joint_limit_penalty([0.0, 0.0], q_min=[1.0, -1.0], q_max=[0.5, 1.0], k_q=1.0)
    with pytest.raises(InfeasibleLimits, match="q_min"):
        rm.joint_limit_penalty([0.0], q_min=[0.0], q_max=[0.0], k_q=1.0)
    with pytest.raises(InvalidInput, match="k_q"):
        rm.joint_limit_penalty([0.0], q_min=[-1.0], q_max=[1.0], k_q=0.0)
    with pytest.raises(InvalidInput, match="q"):
        rm.penalized_jacobian(np.ones((2, 3)), [0.0, 0.0], q_min=[-1.0, -1.0], q_max=[1.0, 1.0], k_q=1.0)


# --- teleoperation ----------------------------------------------------------------------------


def test_tme_of_identical_robots_is_their_ellipsoid(rng):
    J = rng.normal(size=(2, 3))
    np.testing.assert_allclose(rm.teleoperation_ellipsoid(J, J), J @ J.T, atol=1e-12)
    np.testing.assert_allclose(rm.tmi(J, J), rm.manipulability(J), rtol=1e-12)
    R = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    np.testing.assert_allclose(rm.tmi(J, R @ J, H=R), rm.manipulability(J), rtol=1e-12)


def test_tme_hand_computed():
    Jm = np.diag([2.0, 1.0])  # ME semi-axes 2 (x), 1 (y)
    Js = np.diag([1.0, 2.0])  # ME semi-axes 1 (x), 2 (y)
    np.testing.assert_allclose(rm.teleoperation_ellipsoid(Jm, Js), np.eye(2), atol=1e-14)
    assert rm.tmi(Jm, Js) == pytest.approx(1.0)
    # slave ME is a circle of radius 1.5: master axes clipped to 1.5 and 1 -> lambda = 1.5
    assert rm.tmi(Jm, 1.5 * np.eye(2)) == pytest.approx(1.5)


def test_tme_axis_endpoints_lie_in_both_ellipsoids(rng):
    Jm = rng.normal(size=(50, 3, 3))
    Js = rng.normal(size=(50, 2, 2))
    H = rng.normal(size=(50, 2, 3))  # rotation-projection as in eq. 4.26
    A = rm.teleoperation_ellipsoid(Jm, Js, H)
    lengths, V = rm.ellipsoid_axes(A)
    HJ = H @ Jm
    Am = HJ @ np.swapaxes(HJ, -1, -2)
    As = Js @ np.swapaxes(Js, -1, -2)
    ends = V * lengths[:, None, :]  # columns: semi-axis endpoints
    for Ai in (Am, As):
        inside = np.einsum("kim,kij,kjm->km", ends, np.linalg.inv(Ai), ends)
        assert np.all(inside <= 1 + 1e-9)
    lam = rm.tmi(Jm, Js, H)
    np.testing.assert_allclose(lam, np.prod(lengths, axis=-1), rtol=1e-10)
    assert np.all(lam <= np.maximum(rm.manipulability(HJ), rm.manipulability(Js)) * (1 + 1e-12))


def test_tmi_singular_slave_is_zero():
    Jm = np.diag([2.0, 1.0])
    Js = np.array([[1.0, 1.0], [0.0, 0.0]])  # flat slave ME
    assert rm.tmi(Jm, Js) == 0.0


def test_joint_energy_conventions():
    tme = np.diag([4.0, 1.0])  # semi-axes 2, 1
    # eq. 4.22 literally: Lambda_T = diag(sigma) -> |qdot|^2 = 1^2 / 2
    assert rm.joint_energy(tme, [1.0, 0.0]) == pytest.approx(0.5)
    assert rm.joint_energy(tme, [1.0, 0.0], axes_squared=True) == pytest.approx(0.25)
    assert rm.joint_energy(tme, [1.0, 3.0]) == pytest.approx(1 / 2 + 9 / 1)
    assert rm.joint_energy(tme, [0.0, 0.0]) == 0.0
    assert rm.joint_energy(np.diag([1.0, 0.0]), [0.0, 1.0]) == np.inf
    with pytest.raises(NotSPD, match="tme"):
        rm.joint_energy(np.diag([1.0, -1.0]), [1.0, 0.0])
    with pytest.raises(InvalidInput, match="xdot"):
        rm.joint_energy(tme, [1.0, 0.0, 0.0])


def test_teleop_errors(rng):
    with pytest.raises(InvalidInput, match="H"):
        rm.tmi(rng.normal(size=(3, 3)), rng.normal(size=(2, 2)))
    with pytest.raises(InvalidInput, match="H"):
        rm.tmi(rng.normal(size=(3, 3)), rng.normal(size=(2, 2)), H=np.eye(2))


# --- global index -----------------------------------------------------------------------------


def test_global_index(rng):
    v = rng.uniform(size=20)
    w = rng.uniform(size=20)
    assert rm.global_index(v) == pytest.approx(np.mean(v))
    assert rm.global_index(v, w) == pytest.approx(np.sum(w * v) / np.sum(w))
    vv = rng.uniform(size=(20, 3))
    np.testing.assert_allclose(rm.global_index(vv, w), (w @ vv) / w.sum(), rtol=1e-14)
    with pytest.raises(InvalidInput, match="values"):
        rm.global_index([])
    with pytest.raises(InvalidInput, match="values"):
        rm.global_index([1.0, np.nan])
    with pytest.raises(InvalidInput, match="weights"):
        rm.global_index(v, -w)
    with pytest.raises(InvalidInput, match="weights"):
        rm.global_index(v, np.zeros(20))
    with pytest.raises(InvalidInput, match="weights"):
        rm.global_index(v, w[:5])


# --- force capability ---------------------------------------------------------------------------

L3 = np.full(3, 0.25)
Q73 = np.array([np.pi / 4, -np.pi / 3, -np.pi / 6])


def test_max_force_scaling_closed_form(rng):
    J = rng.normal(size=(2, 3))
    u = random_unit(rng, 2)
    lo, hi = np.array([-0.5, -1.0, -0.2]), np.array([1.0, 0.3, 0.2])
    f, tau = rm.max_force_scaling(J, u, torque_min=lo, torque_max=hi, return_torque=True)
    np.testing.assert_allclose(tau, f * (J.T @ u), rtol=1e-14)
    assert np.all(tau <= hi + 1e-14) and np.all(tau >= lo - 1e-14)
    assert np.any(np.isclose(tau, hi) | np.isclose(tau, lo))  # one actuator saturated
    assert rm.max_force(J, u, torque_min=lo, torque_max=hi, projector=None) == f


@pytest.mark.parametrize("projector", ["pseudoinverse", "dynamic"])
def test_max_force_lp_invariants(rng, projector):
    J = rng.normal(size=(6, 2, 4))
    M = random_spd(rng, 4, (6,)) if projector == "dynamic" else None
    u = random_unit(rng, 2, (6,))
    lo, hi = -rng.uniform(0.2, 1.0, 4), rng.uniform(0.2, 1.0, 4)
    f, tau = rm.max_force(J, u, torque_min=lo, torque_max=hi, projector=projector, M=M, return_torque=True)
    f_s = rm.max_force_scaling(J, u, torque_min=lo, torque_max=hi)
    assert np.all(f >= f_s - 1e-12)
    assert np.all(tau <= hi + 1e-7) and np.all(tau >= lo - 1e-7)
    N = rm.nullspace_projector(J, M)
    Jinv = rm.dynamic_pinv(J, M) if projector == "dynamic" else rm.weighted_pinv(J)
    F = f[:, None] * u
    # the torque reproduces the force f u, the rest lies in the null space: tau - N tau_N = J^T F
    np.testing.assert_allclose(np.einsum("kji,kj->ki", Jinv, tau), F, atol=1e-8)
    rest = tau - np.einsum("kji,kj->ki", J, F)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", N, rest), rest, atol=1e-8)


def test_max_force_matches_brute_force_search():
    """3R arm, one-dimensional null space: scan the null-space torque on a fine grid."""
    J = jac_planar(Q73, L3)
    t = J.T @ np.array([1.0, 0.0])
    n0 = np.linalg.svd(J)[2][-1]  # null(J) = range of the pseudoinverse projector
    z = np.linspace(-2, 2, 400001)
    tau_n = z[:, None] * n0
    with np.errstate(divide="ignore"):
        up = np.where(t > 0, (0.5 - tau_n) / t, np.where(t < 0, (-0.5 - tau_n) / t, np.inf))
    feasible = np.all(np.abs(tau_n) <= 0.5, axis=1)
    best = np.max(np.where(feasible, np.min(up, axis=1), -np.inf))
    f = rm.max_force(J, [1, 0], torque_min=-0.5, torque_max=0.5, projector="pseudoinverse")
    assert f == pytest.approx(best, abs=1e-4)


def test_section_7_3_scaling_vs_null_space_optimum():
    """§7.3: 3R planar arm (L = 0.25 m, relative angles), q = [pi/4, -pi/3, -pi/6], |tau| <= 0.5 N m, force along x.

    The thesis reports simple scaling ~12 % below ASCM.

    Computed: scaling 2.0706 N, pseudoinverse-projector optimum 2.3513 N, gap 11.9 %.
    (The dynamic projector with 0.5 kg point masses at the link midpoints, the §6.3
    example's mass model, gives 6.018 N, a 66 % gap: the thesis figure matches the
    pseudoinverse projector.)
    """
    J = jac_planar(Q73, L3)
    u = np.array([1.0, 0.0])
    f_s = rm.max_force_scaling(J, u, torque_min=-0.5, torque_max=0.5)
    f_k, tau = rm.max_force(J, u, torque_min=-0.5, torque_max=0.5, projector="pseudoinverse", return_torque=True)
    assert f_s == pytest.approx(2.0706, abs=1e-4)
    assert f_k == pytest.approx(2.3513, abs=1e-4)
    assert 1 - f_s / f_k == pytest.approx(0.12, abs=0.02)
    assert np.sum(np.isclose(np.abs(tau), 0.5)) == 2  # two joints saturated, as in Fig. 7.1(c)
    M = mass_planar_point(Q73, L3, np.full(3, 0.5))
    f_d = rm.max_force(J, u, torque_min=-0.5, torque_max=0.5, projector="dynamic", M=M)
    assert f_d == pytest.approx(6.018, abs=1e-3)


def test_max_force_errors(rng):
    J = rng.normal(size=(2, 3))
    kw = dict(torque_min=-np.ones(3), torque_max=np.ones(3))
    with pytest.raises(InfeasibleLimits, match="torque_min"):
        rm.max_force_scaling(J, [1, 0], torque_min=[0.0, 2.0, 0.0], torque_max=[1.0, 1.0, 1.0])
    with pytest.raises(InfeasibleLimits, match="torque_min"):
        rm.max_force_scaling(J, [1, 0], torque_min=[0.1, 0.0, 0.0], torque_max=[1.0, 1.0, 1.0])
    with pytest.raises(InfeasibleLimits, match="torque_max"):
        rm.max_force(J, [1, 0], torque_min=-np.ones(3), torque_max=[-0.1, 1.0, 1.0], projector="pseudoinverse")
    with pytest.raises(InvalidInput, match="torque_max"):
        rm.max_force_scaling(J, [1, 0], torque_min=-np.ones(3), torque_max=np.ones(2))
    with pytest.raises(InvalidInput, match="M"):
        rm.max_force(J, [1, 0], **kw)  # default projector is dynamic
    with pytest.raises(InvalidInput, match="M"):
        rm.max_force(J, [1, 0], projector="pseudoinverse", M=np.eye(3), **kw)
    with pytest.raises(InvalidInput, match="projector"):
        rm.max_force(J, [1, 0], projector="pseudo", **kw)
    with pytest.raises(InvalidInput, match="u"):
        rm.max_force(J, [0, 0], projector=None, **kw)
    with pytest.raises(Singular, match="J"):
        rm.max_force(np.array([[1.0, 0, 0], [2.0, 0, 0]]), [1, 0], projector="pseudoinverse", **kw)


def test_max_force_scaling_singular_direction_is_unbounded():
    J = jac_planar(np.array([0.4, 0.0]), np.array([0.3, 0.2]))
    f, tau = rm.max_force_scaling(
        J, [np.cos(0.4), np.sin(0.4)], torque_min=-1.0, torque_max=1.0, return_torque=True
    )
    assert f == np.inf
    np.testing.assert_array_equal(tau, 0.0)


# --- broadcasting: a batch equals the per-item loop ---------------------------------------------


def _batch_cases(rng):
    B = 4
    J = rng.normal(size=(B, 2, 3))
    M = random_spd(rng, 3, (B,))
    u = random_unit(rng, 2, (B,))
    tmax = rng.uniform(0.5, 2.0, (B, 3))
    A = random_spd(rng, 2, (B,))
    q = rng.uniform(-1, 1, (B, 3))
    Js = rng.normal(size=(B, 2, 2))
    lo, hi = -rng.uniform(0.2, 1, (B, 3)), rng.uniform(0.2, 1, (B, 3))
    return [
        (rm.weighted_pinv, (J, M)),
        (rm.dynamic_pinv, (J, M)),
        (rm.nullspace_projector, (J, M)),
        (rm.velocity_nullspace_projector, (J, M)),
        (rm.velocity_ellipsoid, (J,)),
        (rm.effective_manipulability, (J, u)),
        (rm.reflected_friction, (J, u)),
        (rm.manipulability, (J,)),
        (rm.isotropy, (J,)),
        (rm.force_ellipsoid, (J, tmax)),
        (rm.directional_manipulability, (J, u, tmax)),
        (lambda a: rm.ellipsoid_axes(a)[0], (A,)),
        (rm.apparent_inertia, (J, M)),
        (rm.effective_inertia, (J, M, u)),
        (rm.jbld, (A, A[::-1])),
        (rm.desired_vme, (u, np.full(B, 0.1))),
        (lambda j, qq: rm.penalized_jacobian(j, qq, q_min=-np.ones(3), q_max=np.ones(3), k_q=3.0), (J, q)),
        (rm.teleoperation_ellipsoid, (J, Js)),
        (rm.tmi, (J, Js)),
        (rm.joint_energy, (A, u)),
        (lambda j, uu, a, b: rm.max_force_scaling(j, uu, torque_min=a, torque_max=b), (J, u, lo, hi)),
        (lambda j, uu, a, b: rm.max_force(j, uu, torque_min=a, torque_max=b, projector="pseudoinverse"), (J, u, lo, hi)),
    ]


def test_batch_equals_loop(rng):
    for fn, args in _batch_cases(rng):
        batched = fn(*args)
        looped = np.stack([fn(*(a[k] for a in args)) for k in range(4)])
        np.testing.assert_allclose(batched, looped, rtol=1e-10, atol=1e-12, err_msg=repr(fn))


def test_leading_axes_broadcast(rng):
    J = rng.normal(size=(5, 1, 2, 3))
    u = random_unit(rng, 2, (4,))
    rho = rm.effective_manipulability(J, u)
    assert rho.shape == (5, 4)
    np.testing.assert_allclose(rho[3, 2], rm.effective_manipulability(J[3, 0], u[2]), rtol=1e-14)
    M = random_spd(rng, 3)
    assert rm.effective_inertia(J, M, u).shape == (5, 4)
    f = rm.max_force(J, u, torque_min=-1.0, torque_max=1.0, projector="dynamic", M=M)
    assert f.shape == (5, 4)
    assert f[1, 3] == pytest.approx(
        rm.max_force(J[1, 0], u[3], torque_min=-1.0, torque_max=1.0, projector="dynamic", M=M), rel=1e-9
    )


def test_no_function_returns_nan_at_singular_configurations():
    Js = np.stack([jac_planar(np.array([a, 0.0]), np.array([0.3, 0.2])) for a in np.linspace(0, 3, 7)])
    u = np.array([[np.cos(a), np.sin(a)] for a in np.linspace(0, 3, 7)])
    M = np.eye(2)
    outputs = [
        rm.effective_manipulability(Js, u),
        rm.reflected_friction(Js, u),
        rm.manipulability(Js),
        rm.isotropy(Js),
        rm.directional_manipulability(Js, u, 1.0),
        rm.effective_inertia(Js, M, u),
        rm.tmi(Js, Js),
        rm.teleoperation_ellipsoid(Js, Js),
        rm.max_force_scaling(Js, u, torque_min=-1.0, torque_max=1.0),
    ]
    for out in outputs:
        assert not np.any(np.isnan(out))
    assert issubclass(Singular, RhiError)


@pytest.mark.parametrize("scale", [1e-200, 1e-150, 1e150, 1e200])
def test_radius_along_is_scale_invariant(rng, scale):
    """ρ(cJ, u) = c ρ(J, u): semi-axes of 1e-200 m/s neither underflow to 0 nor overflow (radius_along)."""
    J = rng.normal(size=(5, 2, 4))
    u = rng.normal(size=(5, 2))
    ref = rm.effective_manipulability(J, u)
    assert np.all(ref > 0)
    np.testing.assert_allclose(rm.effective_manipulability(scale * J, u), scale * ref, rtol=1e-12)
    flat = J.copy()
    flat[:, 1] = 1e-9 * flat[:, 0]  # rank 1: lost along the second axis, the rule unchanged by the scale
    np.testing.assert_array_equal(rm.effective_manipulability(scale * flat, u) == 0,
                                  rm.effective_manipulability(flat, u) == 0)


def test_log_det_gradient_matches_finite_differences(rhi4, phantom, rng):
    """∇ log det(JJᵀ) against central differences, batched; a singular JJᵀ is `Singular`, a misshapen dJ named."""
    for dev in (rhi4, phantom):
        Q = random_q(dev, rng, 3)
        got = rm.log_det_gradient(dev.jacobian(Q), dev.jacobian_derivative(Q))
        for q, g in zip(Q, got):
            want = fd_jacobian(lambda x, d=dev: np.linalg.slogdet(d.jacobian(x) @ d.jacobian(x).T)[1], q)
            np.testing.assert_allclose(g, want, rtol=1e-5, atol=1e-6)
    with pytest.raises(Singular, match="J"):
        rm.log_det_gradient(np.zeros((2, 3)), np.zeros((2, 3, 3)))
    with pytest.raises(InvalidInput, match="dJ"):
        rm.log_det_gradient(np.eye(2, 3), np.zeros((2, 3)))
