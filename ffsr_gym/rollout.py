"""Initial state of a scenario; the closed loop ``simulate`` lives here too."""

from __future__ import annotations

import numpy as np

from ffsr_gym.collision import SphereObstacle
from ffsr_gym.robot import Robot
from ffsr_gym.scenario import Scenario
from ffsr_gym.types import Array


def initial_configuration(robot: Robot, scenario: Scenario) -> Array:
    """Pinocchio configuration ``q`` of the scenario's initial state."""
    initial = scenario.initial
    return robot.configuration(
        base_position_m=np.array(initial.base_position_m),
        base_quaternion_wxyz=np.array(initial.base_quaternion_wxyz),
        joints_rad=np.radians(np.array(initial.mission_joints_deg + initial.balance_joints_deg)),
    )


def obstacles_of(scenario: Scenario) -> list[SphereObstacle]:
    """The scenario's obstacle as a collision sphere (empty list in free space)."""
    if scenario.obstacle is None:
        return []
    return [SphereObstacle(np.array(scenario.obstacle.position_m), scenario.obstacle.radius_m)]
