"""Hostile input gets the project's own errors: stepping past the end, path escapes, odd action and
seed types, entry names; shared result files follow the umask."""

from __future__ import annotations

import json
import os
import stat

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.bench.entry import EvalReport
from ffsr_gym.exceptions import InvalidInputError, RobotFileError, ScenarioError
from ffsr_gym.model.resources import scenario_path
from ffsr_gym.provenance import write_json_atomic
from ffsr_gym.tasks.certificate import Certificate
from ffsr_gym_lab.board.leaderboard import entry_scenario


@pytest.mark.parametrize("env_id", ["FFSR-v2", "FFSR-Residual-v0"])
def test_step_after_the_episode_ended_is_an_error_not_more_physics(env_id):
    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    action = np.ones(env.action_space.shape, dtype=np.float32)  # ends early: (0.6, 10 s) or +20 deg/s residual
    while True:
        *_, terminated, truncated, _ = env.step(action if env.residual else np.zeros(2, dtype=np.float32))
        if terminated or truncated:
            break
    samples = len(env.trajectory.t)
    with pytest.raises(InvalidInputError, match="episode ended.*reset"):
        env.step(action)
    assert len(env.trajectory.t) == samples
    env.reset(seed=1)
    env.step(action)  # a reset starts a new episode


@pytest.mark.parametrize("robot", ["../../../../../../etc", "/proc/self", "ffsr_dual_arm/..", "", "ghost"])
def test_scenario_robot_must_be_a_shipped_robot_or_a_robot_folder(tmp_path, robot):
    text = scenario_path("paper").read_text().replace('robot = "ffsr_dual_arm"', f"robot = {json.dumps(robot)}")
    path = tmp_path / "escape.toml"
    path.write_text(text)
    with pytest.raises(RobotFileError, match=r"escape.toml: key 'robot': .*(\.urdf|shipped robot)"):
        ffsr_gym.load_scenario(path)


def test_binary_scenario_file_is_a_scenario_error(tmp_path):
    path = tmp_path / "binary.toml"
    path.write_bytes(bytes(range(256)))
    with pytest.raises(ScenarioError, match="UTF-8"):
        ffsr_gym.load_scenario(path)


@pytest.mark.parametrize("action", [{"a": 1}, object(), np.zeros(12) + 1j, ["0.1"] * 12, "0.1", [[0.1], [0.1, 0.2]]])
def test_odd_actions_are_named_errors(action):
    env = gym.make("FFSR-Residual-v2")
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match="action"):
        env.step(action)


def test_vector_env_seeds_of_any_integer_type_and_named_errors():
    venv = gym.make_vec("FFSR-Residual-v2", num_envs=2, vectorization_mode="vector_entry_point")
    np.testing.assert_array_equal(venv.reset(seed=np.int64(3))[0], venv.reset(seed=3)[0])
    for bad in ("abc", [1], 1.5, True, -1):
        with pytest.raises(InvalidInputError, match="seed"):
            venv.reset(seed=bad)


@pytest.mark.parametrize("name", ["../../escaped", "/tmp/x", ".hidden", "a/b", "", "x" * 200])
def test_entry_names_cannot_leave_their_folder(tmp_path, name):
    report = EvalReport("FFSR-v0", {}, {}, [], {}, name=name)
    with pytest.raises(InvalidInputError, match="entry name"):
        report.save(tmp_path / "board")
    assert not any(tmp_path.rglob("*.json"))


def test_leaderboard_entry_scenario_must_be_shipped_or_in_its_folder(tmp_path):
    entry = {"name": "e", "_file": "e.json", "_folder": str(tmp_path), "env_kwargs": {"scenario": "/etc/passwd.toml"}}
    with pytest.raises(InvalidInputError, match="scenario"):
        entry_scenario(entry)
    entry["env_kwargs"]["scenario"] = "../outside.toml"
    with pytest.raises(InvalidInputError, match="scenario"):
        entry_scenario(entry)
    entry["env_kwargs"]["scenario"] = "mine.toml"
    assert entry_scenario(entry) == (tmp_path / "mine.toml").resolve()
    entry["env_kwargs"]["scenario"] = "paper"
    assert entry_scenario(entry) == "paper"


def test_result_files_follow_the_umask(tmp_path):
    old = os.umask(0o022)
    try:
        write_json_atomic(tmp_path / "result.json", {"a": 1})
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "result.json").stat().st_mode) == 0o644
    assert json.loads((tmp_path / "result.json").read_text()) == {"a": 1}


def _soak_pool(env_id: str, tier: str, steps: int) -> int:
    """Random actions (some out of range), and every third episode a certificate: all finite, in space.

    A certificate is played where the env can play it: a constant (m, T_c) on FFSR-v2, a residual
    on FFSR-Residual-v2, and the default setting as a zero residual. Medium tasks on the residual
    env and hard tasks on FFSR-v2 have none (by the tier rule). Returns (successes, certificate
    episodes); every certificate episode must succeed.
    """
    import math

    from ffsr_gym.tasks.splits import pool

    env = gym.make(env_id, task=tier).unwrapped
    tasks = pool(tier, "train")
    rng = np.random.default_rng(0)
    env.action_space.seed(0)
    successes, episode, certified, played = 0, 0, None, 0
    env.reset(seed=0)
    for _ in range(steps):
        if certified is None and episode % 3 == 0:
            index = int(rng.integers(len(tasks)))
            certificate = tasks[index].certificate
            if env.residual and certificate.kind == "constant" and (certificate.m, certificate.T_c_s) == (0.3, 4.0):
                certificate = Certificate("residual", 0.3, 4.0, (0.0,) * 12)  # the default planner = a zero residual
            if (certificate.kind == "residual") == env.residual:
                env.reset(seed=episode, options={"task_index": index})
                certified, played = certificate, played + 1
        if certified is not None and certified.kind == "constant":
            obs, reward, terminated, truncated, info = env.step_with_parameters(certified.m, certified.T_c_s)
        elif certified is not None:
            obs, reward, terminated, truncated, info = env.step(np.array(certified.residual, dtype=np.float32))
        else:
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample() * rng.uniform(0, 2))
        assert np.all(np.isfinite(obs)) and math.isfinite(reward) and env.observation_space.contains(obs)
        if terminated or truncated:
            assert 0.0 <= info["score"] <= 1.0 and (info["score"] > 0) == info["success"]
            assert certified is None or info["success"], (tier, info["failure"])
            successes += info["success"]
            episode, certified = episode + 1, None
            env.reset(seed=int(rng.integers(1 << 30)))
    return successes, played


@pytest.mark.parametrize("env_id", ["FFSR-v2", "FFSR-Residual-v2"])
@pytest.mark.parametrize("tier", ["easy", "medium", "hard"])
def test_pool_soak_short(env_id, tier):
    _soak_pool(env_id, tier, 450)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ["FFSR-v2", "FFSR-Residual-v2"])
@pytest.mark.parametrize("tier", ["easy", "medium", "hard"])
def test_pool_soak_long(env_id, tier):
    successes, played = _soak_pool(env_id, tier, 30_000)
    assert successes >= played
    assert (played > 0) == ((env_id, tier) not in {("FFSR-v2", "hard"), ("FFSR-Residual-v2", "medium")})


def test_provenance_finds_a_commit_or_says_why_not(tmp_path, monkeypatch):
    import subprocess

    from ffsr_gym import provenance as prov

    monkeypatch.setattr(prov, "_SOURCE", tmp_path / "installed")  # as if installed from a wheel
    monkeypatch.chdir(tmp_path)
    outside = prov.provenance()
    assert outside["git_commit"] is None and "not a git checkout" in outside["git_source"]
    subprocess.run(["git", "init", "-q"], check=True)
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "--allow-empty", "-m", "x"], check=True)
    inside = prov.provenance()
    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    assert inside["git_commit"] == head and "working directory" in inside["git_source"]


def test_cli_version_list_and_a_new_leaderboard_folder(tmp_path, capsys):
    from ffsr_gym.cli.main import main

    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out.strip() == f"ffsr-gym {ffsr_gym.__version__}"
    assert main(["list"]) == 0
    listed = capsys.readouterr().out
    assert "FFSR-v2" in listed and "hard: train pool 200 tasks, validation pool 50 tasks, test pool 100 tasks" in listed and "paper" in listed
    assert main(["leaderboard", "render", "--root", str(tmp_path / "missing")]) == 2
    assert "not a folder" in capsys.readouterr().err
    (tmp_path / "mine").mkdir()
    assert main(["leaderboard", "render", "--root", str(tmp_path / "mine")]) == 0
    assert main(["leaderboard", "render", "--root", str(tmp_path / "mine"), "--check"]) == 0


def test_cli_evaluate_writes_an_entry_and_names_bad_policies(tmp_path, capsys):
    from ffsr_gym.cli.main import main

    assert main(["evaluate", "--env-id", "FFSR-v2", "--policy", "0.3,4", "--task", "easy", "--name", "default",
                 "--leaderboard", str(tmp_path), "--no-progress"]) == 0
    entry = json.loads((tmp_path / "v2" / "easy" / "default.json").read_text())
    assert entry["metrics"]["success_rate"] == 1.0 and entry["extra"]["evaluation_pool"] == "easy/test"
    for bad in ("0.3", "nowhere.zip", "math:nothing", "lambda"):
        assert main(["evaluate", "--env-id", "FFSR-v2", "--policy", bad, "--no-progress"]) == 2
        assert "--policy" in capsys.readouterr().err or bad == "nowhere.zip"


def test_cli_render_writes_a_gif_of_an_episode(tmp_path, capsys):
    from PIL import Image

    from ffsr_gym.cli.main import main

    out = tmp_path / "episode.gif"
    assert main(["render", "--policy", "0.3,4", "--every", "50", "--out", str(out)]) == 0
    assert "'success': True" in capsys.readouterr().out
    with Image.open(out) as gif:
        assert gif.n_frames == 5 and gif.size == (480, 480)  # t = 0, 5, 10, 15, 20 s
        gif.seek(2)
        frame = np.asarray(gif.convert("RGB"))
    assert frame.std() > 10  # a drawn scene, not a blank frame
    assert main(["render", "--every", "0", "--out", str(out)]) == 2


@pytest.mark.parametrize("bad", ["local:0", "local:x", "nohost", "host:99999"])
def test_cli_best_known_scheduler_is_named_with_its_forms(tmp_path, capsys, bad):
    from ffsr_gym.cli.main import main

    assert main(["tasks", "best-known", "--work", str(tmp_path), f"--scheduler={bad}"]) == 2
    assert "allowed: local:N" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # refused before any work
    assert main(["tasks", "best-known", "--work", str(tmp_path), "--scheduler", "local:2", "--doubled", "1"]) == 2
    assert "--scheduler with --doubled" in capsys.readouterr().err
