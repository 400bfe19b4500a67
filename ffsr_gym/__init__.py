"""ffsr-gym: a dual-arm free-floating space robot, its predefined-time planner and a benchmark."""

from __future__ import annotations

import gymnasium

from ffsr_gym.bench.evaluation import EvalReport, evaluate, objective_for_params
from ffsr_gym.exceptions import FFSRError, InvalidInputError, RobotFileError, ScenarioError
from ffsr_gym.model.robot import Robot, load_robot
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.sim.simulate import simulate
from ffsr_gym.sim.trajectory import Trajectory

__version__ = "0.1.0"

gymnasium.register(id="FFSR-v0", entry_point="ffsr_gym.environments.env:FFSREnv",
                   vector_entry_point="ffsr_gym.environments.vector_env:FFSRVectorEnv")
gymnasium.register(id="FFSR-v1", entry_point="ffsr_gym.environments.env_v1:FFSRV1Env", max_episode_steps=200,
                   vector_entry_point="ffsr_gym.environments.vector_env_v1:FFSRV1VectorEnv")
gymnasium.register(id="FFSR-Residual-v1", entry_point="ffsr_gym.environments.env_v1:FFSRResidualV1Env",
                   max_episode_steps=200, vector_entry_point="ffsr_gym.environments.vector_env_v1:FFSRResidualV1VectorEnv")
gymnasium.register(id="FFSR-Residual-v0", entry_point="ffsr_gym.environments.env:FFSRResidualEnv",
                   vector_entry_point="ffsr_gym.environments.vector_env:FFSRResidualVectorEnv")

__all__ = [
    "EvalReport",
    "FFSRError",
    "InvalidInputError",
    "Robot",
    "RobotFileError",
    "Scenario",
    "ScenarioError",
    "Trajectory",
    "evaluate",
    "load_robot",
    "load_scenario",
    "objective_for_params",
    "simulate",
]
