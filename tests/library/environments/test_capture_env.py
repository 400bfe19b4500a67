"""The capture rule through the environments (a spec registered from a file: the ids ship with the capture pools):
an episode played decision by decision scores as the certificate path scores it, its info says when the capture
happened, and a missed capture ends with its own failure code."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from ffsr_gym.environments.info import failure_name
from ffsr_gym.environments.registration import register_spec, unregister_spec
from ffsr_gym.exceptions import ScenarioError
from ffsr_gym.tasks.capture_family import draw_capture_task
from ffsr_gym.tasks.certificate import planner_episode
from ffsr_gym.versions.registry import load_benchmark

RULES = load_benchmark("capture-v0")
SPEC = """
schema_version = 1
version = "capture-test"
description = "capture of a tumbling target (test registration)"
status = "frozen"

[ids]
parameters = "FFSR-CaptureTest-v0"
residual = "FFSR-CaptureTest-Residual-v0"

[score]
rule = "capture_smoothness"
rules_file = "capture-v0.toml"

[actions]
boxes = "rules"
residual_fades = true

[reward]
kind = "score_change"
options = ["terminate_on_violation", "dense_shaping"]

[tasks]
kind = "tiers"
keyword = "task"
default = "slow"
tiers = ["slow", "fast"]
splits = ["train", "validation", "test"]
step_option = true

[evaluation]
protocol = "pool"
default_task = "slow"

[observation]
target_twist = true

[leaderboard]
folder = "{version}/{task}"
ranking = "ci_separation"
title = "Capture test"
iqm = "score_iqm"
ci = "score_iqm_ci95"
rate = "success_rate"
rate_column = "success"
"""


@pytest.fixture(scope="module")
def capture_ids(tmp_path_factory):
    path = tmp_path_factory.mktemp("spec") / "spec_capture-test.toml"
    path.write_text(SPEC)
    spec = register_spec(path)
    yield spec
    unregister_spec(spec.version)


def _play(env_id: str, task, m: float, T_c: float) -> dict:
    env = gym.make(env_id, task=task)
    env.reset(seed=0)
    done, info = False, {}
    while not done:
        _, _, terminated, truncated, info = env.unwrapped.step_with_parameters(m, T_c)
        done = terminated or truncated
    env.close()
    return info


def test_an_episode_scores_as_its_certificate_and_says_when_it_captured(capture_ids):
    task = draw_capture_task("slow", 5, RULES)
    info = _play(capture_ids.ids.parameters, task, 0.3, 4.0)
    reference = planner_episode(task, RULES, method="predefined_time", m=0.3, T_c=4.0)
    assert info["episode_end"] and info["success"] and failure_name(info["failure"]) is None
    assert info["score"] == pytest.approx(reference.score, abs=1e-12)
    assert info["capture_time_s"] == pytest.approx(reference.capture_time_s)
    assert info["capture_ratio"] == pytest.approx(reference.capture_ratio)
    assert 14.0 < info["capture_time_s"] <= task.simulation.duration_s


def test_a_missed_capture_ends_with_its_failure_code(capture_ids):
    info = _play(capture_ids.ids.parameters, draw_capture_task("slow", 10, RULES), 0.3, 4.0)
    assert info["episode_end"] and not info["success"] and info["score"] == 0.0
    assert failure_name(info["failure"]) == "no_capture" and info["capture_time_s"] == 0.0
    assert info["capture_ratio"] > 1.0
    assert np.isfinite(info["capture_ratio"])  # a numeric dtype every step (the info contract)


def test_a_capture_rule_needs_its_section(tmp_path):
    path = tmp_path / "spec_bad.toml"
    path.write_text(SPEC.replace('rules_file = "capture-v0.toml"', 'rules_file = "v2.toml"')
                    .replace("capture-test", "bad-test").replace("CaptureTest", "Bad"))
    with pytest.raises(ScenarioError, match="'capture_smoothness' exactly when the rule file has a \\[capture\\]"):
        register_spec(path)


def test_the_observation_ends_with_the_desired_twist_on_both_backends(capture_ids):
    """59 floats: v2's 53, then V_ed of the approach at the observation's time (still at t = 0), the same numbers
    from the compiled step, the Python step and the batched env."""
    task = draw_capture_task("slow", 5, RULES)
    env_id = capture_ids.ids.parameters
    envs = [gym.make(env_id, task=task, backend=backend) for backend in ("kernel", "pinocchio")]
    assert all(env.observation_space.shape == (59,) for env in envs)
    firsts = [env.reset(seed=0)[0] for env in envs]
    assert np.all(firsts[0][53:] == 0.0) and np.abs(firsts[0] - firsts[1]).max() < 1e-6
    path = envs[0].unwrapped.engine.rollout(0).setup.path
    for decision in range(1, 121):
        observations = [env.unwrapped.step_with_parameters(0.3, 4.0)[0] for env in envs]
        if decision % 40 == 0:
            expected = path.at(decision * 0.1)[2].astype(np.float32)
            assert np.abs(observations[0][53:] - expected).max() < 1e-6
            assert np.abs(observations[0] - observations[1]).max() < 1e-5
    assert np.abs(path.at(12.0)[2]).max() > 1e-3  # the frame moves: the twist is not zeros
    vec = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", task=task)
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (2, 59) and np.array_equal(obs[0], firsts[0])
    for env in (*envs, vec):
        env.close()


def test_the_rendered_end_marks_the_capture_window(capture_ids):
    from ffsr_gym.sim.episode_end import episode_end, with_capture

    env = gym.make(capture_ids.ids.parameters, task=draw_capture_task("slow", 5, RULES), render_mode="rgb_array")
    env.reset(seed=0)
    done, info = False, {}
    while not done:
        _, _, terminated, truncated, info = env.unwrapped.step_with_parameters(0.3, 4.0)
        done = terminated or truncated
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.std() > 0.0
    end = with_capture(episode_end(env.unwrapped.rollout), info["capture_time_s"], RULES.capture.hold_s)
    assert end.kind == "captured" and not end.failed
    assert f"{info['capture_time_s'] - 1.0:.2f}-{info['capture_time_s']:.2f} s" in end.text
    env.close()
