"""Closed-loop properties of the four planning methods (docs/model.md §8, paper Section 5)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.planning.planner import METHODS
from ffsr_gym.sim.setup import initial_configuration
from ffsr_gym.sim.simulate import simulate

NON_SINGULAR_JOINTS_DEG = (0.0, 30.0, -60.0, 0.0, -40.0, 0.0)


@pytest.fixture(scope="module")
def hold_still(robot):
    """free_space with a non-singular mission arm whose target is its own initial pose."""
    base = load_scenario("free_space")
    scenario = base.replace(initial=dataclasses.replace(base.initial, mission_joints_deg=NON_SINGULAR_JOINTS_DEG))
    q = initial_configuration(robot, scenario)
    ee = robot.transform_ee_to_world(q, 0)
    return scenario.replace(
        target=dataclasses.replace(scenario.target, position_m=tuple(ee.translation),
                                   quaternion_wxyz=tuple(quat.from_rotation(ee.rotation))),
        simulation=dataclasses.replace(scenario.simulation, duration_s=3.5),
    ), q


def _perturbed(robot, q, rng, scale):
    q0 = q.copy()
    q0[robot.joint_q_index] += np.radians(rng.uniform(-5, 5, 12)) * scale
    q0[:3] += rng.uniform(-3e-3, 3e-3, 3) * scale
    tilt = quat.from_axis_angle(np.array([0.0, 0.6, 0.8]), 0.02 * scale)
    q0[3:7] = quat.xyzw_from_wxyz(quat.multiply(tilt, quat.wxyz_from_xyzw(q0[3:7])))
    return q0


@pytest.mark.parametrize(("T_c", "scale"), [(3.0, 1.0), (1.0, 1.0), (2.0, 0.01)])
def test_predefined_time_converges_before_T_c_in_free_space(robot, hold_still, T_c, scale):
    scenario, q = hold_still
    q0 = _perturbed(robot, q, np.random.default_rng(int(T_c * 10)), scale)
    traj = simulate(scenario, m=0.1, T_c=T_c, q0=q0)
    assert traj.ee_position_error_m[0] > 1e-4 * scale
    assert traj.base_position_error_m[0] > 1e-5 * scale
    assert np.min(traj.sigma_min[:, 0]) > scenario.planner.epsilon_mission  # away from singularities
    k = int(round(T_c / traj.dt)) + 1  # T_c plus one step
    for name in ("ee_position_error_m", "ee_attitude_error", "base_position_error_m", "base_attitude_error"):
        assert getattr(traj, name)[k] < 1e-9, name


@pytest.fixture(scope="module")
def paper_runs():
    return {method: simulate("paper", method=method, m=0.1, T_c=3.0) for method in METHODS}


def test_predefined_time_reaches_the_target_on_paper(paper_runs):
    metrics = paper_runs["predefined_time"].metrics()
    assert metrics["final_ee_position_error_m"] <= 1e-9
    assert metrics["avoidance_release_time_s"] is not None
    assert 0 < metrics["convergence_after_release_s"] <= 3.0
    assert metrics["max_base_position_error_m"] < 2e-5  # micron level
    assert metrics["max_base_attitude_error"] < 2e-5


def test_proportional_leaves_a_clearly_larger_residual(paper_runs):
    pt = paper_runs["predefined_time"].metrics()["final_ee_position_error_m"]
    prop = paper_runs["proportional"].metrics()["final_ee_position_error_m"]
    assert prop > 1e-5 and prop > 1e6 * max(pt, 1e-16)


def test_avoidance_keeps_clearance_while_no_avoidance_collides(paper_runs):
    for method in ("no_feedback", "proportional", "predefined_time"):
        metrics = paper_runs[method].metrics()
        assert metrics["min_clearance_m"] > 0, method
        assert not metrics["collided"], method
    assert paper_runs["no_avoidance"].metrics()["min_clearance_m"] < 0
    assert paper_runs["no_avoidance"].metrics()["collided"]


def test_no_feedback_keeps_the_avoidance_error(paper_runs):
    assert paper_runs["no_feedback"].metrics()["final_ee_position_error_m"] > 0.01


def test_momentum_stays_zero_along_the_paper_run(robot, paper_runs):
    traj = paper_runs["predefined_time"]
    for k in range(0, len(traj.t), 97):
        assert np.linalg.norm(robot.centroidal_momentum(traj.q[k], traj.v[k])) < 1e-10


def test_bad_method_and_parameters_are_rejected():
    with pytest.raises(InvalidInputError, match="allowed"):
        simulate("free_space", method="teleport")
    with pytest.raises(InvalidInputError, match=r"m = 0.0 is out of range"):
        simulate("free_space", m=0.0)
    with pytest.raises(InvalidInputError, match="q must be 19 finite numbers"):
        simulate("free_space", q0=np.full(19, np.nan))
