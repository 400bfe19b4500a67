"""Where an environment's episodes come from, as its benchmark spec says (``[tasks]``).

* ``scenario``: one scenario (a shipped name, a TOML path or a :class:`Scenario`); a scenario with
  a ``[randomization]`` section is a seeded family, drawn anew at every reset.
* ``tiers``: the certified pools of a tier (``split`` = train, validation or test), one task drawn
  uniformly per reset or picked with ``reset(options={"task_index": i})``. A :class:`Scenario`,
  a path to a scenario TOML file or a shipped scenario name is a *custom task* (``custom``): played
  as it is given, scored by the same rule, never ranked (no split applies to it).

Every task is played as the score rule transforms it (``rule.task``: the rule file's planner
defaults, tolerances and action box). With ``dt_s`` (a version whose spec offers it), every task
runs at that physics step instead of its own; the decisions stay every 0.1 s, so a sensitivity
study plays the same tasks with the same decisions at dt/2 or dt/4.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.scoring.rules import ScoreRule
from ffsr_gym.sim.setup import check_start, prepare
from ffsr_gym.tasks.random_family import sample_scenario
from ffsr_gym.tasks.splits import PoolTask, pool, pool_path, task_scenario


class TaskSource:
    """The tasks of one environment: a fixed scenario, a seeded family, or a tier's pool.

    Attributes:
        name: the task's name (tier, scenario name).
        family: the scenario played (fixed task), the family drawn from, or the pool's first task.
        pool: the pool's tasks (tiers only), else None.
        custom: whether the task is a custom one (a version with tiers given a scenario instead).
    """

    def __init__(self, spec: BenchmarkSpec, rule: ScoreRule, task: Any = None, split: str | None = None,
                 dt_s: Any = None) -> None:
        self.spec, self.rule, self.dt_s = spec, rule, dt_s
        task = spec.tasks.default if task is None else task
        self.custom = is_custom(spec, task)
        self.split = self._check_split(split)
        self.pool: tuple[PoolTask, ...] | None = None
        if isinstance(task, str) and task in spec.tasks.tiers:
            if spec.status == "building" and not pool_path(task, rule.benchmark.version).is_file():
                built = [t for t in spec.tasks.tiers if pool_path(t, rule.benchmark.version).is_file()]
                raise InvalidInputError(f"{spec.tasks.keyword} = {task!r}: the {spec.version} pool of this tier is "
                                        "being built (not shipped yet); allowed until then: "
                                        + (f"the built tiers {built}, or " if built else "")
                                        + "a scenario (a shipped scenario name, a Scenario or a path to a scenario "
                                        ".toml file)")
            self.name, self.pool = task, pool(task, self.split, version=rule.benchmark.version)
            self.family = task_scenario(task, self.pool[0].seed, rule.benchmark)
        else:
            self.name = task if isinstance(task, str) else getattr(task, "name", str(task))
            self.family = rule.task(self._scenario(task))
        if dt_s is not None:
            self.family = self.family.at_step(dt_s)
        self.randomised = self.family.randomization is not None and self.pool is None
        if spec.rules is not None and spec.rules.capture is not None and self.family.tumbling_target is None:
            raise InvalidInputError(f"task {self.name!r}: {spec.ids.parameters} scores a capture, and this scenario has "
                                    "no [tumbling_target] to capture; allowed: a tier of "
                                    f"{list(spec.tasks.tiers)} or a scenario with a [tumbling_target] section")
        if self.pool is None:  # a pool's tasks are certified; a scenario or family is checked before it is played
            check_start(prepare(self.family))

    def _check_split(self, split: str | None) -> str | None:
        splits = self.spec.tasks.splits
        if self.custom and split is not None:
            raise InvalidInputError(f"split = {split!r}: a custom task (a scenario) has no pools; split applies to "
                                    f"the tiers {list(self.spec.tasks.tiers)}")
        if not splits or self.custom:
            if split is not None:
                raise InvalidInputError(f"split = {split!r}: {self.spec.ids.parameters} has no task splits")
            return None
        split = splits[0] if split is None else split
        if split not in splits:
            raise InvalidInputError(f"split {split!r}; allowed: {list(splits)}")
        return split

    def _scenario(self, task: Any) -> Scenario:
        """The scenario of a task that is not a tier (the spec decides what names it accepts)."""
        return scenario_task(self.spec, task)

    def reset_options(self) -> tuple[str, ...]:
        """The ``reset(options=...)`` keys one episode takes: ``task_index`` on a pool, none otherwise."""
        return () if self.pool is None else ("task_index",)

    def draw(self, rng: np.random.Generator, options: dict | None) -> tuple[Scenario, dict[str, int]]:
        """The next episode's scenario (drawn from ``rng``) and what ``reset``'s info says about it.

        Raises:
            InvalidInputError: ``options`` not a dict, a key it does not take (:meth:`reset_options`), or a
                ``task_index`` outside the pool.
        """
        if options is not None and not isinstance(options, dict):
            raise InvalidInputError(f"options must be a dict or None, got {type(options).__name__}")
        check_reset_options(options, self.reset_options(), self.spec)
        if self.pool is None:
            return (sample_scenario(self.family, rng) if self.randomised else self.family), {}
        index = (options or {}).get("task_index")
        if index is None:
            index = int(rng.integers(len(self.pool)))
        elif isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < len(self.pool):
            raise InvalidInputError(f"options['task_index'] = {index!r}; allowed: an integer in [0, {len(self.pool) - 1}]")
        seed = self.pool[int(index)].seed
        task = task_scenario(self.name, seed, self.rule.benchmark)
        if self.dt_s is not None:
            task = task.at_step(self.dt_s)
        return task, {"task_index": int(index), "task_seed": seed}


def check_reset_options(options: dict | None, allowed: tuple[str, ...], spec: BenchmarkSpec) -> None:
    """Refuse a ``reset`` option that this environment does not know or cannot honour, by name.

    Raises:
        InvalidInputError: a key of ``options`` outside ``allowed``.
    """
    unknown = sorted(str(key) for key in (options or {}) if key not in allowed)
    if unknown:
        where = "" if allowed else f" ({spec.ids.parameters} plays a scenario, not a task pool)"
        raise InvalidInputError(f"reset option {unknown[0]!r}; allowed here: {list(allowed)}{where}")


def is_custom(spec: BenchmarkSpec, task: Any) -> bool:
    """Whether ``task`` is a custom task of ``spec``: a version with tiers given anything but a tier or a named task."""
    if spec.tasks.kind != "tiers":
        return False
    return not (isinstance(task, str) and task in (*spec.tasks.tiers, *spec.tasks.scenarios))


def scenario_task(spec: BenchmarkSpec, task: Any) -> Scenario:
    """The scenario of a task that is not a tier: a :class:`Scenario`, a shipped name or a TOML path.

    Raises:
        InvalidInputError: anything else, or a scenario file that does not load (the file's own
            error, which names the key), with what ``task`` allows.
    """
    tasks = spec.tasks
    if not isinstance(task, (Scenario, str, Path)):
        raise InvalidInputError(f"{tasks.keyword} = {type(task).__name__} object; allowed: "
                                f"{[*tasks.scenarios, *tasks.tiers]}, a Scenario or a path to a scenario .toml file")
    try:
        return load_scenario(task)
    except ScenarioError as exc:
        if tasks.kind == "scenario":
            raise
        raise InvalidInputError(f"{tasks.keyword} = {str(task)!r}: {exc}; allowed: {[*tasks.scenarios, *tasks.tiers]}, "
                                "a Scenario, or a shipped scenario name or path to a scenario .toml file "
                                "(a custom task, never ranked)") from None
