"""Long studies on a Dask cluster (``--scheduler``): the address is checked by name, workers run with pinned threads,
and a real scheduler with two worker processes on 127.0.0.1 (separate processes, TCP) gives the same results as a
local run: a best-known search, a pool build, a pool build one of whose workers is killed with SIGKILL, RL seeds,
hyperparameter-search trials, and a best-known search whose client is killed and run again."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ffsr_gym.cluster import Scheduler, cluster_executor, parse_scheduler
from ffsr_gym.exceptions import InvalidInputError

ROOT = Path(__file__).resolve().parents[3]
distributed = pytest.importorskip("distributed")


@pytest.mark.parametrize(("text", "parsed"), [("local:2", Scheduler(None, 2)), ("127.0.0.1:8786",
                                              Scheduler("tcp://127.0.0.1:8786")),
                                              ("tcp://head.cluster:8786", Scheduler("tcp://head.cluster:8786"))])
def test_a_scheduler_is_named_one_way(text, parsed):
    assert parse_scheduler(text) == parsed


@pytest.mark.parametrize("text", ["local:0", "local:257", "local:two", "localhost", "host:99999", "", "tcp://", 2])
def test_a_malformed_scheduler_is_refused_by_name(text):
    with pytest.raises(InvalidInputError, match="allowed: local:N"):
        parse_scheduler(text)


def _threads() -> tuple[int, int, str]:
    import gymnasium as gym
    import torch

    import ffsr_gym  # noqa: F401  (registers the environments)

    venv = gym.make_vec("FFSR-v2", num_envs=2, vectorization_mode="vector_entry_point")
    return venv.unwrapped.engine.threads, torch.get_num_threads(), os.environ["OMP_NUM_THREADS"]


def test_a_local_cluster_pins_its_workers_threads():
    pytest.importorskip("torch")
    with cluster_executor("local:1", say=lambda text: None) as (executor, slots):
        assert slots == 1
        assert executor.submit(_threads).result(timeout=120) == (1, 1, "1")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Cluster:
    """A ``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1, as a user starts them by hand."""

    def __init__(self, tmp: Path) -> None:
        self.address = f"tcp://127.0.0.1:{_free_port()}"
        dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        port = self.address.rsplit(":", 1)[1]
        self.scheduler = subprocess.Popen([*dask, "--host", "127.0.0.1", "--port", port, "--no-dashboard"],
                                          env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        worker = [sys.executable, "-m", "distributed.cli.dask_worker", self.address, "--nthreads", "1", "--no-nanny",
                  "--no-dashboard", "--memory-limit", "0", "--local-directory", str(tmp)]
        self.workers = [subprocess.Popen(worker, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                        for _ in range(2)]
        with distributed.Client(self.address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)

    def close(self) -> None:
        for process in [*self.workers, self.scheduler]:
            if process.poll() is None:
                process.terminate()
        for process in [*self.workers, self.scheduler]:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()


@pytest.fixture
def cluster(tmp_path):
    running = _Cluster(tmp_path / "dask")
    yield running
    running.close()


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _records(path: Path) -> list[dict]:
    """A best-known work file's records by task, without the wall times (the only field that depends on the run)."""
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    return sorted(({k: v for k, v in r.items() if k != "wall_time_s"} for r in rows), key=lambda r: r["index"])


_KILLED_CLIENT = """
from ffsr_gym.cluster import cluster_executor
from ffsr_gym_lab.best_known import build
with cluster_executor({address!r}, say=lambda text: None) as (executor, _):
    build.run("slow", "test", {work!r}, version="capture-v0", generations=2, indices=[0, 1, 2], progress=False,
              executor=executor)
"""


@pytest.mark.slow
def test_a_best_known_search_on_a_real_cluster_equals_the_local_one_after_its_client_is_killed(cluster, tmp_path):
    from ffsr_gym_lab.best_known import build

    local = build.run("slow", "test", tmp_path / "local", version="capture-v0", generations=2, indices=[0, 1, 2],
                      progress=False)
    remote = build.work_file(tmp_path / "remote", "slow", "test")
    client = subprocess.Popen([sys.executable, "-c", _KILLED_CLIENT.format(address=cluster.address,
                                                                           work=str(remote.parent))],
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
    deadline = time.monotonic() + 900
    while not (remote.is_file() and build.read_lines(remote)) and time.monotonic() < deadline:
        assert client.poll() is None, "the client ended before it was killed"
        time.sleep(0.2)
    client.send_signal(signal.SIGKILL)
    client.wait()
    kept = [r["index"] for r in build.read_lines(remote)]
    assert 1 <= len(kept) < 3  # killed with work left
    with cluster_executor(cluster.address, say=lambda text: None) as (executor, slots):
        assert slots == 2
        build.run("slow", "test", remote.parent, version="capture-v0", generations=2, indices=[0, 1, 2],
                  progress=False, executor=executor)
    records = build.read_lines(remote)
    assert [r["index"] for r in records][:len(kept)] == kept  # what the killed client wrote is kept, not redone
    assert _records(remote) == _records(local)


def _pool_build(work: Path, monkeypatch, executor=None, workers: int = 2) -> tuple[list[dict], dict]:
    """A two-task slow test pool: its verdicts and its summary (what the pool file holds). Without ``executor``, two
    local processes (``--workers 2``): the chunks classified at once are the build's, so both runs use two."""
    from concurrent.futures import ProcessPoolExecutor

    from ffsr_gym_lab.pools import build

    monkeypatch.setattr(build, "expected_count", lambda tier, split, version=None: 2)  # the client decides the size
    local = ProcessPoolExecutor(workers) if executor is None else None
    try:
        verdicts = build.build_split(work, "test", version="capture-v0", target="slow", chunk=4,
                                     executor=executor or local, workers=workers, progress=False)
    finally:
        if local is not None:
            local.shutdown()
    return [v.as_dict() for v in verdicts], build.summarise_split(verdicts, 2, "slow")


@pytest.mark.slow
def test_a_pool_build_on_a_real_cluster_is_byte_identical_to_the_local_one(cluster, tmp_path, monkeypatch):
    local = _pool_build(tmp_path / "local", monkeypatch)
    with cluster_executor(cluster.address, say=lambda text: None) as (executor, slots):
        remote = _pool_build(tmp_path / "remote", monkeypatch, executor, slots)
    assert remote == local
    assert _files(tmp_path / "remote") == _files(tmp_path / "local")


@pytest.mark.slow
def test_a_worker_killed_mid_build_loses_only_its_piece(cluster, tmp_path, monkeypatch):
    local = _pool_build(tmp_path / "local", monkeypatch)
    with cluster_executor(cluster.address, say=lambda text: None) as (executor, slots):
        def kill_soon() -> None:
            time.sleep(5.0)  # both workers are classifying their first chunk
            cluster.workers[0].send_signal(signal.SIGKILL)

        import threading

        killer = threading.Thread(target=kill_soon)
        killer.start()
        remote = _pool_build(tmp_path / "remote", monkeypatch, executor, slots)
        killer.join()
    assert cluster.workers[0].poll() == -signal.SIGKILL  # it did die, mid-run
    assert remote == local
    assert _files(tmp_path / "remote") == _files(tmp_path / "local")


def _comparable(value):
    """A record without what belongs to the run rather than its result: provenance, wall times, file paths."""
    if isinstance(value, dict):
        return {k: _comparable(v) for k, v in value.items()
                if k != "provenance" and "wall_time" not in k and k != "created_utc"}
    if isinstance(value, list):
        return [_comparable(v) for v in value]
    return value


@pytest.mark.slow
def test_an_rl_study_on_a_real_cluster_records_what_a_local_run_records(cluster, tmp_path):
    pytest.importorskip("stable_baselines3")
    from ffsr_gym.optim.rl_study import seed_folder, seed_piece, train_and_evaluate, write_seed

    group, steps = ("ppo", "FFSR-v2", "easy"), 2048  # one PPO rollout of 16 envs x 128 steps
    for seed in (0, 1):
        train_and_evaluate(*group[:2], task=group[2], seeds=[seed], out=tmp_path / "local", timesteps=steps,
                           curve_every=steps, progress=False)
    with cluster_executor(cluster.address, say=lambda text: None) as (executor, _):
        pieces = {seed: executor.submit(seed_piece, *group, seed, steps, steps, ["rl_study.py"]) for seed in (0, 1)}
        for seed, piece in pieces.items():
            write_seed(tmp_path / "remote", *group, seed, piece.result(timeout=1800))
    for seed in (0, 1):
        local, remote = (seed_folder(tmp_path / side, *group, seed) for side in ("local", "remote"))
        names = sorted(p.name for p in remote.glob("*.json"))
        assert names == ["evaluation.json", "evaluation_best_on_validation.json", "train_record.json"]
        for name in names:
            assert _comparable(json.loads((remote / name).read_text())) == \
                _comparable(json.loads((local / name).read_text())), (seed, name)


@pytest.mark.slow
def test_a_hyperparameter_search_on_a_real_cluster_equals_the_local_one(cluster):
    pytest.importorskip("stable_baselines3")
    optuna = pytest.importorskip("optuna")
    from functools import partial

    from ffsr_gym_lab.studies.tune_loop import default_space, search, train_trial
    from ffsr_gym_lab.studies.tuning import make_pruner, make_sampler

    piece, space = partial(train_trial, "ppo", "FFSR-v2", "easy", 2048, 2), default_space("ppo", "FFSR-v2")
    studies = [optuna.create_study(direction="maximize", sampler=make_sampler(), pruner=make_pruner())
               for _ in range(2)]
    search(studies[0], piece, space, trials=2, batch=2, progress=False)
    with cluster_executor(cluster.address, say=lambda text: None) as (executor, _):
        search(studies[1], piece, space, trials=2, batch=2, executor=executor, progress=False)
    here, there = ([(t.number, t.state.name, t.params, t.value, t.intermediate_values, t.user_attrs["env_steps"])
                    for t in study.trials] for study in studies)
    assert there == here and len(here) == 2


@pytest.mark.slow
def test_the_ga_on_a_local_cluster_finds_what_it_finds_in_this_process(tmp_path):
    from ffsr_gym.optim.ga import GAConfig
    from ffsr_gym.optim.ga_study import run_study

    config = GAConfig(population=6, generations=2, seed=3)
    here = run_study(tmp_path / "here", modes=("reproduction",), config=config, executor="none", progress=False)
    there = run_study(tmp_path / "there", modes=("reproduction",), config=config, scheduler="local:2", progress=False)
    assert there["reproduction"]["optimum"] == here["reproduction"]["optimum"]


def test_the_docs_hold_the_measured_speed_up():
    from conftest import script_module

    study = script_module("cluster_speedup")
    result = json.loads((ROOT / "experiments" / "cluster_speedup.json").read_text())
    text = (ROOT / "docs" / "cluster.md").read_text(encoding="utf-8")
    block = text[text.index(study.START) + len(study.START):text.index(study.END)]
    assert block.strip() == study.docs_text(result).strip()
    assert result["same_records"] and result["wall_time_s"]["1"] / result["wall_time_s"]["2"] == result["speedup"]
