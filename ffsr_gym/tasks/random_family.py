"""The randomised scenario family: target pose and obstacle drawn from a seeded generator."""

from __future__ import annotations

import dataclasses
from collections import Counter

import numpy as np
import pinocchio as pin

from ffsr_gym.exceptions import ScenarioError
from ffsr_gym.model import portable
from ffsr_gym.model.collision import SphereObstacle
from ffsr_gym.model.quaternion import from_rotation
from ffsr_gym.model.robot import Robot
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.model.scenario_sections import Randomization
from ffsr_gym.planning.desired_path import DesiredPath
from ffsr_gym.sim.setup import prepare
from ffsr_gym.types import Array


def sample_scenario(family: Scenario, rng: np.random.Generator) -> Scenario:
    """Draw one member of a randomised family.

    The target is reachable by construction (forward kinematics of perturbed mission-arm angles,
    kept only if the end-effector travels far enough and the target configuration is well
    conditioned); the obstacle is on the desired straight path, both arms start at least the
    danger radius away from it, and the target configuration clears it by ``min_final_distance_m``
    (so the avoidance releases and the error can converge) and its own parts by
    ``min_self_clearance_m``. See :class:`ffsr_gym.model.scenario.Randomization` for the ranges.

    Args:
        family: a scenario with a ``randomization`` section.
        rng: the generator (an env's ``self.np_random``); the only source of randomness.

    Raises:
        ScenarioError: no admissible draw within ``max_attempts``.
    """
    spec = family.randomization
    if spec is None:
        raise ScenarioError(f"scenario {family.name!r} has no 'randomization' section")
    setup = prepare(family)
    robot, collision, q_start = setup.robot, setup.assets.collision, setup.q0
    start = robot.transform_ee_to_world(q_start, 0)
    danger, radius = family.obstacle.danger_radius_m, family.obstacle.radius_m

    def clearance(q: np.ndarray, point: np.ndarray) -> float:
        return collision.obstacle_proximity(q, [SphereObstacle(point, radius)]).distance_m

    rejected = Counter()
    for _ in range(int(spec.max_attempts)):
        drawn = target_attempt(robot, q_start, spec, rng)
        if drawn is None:
            rejected["min_travel_m / min_sigma_target (the target draw)"] += 1
            continue
        q_target, target = drawn
        path = DesiredPath.between(start.translation, from_rotation(start.rotation), target.translation,
                                   from_rotation(target.rotation), motion_time=1.0, accel_time=0.25)
        lateral = rng.normal(size=3)
        obstacle = path.at(rng.uniform(*spec.path_fraction))[0] + spec.lateral_offset_m * rng.uniform() * lateral / portable.norm(lateral)
        if clearance(q_target, obstacle) < spec.min_final_distance_m:
            rejected["min_final_distance_m (the obstacle at the target configuration)"] += 1
            continue
        if clearance(q_start, obstacle) < danger:
            rejected["obstacle.danger_radius_m (the obstacle at the start configuration)"] += 1
            continue
        if collision.self_proximity(q_target).distance_m < spec.min_self_clearance_m:
            rejected["min_self_clearance_m (the target configuration's own parts)"] += 1
            continue
        return family.replace(
            target=dataclasses.replace(family.target, position_m=tuple(target.translation),
                                       quaternion_wxyz=tuple(from_rotation(target.rotation))),
            obstacle=dataclasses.replace(family.obstacle, position_m=tuple(obstacle)),
        )
    causes = ", ".join(f"{cause}: {count}" for cause, count in rejected.most_common())
    raise ScenarioError(f"scenario {family.name!r}: no admissible target/obstacle in {int(spec.max_attempts)} draws "
                        f"(rejected by {causes}); widen the 'randomization' ranges or relax that constraint")


def target_attempt(robot: Robot, q_start: Array, spec: Randomization, rng: np.random.Generator
                   ) -> tuple[Array, pin.SE3] | None:
    """One draw of a target: the mission arm's start angles plus offsets uniform in ``±mission_joint_offsets_deg``,
    kept (as ``(q_target, end-effector pose)``) when the end-effector travels at least ``min_travel_m`` and the
    target configuration has σ_min(J_m) >= ``min_sigma_target``; else None. Six uniform numbers from ``rng``."""
    q_target = q_start.copy()
    offsets = rng.uniform(-1.0, 1.0, 6) * np.radians(spec.mission_joint_offsets_deg)
    q_target[robot.arm_q_index[0]] += offsets
    start = robot.transform_ee_to_world(q_start, 0)
    robot.update_kinematics(q_target)
    target = robot.data.oMf[int(robot.ee_frame_ids[0])].copy()
    if portable.norm(target.translation - start.translation) < spec.min_travel_m:
        return None
    if np.linalg.svd(robot.arm_jacobian(0), compute_uv=False)[-1] < spec.min_sigma_target:
        return None
    return q_target, target
