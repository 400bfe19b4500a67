"""The servo plant: drives from data, momentum and energy of its dynamics, its kinematic limit, its scenarios."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from ffsr_gym import _native
from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.kernel import layout as sv
from ffsr_gym.kernel.robot import native_plant
from ffsr_gym.model.drives import drive_array, drives_path, load_drives
from ffsr_gym.model.resources import robot_dir
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import simulate


def servo_scenario(base: Scenario, **settings) -> Scenario:
    """``base`` on the servo plant, with ``[servo]`` settings."""
    data = dict(simulation=dataclasses.replace(base.simulation, plant="servo"))
    if settings:
        from ffsr_gym.model.scenario import ServoSettings

        data["servo"] = ServoSettings(**settings)
    return base.replace(**data)


@pytest.fixture(scope="module")
def drives():
    return load_drives(drives_path(robot_dir("ffsr_dual_arm")))


def test_drive_file_follows_its_scaling_rule(robot, drives):
    """Gains, limits and friction are the reference's scaled by arm mass / reference arm mass (4 significant figures)."""
    ref = drives.reference
    for arm, name in enumerate(("mission", "balance")):
        mass = sum(robot.model.inertias[int(j)].mass for j in robot.joint_ids[arm])
        factor = mass / ref.arm_mass_kg
        own = getattr(drives, name)
        for j in range(6):
            group = 0 if j < 3 else 1
            assert own.servo_gain_Nm_s_per_rad[j] == pytest.approx(ref.servo_gain_Nm_s_per_rad[group] * factor, rel=5e-4)
            assert own.torque_limit_Nm[j] == pytest.approx(ref.torque_limit_Nm[group] * factor, rel=5e-4)
            assert own.viscous_friction_Nm_s_per_rad[j] == pytest.approx(0.01 * own.servo_gain_Nm_s_per_rad[j], rel=5e-4)
    array = drive_array(drives, gain_scale=2.0, torque_limited=False)
    assert array[0, sv.DRIVE_GAIN] == 2.0 * drives.mission.servo_gain_Nm_s_per_rad[0]
    assert np.all(np.isinf(array[:, sv.DRIVE_LIMIT]))
    assert array[7, sv.DRIVE_ARMATURE] == pytest.approx(101.0**2 * drives.balance.rotor_inertia_kg_m2[1])


@pytest.fixture(scope="module")
def servo_paper():
    return simulate(servo_scenario(load_scenario("paper")))


def test_momentum_is_conserved_over_20_s_with_saturating_torques(robot, servo_paper, drives):
    """Pinocchio's centroidal momentum of every logged state stays at the scenario's (zero) within 1e-9."""
    traj = servo_paper
    assert traj.t[-1] == pytest.approx(20.0)
    saturation = traj.info["torque_saturation"]
    assert saturation["saturated_fraction"] > 0.0  # the drives do hit their limits on this run
    model, data = robot.model, robot.model.createData()
    worst = max(np.abs(pin.computeCentroidalMomentum(model, data, q, v).vector).max() for q, v in zip(traj.q, traj.v))
    assert worst < 1e-9
    limits = drive_array(drives)[:, sv.DRIVE_LIMIT]
    assert np.all(np.abs(traj.joint_torque_Nm) <= limits * (1.0 + 1e-12))
    assert np.any(np.isclose(np.abs(traj.joint_torque_Nm).max(axis=0), limits, rtol=1e-12, atol=0.0))


def test_logged_rates_are_the_ones_the_joints_made(robot, servo_paper):
    traj = servo_paper
    angles = traj.q[:, robot.joint_q_index]
    made = np.diff(angles, axis=0) / traj.dt
    assert np.allclose(traj.dq_joints[:-1], made, rtol=0.0, atol=1e-9)


def _open_loop(setup, drive, h, seconds, every=0):
    kernel = setup.assets.kernel
    n = int(round(seconds / h))
    t = np.arange(n) * h
    cmds = np.sin(3.0 * t[:, None] + np.arange(12)[None, :])  # [rad/s]
    x = np.zeros(sv.N_STATE)
    x[:7], x[7:19] = setup.q0[:7], setup.q0[kernel.q_index]
    plant = native_plant(kernel, (kernel.mass, kernel.lever, kernel.inertia, drive))
    return _native.drive_open_loop(plant, x, cmds, h, np.zeros(6), every)


def test_the_dynamics_alone_conserve_momentum_to_first_order_in_the_step(robot, drives):
    """Without the per-planner-step reset, Euler lets the momentum drift by O(h): a tenth of the step, a tenth of
    the drift (the dynamics conserve it; the kernel's base acceleration is right), and the reset removes it."""
    setup = prepare(load_scenario("paper"))
    kernel, model, data, drive = setup.assets.kernel, robot.model, robot.model.createData(), drive_array(drives)

    def momentum(x):
        q, v = np.empty(19), np.empty(18)
        q[:7], q[kernel.q_index] = x[:7], x[7:19]
        v[:6], v[kernel.v_index] = x[sv.X_V:sv.X_V + 6], x[sv.X_V + 6:sv.X_V + 18]
        return pin.computeCentroidalMomentum(model, data, q, v).vector

    drifts = []
    for h in (1e-3, 1e-4):
        states, _ = _open_loop(setup, drive, h, 1.0)
        drifts.append(np.abs(momentum(states[-1])).max())
    assert drifts[0] > 1e-6  # Euler does drift, so the reset has work to do
    assert 7.0 < drifts[0] / drifts[1] < 13.0
    states, _ = _open_loop(setup, drive, 1e-3, 1.0, every=10)
    assert max(np.abs(momentum(x)).max() for x in states[::10]) < 1e-12


def test_kinetic_energy_change_is_the_work_of_the_joint_torques(robot, drives):
    """ΔKE (Pinocchio's mass matrix) = ∫ (τ_drive − b q̇) · q̇ dt, to first order in the physics step."""
    setup = prepare(load_scenario("paper"))
    drive = drive_array(drives)
    model = robot.model.copy()
    model.armature[robot.joint_v_index] = drive[:, sv.DRIVE_ARMATURE]
    data = model.createData()
    kernel = setup.assets.kernel

    def energy(x):
        q, v = np.empty(19), np.empty(18)
        q[:7], q[kernel.q_index] = x[:7], x[7:19]
        v[:6], v[kernel.v_index] = x[sv.X_V:sv.X_V + 6], x[sv.X_V + 6:sv.X_V + 18]
        M = pin.crba(model, data, q)
        return 0.5 * v @ (np.triu(M) + np.triu(M, 1).T) @ v

    errors = []
    for h in (1e-3, 1e-4):
        states, torques = _open_loop(setup, drive, h, 1.0)
        rates = states[:, sv.X_V + 6:sv.X_V + 18]
        mean = 0.5 * (rates[1:] + rates[:-1])
        work = np.sum((torques - drive[:, sv.DRIVE_FRICTION] * mean) * mean) * h
        change = energy(states[-1]) - energy(states[0])
        errors.append(abs(work - change) / abs(change))
    assert errors[1] < 1e-4
    assert 7.0 < errors[0] / errors[1] < 13.0  # first order in h


def test_servo_plant_converges_to_the_kinematic_plant_as_the_gain_grows():
    """Stiff servos without torque limits follow the planned rates: the joint-angle gap shrinks ~1/gain."""
    paper = load_scenario("paper")
    kinematic = simulate(paper)
    gaps = []
    for scale in (1.0, 100.0, 10000.0):
        traj = simulate(servo_scenario(paper, gain_scale=scale, torque_limited=False))
        gaps.append(np.abs(traj.q[:, 7:] - kinematic.q[:, 7:]).max())
    assert gaps[0] > gaps[1] > gaps[2]
    assert gaps[2] < 0.05 * gaps[0]
    assert gaps[2] < 1e-3  # [rad]


def test_servo_scenarios_are_validated_and_hashed():
    paper = load_scenario("paper")
    explicit = paper.replace(simulation=dataclasses.replace(paper.simulation, plant="kinematic"))
    assert explicit.sha256() == paper.sha256()  # the new key at its default leaves the hash alone
    servo = servo_scenario(paper)
    assert servo.sha256() != paper.sha256()
    assert servo.physics_substeps == 10 and paper.physics_substeps == 0
    from ffsr_gym.model.scenario import ServoSettings

    with pytest.raises(ScenarioError, match="section 'servo' needs key 'simulation.plant'"):
        paper.replace(servo=ServoSettings())
    assert servo_scenario(paper, physics_step_s=0.003).physics_substeps == 4  # 2.5 ms: the longest step <= 3 ms
    assert servo.at_step(0.0025).physics_substeps == 3  # the ensemble's dt / 4: 0.83 ms steps
    assert servo_scenario(paper, physics_step_s=0.1).physics_substeps == 1
    with pytest.raises(ScenarioError, match="simulation.plant"):
        paper.replace(simulation=dataclasses.replace(paper.simulation, plant="hydraulic"))
    with pytest.raises(ScenarioError, match=r"servo.physics_step_s' = 0.0"):
        servo_scenario(paper, physics_step_s=0.0)
    with pytest.raises(InvalidInputError, match="kernel backend"):
        simulate(servo, backend="pinocchio")


def test_mujoco_integrates_the_same_robot_and_drives_to_the_same_joint_rates(drives):
    """An independent simulator: MuJoCo (implicitfast, same bodies, drives, step and commands, built by the speed
    benchmark) ends 1 s of saturating open-loop commands within 1e-4 rad/s of the kernel's joint rates."""
    mujoco = pytest.importorskip("mujoco")
    from conftest import script_module

    bench = script_module("bench")
    setup = prepare(load_scenario("paper"))
    kernel, drive, h = setup.assets.kernel, drive_array(drives), 0.001
    states, torques = _open_loop(setup, drive, h, 1.0)
    assert np.any(np.isclose(np.abs(torques), drive[:, sv.DRIVE_LIMIT]))  # some drives saturate
    model = mujoco.MjModel.from_xml_string(bench.servo_mjcf(kernel, drive, h))
    data = mujoco.MjData(model)
    data.qpos[:3], data.qpos[3], data.qpos[4:7] = setup.q0[:3], setup.q0[6], setup.q0[3:6]
    data.qpos[7:] = setup.q0[kernel.q_index]
    t = np.arange(len(torques)) * h
    for k, row in enumerate(np.sin(3.0 * t[:, None] + np.arange(12)[None, :])):
        data.ctrl[:] = row
        mujoco.mj_step(model, data)
    assert np.abs(data.qvel[6:] - states[-1, sv.X_V + 6:sv.X_V + 18]).max() < 1e-4


def test_an_environment_steps_the_servo_plant_like_simulate():
    """FFSR-Residual-v0 on a servo scenario: Gymnasium's checker passes, and zero actions give simulate's run."""
    import warnings

    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    import ffsr_gym  # noqa: F401  (registers the environments)

    paper = load_scenario("paper")
    short = servo_scenario(paper.replace(simulation=dataclasses.replace(paper.simulation, duration_s=3.0)))
    env = gym.make("FFSR-Residual-v0", scenario=short)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env.unwrapped, skip_render_check=True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(12, dtype=np.float32))
        done = terminated or truncated
    played = env.unwrapped.rollout.trajectory()
    expected = simulate(short)
    np.testing.assert_array_equal(played.q, expected.q)
    np.testing.assert_array_equal(played.dq_joints, expected.dq_joints)
    assert played.info["torque_saturation"] == expected.info["torque_saturation"]


def test_a_malformed_drive_file_names_its_key(tmp_path):
    from ffsr_gym.exceptions import RobotFileError

    shipped = drives_path(robot_dir("ffsr_dual_arm")).read_text()
    bad = tmp_path / "servo.toml"
    bad.write_text(shipped.replace("torque_limit_Nm = [423.7", "torque_limit_Nm = [-423.7"))
    with pytest.raises(RobotFileError, match=r"mission.torque_limit_Nm"):
        load_drives(bad)
    bad.write_text(shipped.replace("gear_ratio = [101.0, 101.0, 101.0, 101.0, 101.0, 101.0]\nrotor", "rotor", 1))
    with pytest.raises(RobotFileError, match=r"missing key 'mission.gear_ratio'"):
        load_drives(bad)
    with pytest.raises(RobotFileError, match="does not exist"):
        load_drives(tmp_path / "none.toml")
