"""The fourth hostile pass on the command line, work files and docs generators: each input gets a named error or a
bound before any work, never a raw traceback, a hang or a machine exhausted. Each failed before its guard."""

from __future__ import annotations

import json
import os

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym  # noqa: F401 - registers the ids
from ffsr_gym.cli.main import main
from ffsr_gym.cluster import machine_workers
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.optim import ga


def test_a_ga_population_or_run_beyond_its_bound_is_refused():
    for population, generations in ((10**12, 10), (1, 10), (100, 0), (100, 10**9)):
        with pytest.raises(InvalidInputError, match=r"allowed: population in \[2, 100,000\]"):
            ga.GAConfig(population=population, generations=generations)


def test_a_torn_or_foreign_ga_checkpoint_is_named_not_resumed(tmp_path):
    path = tmp_path / "ga.json"
    state = ga.run(ga.GAConfig(population=4, generations=2), checkpoint=path, fitness=lambda m, T_c: m + T_c,
                   progress=False, stop_after=1)
    whole = path.read_text()
    assert state.generation == 1
    path.write_text(whole[: len(whole) // 2])  # torn by hand (the run writes atomically)
    with pytest.raises(InvalidInputError, match="move it away to start afresh"):
        ga.run(checkpoint=path, fitness=lambda m, T_c: m + T_c, progress=False)
    edited = json.loads(whole)
    edited["population"] = edited["population"][:2]  # fewer individuals than its settings say
    path.write_text(json.dumps(edited))
    with pytest.raises(InvalidInputError, match="not a GA checkpoint"):
        ga.run(checkpoint=path, fitness=lambda m, T_c: m + T_c, progress=False)
    path.write_text(json.dumps({"config": 3}))
    with pytest.raises(InvalidInputError, match="not a GA checkpoint"):
        ga.run(checkpoint=path, fitness=lambda m, T_c: m + T_c, progress=False)


def test_worker_processes_are_capped_at_the_machine():
    said = []
    assert machine_workers(100_000, say=said.append) == (os.cpu_count() or 1)
    assert said and "capped" in said[0]
    assert machine_workers(1) == 1


@pytest.mark.parametrize("make", ["missing", "folder", "binary", "fifo"])
def test_the_docs_generators_name_a_page_they_cannot_read(tmp_path, capsys, make):
    page = tmp_path / "page.md"
    if make == "folder":
        page.mkdir()
    elif make == "binary":
        page.write_bytes(b"\xff\xfe\x00 not text")
    elif make == "fifo":
        os.mkfifo(page)  # reading it would wait for a writer forever
    assert main(["tasks", "tables", "--docs", str(page)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(page) in err


def test_a_dataset_author_that_is_not_one_line_of_text_is_refused_before_the_run(tmp_path):
    pytest.importorskip("minari")
    from ffsr_gym_lab.publish.dataset import write_dataset

    for author in ("a\x1b[31mred", "x" * 100_000, 42, "two\nlines"):
        with pytest.raises(InvalidInputError, match="allowed: one line of printable text"):
            write_dataset("easy", root=tmp_path, author=author)


def test_a_closed_vector_env_refuses_to_step_or_reset():
    envs = gym.make_vec("FFSR-v2", num_envs=2, vectorization_mode="vector_entry_point", task="easy")
    envs.reset(seed=0)
    envs.close()
    with pytest.raises(InvalidInputError, match="closed"):
        envs.step(np.zeros((2, 2), dtype=np.float32))
    with pytest.raises(InvalidInputError, match="closed"):
        envs.reset(seed=0)
