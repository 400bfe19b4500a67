"""Many copies of one function of the JAX loop, in compiled calls of at most :data:`COPIES_PER_CALL` copies.

Why not one ``vmap`` over every copy: on the CPU, jaxlib 0.10's LAPACK kernels (the batched LU of
``jnp.linalg.solve`` and the SVD of the planner) split a large enough batch over XLA's intra-op thread pool and
block until its pieces are done. In the closed loop's step, with several such calls in one program, this machine's
two-thread pool wedges: every thread waits on a piece that no thread is free to run (a native stack shows both in
``ParallelBatchMap``; no CPU is used from then on). One step of 1,024 copies hung on every try here; 512 never did. A
``lax.map`` over slices of ``COPIES_PER_CALL`` copies, each slice one ``vmap``, keeps every LAPACK call's batch at
that size and gives each copy the result of ``fn`` on that copy alone (``tests/library/jax/test_jax_copies.py``). docs/jax.md
has the measurements.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.jax.physics import jax

COPIES_PER_CALL = 512


def over_copies(fn: Callable[..., Any], per_call: int = COPIES_PER_CALL) -> Callable[..., Any]:
    """``fn`` of one copy's arguments as a function of stacked arguments (leading axis: the copies), like
    ``jax.vmap(fn)``, but run ``per_call`` copies at a time when there are more (the last slice may be smaller)."""
    if isinstance(per_call, bool) or not isinstance(per_call, int) or per_call < 1:
        raise InvalidInputError(f"per_call = {per_call}; allowed: an integer >= 1")
    batched = jax.vmap(fn)

    def run(*args: Any) -> Any:
        copies = jax.tree_util.tree_leaves(args)[0].shape[0]
        if copies <= per_call:
            return batched(*args)
        return jax.lax.map(lambda one: fn(*one), args, batch_size=per_call)

    return run
