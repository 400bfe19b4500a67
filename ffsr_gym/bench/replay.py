"""``ffsr-gym leaderboard verify ENTRY``: re-run what an entry names and compare its rows, exactly.

What can be re-run: a planner variant (``extra.planner``), fixed (m, T_c) parameters, a
``module:callable`` or ``file.py:callable`` policy, or a stable-baselines3 model (``extra.policy``,
recorded by :func:`ffsr_gym.evaluate` and ``ffsr-gym evaluate``). Models are loaded as
:func:`ffsr_gym.bench.policies.load_policy` loads them (``trust`` for one outside the working folder).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ffsr_gym.bench.evaluation import evaluate
from ffsr_gym.bench.leaderboard import spec_of_entry
from ffsr_gym.bench.planner_scores import evaluate_planner
from ffsr_gym.bench.policies import load_policy
from ffsr_gym.exceptions import InvalidInputError


def replay_entry(path: str | Path, *, trust: bool = False) -> tuple[bool, str]:
    """(reproduced, what happened) for the entry file ``path``.

    Raises:
        InvalidInputError: an unreadable entry file (named).
    """
    path = Path(path)
    try:
        entry = json.loads(path.read_text(encoding="utf-8"))
        spec = spec_of_entry(entry)
    except (OSError, UnicodeDecodeError, ValueError, AttributeError) as exc:
        raise InvalidInputError(f"{path}: not a readable leaderboard entry ({exc})") from None
    extra, kwargs = entry.get("extra", {}), dict(entry.get("env_kwargs", {}))
    if "planner" in extra:
        planner = extra["planner"]
        report = evaluate_planner(planner["method"], task=kwargs["task"], split=kwargs["split"], m=planner["m"],
                                  T_c=planner["T_c_s"], gain_per_s=planner["gain_per_s"], version=spec.version)
    elif isinstance(extra.get("policy"), dict) and len(extra.get("training_seeds") or []) <= 1:
        policy = _policy(extra["policy"], trust)
        if "custom_task" in extra:
            report = evaluate(policy, entry["env_id"], task=_custom_scenario(extra["custom_task"], path),
                              seeds=entry["protocol"]["seeds"],
                              env_kwargs={k: v for k, v in kwargs.items() if k != spec.tasks.keyword})
        elif spec.evaluation.protocol == "pool":
            task, split = kwargs.pop(spec.tasks.keyword), kwargs.pop("split")
            report = evaluate(policy, entry["env_id"], task=task, split=split, env_kwargs=kwargs,
                              indices=[row["task_index"] for row in entry["episodes"]])
        else:
            report = evaluate(policy, entry["env_id"], seeds=entry["protocol"]["seeds"], env_kwargs=kwargs)
    else:
        return False, ("nothing to re-run: the entry names no planner, fixed parameters, callable or model "
                       "(an RL study's entry is re-run by its training command)")
    return _compare(entry["episodes"], report.to_json()["episodes"])


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


def _policy(record: dict[str, Any], trust: bool) -> Any:
    if "fixed" in record:
        return tuple(record["fixed"])
    if "callable" in record:
        return load_policy(record["callable"], None)
    if "sb3" in record:
        return load_policy(record["sb3"], record.get("algo"), trust=trust)
    raise InvalidInputError(f"extra.policy = {record!r}; allowed keys: fixed, callable, sb3 (with algo)")


def _compare(stored: list[dict], rerun: list[dict]) -> tuple[bool, str]:
    if len(stored) != len(rerun):
        return False, f"{len(rerun)} rows re-run, {len(stored)} stored"
    for k, (a, b) in enumerate(zip(stored, rerun)):
        if a != b:
            keys = sorted(key for key in set(a) | set(b) if a.get(key) != b.get(key))
            return False, f"row {k} differs in {keys}: stored {[a.get(x) for x in keys]}, re-run {[b.get(x) for x in keys]}"
    return True, f"all {len(stored)} rows reproduce exactly"
