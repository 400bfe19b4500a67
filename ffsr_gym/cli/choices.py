"""The choices the command line offers, read from the package (tiers, versions, algorithms, build targets)."""

from __future__ import annotations


def build_targets() -> list[str]:
    """What ``tasks build --tier`` builds: ``base`` (easy, medium and hard together), one perturbed tier, or one
    capture tier (``--version capture-v0``, ``capture-v1``, ``capture-v2``)."""
    from ffsr_gym.tasks.capture_family import CAPTURE_TIERS
    from ffsr_gym.tasks.capture_timed import TIMED_TIERS
    from ffsr_gym.tasks.perturbation import PERTURBED_TIERS

    return ["base", *PERTURBED_TIERS, *CAPTURE_TIERS, *TIMED_TIERS]


def all_task_tiers() -> list[str]:
    """Every tier of a pool version: easy, medium, hard and the perturbed ones."""
    from ffsr_gym.tasks.tiers import ALL_TIERS

    return list(ALL_TIERS)


def capture_tiers() -> list[str]:
    """The capture families' tiers (``--version capture-v0``, then ``capture-v1``)."""
    from ffsr_gym.tasks.capture_family import CAPTURE_TIERS
    from ffsr_gym.tasks.capture_timed import TIMED_TIERS

    return list(CAPTURE_TIERS + TIMED_TIERS)


def tier_versions() -> list[str]:
    """The benchmark versions with task tiers (a rule file): the ranked v2 first, then the capture family's."""
    from ffsr_gym.versions.registry import CAPTURE_VERSIONS, VERSIONS

    return list(VERSIONS + CAPTURE_VERSIONS)


def algorithm_names() -> list[str]:
    """The algorithms with a shipped hyperparameter file."""
    from ffsr_gym.optim.rl import algorithms

    return sorted(algorithms())
