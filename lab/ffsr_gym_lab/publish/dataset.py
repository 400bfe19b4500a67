"""``ffsr-gym dataset``: the best known trajectories of a tier's pool as a Minari dataset (offline RL, imitation).

Each stored best-known record (:mod:`ffsr_gym_lab.best_known.records`; the training pools' are in
``envs/benchmark/<version>_best_known_train.json``) whose schedule belongs to the
chosen env (``FFSR-Residual-v2``: the residual family; ``FFSR-v2``: the (m, T_c) family) is played
in that env, from ``reset(seed=0, options={"task_index": i})``, and recorded: observations (one
more than actions), actions, rewards, terminations, truncations, and per step the task's seed and
index (``infos``); the episode's ``seed`` and ``options`` are the reset's, so
``env.reset(seed=ep.seed, options=...)`` then ``env.step`` of the stored actions reproduces the
stored rewards. An episode whose replayed score differs from the stored best known score stops
the writing (the file and the environment disagree). The env spec (id and ``task``/``split``
kwargs) is stored, so ``dataset.recover_environment()`` builds the env again.

Minari and h5py are optional: ``pip install "ffsr-gym[dataset]"``. Datasets go to
``MINARI_DATASETS_PATH`` (or Minari's default folder), or to ``root`` when given. A dataset is
written whole into a hidden folder beside it and moved into place by one rename, so a killed or
failed run (a full disk) never leaves a dataset that Minari would load as valid.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ffsr_gym.exceptions import FFSRError, InvalidInputError, require
from ffsr_gym.tasks.schedule import ENV_IDS, Schedule
from ffsr_gym.tasks.splits import pool
from ffsr_gym_lab.best_known import records as best_known

#: The schedule family whose actions each env takes.
FAMILY_OF = {env_id: family for family, env_id in ENV_IDS.items()}


def _coverage(episodes: int, searched: int, pool_size: int, family: str) -> str:
    """How much of its pool a dataset holds, and why the rest is missing, in words (for its description):
    ``searched`` tasks have a stored best-known record, ``episodes`` of them a schedule of the dataset's env."""
    missing = []
    if searched < pool_size:
        missing.append(f"{pool_size - searched} not searched yet")
    if episodes < searched:
        missing.append(f"{searched - episodes} where no {family} schedule passed the certificate test")
    return f"{episodes} of the pool's {pool_size} tasks" + (f" ({'; '.join(missing)})" if missing else "")


def dataset_id(tier: str, env_id: str, split: str = "train") -> str:
    """The Minari id of a tier's best-known dataset, in Minari's grammar ``namespace/name-vN``: namespace
    ``ffsr/<tier>``, name ``best-known`` (the residual env's schedules; ``-mtc`` for FFSR-v2's (m, T_c) ones) and
    the split when it is not the training pool: ``ffsr/easy/best-known-v0``,
    ``ffsr/hard/best-known-mtc-validation-v0``."""
    name = "best-known" + ("" if env_id == "FFSR-Residual-v2" else "-mtc") + ("" if split == "train" else f"-{split}")
    return f"ffsr/{tier}/{name}-v0"


def reference_returns(tier: str, split: str, stored: list[dict[str, Any]], version: str) -> tuple[float, float, str]:
    """Minari's ``ref_min_score`` and ``ref_max_score`` of a dataset of the ``stored`` records' tasks, and what they
    are, in words. A return is the episode's score minus 1 (the rewards sum to it). ``ref_min_score``: the mean
    return of the lower reference (the uniform random residual, ``random_residual`` on the leaderboard) played on
    the same tasks; ``ref_max_score``: the mean of their reference scores minus 1, the frozen reference for a
    validation pool (the one the leaderboard's normalised column divides by) and the stored best known scores
    for a training pool (which no frozen reference covers)."""
    from ffsr_gym.bench.evaluation import evaluate
    from ffsr_gym.bench.policies import uniform_random_residual
    from ffsr_gym.tasks import reference

    indices = [int(r["index"]) for r in stored]
    lower = evaluate(uniform_random_residual, "FFSR-Residual-v2", task=tier, split=split, indices=indices,
                     name="random_residual")
    frozen = reference.reference_scores(tier, split, version)
    if frozen is not None:
        top, source = frozen[indices], f"the frozen reference {reference.reference_sha256(version)[:8]}"
    else:
        top, source = np.array([r["best"]["score"] for r in stored]), "the stored best known scores"
    low = np.array([row["score"] for row in lower.episodes])
    text = (f"ref_min_score: the mean return of the uniform random residual on the same {len(indices)} tasks; "
            f"ref_max_score: the mean of their scores in {source}, minus 1 (a return is the score minus 1)")
    return float(low.mean() - 1.0), float(top.mean() - 1.0), text


@contextlib.contextmanager
def _datasets_root(root: str | Path | None) -> Iterator[None]:
    """Minari reads its folder from ``MINARI_DATASETS_PATH``: set it to ``root`` for the duration."""
    if root is None:
        yield
        return
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(Path(root).resolve())
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def record_episode(env: gym.Env, record: dict[str, Any], schedule: Schedule, episode_id: int) -> Any:
    """Play ``schedule`` on the record's task in ``env`` and return the Minari episode buffer."""
    from minari.data_collector import EpisodeBuffer

    options = {"task_index": int(record["index"])}
    obs, info = env.reset(seed=0, options=options)
    actions = schedule.actions(env.unwrapped.scenario)
    observations, taken, rewards, terminations, truncations = [obs], [], [], [], []
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        observations.append(obs)
        taken.append(action)
        rewards.append(reward)
        terminations.append(terminated)
        truncations.append(truncated)
        if terminated or truncated:
            break
    stored = record["families"][schedule.family]["score"]
    if info.get("score") != stored:
        raise FFSRError(f"{record['tier']}/{record['split']} task {record['index']}: replayed score {info.get('score')} "
                        f"!= the stored score {stored} of its {schedule.family} schedule")
    steps = len(rewards) + 1
    infos = {"task_index": np.full(steps, record["index"], dtype=np.int64),
             "task_seed": np.full(steps, record["task_seed"], dtype=np.int64)}
    return EpisodeBuffer(id=episode_id, seed=0, options=options, observations=np.asarray(observations),
                         actions=np.asarray(taken), rewards=np.asarray(rewards, dtype=np.float64),
                         terminations=np.asarray(terminations), truncations=np.asarray(truncations), infos=infos)


#: The most characters of a dataset's author or e-mail (Minari stores them in the dataset's metadata).
MAX_AUTHOR_CHARS = 200


def _person(value: Any, name: str) -> str | None:
    """``value`` as a dataset's author field: None, or one line of printable text of at most
    :data:`MAX_AUTHOR_CHARS` characters (checked before the pool is played, not after).

    Raises:
        InvalidInputError: anything else (named).
    """
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip() or len(value) > MAX_AUTHOR_CHARS \
            or not value.isprintable():
        raise InvalidInputError(f"{name} {str(value)[:40]!r}; allowed: one line of printable text, 1 to "
                                f"{MAX_AUTHOR_CHARS} characters")
    return value


def write_dataset(tier: str, env_id: str = "FFSR-Residual-v2", *, split: str = "train", root: str | Path | None = None,
                  best_known_file: str | Path | None = None, version: str = "v2", author: str | None = None,
                  author_email: str | None = None) -> Any:
    """Write the Minari dataset of ``tier``'s ``split`` pool for ``env_id`` and return it (a ``MinariDataset``).

    ``author``, ``author_email``: who built it (default: git's ``user.name`` and ``user.email`` where set, else
    none).

    Raises:
        InvalidInputError: the test split, an env id without schedules, no stored best-known record for the pool, or
            an author that is not one line of text (each named).
    """
    if split not in ("train", "validation"):
        raise InvalidInputError(f"split {split!r}; allowed: 'train' or 'validation' (the test pool's best trajectories "
                                "are the answers the leaderboard scores against: never a dataset)")
    minari = require("minari", "dataset", "minari, h5py", "datasets need")
    from ffsr_gym.provenance import git_config

    author = _person(author if author is not None else git_config("user.name"), "author")
    author_email = _person(author_email if author_email is not None else git_config("user.email"), "author_email")
    if env_id not in FAMILY_OF:
        raise InvalidInputError(f"env_id {env_id!r}; allowed: {sorted(FAMILY_OF)}")
    family = FAMILY_OF[env_id]
    searched = best_known.records(tier, split, version, best_known_file)
    stored = [r for r in searched if r["families"][family]["schedule"] is not None]
    if not stored:
        raise InvalidInputError(f"no best-known {family} schedule is stored for {tier}/{split} (run ffsr-gym tasks "
                                f"best-known --tiers {tier} --splits {split})")
    size = len(pool(tier, split, version=version))
    name = dataset_id(tier, env_id, split)
    with _datasets_root(root):
        from minari.storage.datasets_root_dir import get_dataset_path

        try:
            final = get_dataset_path(name)  # makes the datasets' folder
        except OSError as exc:
            raise InvalidInputError(f"root {str(root)!r}: not a writable folder ({exc.strerror or exc}); allowed: a "
                                    "folder you can write, or a path where one can be made") from None
    staging = _staging_folder(final, name)  # before the episodes are played: every option is checked first
    try:
        ref_min, ref_max, refs = reference_returns(tier, split, stored, version)
        env, scored = gym.make(env_id, task=tier, split=split), gym.make(env_id, task=tier, split="test")
        eval_spec = scored.spec  # what evaluation plays: the tier's test pool
        scored.close()
        buffers = [record_episode(env, r, Schedule.from_dict(r["families"][family]["schedule"]), k)
                   for k, r in enumerate(stored)]
        with _datasets_root(staging):
            minari.create_dataset_from_buffers(
                name, buffers, env=env, eval_env=eval_spec,
                algorithm_name=("best known schedules: per-task CMA-ES, or a baseline's absorbed episode "
                                "(ffsr_gym.optim)"),
                code_permalink=code_permalink(), author=author, author_email=author_email,
                ref_min_score=ref_min, ref_max_score=ref_max,
                description=(f"The best {family} schedule found for each task of the {tier} tier's {split} pool of "
                             f"benchmark {version}, played in {env_id}: "
                             f"{_coverage(len(stored), len(searched), size, family)}. infos: task_index, task_seed per "
                             f"step. {refs}. eval_env: the tier's test pool, which the leaderboard scores."),
                data_format="hdf5")
        _move_into_place(staging, final, name)
    except OSError as exc:
        raise InvalidInputError(f"dataset {name}: could not be written under {final.parent} "
                                f"({exc.strerror or exc}); nothing was left there") from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    with _datasets_root(root):
        return minari.load_dataset(name)


def code_permalink() -> str:
    """Where the code that wrote a dataset is: this module, at the package's version and commit."""
    from importlib.metadata import version

    from ffsr_gym.provenance import source_commit

    commit = source_commit()
    where = ": lab/ffsr_gym_lab/publish/dataset.py"
    return f"ffsr-gym {version('ffsr-gym')}" + (f", commit {commit}" if commit else "") + where


def _staging_folder(final: Path, name: str) -> Path:
    """A fresh folder beside the datasets, where the dataset is written whole before it is moved into place.

    Raises:
        InvalidInputError: the dataset exists already, or the datasets' folder is not a writable folder.
    """
    if final.exists():  # Minari never overwrites one
        raise InvalidInputError(f"dataset {name} already exists at {final}; delete it or pass another root")
    base = final.parents[len(Path(name).parts) - 1]
    try:
        base.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix=".ffsr-dataset-", dir=base))
    except OSError as exc:
        raise InvalidInputError(f"root {str(base)!r}: not a writable folder ({exc.strerror or exc}); allowed: a "
                                "folder you can write, or a path where one can be made") from None


def _move_into_place(staging: Path, final: Path, name: str) -> None:
    """Move the whole dataset from ``staging`` to ``final`` in one rename (with its namespace's metadata).

    Raises:
        InvalidInputError: another writer put the same dataset there meanwhile.
    """
    built = staging / name
    for depth in range(1, len(Path(name).parts)):  # namespace folders and their metadata, where missing
        namespace = Path(*Path(name).parts[:depth])
        target = final.parents[len(Path(name).parts) - 1] / namespace
        target.mkdir(exist_ok=True)
        for meta in (staging / namespace).glob("*.json"):
            if not (target / meta.name).exists():
                shutil.copyfile(meta, target / meta.name)
    try:
        os.rename(built, final)
    except OSError:
        if final.exists():
            raise InvalidInputError(f"dataset {name} was written at {final} by another process meanwhile; this run's "
                                    "copy is discarded") from None
        raise
