"""What a vector env's ``reset`` takes, checked one way for every vector env of the package (the kernel's and the
JAX loop's): the same errors for the same inputs."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.environments.task_source import check_reset_options
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.spec import BenchmarkSpec


def check_open(envs: Any) -> None:
    """Refuse to use a vector env after its ``close()``.

    Raises:
        InvalidInputError: ``envs`` is closed.
    """
    if envs.closed:
        raise InvalidInputError("this vector env is closed; allowed: make a new one (gymnasium.make_vec)")


def check_options(options: Any, allowed: tuple[str, ...], spec: BenchmarkSpec) -> None:
    """``reset``'s ``options``: None, or a dict of the ``allowed`` keys only.

    Raises:
        InvalidInputError: not a dict, or a key outside ``allowed`` (named).
    """
    if options is not None and not isinstance(options, dict):
        raise InvalidInputError(f"options must be a dict or None, got {type(options).__name__}")
    check_reset_options(options, allowed, spec)


def _is_seed(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool) and int(x) >= 0


def copy_seeds(seed: Any, num_envs: int) -> list[int | None]:
    """Per-copy seeds of ``reset(seed=...)``: an int s gives s, s + 1, ...; a list gives one per copy.

    Raises:
        InvalidInputError: anything else, naming what is allowed.
    """
    if seed is None:
        return [None] * num_envs
    if _is_seed(seed):
        return [int(seed) + i for i in range(num_envs)]
    if isinstance(seed, (list, tuple, np.ndarray)) and len(seed) == num_envs \
            and all(s is None or _is_seed(s) for s in seed):
        return [None if s is None else int(s) for s in seed]
    raise InvalidInputError(f"seed = {str(seed)[:80]}; allowed: None, a non-negative integer, or a list of {num_envs} "
                            "such integers (or None), one per copy")


def reset_mask(options: dict | None, num_envs: int, started: bool) -> np.ndarray:
    """The copies a reset resets: ``options["reset_mask"]`` (a bool array, one per copy, at least one True; after
    the first reset), else all.

    Raises:
        InvalidInputError: any other mask, or a partial one at the first reset.
    """
    mask = (options or {}).get("reset_mask")
    if mask is None:
        return np.ones(num_envs, dtype=bool)
    if (not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (num_envs,)
            or not mask.any()):
        raise InvalidInputError(f"options['reset_mask'] = {str(mask)[:80]}; allowed: a numpy bool array of shape "
                                f"({num_envs},) with at least one True")
    if not started and not mask.all():
        raise InvalidInputError("options['reset_mask']: the first reset resets every copy")
    return mask.copy()


def task_indices(options: dict | None, num_envs: int, pooled: bool) -> list[Any] | None:
    """``options["task_index"]``: one pool index per copy (their range is the pool's to check), or None.

    Raises:
        InvalidInputError: not a list of ``num_envs`` entries, or an env that plays no pool.
    """
    indices = (options or {}).get("task_index")
    if indices is None:
        return None
    if not pooled or np.ndim(indices) != 1 or len(indices) != num_envs:
        raise InvalidInputError(f"options['task_index'] = {str(indices)[:80]}; allowed: a list of {num_envs} pool "
                                "indices, one per copy, on a tier's pool")
    return [int(i) if isinstance(i, (int, np.integer)) and not isinstance(i, bool) else i for i in indices]
