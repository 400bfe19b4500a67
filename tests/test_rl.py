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
    assert entry["extra"]["method"].endswith(", 1 training seed")  # not "1 training seeds"
    assert (tmp_path / "runs" / f"{algo}_{env_id}_paper_seed0" / "model.zip").is_file()
    assert any((tmp_path / "runs").rglob("events.out.tfevents*"))  # TensorBoard log


def test_same_seed_same_evaluation(tmp_path):
    a = _smoke("ppo", "FFSR-Residual-v0", tmp_path / "a")
    b = _smoke("ppo", "FFSR-Residual-v0", tmp_path / "b")
    assert a.episodes == b.episodes
    assert a.metrics == b.metrics


def test_hyperparameter_files_cover_every_id():
    for algo in ("ppo", "sac"):
        for env_id in ("FFSR-v0", "FFSR-Residual-v0", "FFSR-v2", "FFSR-Residual-v2"):
            params = load_hyperparams(algo, env_id)
            assert params["n_timesteps"] > 0 and isinstance(params["policy_kwargs"], dict)


def test_pool_training_records_a_validation_curve_scores_the_test_pool_and_resumes(tmp_path):
    from ffsr_gym.bench.leaderboard import recompute as recompute_entry
    from ffsr_gym.tasks.splits import pool

    def run():
        return train_and_evaluate("ppo", "FFSR-v2", task="easy", seeds=[0], out=tmp_path, timesteps=256,
                                     curve_every=128, curve_tasks=3, progress=False)

    report = run()
    entry = report.to_json()
    curve = entry["extra"]["runs"][0]["curve"]
    assert [p["env_steps"] for p in curve["points"]][:2] == [0, 128] and len(curve["points"][0]["scores"]) == 3
    assert curve["split"] == "validation" and curve["indices"] == [0, 24, 49]  # never the test pool
    assert len(entry["episodes"]) == len(pool("easy", "test"))
    assert entry["extra"]["training_pool"] == "easy/train" and entry["extra"]["compute"]["env_steps"] == 256
    recomputed = recompute_entry(entry)
    assert entry["metrics"].keys() == recomputed.keys()
    for key, value in recomputed.items():
        assert entry["metrics"][key] == pytest.approx(value, rel=1e-12), key
    started = (tmp_path / "ppo_FFSR-v2_easy_seed0" / "train_record.json").stat().st_mtime_ns
    assert run().episodes == report.episodes  # resumed from the folder, not retrained
    assert (tmp_path / "ppo_FFSR-v2_easy_seed0" / "train_record.json").stat().st_mtime_ns == started
