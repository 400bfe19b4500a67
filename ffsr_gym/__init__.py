"""ffsr-gym: a dual-arm free-floating space robot, its predefined-time planner and a benchmark."""

from __future__ import annotations

from importlib import metadata as _metadata

from ffsr_gym.bench.evaluation import EvalReport, evaluate, objective_for_params
from ffsr_gym.bench.planner_scores import residual_training_loss, training_loss
from ffsr_gym.environments.info import failure_name
from ffsr_gym.environments.registration import register_all, register_spec
from ffsr_gym.exceptions import FFSRError, InvalidInputError, RobotFileError, ScenarioError
from ffsr_gym.model.robot import Robot, load_robot
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.sim.simulate import simulate
from ffsr_gym.sim.trajectory import Trajectory

__version__ = _metadata.version("ffsr-gym")  # one source: pyproject.toml, through the installed metadata

register_all()

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
    "failure_name",
    "load_robot",
    "load_scenario",
    "register_spec",
    "objective_for_params",
    "residual_training_loss",
    "simulate",
    "training_loss",
]
