"""Benchmark versions as data: the spec files ``envs/benchmark/spec_<version>.toml``.

A spec names everything that makes a benchmark version: its environment ids, its score rule and
the rule file that holds its numbers, the action boxes and the residual law, the reward, where
its tasks come from (one scenario, a seeded family, or tiered pools), the evaluation protocol,
the metric names and the ranking rule of its leaderboard. One code path (the episode engine, the
environments, ``evaluate``, the leaderboard renderer, ``train`` and the command line) serves every
version by reading its spec; a new version is a new spec file (``register_spec`` takes one from
anywhere), never a new module.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

from ffsr_gym.exceptions import ScenarioError
from ffsr_gym.model.benchmark import Benchmark, load_rules
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.model.schema import BOOL, TEXT, TEXTS, choice, integer, load_table, natural, number, rows, section

#: Score rules the engine knows (``ffsr_gym.scoring.rules``): the paper's objective B (lower is
#: better, +inf when infeasible), the bounded episode score 1 / (1 + C) (higher is better), the same
#: with success a capture of a tumbling target, and a capture's worth (time, contact speed, smoothness).
SCORE_RULES = ("paper_objective", "bounded_smoothness", "capture_smoothness", "capture_quality")
#: Rankings the leaderboard renderer knows: by feasible rate then IQM (ascending), or by IQM with
#: ranks that only a non-overlapping bootstrap CI separates.
RANKINGS = ("feasible_then_iqm", "ci_separation")
#: What a ``ci_separation`` table summarises an entry's episode scores by.
STATISTICS = ("iqm", "mean")
#: The project's pages that hold the live version's generated leaderboard blocks (the top three per tier in the
#: README; the summary, the RL study and the RL searches in the baselines page), relative to a checkout.
GENERATED_PAGES = ("README.md", "docs/baselines.md")


@dataclass(frozen=True)
class Ids:
    """The registered ids: one per action mode, and the episode length of the registration (0: none)."""

    parameters: str = field(metadata=TEXT)
    residual: str = field(metadata=TEXT)
    max_episode_steps: int = field(default=0, metadata=natural(10**7))


@dataclass(frozen=True)
class ScoreSpec:
    """The score rule, the rule file with its numbers ("" = the scenario's own sections) and its text."""

    rule: str = field(metadata=choice(*SCORE_RULES))
    rules_file: str = field(default="", metadata=TEXT)
    text: str = field(default="", metadata=TEXT)


@dataclass(frozen=True)
class ActionSpec:
    """Where the action boxes come from (the scenario's [env] or the rule file's [action]), the residual law, and
    whether the action ends with the commanded approach's command (``command``: one more entry a in [-1, 1],
    u = a + 1; docs/model.md §24)."""

    boxes: str = field(metadata=choice("scenario", "rules"))
    residual_fades: bool = field(metadata=BOOL)
    command: bool = field(default=False, metadata=BOOL)


@dataclass(frozen=True)
class RewardSpec:
    """The reward: minus B's increments and penalties, or the change of the episode's bounded value."""

    kind: str = field(metadata=choice("objective_increment", "score_change"))
    options: tuple[str, ...] = field(default=(), metadata=TEXTS)


@dataclass(frozen=True)
class TaskSpec:
    """Where tasks come from: ``scenario`` (a scenario, or its seeded family) or ``tiers`` (certified pools)."""

    kind: str = field(metadata=choice("scenario", "tiers"))
    keyword: str = field(metadata=choice("scenario", "task"))
    default: str = field(metadata=TEXT)
    scenarios: tuple[str, ...] = field(default=(), metadata=TEXTS)
    tiers: tuple[str, ...] = field(default=(), metadata=TEXTS)
    splits: tuple[str, ...] = field(default=(), metadata=TEXTS)
    step_option: bool = field(default=False, metadata=BOOL)


@dataclass(frozen=True)
class ObservationSpec:
    """What the observation holds besides v2's 53 floats: with ``target_twist``, the desired end-effector twist (6)
    of the planner's step (a moving target's motion; ``ffsr_gym.kernel.decision``); with ``grasp`` (and
    ``target_twist``) then the grasp frame relative to the end-effector (6), its twist (6) and the commanded
    approach's state (5): 76 floats."""

    target_twist: bool = field(default=False, metadata=BOOL)
    grasp: bool = field(default=False, metadata=BOOL)


@dataclass(frozen=True)
class EvaluationSpec:
    """The evaluation protocol: public seeds per id, or one episode per task of a tier's split."""

    protocol: str = field(metadata=choice("seeds", "pool"))
    default_task: str = field(metadata=TEXT)
    split: str = field(default="test", metadata=TEXT)
    parameters_seeds: tuple[int, ...] = field(default=(), metadata=rows(0, 0, 2**31, 2))
    residual_seeds: tuple[int, ...] = field(default=(), metadata=rows(0, 0, 2**31, 2))


@dataclass(frozen=True)
class ReplaySpec:
    """How a replayed episode must agree with the row stored for it (the tests, ``leaderboard verify``;
    :mod:`ffsr_gym.bench.replay_tolerance`): seeds, indices, counts, success and failure always exactly; the score,
    the smoothness cost C and the paper's B within ``score_rel_tol`` (relative; 0: bit for bit); every other number
    (C's terms, margins, times) within ``margin_rel_tol`` of its stored value (relative) or within ``margin_abs_tol``
    of it (absolute: a number that is physically nothing, a final attitude error of 1e-9 rad, meets no relative
    tolerance)."""

    score_rel_tol: float = field(default=0.0, metadata=number(0.0, 0.05))
    margin_rel_tol: float = field(default=0.0, metadata=number(0.0, 1.0))
    margin_abs_tol: float = field(default=0.0, metadata=number(0.0, 1e-3))


@dataclass(frozen=True)
class LeaderboardSpec:
    """Where entries live (``{env_id}``, ``{task}``, ``{version}`` are filled in), metric names, ranking.

    ``statistic``: what an entry's episode scores are summarised by, and ranked on with its bootstrap CI: ``iqm``
    (the interquartile mean) or ``mean``; ``iqm`` names its metric, whichever it is."""

    folder: str = field(metadata=TEXT)
    ranking: str = field(metadata=choice(*RANKINGS))
    title: str = field(metadata=TEXT)
    statistic: str = field(default="iqm", metadata=choice(*STATISTICS))
    iqm: str = field(default="score_iqm", metadata=TEXT)
    ci: str = field(metadata=TEXT, default="score_ci95")
    rate: str = field(metadata=TEXT, default="feasible_rate")
    rate_column: str = field(metadata=TEXT, default="feasible")
    marker: str = field(metadata=TEXT, default="")

    @property
    def label(self) -> str:
        """The statistic as the tables name it."""
        return "IQM" if self.statistic == "iqm" else "mean"

    def markers(self, suffix: str = "") -> tuple[str, str]:
        """The markers between which the generated tables go: the leaderboard README's (no suffix), or the blocks
        of the project's pages (``suffix`` "-summary": the summary across tiers, "-top3": the top three per tier)."""
        name = f"{self.marker}{suffix}"
        command = "ffsr-gym leaderboard render" + (f" --readme {' '.join(GENERATED_PAGES)}" if suffix else "")
        return f"<!-- {name}:start (generated by `{command}`) -->", f"<!-- {name}:end -->"


@dataclass(frozen=True)
class BenchmarkSpec:
    """One benchmark version (see the module docstring and ``envs/benchmark/spec_*.toml``)."""

    schema_version: int = field(metadata=integer(1))
    version: str = field(metadata=TEXT)
    description: str = field(metadata=TEXT)
    status: str = field(metadata=choice("live", "frozen", "building"))
    ids: Ids = field(metadata=section(Ids))
    score: ScoreSpec = field(metadata=section(ScoreSpec))
    actions: ActionSpec = field(metadata=section(ActionSpec))
    reward: RewardSpec = field(metadata=section(RewardSpec))
    tasks: TaskSpec = field(metadata=section(TaskSpec))
    evaluation: EvaluationSpec = field(metadata=section(EvaluationSpec))
    leaderboard: LeaderboardSpec = field(metadata=section(LeaderboardSpec))
    observation: ObservationSpec | None = field(default=None, metadata=section(ObservationSpec))
    replay: ReplaySpec = field(default=ReplaySpec(), metadata=section(ReplaySpec))
    source: str = field(default="", compare=False)

    @property
    def target_twist(self) -> bool:
        """Whether the observation ends with the desired end-effector twist (``[observation] target_twist``)."""
        return self.observation is not None and self.observation.target_twist

    @property
    def grasp_observation(self) -> bool:
        """Whether the observation shows the grasp frame and the approach's state (``[observation] grasp``)."""
        return self.observation is not None and self.observation.grasp

    @property
    def env_ids(self) -> tuple[str, str]:
        """(parameters id, residual id)."""
        return self.ids.parameters, self.ids.residual

    def is_residual(self, env_id: str) -> bool:
        """Whether ``env_id`` (of this version) is its residual id."""
        return env_id.split(":")[-1] == self.ids.residual

    @property
    def rules(self) -> Benchmark | None:
        """The rule file's numbers (score, planner defaults, action boxes, tier rule), or None."""
        if not self.score.rules_file:
            return None
        return load_rules(_resolve(self.score.rules_file, self.source))

    def env_options(self) -> set[str]:
        """The keyword arguments this version's environments take: the task keyword, the split (tiers), the
        physics step ``dt_s`` (when the spec offers it), the reward's options."""
        return {self.tasks.keyword, *(("split",) if self.tasks.splits else ()),
                *(("dt_s",) if self.tasks.step_option else ()), *self.reward.options}

    def eval_seeds(self, env_id: str) -> tuple[int, ...]:
        """The public evaluation seeds of ``env_id`` (protocol ``seeds``): a [start, stop) range."""
        start, stop = self.evaluation.residual_seeds if self.is_residual(env_id) else self.evaluation.parameters_seeds
        return tuple(range(int(start), int(stop)))

    def folder(self, env_id: str, task: str) -> str:
        """The leaderboard folder of an entry (relative to the leaderboard root)."""
        return self.leaderboard.folder.format(env_id=env_id.split(":")[-1], task=task, version=self.version)


def _resolve(name: str, source: str) -> Path:
    """A rule file named in a spec: next to the spec file, else a shipped one in ``envs/benchmark``."""
    if source:
        beside = Path(source).parent / name
        if beside.is_file():
            return beside
    return envs_dir() / "benchmark" / name


def read_spec(path: str | Path) -> BenchmarkSpec:
    """Load and validate a spec file.

    Raises:
        ScenarioError: unreadable file, or an invalid key (named, with the file).
    """
    path = Path(path)
    spec = dataclasses.replace(load_table(BenchmarkSpec, path), source=str(path))
    _check(spec, path)
    return spec


def _check(spec: BenchmarkSpec, path: Path) -> None:
    """Cross-field rules of a spec (each error names the key)."""
    if spec.score.rule in ("bounded_smoothness", "capture_smoothness", "capture_quality") and not spec.score.rules_file:
        raise ScenarioError(f"{path}: key 'score.rules_file' is empty; the rule {spec.score.rule!r} needs a rule file")
    if spec.actions.boxes == "rules" and not spec.score.rules_file:
        raise ScenarioError(f"{path}: key 'actions.boxes' = 'rules' needs 'score.rules_file'")
    if spec.tasks.kind == "tiers" and not (spec.tasks.tiers and spec.tasks.splits):
        raise ScenarioError(f"{path}: keys 'tasks.tiers' and 'tasks.splits' must list the tiers and splits")
    if spec.evaluation.protocol == "seeds" and not (len(spec.evaluation.parameters_seeds) == 2
                                                    and len(spec.evaluation.residual_seeds) == 2):
        raise ScenarioError(f"{path}: keys 'evaluation.parameters_seeds' and 'evaluation.residual_seeds' must each be "
                            "[start, stop) for the protocol 'seeds'")
    if spec.evaluation.protocol == "pool" and spec.tasks.kind != "tiers":
        raise ScenarioError(f"{path}: key 'evaluation.protocol' = 'pool' needs 'tasks.kind' = 'tiers'")
    if spec.ids.parameters == spec.ids.residual:
        raise ScenarioError(f"{path}: keys 'ids.parameters' and 'ids.residual' must differ")
    if spec.score.rules_file:
        spec.rules  # noqa: B018 - loads and validates the rule file now, naming it on error
    rules = spec.rules if spec.score.rules_file else None
    if (spec.score.rule == "capture_quality") != (rules is not None and rules.quality is not None):
        raise ScenarioError(f"{path}: key 'score.rule' = {spec.score.rule!r} with rule file {spec.score.rules_file!r}; "
                            "allowed: 'capture_quality' exactly when the rule file has a [quality] section")
    if (spec.score.rule == "capture_smoothness") != (rules is not None and rules.capture is not None
                                                     and rules.quality is None):
        raise ScenarioError(f"{path}: key 'score.rule' = {spec.score.rule!r} with rule file {spec.score.rules_file!r}; "
                            "allowed: 'capture_smoothness' exactly when the rule file has a [capture] section and "
                            "no [quality]")
    if spec.grasp_observation != spec.actions.command or (spec.grasp_observation and not spec.target_twist):
        raise ScenarioError(f"{path}: keys 'actions.command' and 'observation.grasp' go together (with "
                            "'observation.target_twist'): a method that commands the approach sees its state")
