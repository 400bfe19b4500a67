"""The benchmark versions this install knows, and which is ranked: the version policy above the model's data.

The model reads what a version's files say (:mod:`ffsr_gym.model.spec`, :mod:`ffsr_gym.model.benchmark`); this
module says which versions there are: the rule files shipped (:data:`VERSIONS`, :data:`CAPTURE_VERSIONS`,
:func:`load_benchmark`), the spec files shipped and those added at run time (:func:`add_spec`, which
``ffsr_gym.register_spec`` calls), the version of an id, and the live version the generated summary ranks
(:func:`ranked_spec`).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.benchmark import Benchmark, load_rules
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.model.spec import BenchmarkSpec, read_spec

#: The ranked rule files shipped (the newest last: scripts default to it).
VERSIONS = ("v2",)
#: The capture families' rule files (beyond the paper; docs/model.md §22, §24), loaded by the same
#: :func:`load_benchmark`.
CAPTURE_VERSIONS = ("capture-v0", "capture-v1", "capture-v2")


def load_benchmark(version: str = VERSIONS[-1]) -> Benchmark:
    """The rule file of benchmark ``version`` shipped in ``envs/benchmark`` (``<version>.toml``).

    Raises:
        ScenarioError: unknown version, unreadable file or an invalid key (named).
    """
    if version not in VERSIONS + CAPTURE_VERSIONS:
        raise ScenarioError(f"benchmark version {version!r}; allowed: {list(VERSIONS + CAPTURE_VERSIONS)}")
    return load_rules(envs_dir() / "benchmark" / f"{version}.toml")


def shipped_spec_paths() -> list[Path]:
    """The spec files shipped in ``envs/benchmark``, in version order."""
    return sorted((envs_dir() / "benchmark").glob("spec_*.toml"))


_REGISTERED: dict[str, BenchmarkSpec] = {}


@lru_cache(maxsize=1)
def _shipped() -> dict[str, BenchmarkSpec]:
    specs = [read_spec(path) for path in shipped_spec_paths()]
    return {spec.version: spec for spec in specs}


def all_specs() -> dict[str, BenchmarkSpec]:
    """Every known version: the shipped specs, then those added with :func:`add_spec`."""
    return {**_shipped(), **_REGISTERED}


def add_spec(spec: BenchmarkSpec) -> None:
    """Make ``spec`` known (its ids resolve through :func:`spec_for_env_id`).

    Raises:
        ScenarioError: its version or one of its ids is taken by another spec.
    """
    for other in all_specs().values():
        if other.version == spec.version and other.source != spec.source:
            raise ScenarioError(f"{spec.source}: version {spec.version!r} is taken by {other.source}")
        taken = set(other.env_ids) & set(spec.env_ids)
        if taken and other.version != spec.version:
            raise ScenarioError(f"{spec.source}: env ids {sorted(taken)} are taken by version {other.version!r}")
    _REGISTERED[spec.version] = spec


def spec_for_version(version: str) -> BenchmarkSpec:
    """The spec of ``version``.

    Raises:
        ScenarioError: unknown version (the known ones are listed).
    """
    specs = all_specs()
    if version not in specs:
        raise ScenarioError(f"benchmark version {version!r}; allowed: {sorted(specs)}")
    return specs[version]


def registered_ids() -> list[str]:
    """Every id of every known version, in version order."""
    return [env_id for spec in all_specs().values() for env_id in spec.env_ids]


def all_task_names() -> list[str]:
    """Every task name a version takes besides scenario paths: its named scenarios and tiers."""
    names: list[str] = []
    for spec in all_specs().values():
        names += [n for n in (*spec.tasks.scenarios, *spec.tasks.tiers) if n not in names]
    return names


def all_splits() -> list[str]:
    """Every split of a version's pools."""
    return sorted({split for spec in all_specs().values() for split in spec.tasks.splits})


def ranked_spec() -> BenchmarkSpec:
    """The newest live version ranked by CI separation: the one the generated summary, the leaderboard
    figures and the Pareto study show."""
    live = [s for s in all_specs().values() if s.leaderboard.ranking == "ci_separation" and s.status == "live"]
    return sorted(live, key=lambda s: s.version)[-1]


def spec_for_env_id(env_id: str) -> BenchmarkSpec | None:
    """The spec that registers ``env_id`` (a ``module:`` prefix is ignored), or None."""
    key = env_id.split(":")[-1]
    for spec in all_specs().values():
        if key in spec.env_ids:
            return spec
    return None


def spec_of(env_id: Any) -> BenchmarkSpec:
    """The spec of a registered FFSR id.

    Raises:
        InvalidInputError: not one (the known ids are listed).
    """
    spec = spec_for_env_id(env_id) if isinstance(env_id, str) else None
    if spec is None:
        known = [i for s in all_specs().values() for i in s.env_ids]
        raise InvalidInputError(f"env_id {env_id!r}; allowed: {known}")
    return spec


def remove_spec(version: str) -> BenchmarkSpec:
    """Forget a version added with :func:`add_spec` (shipped versions stay).

    Raises:
        ScenarioError: ``version`` was not added.
    """
    if version not in _REGISTERED:
        raise ScenarioError(f"benchmark version {version!r} was not added; added: {sorted(_REGISTERED)}")
    return _REGISTERED.pop(version)
