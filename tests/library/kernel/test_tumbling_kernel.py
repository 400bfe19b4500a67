"""A tumbling target on the compiled kernel (docs/model.md §22): its closed loop equals the Pinocchio reference on
every trajectory array, with the pre-grasp approach and the body in the danger field; the clearance of a box
against a box equals coal's; and an episode's capture quantities come from its trajectory, the end-effector's
twist agreeing with differences of its pose."""

from __future__ import annotations

import coal
import numpy as np
import pytest
from test_kernel import assert_agree
from test_moving_target import _tumbling_toml

from ffsr_gym import _native
from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.benchmark import CaptureRule
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.scoring.capture import capture, episode_relative_motion
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import simulate


def _scenario(tmp_path, *, law: str, danger_m: float, standoff_m: float = 0.15):
    path = _tumbling_toml(tmp_path, standoff_m=standoff_m, insertion_time_s=4.0, danger_radius_m=danger_m)
    with open(path) as f:
        text = f.read()
    with open(path, "w") as f:
        f.write(text.replace('mu_law = "cdf"', f'mu_law = "{law}"'))
    return load_scenario(path)


@pytest.mark.parametrize(("law", "danger_m"), [("distance", 0.3), ("cdf", 0.1)])
def test_the_kernel_follows_a_tumbling_target_as_the_reference_does(tmp_path, law, danger_m):
    scenario = _scenario(tmp_path, law=law, danger_m=danger_m)
    assert_agree(scenario, "predefined_time")
    if law == "distance":  # the body's field acted: the blend left tracking for avoidance near it
        assert simulate(scenario, backend="kernel").mu[:, 0].min() < 0.5


def test_box_against_box_is_coals_distance():
    rng = np.random.default_rng(7)
    checked = 0
    while checked < 40:
        boxes = []
        for _ in range(2):
            q = rng.normal(size=4)
            rotation = quat.to_rotation(q / np.linalg.norm(q))
            boxes.append((rotation, rng.uniform(-1.0, 1.0, 3), rng.uniform(0.05, 0.5, 3)))
        (Ra, ca, ha), (Rb, cb, hb) = boxes
        result = coal.DistanceResult()
        expected = coal.distance(coal.Box(*(2 * ha)), coal.Transform3s(Ra, ca), coal.Box(*(2 * hb)),
                                 coal.Transform3s(Rb, cb), coal.DistanceRequest(), result)
        if expected <= 1e-3:
            continue  # apart only: overlapping boxes are a collision either way, their depths differ
        ours = _native.box_box(Ra, ca, ha, Rb, cb, hb)
        assert ours == pytest.approx(expected, abs=1e-9)
        checked += 1


def test_capture_quantities_come_from_the_trajectory(tmp_path):
    scenario = _scenario(tmp_path, law="distance", danger_m=0.1)
    setup, traj = prepare(scenario), simulate(scenario, backend="kernel")
    relative = episode_relative_motion(setup, traj)
    # the end-effector's twist J(q_k) v_k is the rate of its pose. The rates dq_k are held over step k and the base
    # moves by momentum conservation, so the step's forward difference of the position equals, to second order in
    # dt, the mean of the twists at its two ends with those rates (the later one from Pinocchio's centroidal map)
    robot, dt = setup.robot, scenario.simulation.dt_s
    momentum = np.array(scenario.initial.momentum)
    ee = np.array([robot.transform_ee_to_world(q, 0).translation for q in traj.q])
    twist, later = [], []
    for k in range(len(traj.t) - 1):
        robot.update_kinematics(traj.q[k])
        twist.append(robot.ee_twist(traj.v[k], 0)[:3])
        v_end = robot.velocity(traj.q[k + 1], traj.dq_joints[k], momentum)
        robot.update_kinematics(traj.q[k + 1])
        later.append(robot.ee_twist(v_end, 0)[:3])
    difference = (ee[1:] - ee[:-1]) / dt - 0.5 * (np.array(twist) + np.array(later))
    speed = np.abs(np.array(twist)).max()
    assert speed > 0.05 and np.abs(difference).max() < 1e-5 * speed
    # on the grasp frame after the insertion and T_c, moving with it
    t = traj.t
    after = t >= scenario.desired_path.motion_time_s + 4.0 + scenario.planner.T_c_s - 1e-9
    assert relative[after, 0].max() < 1e-6 and relative[after, 1].max() < 1e-6
    assert relative[after, 2].max() < 1e-5 and relative[after, 3].max() < 1e-5
    assert relative[~after, 0].max() > 0.1  # it was not there before: the stand-off, then the approach
    rule = CaptureRule(position_m=0.005, attitude_rad=0.0175, linear_velocity_m_s=0.005,
                             angular_velocity_rad_s=0.0087, hold_s=1.0)
    result = capture(t, relative, rule)
    assert result.captured and scenario.desired_path.motion_time_s + 1.0 < result.time_s <= t[-1]
    assert np.all(result.worst_ratio <= 1.0)
