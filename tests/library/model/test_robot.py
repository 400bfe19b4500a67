"""Physics invariants of the free-floating robot model, against independent computations."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_configuration

from ffsr_gym.exceptions import RobotFileError
from ffsr_gym.model.quaternion import from_rotation, skew
from ffsr_gym.model.robot import Robot

PAPER_SIGMA_E0 = np.array([0.0, 0.8191, 0.0, 0.5736])  # printed in the paper, scalar first


def test_initial_mission_ee_attitude_is_the_papers_sigma_e0(robot, q_paper):
    sigma = from_rotation(robot.transform_ee_to_world(q_paper, 0).rotation)
    sign = np.sign(sigma @ PAPER_SIGMA_E0)
    assert np.max(np.abs(sign * sigma - PAPER_SIGMA_E0)) < 1e-3


def test_initial_mission_ee_position_is_spec_p_e0(robot, q_paper):
    p_e0 = robot.transform_ee_to_world(q_paper, 0).translation
    assert np.allclose(p_e0, [1.0019, 0.4107, 0.0404], atol=1e-4)


def _cylinder_inertia(mass: float, length: float, axis: int) -> np.ndarray:
    r = 0.15  # docs/model.md §2
    if length == 0.0:
        return np.eye(3) * 0.4 * mass * r * r
    diag = np.full(3, mass * (3 * r * r + length**2) / 12)
    diag[axis] = mass * r * r / 2
    return np.diag(diag)


@pytest.mark.parametrize(
    ("arm", "masses", "extra"),
    [("mission", [10, 15, 10, 5, 5, 3], [0, 0, 0, 0, 0, 0]), ("balance", [20, 30, 20, 10, 10, 30], [0, 0, 0, 1, 1, 5])],
)
def test_urdf_link_inertias_follow_spec_table(robot, arm, masses, extra):
    lengths_axes = [(0.2, 2), (0.5, 0), (0.0, 2), (0.5, 2), (0.0, 2), (0.2, 2)]  # DH d or a, axis
    for k, ((length, axis), mass, added) in enumerate(zip(lengths_axes, masses, extra), start=1):
        inertia = robot.model.inertias[robot.model.getJointId(f"{arm}_joint{k}")]
        expected = _cylinder_inertia(mass, length, axis) + added * np.eye(3)
        assert inertia.mass == pytest.approx(mass)
        assert np.allclose(inertia.inertia, expected, atol=1e-9)
        com = np.zeros(3)
        com[axis] = length / 2
        assert np.allclose(inertia.lever, com)
    assert robot.total_mass == pytest.approx(368.0)


def _momentum_closed_form(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """docs/model.md §2 (SpaceDyn calc_hh) from per-link masses, CoMs and inertias, independent of Pinocchio's map."""
    model, data = robot.model, robot.model.createData()
    pin.forwardKinematics(model, data, q)
    r0, R0 = data.oMi[1].translation, data.oMi[1].rotation
    total = sum(i.mass for i in model.inertias)
    links = []
    for j in range(2, model.njoints):
        placement, inertia = data.oMi[j], model.inertias[j]
        links.append((j, inertia.mass, placement.act(inertia.lever), placement.rotation @ inertia.inertia @ placement.rotation.T))
    r_g = (model.inertias[1].mass * r0 + sum(m * r for _, m, r, _ in links)) / total
    w = total * (r_g - r0)
    H_w = R0 @ model.inertias[1].inertia @ R0.T
    for _, m, r, I in links:
        H_w = H_w + I + m * skew(r - r0).T @ skew(r - r0)
    H_b = np.block([[total * np.eye(3), -skew(w)], [skew(w), H_w]])
    H_bm = []
    for arm_joints in robot.joint_ids:
        axes = [data.oMi[int(j)].rotation[:, 2] for j in arm_joints]
        origins = [data.oMi[int(j)].translation for j in arm_joints]
        top, bottom = np.zeros((3, 6)), np.zeros((3, 6))
        for j, m, r, I in links:
            if j not in arm_joints:
                continue
            depth = list(arm_joints).index(j)
            J_T = np.zeros((3, 6))
            J_R = np.zeros((3, 6))
            for k in range(depth + 1):
                J_T[:, k] = np.cross(axes[k], r - origins[k])
                J_R[:, k] = axes[k]
            top += m * J_T
            bottom += I @ J_R + m * skew(r - r0) @ J_T
        H_bm.append(np.vstack((top, bottom)))
    return H_b, np.array(H_bm)


def test_momentum_matrices_match_spacedyn_closed_form(robot):
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = random_configuration(robot, rng)
        mats = robot.momentum_matrices(q)
        H_b, H_bm = _momentum_closed_form(robot, q)
        assert np.max(np.abs(mats.H_b - H_b)) < 1e-10
        assert np.max(np.abs(mats.H_bm - H_bm)) < 1e-10


def test_momentum_and_com_conserved_along_random_rollout(robot, q_paper):
    rng = np.random.default_rng(1)
    dt, n = 0.01, 2000
    amplitude, freq, phase = rng.uniform(0.2, 1.0, 12), rng.uniform(0.1, 1.0, 12), rng.uniform(0, 2 * np.pi, 12)
    q = q_paper.copy()
    com0 = robot.system_com(q)
    worst = 0.0
    for k in range(n):
        dq = amplitude * np.sin(2 * np.pi * freq * k * dt + phase)
        v = robot.velocity(q, dq)
        joint_only = np.zeros_like(v)
        joint_only[6:] = v[6:]
        scale = np.linalg.norm(robot.centroidal_momentum(q, joint_only))
        worst = max(worst, np.linalg.norm(robot.centroidal_momentum(q, v)) / scale)
        q, _ = robot.step(q, dq, dt)
    assert worst < 1e-10
    drift = np.linalg.norm(robot.system_com(q) - com0)
    assert drift < 1e-6, f"CoM drifted {drift:.3e} m over 20 s at dt = 0.01 s"


def test_nonzero_momentum_is_conserved_too(robot, q_paper):
    h = np.array([0.3, -0.1, 0.2, 0.5, 0.1, -0.4])
    dq = np.linspace(-0.5, 0.5, 12)
    v = robot.velocity(q_paper, dq, h)
    assert np.allclose(robot.centroidal_momentum(q_paper, v), h, atol=1e-12)


def _ee_pose(robot: Robot, q: np.ndarray, arm: int) -> pin.SE3:
    return robot.transform_ee_to_world(q, arm)


@pytest.mark.parametrize("arm", [0, 1])
def test_generalized_jacobian_matches_central_finite_difference(robot, arm):
    rng = np.random.default_rng(2 + arm)
    h = 1e-5
    for _ in range(3):
        q = random_configuration(robot, rng)
        J_g = robot.generalized_jacobian(q, arm)
        J_fd = np.zeros((6, 12))
        for k in range(12):
            dq = np.zeros(12)
            dq[k] = 1.0
            v = robot.velocity(q, dq)  # base responds through momentum conservation
            plus = _ee_pose(robot, pin.integrate(robot.model, q, v * h), arm)
            minus = _ee_pose(robot, pin.integrate(robot.model, q, -v * h), arm)
            J_fd[:3, k] = (plus.translation - minus.translation) / (2 * h)
            J_fd[3:, k] = pin.log3(plus.rotation @ minus.rotation.T) / (2 * h)
        assert np.max(np.abs(J_g - J_fd)) <= 1e-6


def test_base_quaternion_stays_unit_after_1e5_steps(robot, q_paper):
    rng = np.random.default_rng(4)
    dq = rng.uniform(-1, 1, 12)
    q = q_paper.copy()
    for _ in range(100_000):
        q, _ = robot.step(q, dq, 0.01)
    assert abs(np.linalg.norm(q[3:7]) - 1.0) < 1e-12
    assert np.all(np.isfinite(q))


def test_missing_robot_file_names_the_path(tmp_path):
    with pytest.raises(RobotFileError, match="does not exist"):
        Robot(tmp_path / "nope.urdf")


def test_urdf_without_arm_joints_is_rejected(tmp_path):
    path = tmp_path / "one_link.urdf"
    path.write_text('<robot name="x"><link name="base"><inertial><mass value="1"/>'
                    '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>')
    with pytest.raises(RobotFileError, match="mission_joint1"):
        Robot(path)


def test_spec_singular_values_at_the_paper_start(robot, q_paper):
    """docs/model.md §2 report these conditioning numbers for this geometry."""
    robot.update_kinematics(q_paper)
    sv_Jm = np.linalg.svd(robot.arm_jacobian(0), compute_uv=False)
    sv_Hbm2 = np.linalg.svd(robot.momentum_matrices(q_paper).H_bm[1], compute_uv=False)
    assert sv_Jm[-1] == pytest.approx(0.014, abs=5e-4)
    assert sv_Hbm2 == pytest.approx([85.6, 24.9, 15.7, 5.7, 3.2, 2.2], abs=0.06)
    assert math.isclose(robot.total_mass, 368.0)
