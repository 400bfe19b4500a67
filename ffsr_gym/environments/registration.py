"""Gymnasium ids from the benchmark specs: one loop over the versions, two ids each (one per action mode)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium
from gymnasium.wrappers import TimeLimit

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.spec import BenchmarkSpec, read_spec
from ffsr_gym.versions.registry import add_spec, all_specs, remove_spec

SINGLE = "ffsr_gym.environments.registration:make_single"
BATCHED = "ffsr_gym.environments.registration:make_batched"
#: The key of an id's registered kwargs that records what the id fixes (its version and action mode); Gymnasium
#: merges a caller's kwargs over the registered ones, so only this record can tell that a ``version=`` or
#: ``residual=`` argument contradicts the id.
FIXED = "id_fixes"


def _checked(kwargs: dict[str, Any]) -> dict[str, Any]:
    """``kwargs`` without :data:`FIXED`, after checking that ``version`` and ``residual`` are the id's.

    Raises:
        InvalidInputError: a ``version`` or ``residual`` argument other than the id's.
    """
    kwargs = dict(kwargs)
    fixed = kwargs.pop(FIXED, None)
    if fixed is not None:
        version, residual = fixed
        for key, value in (("version", version), ("residual", residual)):
            if key in kwargs and type(kwargs[key]) is type(value) and kwargs[key] != value:  # else its own check
                raise InvalidInputError(f"{key}={kwargs[key]!r}: this id is {key} {value!r}; an id fixes its version "
                                        "and action mode (make the id of the version you want, e.g. "
                                        "gymnasium.make('FFSR-v0'))")
    return kwargs


def make_batched(num_envs: int, **kwargs: Any) -> gymnasium.vector.VectorEnv:
    """The batched env of an id (:class:`~ffsr_gym.environments.vector_env.FFSRVectorEnv`), its version and mode
    checked against the id's."""
    from ffsr_gym.environments.vector_env import FFSRVectorEnv

    return FFSRVectorEnv(num_envs, **_checked(kwargs))


def make_single(**kwargs: Any) -> gymnasium.Env:
    """The single env of an id inside a ``TimeLimit`` of its task's own number of decisions.

    One rule for an episode's length: the task's duration over its decision interval (whole
    numbers, checked when the scenario loads). A 40 s custom task plays 400 decisions through
    ``gymnasium.make`` as through every other path, and ``env.spec.max_episode_steps`` says so;
    the ids are registered without a limit of their own, which could only be the shipped tasks'.
    """
    from ffsr_gym.environments.env import FFSREnv

    env = FFSREnv(**_checked(kwargs))
    return TimeLimit(env, env.decisions)


def register_version(spec: BenchmarkSpec) -> None:
    """Register both ids of ``spec`` (single and batched entry points, the version and mode as kwargs)."""
    for residual, env_id in ((False, spec.ids.parameters), (True, spec.ids.residual)):
        gymnasium.register(id=env_id, entry_point=SINGLE, vector_entry_point=BATCHED,
                           kwargs={"version": spec.version, "residual": residual, FIXED: (spec.version, residual)})


def register_all() -> None:
    """Register every known version's ids."""
    for spec in all_specs().values():
        register_version(spec)


def register_spec(path: str | Path) -> BenchmarkSpec:
    """Read a spec file from anywhere, make its version known and register its two ids.

    Raises:
        ScenarioError: an invalid spec file (the key named), or a version or id already taken.
    """
    spec = read_spec(path)
    add_spec(spec)
    register_version(spec)
    return spec


def unregister_spec(version: str) -> None:
    """Remove a version added with :func:`register_spec`, and its two ids from Gymnasium's registry."""
    spec = remove_spec(version)
    for env_id in spec.env_ids:
        gymnasium.registry.pop(env_id, None)
