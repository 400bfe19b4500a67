"""Every raw traceback the third hostile pass found is a named error, raised before any work where the input can be
checked up front."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.cli.main import main
from ffsr_gym.exceptions import InvalidInputError, RobotFileError, ScenarioError, WriteError
from ffsr_gym.model.resources import scenario_path


@pytest.mark.parametrize("options, named", [
    (["--speed", "1e-300"], "frames .* ms apart; allowed: 10 to 655350 ms"),
    (["--every", "100000"], "frames .* ms apart"),
    (["--out", "/bin/ls/x.gif"], "'/bin/ls' is a file, not a folder"),
])
def test_render_options_are_checked_before_the_episode(options, named, capsys):
    start = time.perf_counter()
    assert main(["render", "--env-id", "FFSR-v2", *options]) == 2
    assert time.perf_counter() - start < 20.0
    import re

    assert re.search(named, capsys.readouterr().err)


def test_a_policy_that_does_not_pickle_is_refused_before_workers_start(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.py").write_text("import numpy as np\n\ndef act(obs):\n    return np.zeros(2, 'float32')\n")
    argv = ["evaluate", "--env-id", "FFSR-v2", "--task", "easy", "--policy", "mine.py:act", "--workers", "2",
            "--no-progress"]
    assert main(argv) == 2 and "does not pickle" in capsys.readouterr().err


def test_the_batched_sb3_env_checks_its_arguments():
    from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv

    for threads in ("1", 1.5, True):
        with pytest.raises(InvalidInputError, match="threads = "):
            BatchedVecEnv("FFSR-v2", 2, threads=threads, task="easy")
    env = BatchedVecEnv("FFSR-v2", 2, task="easy")
    for seed in ("3", -1, 2.0):
        with pytest.raises(InvalidInputError, match="seed = "):
            env.seed(seed)
    env.seed(3)
    env.reset()
    with pytest.raises(InvalidInputError, match="actions = None"):
        env.step_async(None)
    with pytest.raises(InvalidInputError, match="shape"):
        env.step(np.zeros((3, 2), dtype=np.float32))


def test_a_residual_flag_that_is_not_a_boolean_is_refused():
    for value in ("no", 0, None):
        with pytest.raises(InvalidInputError, match="residual = .*allowed: True or False"):
            gym.make("FFSR-v2", residual=value)


def test_an_entry_that_cannot_be_saved_is_named_and_the_old_one_stays(tmp_path, monkeypatch):
    import os

    report = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", indices=[0], name="mine")
    path = report.save(tmp_path)
    before = path.read_bytes()

    def full_disk(*_args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", full_disk)
    report.extra["note"] = "changed"
    with pytest.raises(WriteError, match="No space left on device.*unchanged"):
        report.save(tmp_path, overwrite=True)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["mine.json"]


def test_toml_nested_past_any_real_file_is_named(tmp_path):
    deep = "x = " + "[" * 100_000 + "]" * 100_000 + "\n"
    path = tmp_path / "deep.toml"
    path.write_text(scenario_path("free_space").read_text() + deep)
    with pytest.raises(ScenarioError, match="nested deeper than 32"):
        ffsr_gym.model.scenario.load_scenario(path)
    from test_own_robot import make_robot, scenario_with_robot

    folder = make_robot(tmp_path / "robot")
    (folder / "collision.toml").write_text((folder / "collision.toml").read_text() + deep)
    with pytest.raises(RobotFileError, match="nested deeper than 32"):
        ffsr_gym.model.scenario.load_scenario(scenario_with_robot(tmp_path, "./robot"))
