"""Scoring a pool on executors (processes, a Dask cluster) gives the entry of the serial run."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor

import pytest

from ffsr_gym.bench.evaluation import evaluate as evaluate_pool
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.tasks.certificate import planner_episode
from ffsr_gym.tasks.generator import draw_task
from ffsr_gym.tasks.splits import pool

INDICES = [0, 1, 2, 3, 4, 7]


def _same(a, b):
    assert a.episodes == b.episodes and a.metrics == b.metrics
    assert a.provenance["scenario_sha256"] == b.provenance["scenario_sha256"]


def test_process_pool_gives_the_serial_entry_and_the_planner_episodes():
    serial = evaluate_pool((0.3, 4.0), "FFSR-v2", task="easy", indices=INDICES)
    with ProcessPoolExecutor(2) as executor:
        parallel = evaluate_pool((0.3, 4.0), "FFSR-v2", task="easy", indices=INDICES, executor=executor, chunk=2)
    _same(serial, parallel)
    assert [row["task_index"] for row in parallel.episodes] == INDICES
    from ffsr_gym.versions.registry import load_benchmark

    benchmark = load_benchmark("v2")
    for row in parallel.episodes:  # the env episodes, replayed by the planner alone
        task = draw_task(pool("easy", "test")[row["task_index"]].seed, benchmark)
        assert row["score"] == planner_episode(task, benchmark, method="predefined_time", m=0.3, T_c=4.0).score


def test_dask_cluster_gives_the_serial_entry():
    """The executor of ``ffsr-gym evaluate --scheduler local:2`` (pinned workers of a LocalCluster)."""
    pytest.importorskip("distributed")
    from ffsr_gym.cluster import cluster_executor

    with cluster_executor("local:2", say=lambda text: None) as (executor, slots):
        assert slots == 2
        remote = evaluate_pool((0.3, 4.0), "FFSR-v2", task="medium", indices=INDICES, executor=executor, chunk=3)
    _same(evaluate_pool((0.3, 4.0), "FFSR-v2", task="medium", indices=INDICES), remote)


@pytest.mark.parametrize(("argv", "named"), [
    (["--scheduler", "local:0"], "allowed: local:N"),
    (["--scheduler", "local:2", "--scenario", "paper"], "only for a tier's pool")])
def test_evaluate_names_a_bad_scheduler(argv, named, capsys, tmp_path):
    from ffsr_gym.cli.main import main

    assert main(["evaluate", "--env-id", "FFSR-v2", "--policy", "0.3,4", "--leaderboard", str(tmp_path), *argv]) == 2
    assert named in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_chunk_is_checked():
    with pytest.raises(InvalidInputError, match="chunk"):
        evaluate_pool((0.3, 4.0), "FFSR-v2", task="easy", indices=[0], chunk=0)


@pytest.mark.parametrize("task", ["easy", "hard", "debris"])
def test_batched_fixed_parameters_give_the_serial_entry(task):
    """A fixed (m, T_c) on FFSR-v2 runs all tasks in one batched env: rows equal the single env's, bit for bit."""
    indices = INDICES
    for m, T_c in ((0.3, 4.0), (0.1, 1.5)):  # (0.1, 1.5 s) breaks the rate limit: early ends in the batch
        serial = evaluate_pool((m, T_c), "FFSR-v2", task=task, indices=indices, batched=False)
        _same(serial, evaluate_pool((m, T_c), "FFSR-v2", task=task, indices=indices, batched=True))
    with ProcessPoolExecutor(2) as executor:
        _same(serial, evaluate_pool((0.1, 1.5), "FFSR-v2", task=task, indices=indices, executor=executor, chunk=4))
    with pytest.raises(InvalidInputError, match="batched"):
        evaluate_pool((0.0,) * 12, "FFSR-Residual-v2", task=task, indices=indices, batched=True)
