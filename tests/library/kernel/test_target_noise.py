"""A noisy target (``[target_noise]``): the planner follows an estimate, the log and the score use the truth.

The estimate the planner used is read back from what it saw (its pose error) and the forward
kinematics of the logged state, and compared with bias + σ · standard normal draws made here.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import retired_v1_rules
from test_kernel import ARRAYS, assert_agree
from test_scenario import assert_section_rejected

from ffsr_gym.model.robot import load_robot
from ffsr_gym.model.scenario import TargetNoise, load_scenario, to_dict
from ffsr_gym.sim.simulate import make_rollout, simulate

NOISE = TargetNoise(position_bias_m=(3e-4, -2e-4, 1e-4), attitude_bias_rad=(2e-4, 0.0, -3e-4),
                    position_sigma_m=2e-4, attitude_sigma_rad=2e-4, interval_s=0.1, seed=7)


@pytest.fixture(scope="module")
def scenario():
    # v1's rules on `paper` (the scenario's own blend law): under v2's the arm never reaches this target.
    return retired_v1_rules().task(load_scenario("paper")).replace(target_noise=NOISE)


def test_kernel_matches_reference_with_a_noisy_target(scenario):
    assert_agree(scenario, "predefined_time")


@pytest.mark.parametrize("backend", ["kernel", "pinocchio"])
def test_planner_follows_bias_plus_white_noise_and_the_log_keeps_the_truth(scenario, backend):
    """After the motion, p̂_k = p_e − e₁ (what the planner saw) equals p_t + b + σ n_k; the logged
    error is |p_e − p_t| from Pinocchio's forward kinematics."""
    robot = load_robot()
    draws = np.random.default_rng(NOISE.seed).standard_normal((201, 6))
    rollout = make_rollout(scenario, backend=backend)
    target = np.array(scenario.target.position_m)
    for k in (185, 199):  # decisions at t = 18.5 s and 19.9 s (the desired path is at the estimate)
        rollout.advance(k * 10 - rollout.k)
        _, e1, _, _, _ = rollout.observation()
        ee = robot.transform_ee_to_world(rollout.q, 0).translation
        expected = target + np.array(NOISE.position_bias_m) + NOISE.position_sigma_m * draws[k, :3]
        np.testing.assert_allclose(ee - e1[:3], expected, atol=1e-12)
    rollout.advance(scenario.n_steps - rollout.k)
    rollout.finish()
    trajectory = rollout.trajectory()
    final_ee = robot.transform_ee_to_world(trajectory.q[-1], 0).translation
    assert trajectory.ee_position_error_m[-1] == pytest.approx(np.linalg.norm(final_ee - target), abs=1e-12)
    assert 1e-4 < trajectory.ee_position_error_m[-1] < 1e-3  # the bias is 0.37 mm: the truth is missed by it


def test_zero_noise_reproduces_the_plain_task_bit_for_bit(scenario):
    plain = scenario.replace(target_noise=None)
    zero = plain.replace(target_noise=TargetNoise(seed=3))
    assert to_dict(plain) != to_dict(zero) and "target_noise" not in to_dict(plain)
    a, b = simulate(plain, backend="kernel"), simulate(zero, backend="kernel")
    for name in ARRAYS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_batched_env_with_a_noisy_target_equals_single_envs(scenario):
    from test_vector_env import assert_batch_matches_singles

    assert_batch_matches_singles(scenario)


@pytest.mark.parametrize("section, message", [
    ("position_bias_m = [0.0, 0.02, 0.0]",
     "'target_noise.position_bias_m[1]' = 0.02 is out of range; allowed: [-0.01, 0.01]"),
    ("attitude_sigma_rad = -1e-3", "'target_noise.attitude_sigma_rad' = -0.001 is out of range; allowed: [0.0, 0.01]"),
    ("interval_s = 0.0", "'target_noise.interval_s' = 0.0 is out of range; allowed: [0.001, 100.0]"),
    ("seed = 1.5", "'target_noise.seed' is 1.5; allowed: an integer in [0, 9223372036854775807]"),
    ("seed = -1", "'target_noise.seed' is -1; allowed: an integer in [0,"),
    ("jitter = 1.0", "unknown key 'target_noise.jitter'"),
])
def test_malformed_target_noise_is_named(tmp_path, section, message):
    assert_section_rejected(tmp_path, "target_noise", section, message)
