"""A scored evaluation as a leaderboard entry (:class:`EvalReport`), and how a policy steps an env."""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np

from ffsr_gym.bench.verify import ENTRY_NAME, entry_problems
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.provenance import dirty_allowed
from ffsr_gym.scoring.aggregate import BOOTSTRAP_SAMPLES, BOOTSTRAP_SEED

V0_SCORE_RULE = "objective B if feasible else inf (null in JSON)"


def check_compute(compute: Any) -> dict[str, Any]:
    """``compute`` as an entry records it (the tables' compute column): what training or tuning the policy cost.

    Keys: ``env_steps`` (environment steps, RL) and/or ``objective_evaluations`` (whole episodes
    run by an optimiser), at least one, integers >= 0; ``wall_time_s`` (required, >= 0); optionally
    ``hardware`` (text).

    Raises:
        InvalidInputError: anything else, naming the key and what is allowed.
    """
    counts, optional = ("env_steps", "objective_evaluations"), ("hardware",)
    allowed = (*counts, "wall_time_s", *optional)
    if (not isinstance(compute, dict) or "wall_time_s" not in compute or not any(k in compute for k in counts)
            or not set(compute) <= set(allowed)):
        raise InvalidInputError(f"compute = {compute!r}; allowed: a dict with 'wall_time_s' (number >= 0 [s]), "
                                "'env_steps' and/or 'objective_evaluations' (integers >= 0), optionally 'hardware' "
                                "(text)")
    out: dict[str, Any] = {}
    for key in counts:
        if key in compute:
            value = compute[key]
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise InvalidInputError(f"compute[{key!r}] = {value!r}; allowed: an integer >= 0")
            out[key] = int(value)
    seconds = compute["wall_time_s"]
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float, np.floating)) or not 0 <= seconds < np.inf:
        raise InvalidInputError(f"compute['wall_time_s'] = {seconds!r}; allowed: a finite number >= 0 [s]")
    out["wall_time_s"] = float(seconds)
    if "hardware" in compute:
        if not isinstance(compute["hardware"], str):
            raise InvalidInputError(f"compute['hardware'] = {compute['hardware']!r}; allowed: a text, e.g. '2 CPU cores'")
        out["hardware"] = compute["hardware"]
    return out


@runtime_checkable
class PredictsActions(Protocol):
    """Anything with a stable-baselines3-style ``predict``."""

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[Any, Any]: ...


Policy = Callable[[np.ndarray], np.ndarray] | PredictsActions | tuple[float, ...]
def _json_safe(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    return x


@dataclass
class EvalReport:
    """Result of :func:`evaluate`: aggregate metrics, per-episode rows and provenance."""

    env_id: str
    env_kwargs: dict[str, Any]
    metrics: dict[str, Any]
    episodes: list[dict[str, Any]]
    provenance: dict[str, Any]
    name: str = "submission"
    extra: dict[str, Any] = field(default_factory=dict)
    score_rule: str = V0_SCORE_RULE

    def to_json(self) -> dict[str, Any]:
        """The leaderboard entry (infinite values as ``null``)."""
        return _json_safe({
            "name": self.name, "env_id": self.env_id, "env_kwargs": self.env_kwargs,
            "protocol": {"seeds": [row["seed"] for row in self.episodes], "episodes": len(self.episodes),
                         "score": self.score_rule,
                         "bootstrap": {"seed": BOOTSTRAP_SEED, "samples": BOOTSTRAP_SAMPLES}},
            "metrics": self.metrics, "episodes": self.episodes, "extra": self.extra, "provenance": self.provenance,
        })

    def save(self, directory: str | Path, *, overwrite: bool = False, allow_dirty: bool | None = None) -> Path:
        """Write the entry atomically to ``directory/<name>.json`` and return its path; a policy's trace of applied
        actions goes to ``directory/<name>.trace`` beside it (:mod:`ffsr_gym.bench.trace_file`).

        An entry already there is replaced only with ``overwrite=True`` (a submitted result is never
        lost to a second run of the same name).

        A folder that is a leaderboard table by its path (``<version>/<tier>`` of a version with
        tiers, or a ``<env id>`` folder of one scored on seeds) only takes an entry that the
        leaderboard would rank there: the same checks as ``ffsr-gym leaderboard render``
        (:func:`ffsr_gym.bench.verify.entry_problems`), and, unless ``allow_dirty=True`` (None: the
        variable ``FFSR_GYM_ALLOW_DIRTY=1``), not one made by a source checkout with uncommitted changes to
        its code (``provenance.git_dirty``: nobody could run that code again; an installed package records
        None and is taken). Any other folder takes any entry.

        Raises:
            InvalidInputError: a name that is not a plain file name, an entry of that name already there
                (without ``overwrite``), or an entry that the table folder would refuse (every reason named),
                or a dirty checkout's entry in a table folder (without ``allow_dirty``).
        """
        if not isinstance(self.name, str) or not ENTRY_NAME.fullmatch(self.name):
            raise InvalidInputError(f"entry name {self.name!r}; allowed: 1-128 characters of letters, digits, '.', '_', "
                                    "'-', not starting with '.' (it becomes a file name in the entry's folder)")
        from ffsr_gym.bench.board_layout import leaderboard_table

        table = leaderboard_table(Path(directory))
        if table is not None:
            spec, group = table
            problems = entry_problems(self.to_json(), spec, group)
            if self.provenance.get("git_dirty") is True and not dirty_allowed(allow_dirty):
                problems.append("it was made by a checkout with uncommitted code changes (provenance.git_dirty); "
                                "commit them and run again, or pass allow_dirty=True (the table marks it +dirty)")
            if problems:
                raise InvalidInputError(f"{directory} is the {spec.version} leaderboard table {group!r}, which would refuse "
                                        f"this entry: {'; '.join(problems)} (save elsewhere, e.g. "
                                        f"leaderboards/{spec.version}/custom/ for a custom task)")
        path = Path(directory) / f"{self.name}.json"
        if path.exists() and not overwrite:
            raise InvalidInputError(f"{path} exists: a previous result would be replaced; choose another name, or pass "
                                    "overwrite=True to replace it")
        from ffsr_gym.bench.trace_file import SUFFIX, write_entry_files

        write_entry_files(path, self.to_json())
        if "trace" not in self.extra:  # a replaced entry's trace file does not outlive it
            path.with_name(path.stem + SUFFIX).unlink(missing_ok=True)
        return path


def entry_name(algo: str, spec: BenchmarkSpec, env_id: str, task: str) -> str:
    """The leaderboard entry name of a training study (``ppo_residual_easy``)."""
    return f"{algo}_{'residual_' if spec.is_residual(env_id) else ''}{task}"


class _Recurrent:
    """One episode of a policy with stable-baselines3's stateful ``predict(obs, state, episode_start, deterministic)``
    (sb3-contrib's RecurrentPPO): its state carried from step to step, the episode's start flagged once."""

    def __init__(self, policy: PredictsActions) -> None:
        self.policy, self.state, self.start = policy, None, True

    def __call__(self, observation: np.ndarray) -> Any:
        action, self.state = self.policy.predict(observation, state=self.state,
                                                 episode_start=np.array([self.start]), deterministic=True)
        self.start = False
        return action


def policy_origin(policy: Any, library: str | None = None) -> dict[str, Any]:
    """What made a policy, for the entry's provenance: its type, and the installed distribution of the package it
    comes from with its version (found from the object's module: ``stable_baselines3``, ``sb3_contrib``, ``sbx``,
    ``tianshou``, ...), or ``library`` when given (e.g. ``"tianshou 2.0.1"`` for a plain function wrapping it).

    Raises:
        InvalidInputError: ``library`` that is not one line of text.
    """
    from importlib import metadata

    if library is not None and (not isinstance(library, str) or not library.strip() or "\n" in library):
        raise InvalidInputError(f"policy_library = {library!r}; allowed: one line of text, e.g. 'tianshou 2.0.1'")
    kind = type(policy)
    module = getattr(policy, "__module__", None) if callable(policy) and not isinstance(policy, PredictsActions) \
        else kind.__module__
    origin: dict[str, Any] = {"type": f"{kind.__module__}.{kind.__qualname__}", "module": module}
    top = (module or "").split(".")[0]
    packages = metadata.packages_distributions().get(top, [])
    if packages:
        origin["package"] = packages[0]
        origin["version"] = metadata.version(packages[0])
    if library is not None:
        origin["library"] = library.strip()
    return origin


def actor(policy: Policy) -> Callable[[np.ndarray], Any]:
    """The env action ``policy`` takes given an observation, for **one episode** (make one per episode): a tuple is
    a constant action (float32), an object with ``predict`` its deterministic prediction (given its state and the
    episode's start when its ``predict`` takes them, as every stable-baselines3 model's does), a callable its value."""
    if isinstance(policy, tuple):
        action = np.array(policy, dtype=np.float32)
        return lambda _obs: action
    if isinstance(policy, PredictsActions):
        parameters = inspect.signature(policy.predict).parameters
        if "state" in parameters and "episode_start" in parameters:
            return _Recurrent(policy)
        return lambda obs: policy.predict(obs, deterministic=True)[0]
    if callable(policy):
        return policy
    raise InvalidInputError(f"policy must be callable, have .predict, or be a tuple ((m, T_c), or a constant residual "
                            f"action); got {type(policy).__name__}")


def stepper(policy: Policy, env: gym.Env) -> Callable[[np.ndarray], tuple]:
    """One env step for ``policy`` given the last observation (fixed (m, T_c) bypass float32 actions; on a residual
    env a tuple is a constant action)."""
    if isinstance(policy, tuple) and not env.unwrapped.residual:
        if len(policy) == 3:  # timed (m, T_c, go_s): hold the start pose, then the insertion from go_s on
            base, (m, T_c, go) = env.unwrapped, policy
            return lambda _obs: base.step_with_parameters(
                m, T_c, command=2.0 if base.engine.K[0] * base.engine.dt >= go - 1e-9 else 0.0)
        return lambda _obs: env.unwrapped.step_with_parameters(*policy)
    act = actor(policy)  # a tuple on a residual env: a constant action (checked by ``evaluate``)
    return lambda obs: env.step(act(obs))
