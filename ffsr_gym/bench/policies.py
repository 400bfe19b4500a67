"""Policies from the command line and from files: fixed parameters, stable-baselines3 models, callables."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError, MissingDependencyError

#: stable-baselines3 classes by algorithm name.
SB3_CLASSES = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "a2c": "A2C", "ddpg": "DDPG"}


def sb3_modules():
    """(stable_baselines3, torch), or a named error with the install hint."""
    try:
        import stable_baselines3
        import torch
    except ImportError as exc:
        raise MissingDependencyError('RL baselines need: pip install "ffsr-gym[rl]" (stable-baselines3, torch==2.13.0)') from exc
    return stable_baselines3, torch


def load_model(algo: str, path: str | Path) -> Any:
    """A saved stable-baselines3 model of ``algo`` (a key of :data:`SB3_CLASSES`), on the CPU."""
    if algo not in SB3_CLASSES:
        raise InvalidInputError(f"algo {algo!r}; allowed: {sorted(SB3_CLASSES)}")
    return getattr(sb3_modules()[0], SB3_CLASSES[algo]).load(path, device="cpu")


def load_policy(spec: str, algo: str | None):
    """A policy from the command line: ``"m,T_c"`` (fixed parameters), an SB3 ``.zip`` (with ``algo``),
    or ``module:callable`` (imported; called with an observation, returns an action).

    Raises:
        InvalidInputError: none of these, naming the accepted forms.
    """
    import importlib

    from ffsr_gym.exceptions import InvalidInputError

    parts = spec.split(",")
    if len(parts) == 2:
        try:
            return float(parts[0]), float(parts[1])
        except ValueError:
            pass
    if spec.endswith(".zip"):

        if algo not in SB3_CLASSES:
            raise InvalidInputError(f"--algo {algo!r}: an SB3 .zip needs --algo, one of {sorted(SB3_CLASSES)}")
        if not Path(spec).is_file():
            raise InvalidInputError(f"--policy {spec!r}: no such file")
        return load_model(algo, spec)
    module, _, name = spec.partition(":")
    if module and name:
        try:
            policy = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError) as exc:
            raise InvalidInputError(f"--policy {spec!r}: {exc}") from None
        if callable(policy):
            return policy
    raise InvalidInputError(f"--policy {spec!r}; allowed: 'm,T_c' (e.g. 0.3,4), an SB3 .zip with --algo, "
                            "or module:callable")


