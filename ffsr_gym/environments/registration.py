"""Gymnasium ids from the benchmark specs: one loop over the versions, two ids each (one per action mode)."""

from __future__ import annotations

from pathlib import Path

import gymnasium

from ffsr_gym.model.spec import BenchmarkSpec, add_spec, all_specs, read_spec, remove_spec

SINGLE = "ffsr_gym.environments.env:FFSREnv"
BATCHED = "ffsr_gym.environments.vector_env:FFSRVectorEnv"


def register_version(spec: BenchmarkSpec) -> None:
    """Register both ids of ``spec`` (single and batched entry points, the version and mode as kwargs)."""
    for residual, env_id in ((False, spec.ids.parameters), (True, spec.ids.residual)):
        gymnasium.register(id=env_id, entry_point=SINGLE, vector_entry_point=BATCHED,
                           max_episode_steps=spec.ids.max_episode_steps or None,
                           kwargs={"version": spec.version, "residual": residual})


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
