import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from lookout._math import rotate, rotate_transpose, rotation, ssa

angles = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False)


@given(angles)
def test_ssa_range_and_congruence(angle):
    wrapped = float(ssa(jnp.asarray(angle)))
    assert -np.pi <= wrapped < np.pi
    assert abs(np.sin(wrapped) - np.sin(angle)) < 1e-9 and abs(np.cos(wrapped) - np.cos(angle)) < 1e-9


@given(angles)
def test_rotation_is_orthogonal_with_unit_determinant(psi):
    J = np.asarray(rotation(jnp.asarray(psi)))
    np.testing.assert_allclose(J @ J.T, np.eye(3), atol=1e-12)
    assert abs(np.linalg.det(J) - 1.0) < 1e-12


@given(angles, st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3))
def test_written_out_rotations_match_matrix(psi, vector):
    v = jnp.asarray(vector)
    J = np.asarray(rotation(jnp.asarray(psi)))
    np.testing.assert_allclose(rotate(psi, v), J @ np.asarray(vector), atol=1e-9)
    np.testing.assert_allclose(rotate_transpose(psi, v), J.T @ np.asarray(vector), atol=1e-9)


def test_sincos_matches_numpy_to_one_unit_in_the_last_place():
    from lookout._math import sincos

    rng = np.random.default_rng(0)
    for scale in (np.pi, 1e3, 1.5e6):
        x = rng.uniform(-scale, scale, 200_000)
        s, c = sincos(jnp.asarray(x))
        assert np.max(np.abs(np.asarray(s) - np.sin(x))) <= 2 * np.spacing(1.0)
        assert np.max(np.abs(np.asarray(c) - np.cos(x))) <= 2 * np.spacing(1.0)
    quadrants = np.array([0.0, -0.0, np.pi / 2, np.pi, -np.pi, 1.5 * np.pi, 2 * np.pi, 1e-300])
    s, c = sincos(jnp.asarray(quadrants))
    np.testing.assert_allclose(s, np.sin(quadrants), atol=1e-16)
    np.testing.assert_allclose(c, np.cos(quadrants), atol=1e-16)


def test_ssa_maps_pi_to_minus_pi_and_keeps_the_interval_half_open():
    assert float(ssa(jnp.pi)) == -np.pi
    assert float(ssa(-jnp.pi)) == -np.pi
    assert float(ssa(3 * jnp.pi)) == -np.pi
    wrapped = np.asarray(ssa(jnp.asarray(np.random.default_rng(1).uniform(-1e4, 1e4, 100_000))))
    assert wrapped.min() >= -np.pi and wrapped.max() < np.pi


def test_computed_once_returns_its_argument_bit_for_bit():
    from lookout._math import computed_once

    rng = np.random.default_rng(2)
    x = np.concatenate([rng.normal(0, 1, 10_000) * 10.0 ** rng.integers(-300, 300, 10_000), [0.0, -0.0, 2.2250738585072014e-308, 1.7e308]])
    out = np.asarray(computed_once(jnp.asarray(x)))
    # signs of zero included; (subnormals are flushed to zero by XLA:CPU arithmetic in general)
    assert np.array_equal(out.view(np.int64), x.view(np.int64))
    assert np.isnan(np.asarray(computed_once(jnp.asarray([np.nan, np.inf, -np.inf])))).all()


@given(st.integers(1, 6), st.integers(1, 6), st.lists(st.floats(-1e6, 1e6, allow_subnormal=False), min_size=42, max_size=42))
def test_written_out_matvec_equals_matmul_for_every_size(rows, columns, values):
    from lookout._math import matvec

    A, v = np.reshape(values[: rows * columns], (rows, columns)), np.asarray(values[36 : 36 + columns])
    # XLA:CPU treats subnormal inputs as zero and flushes subnormal products to zero, so inputs
    # are normal numbers and agreement is to one smallest normal number per summed product
    atol = max(1e-12 * np.abs(A).sum() * np.abs(v).max(), columns * np.finfo(float).tiny)
    np.testing.assert_allclose(matvec(jnp.asarray(A), jnp.asarray(v)), A @ v, rtol=1e-12, atol=atol)


def test_matvec_refuses_mismatched_shapes_and_uses_matmul_for_wide_matrices():
    from lookout._math import matvec

    with pytest.raises(ValueError, match=r"matvec needs an \(m, n\) matrix and an \(n,\) vector; got shapes \(2, 2\) and \(3,\)"):
        matvec(jnp.ones((2, 2)), jnp.ones(3))
    A, v = np.arange(90.0).reshape(9, 10), np.linspace(-1, 1, 10)
    np.testing.assert_allclose(matvec(jnp.asarray(A), jnp.asarray(v)), A @ v, rtol=1e-13)


@given(angles, st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3))
def test_earth_frame_velocity_is_the_planar_part_of_the_rotation(psi, nu):
    from lookout.analysis import earth_frame_velocity

    expected = np.asarray(rotation(jnp.asarray(psi))) @ np.asarray(nu)
    np.testing.assert_allclose(earth_frame_velocity(psi, nu), expected[:2], rtol=1e-12, atol=1e-9)
    stacked = earth_frame_velocity(np.full(4, psi), np.tile(nu, (4, 1)))
    np.testing.assert_allclose(stacked, np.tile(expected[:2], (4, 1)), rtol=1e-12, atol=1e-9)


@given(st.integers(1, 4), st.lists(st.floats(-1.0, 1.0), min_size=20, max_size=20))
def test_small_solve_equals_lapack(n, values):
    from lookout._math import solve

    A = np.reshape(values[: n * n], (n, n)) + 3.0 * np.eye(n)  # diagonally dominant: well conditioned, like an inertia matrix
    b = np.asarray(values[16 : 16 + n])
    np.testing.assert_allclose(solve(jnp.asarray(A), jnp.asarray(b)), np.linalg.solve(A, b), rtol=1e-12, atol=1e-13)
