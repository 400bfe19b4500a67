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

from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.board.leaderboard import render_readme

START, END = spec_for_version("v0").leaderboard.markers()
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.optim import ga

ROOT = Path(__file__).resolve().parents[3]


def spawn(code: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def kill(child: subprocess.Popen) -> None:
    os.killpg(child.pid, signal.SIGKILL)
    child.wait()
    child.stderr.close()  # no unclosed pipe left for a later test's warning check


def wait_for(path: Path, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.02)


HANG_IN_FSYNC = """
import os, time
os.fsync = lambda fd: time.sleep(1000)  # the data is written, not yet renamed: the worst moment to die
"""


def kill_mid_write(code: str, folder: Path, name: str) -> None:
    """Run ``code`` in a child that hangs inside the atomic write of ``folder/name``, and kill -9 it there."""
    child = spawn(HANG_IN_FSYNC + textwrap.dedent(code))
    deadline = time.monotonic() + 120
    while not list(folder.glob(f".{name}.*.tmp")):
        assert child.poll() is None, child.stderr.read().decode()
        assert time.monotonic() < deadline, "the child never started writing"
        time.sleep(0.01)
    kill(child)


def test_kill_during_entry_save_keeps_the_previous_entry(tmp_path):
    from ffsr_gym.bench.entry import EvalReport

    def report(version: int) -> EvalReport:
        return EvalReport("FFSR-v0", {}, {"version": version}, [{"seed": version, "score": float(k)} for k in range(20_000)],
                          {}, name="entry")

    entry = report(1).save(tmp_path)
    previous = entry.read_bytes()
    kill_mid_write(f"""
        from ffsr_gym.bench.entry import EvalReport
        rows = [{{"seed": 2, "score": float(k)}} for k in range(20_000)]
        EvalReport("FFSR-v0", {{}}, {{"version": 2}}, rows, {{}}, name="entry").save({str(tmp_path)!r}, overwrite=True)
    """, tmp_path, "entry.json")
    assert entry.read_bytes() == previous  # whole, and the previous version
    report(3).save(tmp_path, overwrite=True)
    assert json.loads(entry.read_text())["metrics"] == {"version": 3}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["entry.json"]  # the killed writer's temporary is gone


def test_kill_during_leaderboard_render_keeps_the_previous_readme(tmp_path):
    root = tmp_path / "board"
    for folder in (ROOT / "leaderboards").iterdir():
        if folder.is_dir() and folder.name != "v2":
            (root / folder.name).mkdir(parents=True)
            for p in folder.glob("*.json"):
                (root / folder.name / p.name).write_bytes(p.read_bytes())
    readme = root / "README.md"
    stub = f"# Board\n{START}\n{END}\n"
    readme.write_text(stub)
    assert render_readme(root) != stub
    kill_mid_write(f"""
        from ffsr_gym_lab.board.leaderboard import write_readme
        write_readme({str(root)!r})
    """, root, "README.md")
    assert readme.read_text() == stub


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
