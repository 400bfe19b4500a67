"""RL baselines: short smoke trainings produce valid leaderboard entries, and are reproducible."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

pytest.importorskip("stable_baselines3")

from ffsr_gym.optim.rl import load_hyperparams  # noqa: E402
from ffsr_gym.optim.rl_study import train_and_evaluate  # noqa: E402
from ffsr_gym_lab.board import leaderboard  # noqa: E402

SCHEMA = json.loads((Path(__file__).resolve().parents[3] / "leaderboards" / "schema.json").read_text())
CASES = [(algo, env_id) for algo in ("ppo", "sac") for env_id in ("FFSR-v0", "FFSR-Residual-v0")]


def _smoke(algo, env_id, out, seeds=(0,)):
    reports = train_and_evaluate(algo, env_id, seeds=list(seeds), out=out, timesteps=256, eval_seeds=[1, 2],
                                 progress=False)
    assert list(reports) == ["last"]  # a version scored on seeds has no validation pool to select on
    return reports["last"]


@pytest.mark.parametrize(("algo", "env_id"), CASES)
def test_smoke_training_writes_a_valid_entry(algo, env_id, tmp_path):
    report = _smoke(algo, env_id, tmp_path / "runs")
    path = report.save(tmp_path / "leaderboards" / env_id)
    entry = json.loads(path.read_text())
    jsonschema.validate(entry, SCHEMA)
    assert entry["metrics"]["episodes"] == 2
    assert leaderboard.recompute(entry)["feasible_rate"] == entry["metrics"]["feasible_rate"]
    assert entry["extra"]["runs"][0]["timesteps"] == 256
    assert ", 1 training seed, " in entry["extra"]["method"]  # not "1 training seeds"
    assert (tmp_path / "runs" / f"{algo}_{env_id}_paper_seed0" / "model.zip").is_file()
    assert any((tmp_path / "runs").rglob("events.out.tfevents*"))  # TensorBoard log


def test_same_seed_same_evaluation(tmp_path):
    a = _smoke("ppo", "FFSR-Residual-v0", tmp_path / "a")
    b = _smoke("ppo", "FFSR-Residual-v0", tmp_path / "b")
    assert a.episodes == b.episodes
    assert a.metrics == b.metrics


def test_a_study_entry_replays_from_its_seeds_traces_without_its_models(tmp_path):
    """An RL entry of several training seeds carries each seed's applied actions: ``verify`` replays it with the
    models gone and nothing of the entry's run as code."""
    import shutil

    from ffsr_gym.bench.replay import replay_entry

    report = _smoke("ppo", "FFSR-Residual-v0", tmp_path / "runs", seeds=(0, 1))
    assert len(report.extra["trace"]["episodes"]) == len(report.episodes) == 4
    shutil.rmtree(tmp_path / "runs")
    path = report.save(tmp_path / "entry")
    verdict = replay_entry(path)
    assert verdict.status == "reproduced" and "trace" in verdict.text


def test_hyperparameter_files_cover_every_id():
    """Every id of every shipped version (a new version's ids included: its RL study reads them from here)."""
    from ffsr_gym.versions.registry import all_specs

    ids = {env_id for spec in all_specs().values() for env_id in spec.env_ids}
    assert {"FFSR-v0", "FFSR-v2", "FFSR-Capture-v2", "FFSR-Capture-Residual-v2"} <= ids
    for algo in ("ppo", "sac"):
        for env_id in sorted(ids):
            params = load_hyperparams(algo, env_id)
            assert params["n_timesteps"] > 0 and isinstance(params["policy_kwargs"], dict)


def test_v2_hyperparameters_are_the_searched_best():
    """The shipped v2 hyperparameters are the best trial of the search record next to them."""
    search = Path(load_hyperparams.__globals__["DEFAULT_HYPERPARAMS"]) / "search"
    records = sorted(search.glob("*.json"))
    assert records, "no search record"
    for path in records:
        record = json.loads(path.read_text())
        shipped = load_hyperparams(record["algo"], record["env_id"])
        best = record["best"]["hyperparams"]
        assert {k: v for k, v in shipped.items() if k != "n_timesteps"} == best, path.name
        trials = [t["value"] for t in record["trials"] if t["state"] == "COMPLETE"]
        assert record["best"]["value"] == max(trials)
        assert record["cost"]["trials"] == len(record["trials"])
        assert record["training_pool"].endswith("/train") and record["selection_pool"].endswith("/validation")


@pytest.mark.slow  # half a minute or more: with -m slow (CI stays under 20 minutes)
def test_pool_training_selects_on_validation_scores_both_checkpoints_on_test_and_resumes(tmp_path):
    import torch

    from ffsr_gym.bench.evaluation import evaluate
    from ffsr_gym.bench.policies import load_model
    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.tasks.splits import pool
    from ffsr_gym_lab.board.leaderboard import recompute as recompute_entry

    def run():
        return train_and_evaluate("ppo", "FFSR-v2", task="easy", seeds=[0], out=tmp_path, timesteps=1024,
                                  curve_every=256, curve_tasks=3, progress=False, n_envs=8)  # 8 x 128: one rollout

    reports = run()
    assert [r.name for r in reports.values()] == ["ppo_easy", "ppo_easy_valbest"]
    entry = reports["last"].to_json()
    curve = entry["extra"]["runs"][0]["curve"]
    assert [p["env_steps"] for p in curve["points"]] == [0, 256, 512, 768, 1024]
    assert curve["split"] == "validation" and curve["indices"] == [0, 24, 49]  # never the test pool
    assert len(entry["episodes"]) == len(pool("easy", "test"))
    assert entry["extra"]["training_pool"] == "easy/train" and entry["extra"]["compute"]["env_steps"] == 1024
    assert entry["extra"]["selection_pool"] == "easy/validation"
    for report in reports.values():
        report.save(tmp_path / "leaderboards" / "v2" / "easy")  # a leaderboard table takes it (refused entries raise)
        recomputed = recompute_entry(report.to_json())
        assert report.metrics.keys() == recomputed.keys()
        for key, value in recomputed.items():
            assert report.metrics[key] == pytest.approx(value, rel=1e-12), key
    # the selected checkpoint: the best validation mean, and the saved model scores exactly that again
    folder = tmp_path / "ppo_FFSR-v2_easy_seed0"
    means = [sum(p["scores"]) / 3 for p in curve["points"]]
    best = entry["extra"]["runs"][0]["best_on_validation"]
    assert best["validation_mean"] == pytest.approx(max(means), rel=1e-12)
    assert best["env_steps"] == curve["points"][means.index(max(means))]["env_steps"]
    torch.set_num_threads(2)
    chosen = load_model("ppo", folder / "best_on_validation.zip")
    assert torch.get_num_threads() == 1  # one observation at a time: one thread (load_model's threads=1)
    torch.set_num_threads(2)
    load_model("ppo", folder / "best_on_validation.zip", threads=None)
    assert torch.get_num_threads() == 2  # None leaves the process's setting
    torch.set_num_threads(1)
    for bad in (0, 1.5, True):
        with pytest.raises(InvalidInputError, match="threads"):
            load_model("ppo", folder / "best_on_validation.zip", threads=bad)
    again = evaluate(chosen, "FFSR-v2", task="easy", split="validation", indices=[0, 24, 49])
    assert [row["score"] for row in again.episodes] == curve["points"][means.index(max(means))]["scores"]
    test = evaluate(chosen, "FFSR-v2", task="easy")
    assert [row["score"] for row in test.episodes] == [row["score"] for row in reports["best_on_validation"].episodes]
    started = (folder / "train_record.json").stat().st_mtime_ns
    for model in folder.glob("*.zip"):
        model.unlink()  # a scored seed resumes from its records alone (they can be kept in git, models not)
    again = run()
    assert {c: r.episodes for c, r in again.items()} == {c: r.episodes for c, r in reports.items()}
    assert (folder / "train_record.json").stat().st_mtime_ns == started  # not retrained


def test_a_seed_being_trained_elsewhere_is_refused_by_name(tmp_path):
    import subprocess
    import sys

    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.optim.rl import train

    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        folder = tmp_path / "seed"
        folder.mkdir()
        (folder / ".training").write_text(str(other.pid))  # a live process holds it
        with pytest.raises(InvalidInputError, match=f"being trained by process {other.pid}"):
            train("ppo", "FFSR-v2", seed=0, out=folder, task="easy", timesteps=256, n_envs=2, progress=False)
    finally:
        other.kill()
        other.wait()
    # its process is gone: the lock is taken, the seed trains, and the lock is released
    train("ppo", "FFSR-v2", seed=0, out=folder, task="easy", timesteps=256, n_envs=2, curve_every=10_000,
          curve_tasks=1, progress=False)
    assert (folder / "model.zip").is_file() and not (folder / ".training").exists()


def test_seeds_scored_on_another_step_or_pool_are_refused_by_folder():
    from ffsr_gym.exceptions import InvalidInputError
    from ffsr_gym.optim.rl_study import same_scoring

    def scored(dt, pool="a" * 64):
        return {"extra": {"pool_file_sha256": pool, "dt_s": dt, "reference_sha256": None}}

    recorded = {}
    same_scoring(recorded, "last", scored(0.01), "seed0", 0)
    same_scoring(recorded, "last", scored(0.01), "seed1", 0)  # the same: accepted
    same_scoring(recorded, "best_on_validation", scored(0.02), "seed1", 0)  # each checkpoint apart
    for other in (scored(0.005), scored(0.01, pool="b" * 64)):
        with pytest.raises(InvalidInputError, match="seed2: scored on another pool file or step than seed 0"):
            same_scoring(recorded, "last", other, "seed2", 0)
    assert recorded["last"]["dt_s"] == 0.01  # a refused seed does not replace the record
