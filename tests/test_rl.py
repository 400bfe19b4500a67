"""RL baselines: short smoke trainings produce valid leaderboard entries, and are reproducible."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

pytest.importorskip("stable_baselines3")

from ffsr_gym.bench import leaderboard  # noqa: E402
from ffsr_gym.optim.rl import load_hyperparams, train_and_evaluate  # noqa: E402

SCHEMA = json.loads((Path(__file__).resolve().parent.parent / "leaderboards" / "schema.json").read_text())
CASES = [(algo, env_id) for algo in ("ppo", "sac") for env_id in ("FFSR-v0", "FFSR-Residual-v0")]


def _smoke(algo, env_id, out, seeds=(0,)):
    return train_and_evaluate(algo, env_id, seeds=list(seeds), out=out, timesteps=256, eval_seeds=[1, 2], progress=False)


@pytest.mark.parametrize(("algo", "env_id"), CASES)
def test_smoke_training_writes_a_valid_entry(algo, env_id, tmp_path):
    report = _smoke(algo, env_id, tmp_path / "runs")
    path = report.save(tmp_path / "leaderboards" / env_id)
    entry = json.loads(path.read_text())
    jsonschema.validate(entry, SCHEMA)
    assert entry["metrics"]["episodes"] == 2
    assert leaderboard.recompute(entry)["feasible_rate"] == entry["metrics"]["feasible_rate"]
    assert entry["extra"]["runs"][0]["timesteps"] == 256
    assert (tmp_path / "runs" / f"{algo}_{env_id}_paper_seed0" / "model.zip").is_file()
    assert any((tmp_path / "runs").rglob("events.out.tfevents*"))  # TensorBoard log


def test_same_seed_same_evaluation(tmp_path):
    a = _smoke("ppo", "FFSR-Residual-v0", tmp_path / "a")
    b = _smoke("ppo", "FFSR-Residual-v0", tmp_path / "b")
    assert a.episodes == b.episodes
    assert a.metrics == b.metrics


def test_hyperparameter_files_cover_both_ids():
    for algo in ("ppo", "sac"):
        for env_id in ("FFSR-v0", "FFSR-Residual-v0"):
            params = load_hyperparams(algo, env_id)
            assert params["n_timesteps"] > 0 and isinstance(params["policy_kwargs"], dict)
