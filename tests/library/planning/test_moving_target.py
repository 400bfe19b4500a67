"""The approach onto a moving grasp frame (docs/model.md §22): its twist against finite differences of its pose, a
still grasp frame giving the paper's path back, and the predefined-time planner following a spinning, drifting
grasp frame in free space, its error settled within T_c."""

from __future__ import annotations

import numpy as np
import pytest

from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.model.tumbling import point_motion, propagate
from ffsr_gym.planning.desired_path import DesiredPath
from ffsr_gym.planning.moving_target import (
    GraspFrameMotion,
    MovingTargetPath,
    left_jacobian_inverse_times,
    left_jacobian_times,
)
from ffsr_gym.sim.pinocchio_backend import PinocchioRollout

SCENARIO = load_scenario("free_space")
DT, STEPS = SCENARIO.simulation.dt_s, SCENARIO.n_steps
HANDLE_BODY_M = np.array([0.0, 0.0, -0.2])  # the grasp frame, 20 cm before the centre along the approach (z) axis


def _grasp(spin_deg_s: float, drift_m_s=(0.0, 0.0, 0.0)) -> GraspFrameMotion:
    """A body spinning about its z axis whose grasp frame starts at the scenario's target pose."""
    start = np.array(SCENARIO.target.quaternion_wxyz)
    centre = np.array(SCENARIO.target.position_m) - quat.to_rotation(start) @ HANDLE_BODY_M
    motion = propagate(position_m=centre, velocity_m_s=np.array(drift_m_s), quaternion=start,
                       omega_body_rad_s=np.deg2rad(spin_deg_s) * np.array([0.0, 0.0, 1.0]),
                       inertia_kg_m2=np.array([2.25, 2.25, 2.25]), dt_s=DT, steps=STEPS)
    position, velocity = point_motion(motion, HANDLE_BODY_M)
    return GraspFrameMotion(DT, position, motion.quaternion, velocity, motion.omega_world_rad_s())


def _path(rollout: PinocchioRollout, grasp: GraspFrameMotion, offset_m=(0.0, 0.0, 0.0), tilt_rad=0.0):
    paper = rollout.planner.path
    start = quat.multiply(quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), tilt_rad), paper.start_attitude)
    return MovingTargetPath.onto(paper.start_position + np.array(offset_m), start, grasp,
                                 motion_time=paper.motion_time, accel_time=paper.accel_time)


def _rate(path, t: float, h: float) -> np.ndarray:
    """Central difference of the desired pose over ±h: linear velocity and mean world angular velocity."""
    (p_after, s_after, _), (p_before, s_before, _) = path.at(t + h), path.at(t - h)
    turned = quat.rotation_vector(quat.multiply(s_after, quat.conjugate(s_before)))
    return np.concatenate(((p_after - p_before) / (2 * h), turned / (2 * h)))


def test_the_desired_twist_is_the_derivative_of_the_desired_pose():
    """Against central differences of the pose over ±dt and ±2 dt, extrapolated (Richardson) to fourth order."""
    path = _path(PinocchioRollout(SCENARIO), _grasp(3.0, (0.003, -0.002, 0.001)))
    for t in (1.0, 3.0, 6.0, 9.5, 15.0):
        _, _, twist = path.at(t)
        assert np.abs(_rate(path, t, DT) - twist).max() < 2e-7  # second order
        assert np.abs((4.0 * _rate(path, t, DT) - _rate(path, t, 2 * DT)) / 3.0 - twist).max() < 1e-9


def test_a_still_grasp_frame_gives_the_papers_path():
    rollout = PinocchioRollout(SCENARIO)
    paper = rollout.planner.path
    moving = _path(rollout, _grasp(0.0))
    still = DesiredPath.between(paper.start_position, paper.start_attitude, np.array(SCENARIO.target.position_m),
                                np.array(SCENARIO.target.quaternion_wxyz), motion_time=paper.motion_time,
                                accel_time=paper.accel_time)
    for t in (0.0, 2.0, 5.0, 9.0, 12.0):
        for ours, theirs in zip(moving.at(t), still.at(t)):
            assert np.abs(ours - theirs).max() < 1e-12 or np.abs(ours + theirs).max() < 1e-12  # q and -q


def test_the_planner_follows_a_spinning_drifting_grasp_frame_within_T_c():
    rollout = PinocchioRollout(SCENARIO)
    rollout.set_parameters(0.3, 4.0)  # v2's default planner
    path = _path(rollout, _grasp(3.0, (0.003, -0.002, 0.001)), offset_m=(0.03, -0.02, 0.02), tilt_rad=0.05)
    rollout.planner.path, rollout.planner.estimates = path, (path,)
    for _ in range(STEPS):
        rollout.step()
    rollout.finish()
    traj = rollout.trajectory()
    t, position, attitude = traj.t, np.asarray(traj.ee_position_error_m), np.asarray(traj.ee_attitude_error)
    assert position[0] == pytest.approx(np.linalg.norm([0.03, -0.02, 0.02]))  # it starts 4 cm off the path
    settled = t >= rollout.T_c - 1e-9
    assert position[settled].max() < 2e-5 and attitude[settled].max() < 2e-5  # within T_c, while the target moves
    captured = t >= path.motion_time + rollout.T_c - 1e-9
    assert position[captured].max() < 1e-7 and attitude[captured].max() < 1e-7  # on the grasp frame after the approach
    assert np.rad2deg(np.abs(np.asarray(traj.dq_joints))).max() < 200.0


def _tumbling_toml(tmp_path, **changes) -> str:
    """free_space with a tumbling target whose grasp frame starts at the scenario's target pose."""
    from ffsr_gym.model.resources import scenario_path

    start = np.array(SCENARIO.target.quaternion_wxyz)
    centre = np.array(SCENARIO.target.position_m) - quat.to_rotation(start) @ HANDLE_BODY_M
    values = {"size_m": [0.3, 0.3, 0.3], "mass_kg": 150.0, "inertia_kg_m2": [2.25, 2.25, 2.25],
              "position_m": centre.tolist(), "quaternion_wxyz": start.tolist(),
              "handle_position_m": HANDLE_BODY_M.tolist(), "velocity_m_s": [0.003, -0.002, 0.001],
              "omega_body_deg_s": [0.0, 0.0, -3.0], **changes}
    lines = [f"{key} = {value!r}" for key, value in values.items()]
    text = scenario_path("free_space").read_text().replace('name = "free_space"', 'name = "tumbling"')
    path = tmp_path / "tumbling.toml"
    path.write_text(text + "\n[tumbling_target]\n" + "\n".join(lines) + "\n")
    return str(path)


def test_a_tumbling_target_scenario_plans_onto_its_grasp_frame(tmp_path):
    import ffsr_gym
    from ffsr_gym.exceptions import InvalidInputError

    scenario = load_scenario(_tumbling_toml(tmp_path))
    traj = ffsr_gym.simulate(scenario, backend="pinocchio")
    captured = traj.t >= scenario.desired_path.motion_time_s + scenario.planner.T_c_s - 1e-9
    assert np.asarray(traj.ee_position_error_m)[captured].max() < 1e-7
    # a frame that turns half a turn before the approach ends has no unique rotation from its start: refused
    spinning = load_scenario(_tumbling_toml(tmp_path, omega_body_deg_s=[0.0, 0.0, 20.0]))
    with pytest.raises(InvalidInputError, match="turns by 180 deg before the end of the motion"):
        ffsr_gym.simulate(spinning, backend="kernel")


@pytest.mark.parametrize(("change", "named"), [
    ({"inertia_kg_m2": [10.0, 10.0, 30.0]}, "moment 3 exceeds the sum of the other two"),
    ({"handle_position_m": [0.0, 0.1, 0.1]}, "lies inside the body"),
    ({"velocity_m_s": [2.0, 0.0, 0.0]}, "tumbling_target.velocity_m_s"),
    ({"standoff_m": 0.1, "insertion_time_s": 12.0}, "insertion ends at t = 22 s, after the episode"),
    ({"quaternion_wxyz": [1.0, 1.0, 0.0, 0.0]}, "tumbling_target.quaternion_wxyz. = .* has norm 1.414214"),
    ({"handle_quaternion_wxyz": [0.0, 0.0, 0.0, 1.0]}, "is not the grasp frame of 'tumbling_target' at t = 0"),
])
def test_an_impossible_tumbling_target_is_named(tmp_path, change, named):
    from ffsr_gym.exceptions import ScenarioError

    with pytest.raises(ScenarioError, match=named):
        load_scenario(_tumbling_toml(tmp_path, **change))


def test_the_target_body_is_an_obstacle_whose_clearance_the_trajectory_logs(tmp_path):
    """The body's clearance as logged is at most the end-effector frame's distance to the box, computed here in
    the box's frame (the robot's nearest part is never farther than its end-effector's frame)."""
    from ffsr_gym.sim.setup import prepare

    scenario = load_scenario(_tumbling_toml(tmp_path, standoff_m=0.15, insertion_time_s=4.0))
    rollout = PinocchioRollout(scenario)
    for _ in range(STEPS):
        rollout.step()
    rollout.finish()
    traj, motion = rollout.trajectory(), prepare(scenario).target_motion
    clearance = np.asarray(traj.clearance_m)
    assert np.all(np.isfinite(clearance)) and clearance.min() > 0.0  # no contact (free_space sets no keep-out)
    half = np.array(scenario.tumbling_target.size_m) / 2.0
    # captured, the tool capsule ends on the handle, which stands off the box face: clearance = stand-off - radius
    import tomllib

    from ffsr_gym.model.resources import envs_dir

    radius = tomllib.loads((envs_dir() / "robots" / "ffsr_dual_arm" / "collision.toml").read_text())["capsule_radius_m"]
    assert clearance[-1] == pytest.approx(abs(HANDLE_BODY_M[2]) - half[2] - radius, abs=1e-6)
    for k in range(0, STEPS + 1, 250):
        ee = rollout.robot.transform_ee_to_world(traj.q[k], 0).translation
        local = quat.to_rotation(motion.quaternion[k]).T @ (ee - motion.position_m[k])
        outside = np.linalg.norm(np.maximum(np.abs(local) - half, 0.0))
        assert clearance[k] <= outside + 1e-9


def test_a_pre_grasp_standoff_brings_the_tool_in_along_the_grasp_axis(tmp_path):
    """The straight approach sweeps the tool past the body's edge (0.5 mm); a 15 cm standoff closed over a 4 s
    insertion after the approach keeps every part beyond v2's 1 cm keep-out, and ends on the grasp frame."""
    from ffsr_gym.planning.moving_target import pre_grasp

    scenario = load_scenario(_tumbling_toml(tmp_path))
    straight = PinocchioRollout(scenario)
    grasp = straight.planner.path.grasp
    frame = pre_grasp(grasp, standoff_m=0.15, insert_start_s=10.0, insert_time_s=4.0)
    central = (frame.position_m[2:] - frame.position_m[:-2]) / (2 * DT)
    # its velocity is its position's derivative: central differences are exact but at the trapezoid's corners, where
    # the acceleration jumps by standoff / ((t_i - t_a) t_a) and they miss by up to half a step of that jump
    jump = 0.15 / ((4.0 - 1.0) * 1.0)
    assert np.abs(central - frame.velocity_m_s[1:-1]).max() < 0.5 * DT * jump
    assert np.abs(frame.position_m[-1] - grasp.position_m[-1]).max() < 1e-12  # inserted by the end
    for rollout, path in ((straight, straight.planner.path), (PinocchioRollout(scenario), None)):
        if path is None:
            paper = rollout.planner.path
            path = MovingTargetPath.onto(paper.start_position, paper.start_attitude, frame,
                                         motion_time=paper.motion_time, accel_time=paper.accel_time)
            rollout.planner.path, rollout.planner.estimates = path, (path,)
        for _ in range(STEPS):
            rollout.step()
        rollout.finish()
    near, far = (np.asarray(r.trajectory().clearance_m) for r in (straight, rollout))
    assert near.min() < 0.001 and far.min() > 0.01  # v2's keep-out
    traj = rollout.trajectory()
    assert np.asarray(traj.ee_position_error_m)[-1] < 1e-7
    assert np.rad2deg(np.abs(np.asarray(traj.dq_joints))).max() < 200.0


@pytest.mark.parametrize("angle", [0.0, 1e-7, 0.05, 0.0999999, 0.1, 0.1000001, 0.7, 2.0, 3.0])
def test_the_left_jacobian_maps_rotation_vector_rates_to_angular_velocity(angle):
    """J_l(φ) φ̇ against the world angular velocity of exp(φ(t)) by central differences (fourth order), on both sides
    of the series switch at |φ| = 0.1; J_l⁻¹ against a linear solve of the matrix built column by column."""
    rng = np.random.default_rng(int(angle * 1e7) % 2**32)
    axis = rng.normal(size=3)
    phi, phi_dot = angle * axis / np.linalg.norm(axis), rng.normal(size=3)

    def turned(h):  # the world rotation from exp(φ(t - h)) to exp(φ(t + h)), as a rotation vector
        after, before = quat.from_rotation_vector(phi + h * phi_dot), quat.from_rotation_vector(phi - h * phi_dot)
        return quat.rotation_vector(quat.multiply(after, quat.conjugate(before))) / (2.0 * h)

    h = 1e-4
    omega = (4.0 * turned(h) - turned(2.0 * h)) / 3.0
    assert np.abs(np.array(left_jacobian_times(phi, phi_dot)) - omega).max() < 1e-9
    matrix = np.column_stack([left_jacobian_times(phi, e) for e in np.eye(3)])
    w = rng.normal(size=3)
    np.testing.assert_allclose(left_jacobian_inverse_times(phi, w), np.linalg.solve(matrix, w), rtol=0, atol=1e-13)
