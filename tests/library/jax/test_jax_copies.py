"""``ffsr_gym.jax.copies.over_copies``: copies run in slices give, copy by copy, what the function gives on each copy
alone (a Python loop, no ``vmap``), with a last slice smaller than the others; bad slice sizes are refused."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from ffsr_gym.exceptions import InvalidInputError  # noqa: E402
from ffsr_gym.jax.copies import over_copies  # noqa: E402


def _one(A, b, scale):
    """A function of one copy with the LAPACK calls the loop's step makes (LU solve and SVD) and a pytree out."""
    x = jnp.linalg.solve(A, b)
    return {"x": x * scale, "s_min": jnp.linalg.svd(A, compute_uv=False)[-1]}


@pytest.mark.parametrize("copies, per_call", [(7, 3), (6, 3), (2, 5), (1, 1)])
def test_slices_give_each_copys_own_result(copies, per_call):
    rng = np.random.default_rng(copies)
    A = np.eye(6) + 0.3 * rng.standard_normal((copies, 6, 6))
    b, scale = rng.standard_normal((copies, 6)), rng.uniform(0.5, 2.0, copies)
    out = jax.jit(over_copies(_one, per_call))(A, b, scale)
    for i in range(copies):
        alone = np.linalg.solve(A[i], b[i]) * scale[i]
        np.testing.assert_allclose(out["x"][i], alone, rtol=1e-12, atol=1e-12)
        assert out["s_min"][i] == pytest.approx(np.linalg.svd(A[i], compute_uv=False)[-1], rel=1e-12)


@pytest.mark.parametrize("per_call", [0, -4, 2.5, True])
def test_a_bad_slice_size_is_refused(per_call):
    with pytest.raises(InvalidInputError, match="per_call"):
        over_copies(_one, per_call)
