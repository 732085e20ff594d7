import jax.numpy as jnp
import numpy as np
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
