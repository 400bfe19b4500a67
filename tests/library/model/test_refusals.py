"""Inputs refused by name before any work: a start that is already a failure, a randomisation that admits no draw,
an argument that contradicts its id, a reset option an env cannot honour, an adapter index past the last copy.
Each case passed silently, or hung, before (hostile pass 3's rerun)."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym  # noqa: F401  (registers the ids)
from ffsr_gym.exceptions import FFSRError, InvalidInputError, ScenarioError
from ffsr_gym.model.resources import envs_dir, scenario_path
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.model.schema import MAX_DRAW_ATTEMPTS
from ffsr_gym.sim.setup import check_start, prepare
from ffsr_gym.tasks.random_family import sample_scenario

SHIPPED = envs_dir() / "robots" / "ffsr_dual_arm"


def _robot_with_radius(folder: Path, radius_m: float) -> Path:
    """The shipped robot with every capsule of radius ``radius_m`` [m]."""
    folder.mkdir(parents=True)
    (folder / "ffsr_dual_arm.urdf").write_text((SHIPPED / "ffsr_dual_arm.urdf").read_text())
    text = (SHIPPED / "collision.toml").read_text().replace("capsule_radius_m = 0.02", f"capsule_radius_m = {radius_m}")
    (folder / "collision.toml").write_text(text)
    return folder


def _scenario_file(folder: Path, text: str) -> Path:
    path = folder / "mine.toml"
    path.write_text(text)
    return path


def test_a_robot_whose_parts_overlap_at_the_start_is_refused_naming_them(tmp_path):
    _robot_with_radius(tmp_path / "fat", 0.45)
    text = scenario_path("free_space").read_text().replace('robot = "ffsr_dual_arm"', 'robot = "./fat"')
    scenario = load_scenario(_scenario_file(tmp_path, text))
    with pytest.raises(ScenarioError, match=r"at the start pose '\w+' and '\w+' overlap \(clearance -\d+\.\d mm\)"):
        check_start(prepare(scenario))
    with pytest.raises(ScenarioError, match="overlap"):
        env = gym.make("FFSR-v0", scenario=str(tmp_path / "mine.toml"))
        env.reset(seed=0)
    _robot_with_radius(tmp_path / "slim", 0.03)  # thicker than shipped, still apart: accepted
    check_start(prepare(load_scenario(_scenario_file(tmp_path, text.replace("./fat", "./slim")))))


def test_an_obstacle_on_the_arm_at_t0_is_refused_naming_the_bodies():
    paper = load_scenario("paper")
    setup = prepare(paper)
    tip = setup.robot.transform_ee_to_world(setup.q0, 0).translation  # the mission end-effector at the start
    inside = paper.replace(obstacle=dataclasses.replace(paper.obstacle, position_m=tuple(float(x) for x in tip),
                                                        radius_m=0.05))
    with pytest.raises(ScenarioError, match=r"at t = 0 'obstacle' is -\d+\.\d mm from 'mission_\w+'.*keep-out"):
        check_start(prepare(inside))
    with pytest.raises(ScenarioError, match=r"at t = 0 'obstacle' is"):
        gym.make("FFSR-v0", scenario=inside)
    check_start(prepare(paper))  # the paper's own obstacle is far from the arms at the start
    with pytest.raises(ScenarioError, match=r"at t = 0 'obstacle' is -107\.0 mm from 'base'"):
        gym.make("FFSR-v0", scenario="paper_as_printed")  # the paper's printed point lies inside the base


def test_an_impossible_randomisation_is_refused_in_seconds_naming_the_constraint(tmp_path):
    family = load_scenario("random")
    impossible = family.replace(randomization=dataclasses.replace(family.randomization, min_travel_m=10.0,
                                                                  max_attempts=MAX_DRAW_ATTEMPTS))
    start = time.perf_counter()
    with pytest.raises(ScenarioError, match=r"rejected by min_travel_m / min_sigma_target \(the target draw\): 10000"):
        sample_scenario(impossible, np.random.default_rng(0))
    assert time.perf_counter() - start < 60.0  # about 1 s here: bounded by the attempts, not by a timer
    text = scenario_path("random").read_text()
    many = text.replace("max_attempts = 2000", "max_attempts = 1e6")
    assert many != text
    with pytest.raises(ScenarioError, match=r"randomization\.max_attempts.*10000"):
        load_scenario(_scenario_file(tmp_path, many))


@pytest.mark.parametrize(("env_id", "kwargs"), [("FFSR-v2", {"version": "v0"}), ("FFSR-v2", {"residual": True}),
                                                ("FFSR-Residual-v2", {"residual": False}),
                                                ("FFSR-v0", {"version": "capture-v0"})])
def test_an_argument_that_contradicts_its_id_is_refused(env_id, kwargs):
    key = next(iter(kwargs))
    with pytest.raises(InvalidInputError, match=rf"{key}=.*this id is {key}"):
        gym.make(env_id, **kwargs)
    with pytest.raises(InvalidInputError, match=rf"{key}=.*this id is {key}"):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    gym.make(env_id, **{key: gym.spec(env_id).kwargs[key]})  # the id's own value is accepted


@pytest.mark.parametrize("options", [{"task_index": -1}, {"task_index": 0}, {"seed": 3}])
def test_v0_refuses_reset_options_it_cannot_honour(options):
    for env_id in ("FFSR-v0", "FFSR-Residual-v0"):
        env = gym.make(env_id)
        with pytest.raises(InvalidInputError, match=r"reset option '\w+'; allowed here: \[\] \(FFSR-v0 plays a scenario"):
            env.reset(seed=0, options=options)


def test_a_pool_env_refuses_unknown_reset_options_by_name():
    env = gym.make("FFSR-v2", task="easy", split="test")
    with pytest.raises(InvalidInputError, match=r"reset option 'task'; allowed here: \['task_index'\]"):
        env.reset(seed=0, options={"task": 1})
    venv = gym.make_vec("FFSR-v2", num_envs=2, vectorization_mode="vector_entry_point", task="easy")
    with pytest.raises(InvalidInputError, match=r"reset option 'reset'; allowed here: \['reset_mask', 'task_index'\]"):
        venv.reset(seed=0, options={"reset": True})


def test_the_sb3_adapter_refuses_an_index_past_its_copies():
    pytest.importorskip("stable_baselines3")
    from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv

    env = BatchedVecEnv("FFSR-v2", 2, task="easy")
    assert env.get_attr("num_envs", indices=[0, 1]) == [2, 2] and env.env_is_wrapped(gym.Wrapper) == [False, False]
    for indices in ([2], 5, [-1], [0.5]):
        with pytest.raises(InvalidInputError, match=r"indices .*allowed: integers in \[0, 1\]"):
            env.get_attr("num_envs", indices=indices)
    with pytest.raises(FFSRError):
        env.env_is_wrapped(gym.Wrapper, indices=[7])
