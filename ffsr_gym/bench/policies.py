"""Policies from the command line and from files: fixed parameters, stable-baselines3 models, callables."""

from __future__ import annotations

import importlib
import importlib.util
import zipfile
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError, MissingDependencyError

#: Policies of this package that an entry may name and ``verify`` runs without being asked: they are the
#: verifier's own code, not the entry's.
BUILTIN_POLICIES = ("ffsr_gym.bench.policies:uniform_random_residual",)
#: The most an SB3 model's zip may unpack to [bytes].
MAX_MODEL_BYTES = 2 * 2**30
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


def load_model(algo: str, path: str | Path, *, threads: int | None = 1) -> Any:
    """A saved stable-baselines3 model of ``algo`` (a key of :data:`SB3_CLASSES`), on the CPU.

    ``threads`` sets torch's intra-op threads for the process (``None`` leaves them): a model played one
    observation at a time gains nothing from more, and they contend with whatever else runs. With torch's
    default on a 2-core machine already running two other jobs, playing a PPO model on 50 tasks took 23 s, 5.5 s
    with one thread."""
    if algo not in SB3_CLASSES:
        raise InvalidInputError(f"algo {algo!r}; allowed: {sorted(SB3_CLASSES)}")
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
        raise InvalidInputError(f"threads {threads!r}; allowed: an integer >= 1, or None")
    stable_baselines3, torch = sb3_modules()
    if threads is not None:
        torch.set_num_threads(threads)
    return getattr(stable_baselines3, SB3_CLASSES[algo]).load(path, device="cpu")


def load_policy(spec: str, algo: str | None, *, trust: bool = False):
    """A policy from the command line: ``"m,T_c"`` (fixed parameters; ``"m,T_c,go_s"`` a timed one, on an id whose
    action commands the approach), an SB3 ``.zip`` (with ``algo``),
    or ``module:callable`` / ``path/to/file.py:callable`` (called with an observation, returns an action).

    A stable-baselines3 ``.zip`` is unpickled when it loads, so loading one runs code of its maker's
    choosing: it loads only when ``trust`` (``--trust-model``) says its source is trusted, wherever it
    lies (a pull request can ship a model into the working folder as easily as anywhere).

    Raises:
        InvalidInputError: none of these forms, an untrusted or unreadable model, a policy file that
            fails to import (each named).
    """
    parts = spec.split(",")
    if len(parts) in (2, 3):
        try:
            return tuple(float(part) for part in parts)
        except ValueError:
            pass
    if spec.endswith(".zip"):
        return _load_zip(spec, algo, trust)
    target, _, name = spec.rpartition(":")
    if target and name:
        policy = getattr(_import(target, spec), name, None)
        if callable(policy):
            return policy
        raise InvalidInputError(f"--policy {spec!r}: {target!r} has no callable {name!r}")
    raise InvalidInputError(f"--policy {spec!r}; allowed: 'm,T_c' (e.g. 0.3,4), 'm,T_c,go_s' (e.g. 0.3,4,24: "
                            "capture v1), an SB3 .zip with --algo, module:callable or path/to/file.py:callable")


def _load_zip(spec: str, algo: str | None, trust: bool) -> Any:
    if algo not in SB3_CLASSES:
        raise InvalidInputError(f"--algo {algo!r}: an SB3 .zip needs --algo, one of {sorted(SB3_CLASSES)}")
    path = Path(spec).resolve()
    if not path.is_file():
        raise InvalidInputError(f"--policy {spec!r}: no such file")
    if not trust:
        raise InvalidInputError(f"--policy {spec!r}: loading an SB3 model unpickles it, which can run any code its "
                                "maker chose; pass --trust-model if you trust its source")
    try:
        with zipfile.ZipFile(path) as archive:
            unpacked = sum(info.file_size for info in archive.infolist())
        if unpacked > MAX_MODEL_BYTES:
            raise InvalidInputError(f"--policy {spec!r}: unpacks to {unpacked:,} bytes; allowed: at most "
                                    f"{MAX_MODEL_BYTES:,} (an SB3 model of this benchmark is a few MB)")
        model = load_model(algo, path)
    except InvalidInputError:
        raise
    except Exception as exc:  # noqa: BLE001 - a file that is not a model of ``algo`` fails in many ways
        raise InvalidInputError(f"--policy {spec!r}: not a stable-baselines3 {algo} model "
                                f"({type(exc).__name__}: {exc})") from None
    try:  # a model of another algorithm loads, then fails at its first prediction: fail here, by name
        import numpy as np

        model.predict(np.zeros(model.observation_space.shape, dtype=model.observation_space.dtype), deterministic=True)
    except Exception as exc:  # noqa: BLE001 - whatever the mismatch raises deep inside torch or SB3
        raise InvalidInputError(f"--policy {spec!r} loaded as {SB3_CLASSES[algo]} but cannot predict "
                                f"({type(exc).__name__}: {exc}); is --algo {algo} the algorithm it was trained with?"
                                ) from None
    return model


def _import(target: str, spec: str) -> Any:
    """A module by name, or a ``.py`` file by path."""
    try:
        if target.endswith(".py"):
            path = Path(target)
            if not path.is_file():
                raise InvalidInputError(f"--policy {spec!r}: no such file {target!r}")
            module_spec = importlib.util.spec_from_file_location(path.stem, path)
            module = importlib.util.module_from_spec(module_spec)
            module_spec.loader.exec_module(module)
            return module
        try:
            return importlib.import_module(target)
        except ModuleNotFoundError as exc:  # a module file in the working folder, not on sys.path
            local = Path(*target.split(".")).with_suffix(".py")
            if exc.name != target.split(".")[0] or not local.is_file():
                raise
            return _import(str(local), spec)
    except InvalidInputError:
        raise
    except Exception as exc:  # noqa: BLE001 - a user's file: whatever it raises is reported by name
        raise InvalidInputError(f"--policy {spec!r}: {target!r} failed to import ({type(exc).__name__}: {exc})") from None


def policy_record(spec: str, algo: str | None) -> dict[str, Any]:
    """An entry's ``extra.policy`` for a ``--policy`` that is code: the text, and the sha256 of the file it names (a
    ``.zip`` model or a ``file.py``), so that a run with ``--run-code`` elsewhere checks it has the same file."""
    import hashlib

    path = Path(spec if spec.endswith(".zip") else spec.rpartition(":")[0])
    record: dict[str, Any] = {"sb3": spec, "algo": algo} if spec.endswith(".zip") else {"callable": spec}
    if path.suffix in (".zip", ".py") and path.is_file():
        record["sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    return record


def resolve_recorded(spec: str, sha256: str | None, folder: Path) -> str:
    """The ``--policy`` text of an entry's code as it can be loaded here: a file path that does not exist from the
    working folder is looked up in the entry's ``folder``; a recorded hash must match the file found.

    Raises:
        InvalidInputError: the file is in neither place, or its hash differs (named).
    """
    import hashlib

    zip_model = spec.endswith(".zip")
    target, _, name = (spec, "", "") if zip_model else spec.rpartition(":")
    if not target.endswith((".zip", ".py")):
        return spec  # a module: imported by name
    path = Path(target)
    if not path.is_file() and not path.is_absolute() and (folder / path).is_file():
        path = folder / path
    if not path.is_file():
        raise InvalidInputError(f"{target!r}: no such file here or beside the entry ({folder})")
    if sha256 is not None and hashlib.sha256(path.read_bytes()).hexdigest() != sha256:
        raise InvalidInputError(f"{path}: its sha256 differs from the one the entry recorded: not the file it was "
                                "scored with")
    return str(path) if zip_model else f"{path}:{name}"


def uniform_random_residual(observation: Any) -> Any:
    """The lower reference of the residual tables: an action drawn uniformly from [-1, 1]^12 at every decision
    (13 values, the approach's command too, for an observation of 76 floats: capture v1's).

    The draw is seeded by the observation's bytes (SHA-256), so the policy is a fixed function of
    what it sees: episodes replay exactly whatever order or process they run in
    (``ffsr-gym leaderboard verify``), and distinct observations get independent draws.
    """
    import hashlib

    import numpy as np

    digest = hashlib.sha256(np.ascontiguousarray(observation, dtype=np.float32).tobytes()).digest()
    size = 13 if np.size(observation) == 76 else 12
    return np.random.default_rng(int.from_bytes(digest[:8], "little")).uniform(-1.0, 1.0, size).astype(np.float32)
