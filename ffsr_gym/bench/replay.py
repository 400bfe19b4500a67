"""``ffsr-gym leaderboard verify ENTRY``: replay what an entry records and compare its rows, exactly.

An entry is data, often from a pull request, so nothing it names runs as code unless the person
verifying names that code too (``run_code``, ``--run-code``). Without consent ``verify`` replays
what needs no code of the entry's:

* the **trace** of applied actions (``extra.trace``, :mod:`ffsr_gym.bench.trace`), which
  :func:`ffsr_gym.evaluate` stores for every policy that is code: the default check of an RL or
  optimiser entry;
* a planner variant (``extra.planner``) or fixed parameters (``extra.policy.fixed``);
* a policy of this package (:data:`ffsr_gym.bench.policies.BUILTIN_POLICIES`).

A callable or a stable-baselines3 model the entry names runs only when ``run_code`` is exactly
the text the entry names; otherwise the verdict is ``skipped``, naming what was not run.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ffsr_gym.bench.board_layout import spec_of_entry
from ffsr_gym.bench.evaluation import NEUTRAL_KWARGS, plan_evaluation, run_plan
from ffsr_gym.bench.planner_scores import evaluate_planner
from ffsr_gym.bench.policies import BUILTIN_POLICIES, load_policy, resolve_recorded
from ffsr_gym.bench.replay_tolerance import bias_problem, differing_keys
from ffsr_gym.bench.trace import clipped_counts, decode, trace_episodes
from ffsr_gym.bench.trace_file import in_file, read_actions
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.model.spec import BenchmarkSpec, ReplaySpec
from ffsr_gym.user_files import parse_json, read_text

#: The most training seeds an entry's rows may repeat each task for (a bound on what ``verify`` plays).
MAX_TRAINING_SEEDS = 20

EXIT_CODES = {"reproduced": 0, "differs": 1, "skipped": 3}


@dataclass(frozen=True)
class Verdict:
    """What ``verify`` found: ``reproduced``, ``differs`` or ``skipped`` (nothing it may run), and why."""

    status: str
    text: str
    #: The exact text of the entry file that was replayed (what a stamp may bind), or empty.
    entry_text: str = field(default="", repr=False)

    @property
    def exit_code(self) -> int:
        """0 reproduced, 1 differs, 3 skipped (2 is a named error of the command)."""
        return EXIT_CODES[self.status]


def replay_entry(path: str | Path, *, run_code: str | None = None) -> Verdict:
    """Replay the entry file ``path`` and compare its rows.

    Args:
        path: the entry's JSON file.
        run_code: consent to run the code the entry names: exactly its ``extra.policy`` callable
            (``module:callable`` / ``file.py:callable``) or SB3 ``.zip`` path, or another path to the
            same file (the sha256 the entry records) and callable. A relative file path is looked up
            from the working folder, then beside the entry. Loading a model unpickles it and
            importing a file runs it.

    The file is read once: the verdict's ``entry_text`` is the text that was replayed, whatever the file
    holds by the time the replay ends.

    Raises:
        InvalidInputError: an unreadable or malformed entry (named), or ``run_code`` that is not what
            the entry names.
    """
    path = Path(path)
    try:
        text = read_text(path)
    except FFSRError as exc:
        raise InvalidInputError(f"{path}: not a readable leaderboard entry ({exc})") from None
    return replace(_replay(path, text, run_code), entry_text=text)


def _replay(path: Path, text: str, run_code: str | None) -> Verdict:
    entry, spec = _read_entry(path, text)
    extra, rows = entry["extra"], entry["episodes"]
    named = _named_code(extra.get("policy"), path)
    if run_code is not None and run_code != named:
        if named is None:
            raise InvalidInputError(f"--run-code {run_code!r}: the entry names no code")
        if not _same_code(run_code, named, extra["policy"].get("sha256")):
            raise InvalidInputError(f"--run-code {run_code!r}: the entry names {named!r} as its code; consent is given "
                                    "to exactly that text, or to a path of the same file (the sha256 the entry "
                                    "records) and callable")
        extra["policy"] = {**extra["policy"], ("callable" if "callable" in extra["policy"] else "sb3"): run_code}
        named = run_code
    if "planner" in extra:
        planner = _planner(extra["planner"], path)
        kwargs = entry["env_kwargs"]
        report = evaluate_planner(planner["method"], task=kwargs.get(spec.tasks.keyword), split=kwargs.get("split"),
                                  m=planner["m"], T_c=planner["T_c_s"], gain_per_s=planner["gain_per_s"],
                                  go_s=planner.get("go_s"), version=spec.version)
        return _compare(rows, report.to_json()["episodes"], "the planner variant", spec)
    if "trace" in extra:
        verdict = _replay_trace(entry, spec, path)
        if verdict.status != "reproduced" or named is None or run_code is None:
            return verdict
    policy_record = extra.get("policy")
    if policy_record is None:
        return Verdict("skipped", "nothing to replay: the entry records no trace, planner, fixed parameters or "
                                  "policy (an RL study's entry without a trace is re-run by its training command)")
    if named is not None and named not in BUILTIN_POLICIES and run_code is None:
        return Verdict("skipped", f"not run: the entry names code ({named!r}) and records no trace; running it needs "
                                  f"consent: verify again with --run-code {named!r} if you trust it")
    policy = _policy(policy_record, path)
    return _compare(rows, _play(policy, entry, spec, path).to_json()["episodes"],
                    "the fixed parameters" if named is None else f"{named!r}", spec)


def _read_entry(path: Path, text: str) -> tuple[dict[str, Any], BenchmarkSpec]:
    """The entry ``text`` (read from ``path``) and its version, checked for what a replay reads."""
    try:
        entry = parse_json(text, str(path))
    except FFSRError as exc:
        raise InvalidInputError(f"{path}: not a readable leaderboard entry ({exc})") from None
    if not isinstance(entry, dict):
        raise InvalidInputError(f"{path}: not a leaderboard entry (a JSON object), got {type(entry).__name__}")
    for key, kind in (("extra", dict), ("env_kwargs", dict), ("episodes", list), ("protocol", dict)):
        if not isinstance(entry.get(key, {} if key in ("extra", "protocol") else None), kind):
            raise InvalidInputError(f"{path}: {key} = {str(entry.get(key))[:80]!r}; allowed: a JSON {kind.__name__}")
    entry.setdefault("extra", {})
    entry.setdefault("protocol", {})
    rows = entry["episodes"]
    if not rows or not all(isinstance(row, dict) for row in rows):
        raise InvalidInputError(f"{path}: episodes: allowed: a non-empty list of rows (objects)")
    spec = spec_of_entry(entry)
    _check_kwargs(entry["env_kwargs"], spec, path)
    _check_rows(entry, spec, path)
    return entry, spec


def _check_kwargs(kwargs: dict[str, Any], spec: BenchmarkSpec, path: Path) -> None:
    allowed = spec.env_options() | set(NEUTRAL_KWARGS)
    unknown = sorted(set(kwargs) - allowed)
    if unknown:
        raise InvalidInputError(f"{path}: env_kwargs {unknown}; allowed: {sorted(allowed)}")
    if spec.tasks.keyword not in kwargs:
        raise InvalidInputError(f"{path}: env_kwargs has no {spec.tasks.keyword!r}; allowed: the task the entry played")
    kwargs.pop("render_mode", None)  # drawing changes no score; a replay never draws


def _check_rows(entry: dict[str, Any], spec: BenchmarkSpec, path: Path) -> None:
    """Rows a replay may play: integer seeds (and pool indices), each task at most once per training seed."""
    rows, extra = entry["episodes"], entry["extra"]
    seeds = extra.get("training_seeds")
    if seeds is not None and (not isinstance(seeds, list) or not 1 <= len(seeds) <= MAX_TRAINING_SEEDS):
        raise InvalidInputError(f"{path}: extra.training_seeds; allowed: a list of 1 to {MAX_TRAINING_SEEDS} seeds")
    copies = len(seeds or [None])
    keys = ("seed", "task_index") if spec.evaluation.protocol == "pool" and "custom_task" not in extra else ("seed",)
    for k, row in enumerate(rows):
        for key in keys:
            value = row.get(key)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InvalidInputError(f"{path}: episodes[{k}].{key} = {value!r}; allowed: an integer >= 0")
    counts = Counter(tuple(row[key] for key in keys) for row in rows)
    repeated = [key for key, count in counts.items() if count > copies]
    if repeated:
        raise InvalidInputError(f"{path}: episodes repeat {keys} {repeated[0]} more than once per training seed "
                                f"({copies}); allowed: each episode once per training seed")


def _named_code(record: Any, path: Path) -> str | None:
    """The code an entry's ``extra.policy`` names (a callable or a model path), or None (fixed, absent); the record
    checked."""
    if record is None:
        return None
    if not isinstance(record, dict) or len(set(record) & {"fixed", "callable", "sb3"}) != 1:
        raise InvalidInputError(f"{path}: extra.policy = {str(record)[:80]!r}; allowed: an object with one of "
                                "'fixed' (numbers), 'callable' (text), 'sb3' (text, with 'algo')")
    for key in ("callable", "sb3"):
        if key in record:
            if not isinstance(record[key], str):
                raise InvalidInputError(f"{path}: extra.policy.{key} = {record[key]!r}; allowed: a text")
            return record[key]
    fixed = record["fixed"]
    if not isinstance(fixed, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in fixed):
        raise InvalidInputError(f"{path}: extra.policy.fixed = {str(fixed)[:80]!r}; allowed: a list of numbers")
    return None


def _same_code(given: str, named: str, sha256: str | None) -> bool:
    """Whether ``given`` names the file the entry recorded (same sha256) and the same callable."""
    import hashlib

    if sha256 is None:
        return False
    target, _, name = (given, "", "") if given.endswith(".zip") else given.rpartition(":")
    if name != ("" if named.endswith(".zip") else named.rpartition(":")[2]) or not Path(target).is_file():
        return False
    return hashlib.sha256(Path(target).read_bytes()).hexdigest() == sha256


def _policy(record: dict[str, Any], path: Path) -> Any:
    """The policy of ``extra.policy``, loaded (the caller has consent for code)."""
    if "fixed" in record:  # checked by _named_code
        return tuple(record["fixed"])
    folder = path.resolve().parent
    if "callable" in record:
        return load_policy(resolve_recorded(record["callable"], record.get("sha256"), folder), None)
    return load_policy(resolve_recorded(record["sb3"], record.get("sha256"), folder), record.get("algo"), trust=True)


def _planner(record: Any, path: Path) -> dict[str, Any]:
    keys = ("method", "m", "T_c_s", "gain_per_s")
    if not isinstance(record, dict) or not set(keys) <= set(record) or not set(record) <= {*keys, "go_s"}:
        raise InvalidInputError(f"{path}: extra.planner = {str(record)[:80]!r}; allowed: an object with {list(keys)} "
                                "(and go_s on a version whose action commands the approach)")
    return record


def _play(policy: Any, entry: dict[str, Any], spec: BenchmarkSpec, path: Path) -> Any:
    """The report of ``policy`` on the entry's own episodes (its tasks, seeds and env arguments)."""
    return run_plan(policy, _plan(policy, entry, spec, path))


def _plan(policy: Any, entry: dict[str, Any], spec: BenchmarkSpec, path: Path) -> Any:
    extra, kwargs, rows = entry["extra"], dict(entry["env_kwargs"]), entry["episodes"]
    if "custom_task" in extra:
        return plan_evaluation(policy, entry["env_id"], task=_custom_scenario(extra["custom_task"], path),
                               seeds=[row["seed"] for row in rows],
                               env_kwargs={k: v for k, v in kwargs.items() if k != spec.tasks.keyword})
    if spec.evaluation.protocol == "pool":
        task, split = kwargs.pop(spec.tasks.keyword), kwargs.pop("split", None)
        return plan_evaluation(policy, entry["env_id"], task=task, split=split, env_kwargs=kwargs,
                               indices=[row["task_index"] for row in rows])
    return plan_evaluation(policy, entry["env_id"], seeds=[row["seed"] for row in rows], env_kwargs=kwargs)


class _TraceSpent(Exception):
    """The stored actions ran out before the episodes did."""


class _TracePlayer:
    """A policy that plays an entry's stored actions, episode after episode (no code of the entry's runs)."""

    def __init__(self, episodes: list[np.ndarray]):
        self.episodes, self.episode, self.decision = episodes, 0, 0

    def __call__(self, _observation: Any) -> np.ndarray:
        while self.decision >= len(self.episodes[self.episode]):  # this episode's actions are spent: the next one's
            self.episode, self.decision = self.episode + 1, 0
            if self.episode >= len(self.episodes):
                raise _TraceSpent
        self.decision += 1
        return self.episodes[self.episode][self.decision - 1]


def _replay_trace(entry: dict[str, Any], spec: BenchmarkSpec, path: Path) -> Verdict:
    """Play the stored actions and compare the rows and the actions the env applied, exactly."""
    rows, record = entry["episodes"], entry["extra"]["trace"]
    if in_file(record):
        episodes = read_actions(record, path, len(rows))
        width = record["action_shape"][0]
    else:
        width, texts = trace_episodes(record, len(rows), where=f"{path}: extra.trace")
        episodes = [decode(text, width, where=f"{path}: extra.trace.episodes[{k}]") for k, text in enumerate(texts)]
    try:
        report = _play(_TracePlayer(episodes), entry, spec, path).to_json()
    except _TraceSpent:
        return Verdict("differs", "the trace ends before the last episode does (an episode's trace is too short)")
    for k, played in enumerate(report["extra"]["trace"]["episodes"]):
        applied = decode(played, width, where="the replay")
        if applied.tobytes() != episodes[k].tobytes():
            return Verdict("differs", f"episode {k}: its trace does not fit the episode (the env applied "
                                      f"{len(applied)} actions, {len(episodes[k])} stored, or other values)")
    counts = clipped_counts(entry["extra"]["trace"], episodes, where=f"{path}: extra.trace")
    replayed = report["episodes"]  # the stored actions are in the box: what the env clipped, the trace lists
    if counts is None and any("clipped_actions" in row for row in rows):
        return Verdict("differs", "the rows count clipped actions but the trace lists no clipped decisions")
    if counts is not None:
        replayed = [row | {"clipped_actions": count} for row, count in zip(replayed, counts)]
    return _compare(rows, replayed, "the stored trace of applied actions", spec)


def _custom_scenario(record: Any, path: Path) -> Any:
    """The scenario a custom-task entry stores, checked against the hash it was scored with.

    Raises:
        InvalidInputError: a malformed record, a robot folder missing on this machine, or a hash that
            differs (the robot's files changed since).
    """
    from ffsr_gym.exceptions import RobotFileError, ScenarioError
    from ffsr_gym.model.scenario import scenario_from_dict

    try:
        scenario = scenario_from_dict(record["scenario"], source=f"{path} extra.custom_task.scenario")
    except (KeyError, TypeError, ScenarioError, RobotFileError) as exc:
        raise InvalidInputError(f"{path}: its custom task cannot be rebuilt here ({exc})") from None
    if scenario.sha256() != record.get("scenario_sha256"):
        raise InvalidInputError(f"{path}: the custom task's hash differs from the one scored ({scenario.sha256()[:12]} vs "
                                f"{str(record.get('scenario_sha256'))[:12]}): the stored scenario or its robot's files changed")
    return scenario


def _compare(stored: list[dict], rerun: list[dict], what: str, spec: BenchmarkSpec) -> Verdict:
    """Rows compared under the version's ``[replay]`` tolerances (:mod:`ffsr_gym.bench.replay_tolerance`: exactly for
    v0 and v2); an RL study's rows also name their training seed, which a replay keeps; a row written before rows
    counted clipped actions is compared without that count."""
    if len(stored) != len(rerun):
        return Verdict("differs", f"{len(rerun)} rows replayed, {len(stored)} stored")
    rerun = [b | {"train_seed": a["train_seed"]} if "train_seed" in a else b for a, b in zip(stored, rerun)]
    # rows written before the clipped-action count have none to compare
    rerun = [b if "clipped_actions" in a else {k: v for k, v in b.items() if k != "clipped_actions"}
             for a, b in zip(stored, rerun)]
    tolerance = spec.replay
    for k, (a, b) in enumerate(zip(stored, rerun)):
        keys = differing_keys(a, b, tolerance)
        if keys:
            return Verdict("differs", f"row {k} differs in {keys}: stored {[a.get(x) for x in keys]}, "
                                      f"replayed {[b.get(x) for x in keys]}{_within(tolerance)}")
    biased = bias_problem(stored, rerun, tolerance)
    if biased is not None:
        return Verdict("differs", f"{biased}{_within(tolerance)}")
    exact = all(a == b for a, b in zip(stored, rerun))
    how = "exactly" if exact else f"with the same verdicts{_within(tolerance)}"
    return Verdict("reproduced", f"all {len(stored)} rows reproduce {how} ({what})")


def _within(tolerance: ReplaySpec) -> str:
    """The tolerance a comparison allowed, as text ('' when exact)."""
    if tolerance.score_rel_tol == 0.0 and tolerance.margin_rel_tol == 0.0 and tolerance.margin_abs_tol == 0.0:
        return ""
    return (f" (allowed: the score, C and B within a relative {tolerance.score_rel_tol:g}, other numbers within "
            f"{tolerance.margin_rel_tol:g} or {tolerance.margin_abs_tol:g} absolute, verdicts exactly; this version's "
            "[replay])")
