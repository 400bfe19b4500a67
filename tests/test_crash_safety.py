"""kill -9 in the middle of writing results: the previous file stays whole, and a killed GA using a
process pool resumes to the uninterrupted result."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from ffsr_gym.bench.leaderboard import END, START, render_readme
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.optim import ga

ROOT = Path(__file__).resolve().parents[1]


def spawn(code: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def kill(child: subprocess.Popen) -> None:
    os.killpg(child.pid, signal.SIGKILL)
    child.wait()


def wait_for(path: Path, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.02)


def test_kill_during_entry_save_leaves_a_whole_entry(tmp_path):
    """A child rewrites a 3 MB entry in a loop; killed at random moments, the file is always one whole version."""
    code = f"""
        from ffsr_gym.bench.entry import EvalReport
        i = 0
        while True:
            rows = [{{"seed": i, "score": float(k)}} for k in range(60_000)]
            EvalReport("FFSR-v0", {{}}, {{"version": i}}, rows, {{}}, name="entry").save({str(tmp_path)!r})
            i += 1
    """
    entry = tmp_path / "entry.json"
    rng = np.random.default_rng(0)
    for _ in range(4):
        child = spawn(code)
        wait_for(entry)
        time.sleep(rng.uniform(0.05, 0.6))
        kill(child)
        data = json.loads(entry.read_text())
        assert {row["seed"] for row in data["episodes"]} == {data["metrics"]["version"]}
        assert len(data["episodes"]) == 60_000
    from ffsr_gym.provenance import write_json_atomic

    write_json_atomic(entry, {"after": True})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["entry.json"]  # the killed writers' temporaries are gone


def test_kill_during_leaderboard_render_leaves_the_previous_readme(tmp_path):
    root = tmp_path / "board"
    for folder in (ROOT / "leaderboards").iterdir():
        if folder.is_dir():
            (root / folder.name).mkdir(parents=True)
            for p in folder.glob("*.json"):
                (root / folder.name / p.name).write_bytes(p.read_bytes())
    readme = root / "README.md"
    stub = f"# Board\n{START}\n{END}\n"
    readme.write_text(stub)
    expected = render_readme(root)
    code = f"""
        from ffsr_gym.bench.leaderboard import write_readme
        from ffsr_gym.provenance import write_text_atomic
        while True:
            write_readme({str(root)!r})
            write_text_atomic({str(readme)!r}, {stub!r})  # back to the stub, so that every round writes
    """
    rng = np.random.default_rng(1)
    for _ in range(3):
        child = spawn(code)
        time.sleep(rng.uniform(0.5, 2.0))
        kill(child)
        assert readme.read_text() in (expected, stub)


def test_kill_ga_with_a_process_pool_mid_generation_then_resume_exactly(tmp_path):
    scenario = tmp_path / "paper_8s.toml"
    scenario.write_text(Path(load_scenario("paper").source).read_text().replace("duration_s = 20.0", "duration_s = 8.0"))
    config = ga.GAConfig(population=8, generations=40, T_c_fixed=None, seed=4, scenario=str(scenario))
    uninterrupted = ga.run(config, checkpoint=tmp_path / "a.json", progress=False)
    checkpoint = tmp_path / "b.json"
    child = spawn(f"""
        from concurrent.futures import ProcessPoolExecutor
        from ffsr_gym.optim import ga
        config = ga.GAConfig(population=8, generations=40, T_c_fixed=None, seed=4, scenario={str(scenario)!r})
        with ProcessPoolExecutor(2) as pool:
            ga.run(config, checkpoint={str(checkpoint)!r}, executor=pool, progress=False)
    """)
    wait_for(checkpoint)
    deadline = time.monotonic() + 120
    while json.loads(checkpoint.read_text())["generation"] < 2:  # the checkpoint is always whole (atomic)
        assert time.monotonic() < deadline
        time.sleep(0.005)
    kill(child)  # the pool is mid-way through a later generation
    saved = json.loads(checkpoint.read_text())
    assert saved["generation"] < config.generations, "the child finished before it was killed"
    with ProcessPoolExecutor(2) as pool:
        resumed = ga.run(None, checkpoint=checkpoint, executor=pool, progress=False)
    assert resumed.history == uninterrupted.history
    assert np.array_equal(resumed.population, uninterrupted.population)
    assert resumed.rng_state == uninterrupted.rng_state
