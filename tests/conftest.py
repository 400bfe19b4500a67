"""Shared fixtures: the shipped robot, its collision model and the paper's initial state; the
scripts of ``experiments/`` as modules."""

from __future__ import annotations

import importlib.util
import os
import sys
from functools import cache
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

# the kernel's first-use notices (a compilation's progress bar) stay out of tests that read stderr
os.environ.setdefault("FFSR_GYM_QUIET_COMPILE", "1")
# A developer runs the tests on uncommitted code: the tables the tests write take its entries
# (tests/library/bench/test_entry_save.py checks the refusal without it).
os.environ.setdefault("FFSR_GYM_ALLOW_DIRTY", "1")

from ffsr_gym.model.collision import CollisionModel  # noqa: E402
from ffsr_gym.model.robot import Robot, load_robot  # noqa: E402
from ffsr_gym.model.scenario import Scenario, load_scenario  # noqa: E402


@pytest.fixture(scope="session")
def robot() -> Robot:
    return load_robot("ffsr_dual_arm")


@pytest.fixture(scope="session")
def collision_model(robot: Robot) -> CollisionModel:
    return CollisionModel(robot)


@pytest.fixture(scope="session")
def paper() -> Scenario:
    return load_scenario("paper")


@pytest.fixture()
def q_paper(robot: Robot, paper: Scenario) -> np.ndarray:
    joints = np.radians(paper.initial.mission_joints_deg + paper.initial.balance_joints_deg)
    return robot.configuration(
        base_position_m=np.array(paper.initial.base_position_m),
        base_quaternion_wxyz=np.array(paper.initial.base_quaternion_wxyz),
        joints_rad=joints,
    )


def random_configuration(robot: Robot, rng: np.random.Generator) -> np.ndarray:
    """A configuration with a random base pose and joint angles in [-pi, pi]."""
    quat = rng.normal(size=4)
    return robot.configuration(
        base_position_m=rng.uniform(-1, 1, 3),
        base_quaternion_wxyz=quat / np.linalg.norm(quat),
        joints_rad=rng.uniform(-np.pi, np.pi, 12),
    )


@cache
def script_module(name: str, folder: str = "experiments") -> ModuleType:
    """``<folder>/<name>.py`` (a script of ``experiments/`` or ``baselines/``, not a package module) loaded as a
    module, once per session, with its folder on ``sys.path`` as ``python <folder>/<name>.py`` has it (the scripts
    import their sibling helpers, e.g. ``study_rows``)."""
    path = Path(__file__).resolve().parents[1] / folder / f"{name}.py"
    if str(path.parent) not in sys.path:
        sys.path.append(str(path.parent))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@cache
def retired_v1_rules():
    """Benchmark v1's rule file (retired) as v2's with v1's blend law, contact as the collision test and no
    ensemble or validation pool: v2.toml differs from v1.toml in exactly these keys (checked equal when v1 was
    retired). For the tests that keep v1's documented history regenerable; no environment plays v1."""
    import dataclasses

    from ffsr_gym.versions.registry import load_benchmark

    v2 = load_benchmark("v2")
    return dataclasses.replace(v2, version="v1", score=dataclasses.replace(v2.score, keep_out_m=0.0),
                               planner=dataclasses.replace(v2.planner, mu_law="cdf"),
                               tasks=dataclasses.replace(v2.tasks, ensemble=None, validation_tasks=0))


def assert_edited_rule_file_is_named(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, name: str, path_function: str,
                                     loader, edit: tuple[str, str], message: str) -> None:
    """Load the shipped rule file ``envs/benchmark/<name>`` with one edit (``old`` -> ``new``) through ``loader`` (a
    cached loader of :mod:`ffsr_gym.tasks.perturbation`, whose ``path_function`` names the file's path), and expect
    a :class:`~ffsr_gym.exceptions.ScenarioError` containing ``message``."""
    import re

    from ffsr_gym.exceptions import ScenarioError
    from ffsr_gym.model.resources import envs_dir
    from ffsr_gym.tasks import perturbation

    old, new = edit
    text = (envs_dir() / "benchmark" / name).read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    monkeypatch.setattr(perturbation, path_function, lambda version: str(path))
    loader.cache_clear()
    try:
        with pytest.raises(ScenarioError, match=re.escape(message)):
            loader("v2")
    finally:
        monkeypatch.undo()
        loader.cache_clear()


def replay_certificate(version: str, tier: str, split: str, index: int) -> dict:
    """Step pool task ``index``'s certificate through the version's registered environment (its parameters id
    with ``step_with_parameters`` for a constant certificate, its residual id for a residual one); the last
    step's info."""
    import gymnasium as gym

    from ffsr_gym.tasks.splits import pool
    from ffsr_gym.versions.registry import spec_for_version

    task = pool(tier, split, version=version)[index]
    certificate, ids = task.certificate, spec_for_version(version).ids
    env = gym.make(ids.parameters if certificate.kind == "constant" else ids.residual, task=tier, split=split)
    _, info = env.reset(seed=0, options={"task_index": index})
    assert info["task_seed"] == task.seed
    action = None if certificate.residual is None else np.array(certificate.residual, dtype=np.float32)
    try:
        while True:
            if action is None:
                _, _, terminated, truncated, info = env.unwrapped.step_with_parameters(certificate.m,
                                                                                       certificate.T_c_s)
            else:
                _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                return info
    finally:
        env.close()


def random_states(rng, n):
    """(19,) kernel states: base position, unit quaternion (x, y, z, w), 12 joint angles in ±1.5 rad."""
    out = []
    for _ in range(n):
        quat = rng.normal(size=4)
        out.append(np.concatenate((rng.uniform(-0.5, 0.5, 3), quat / np.linalg.norm(quat), rng.uniform(-1.5, 1.5, 12))))
    return out


def pool_cases(version: str, tiers: tuple[str, ...], per_pool: int | None,
               splits: tuple[str, ...] = ("train", "validation", "test")) -> list[tuple[str, str, int]]:
    """(tier, split, index) of ``per_pool`` tasks spread over each of ``version``'s pools (None: every task)."""
    from ffsr_gym.tasks.splits import pool

    out = []
    for tier in tiers:
        for split in splits:
            n = len(pool(tier, split, version=version))
            picks = range(n) if per_pool is None else np.linspace(0, n - 1, per_pool).round().astype(int)
            out += [(tier, split, int(i)) for i in picks]
    return out


def ensemble_problems(version: str, tier: str, split: str, index: int) -> list[str]:
    """Replay pool task ``index``'s certificate at dt and in every member of its ensemble (the spin members and the
    confirmation backend included); what fails, or what differs from the worst margins the pool file stores. Each
    member's margins are :func:`~ffsr_gym.tasks.certificate.replay_with_margins`' (a timed certificate's capture
    ratio is its whole run's), merged over the members as the build merges them."""
    from ffsr_gym.bench.replay_tolerance import tolerance_for
    from ffsr_gym.tasks.certificate import Member, ensemble_members, replay_with_margins
    from ffsr_gym.tasks.perturbation import confirmation_member
    from ffsr_gym.tasks.splits import pool, task_scenario
    from ffsr_gym.versions.registry import load_benchmark

    rules = load_benchmark(version)
    entry = pool(tier, split, version=version)[index]
    task = task_scenario(tier, entry.seed, rules)
    members = [Member("dt", task), *ensemble_members(task, entry.seed, rules.tasks.ensemble, pinocchio=False),
               confirmation_member(task, version)]
    where, worst = f"{version} {tier}/{split}[{index}]", None
    for member in members:
        result, margins = replay_with_margins(member.task, entry.certificate, rules, backend=member.backend)
        if not result.success:
            return [f"{where}: fails at {member.name} ({result.failure})"]
        worst = margins if worst is None else worst.merge(margins)
    stored = entry.margins
    if stored is None or stored.episodes != worst.episodes:
        return [f"{where}: stored margins {stored} for {worst.episodes} episodes"]
    problems = [] if worst.short(rules) is None else [f"{where}: {worst.short(rules)}"]
    tolerance = tolerance_for(version)
    for key in ("min_clearance_m", "min_self_clearance_m", "peak_rate_deg_s", "capture_ratio"):
        if getattr(stored, key) != pytest.approx(getattr(worst, key), rel=tolerance.margin_rel_tol):
            problems.append(f"{where}: stored {key} {getattr(stored, key)} != {getattr(worst, key)}")
    return problems


def timed_episode(tier: str, split: str, index: int, m: float, T_c: float, go_s: float) -> dict:
    """Capture-v1 pool task ``index`` stepped through ``FFSR-Capture-v1``: the planner at (m, T_c [s]), the start pose
    held (u = 0) until the first decision at or after ``go_s`` [s], then the grasp frame commanded (u = 2); the
    last step's info."""
    import gymnasium as gym

    from ffsr_gym.tasks.splits import pool, task_scenario
    from ffsr_gym.versions.registry import load_benchmark

    rules = load_benchmark("capture-v1")
    task = pool(tier, split, version="capture-v1")[index]
    env = gym.make("FFSR-Capture-v1", task=tier, split=split)
    _, info = env.reset(seed=0, options={"task_index": index})
    assert info["task_seed"] == task.seed
    decision = task_scenario(tier, task.seed, rules).env.decision_interval_s
    try:
        for k in range(600):
            command = 2.0 if k * decision >= go_s - 1e-9 else 0.0
            _, _, terminated, truncated, info = env.unwrapped.step_with_parameters(m, T_c, command=command)
            if terminated or truncated:
                return info
    finally:
        env.close()
    raise AssertionError("the episode did not end in 600 decisions")
