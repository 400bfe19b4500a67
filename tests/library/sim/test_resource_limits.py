"""Settings allowed alone but too large together are refused by name before any work (no raw MemoryError, no
hour-long compiled step that Ctrl-C cannot stop)."""

from __future__ import annotations

import time

import gymnasium as gym
import pytest

import ffsr_gym
from ffsr_gym.model.resources import scenario_path
from ffsr_gym.sim.budget import MEMORY_VARIABLE, ResourceLimitError


def _custom(tmp_path, replacements: dict[str, str]) -> str:
    text = scenario_path("free_space").read_text()
    for old, new in replacements.items():
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "big.toml"
    path.write_text(text)
    return str(path)


def _refused_fast(call, match: str) -> None:
    start = time.perf_counter()
    with pytest.raises(ResourceLimitError, match=match):
        call()
    assert time.perf_counter() - start < 10.0


def test_buffers_beyond_the_memory_limit_are_refused_before_the_run(tmp_path):
    from ffsr_gym.environments.vector_env import FFSRVectorEnv

    _refused_fast(lambda: FFSRVectorEnv(100, "v2", task="easy", dt_s=1e-4, record_trajectories=True),
                  r"100 copies x 200,001 trajectory rows need about 10.9 GiB; allowed: at most 8 GiB")
    FFSRVectorEnv(100, "v2", task="easy", dt_s=1e-4)  # copies that keep no trajectory: 64 kB each
    with pytest.raises(ffsr_gym.exceptions.FFSRError, match=r"2,000,000 steps; allowed: at most 200,000 steps"):
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", env_kwargs={"dt_s": 1e-5})  # one episode is too long
    hour = _custom(tmp_path, {"duration_s = 20.0": "duration_s = 3600.0", "dt_s = 0.01": "dt_s = 0.00001"})
    with pytest.raises(ffsr_gym.exceptions.FFSRError, match="allowed: at most 200,000 steps in an episode"):
        gym.make("FFSR-v2", task=hour)
    from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv

    _refused_fast(lambda: BatchedVecEnv("FFSR-v2", 1_000_000, task="easy"),
                  "1,000,000 copies x 64 kB need about 61.0 GiB")


def test_the_limit_can_be_set_and_is_checked(monkeypatch):
    monkeypatch.setenv(MEMORY_VARIABLE, "0.0001")
    _refused_fast(lambda: gym.make("FFSR-v2", task="easy"), f"set {MEMORY_VARIABLE} to change it")
    monkeypatch.setenv(MEMORY_VARIABLE, "lots")
    with pytest.raises(ffsr_gym.exceptions.InvalidInputError, match=f"{MEMORY_VARIABLE} = 'lots'"):
        gym.make("FFSR-v2", task="easy")


def test_a_decision_of_too_many_physics_steps_is_refused(tmp_path):
    servo = _custom(tmp_path, {"decision_interval_s = 0.1": "decision_interval_s = 10.0",
                               "[simulation]": '[simulation]\nplant = "servo"'})
    with open(servo, "a", encoding="utf-8") as handle:
        handle.write("\n[servo]\nphysics_step_s = 0.000001\n")
    _refused_fast(lambda: gym.make("FFSR-v2", task=servo), r"10,000,000 physics steps in one decision")


def test_a_robot_folder_too_large_to_hash_or_a_zip_bomb_is_refused(tmp_path):
    import zipfile

    from test_own_robot import make_robot, scenario_with_robot

    from ffsr_gym.bench.policies import load_policy
    from ffsr_gym.exceptions import InvalidInputError, RobotFileError
    from ffsr_gym.model.scenario import load_scenario

    folder = make_robot(tmp_path / "robot")
    with open(folder / "huge.bin", "wb") as handle:  # sparse: 300 MB that take no disk
        handle.truncate(300 * 2**20)
    with pytest.raises(RobotFileError, match="allowed: at most 268,435,456"):
        load_scenario(scenario_with_robot(tmp_path, "./robot")).sha256()
    bomb = tmp_path / "model.zip"
    with zipfile.ZipFile(bomb, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open("data", "w", force_zip64=True) as member:
            for _ in range(2100):
                member.write(bytes(2**20))
    assert bomb.stat().st_size < 5 * 2**20
    with pytest.raises(InvalidInputError, match="unpacks to 2,202,009,600 bytes"):
        load_policy(str(bomb), "ppo", trust=True)
