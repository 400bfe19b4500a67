"""Capture of a moving grasp frame (ffsr_gym.scoring.capture) on motions whose answers are known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.benchmark import CaptureRule
from ffsr_gym.scoring.capture import capture, relative_motion

TOLERANCES = CaptureRule(position_m=0.01, attitude_rad=0.05, linear_velocity_m_s=0.02,
                               angular_velocity_rad_s=0.03, hold_s=1.0)


def test_relative_motion_measures_offsets_turns_and_twist_differences():
    grasp_q = quat.from_axis_angle(np.array([0.0, 0.6, 0.8]), 0.9)
    turned = quat.multiply(grasp_q, quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.2))
    grasp_twist = np.array([[0.1, 0.0, 0.0, 0.0, 0.0, 0.05]])
    ee_twist = grasp_twist + np.array([[0.0, 0.03, 0.04, 0.0, 0.0, -0.01]])
    values = relative_motion(np.array([[1.0, 2.0, 3.0]]), -turned[None, :], ee_twist, np.array([[1.0, 2.0, 3.12]]),
                             grasp_q[None, :], grasp_twist)  # -q: the same attitude
    assert values[0] == pytest.approx([0.12, 0.2, 0.05, 0.01], abs=1e-12)


def test_a_decaying_error_is_captured_once_it_has_held_inside_for_the_window():
    t = np.arange(0.0, 10.0 + 1e-9, 0.01)
    relative = np.column_stack([0.1 * np.exp(-t), np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)])
    result = capture(t, relative, TOLERANCES)
    first_inside = math.log(10.0)  # 0.1 e^-t = 0.01
    assert result.captured and result.time_s == pytest.approx(math.ceil(first_inside / 0.01) * 0.01 + 1.0, abs=1e-9)
    assert result.worst_ratio[0] == pytest.approx(0.1 * math.exp(-(result.time_s - 1.0)) / 0.01)
    assert result.worst_ratio[0] <= 1.0 and np.all(result.worst_ratio[1:] == 0.0)
    # the best window is the last: it starts at t = 9 s, where the error is 0.1 e^-9
    assert result.margin_ratio == pytest.approx(0.1 * math.exp(-9.0) / 0.01)


def test_a_window_broken_by_one_sample_outside_starts_again():
    t = np.arange(0.0, 5.0 + 1e-9, 0.01)
    relative = np.zeros((len(t), 4))
    relative[:100, 2] = 1.0  # fast until 1 s
    relative[150, 3] = 0.031  # one sample spinning too fast at 1.5 s
    result = capture(t, relative, TOLERANCES)
    assert result.captured and result.time_s == pytest.approx(2.51)
    never = capture(t, relative + np.array([0.02, 0.0, 0.0, 0.0]), TOLERANCES)
    assert not never.captured and math.isnan(never.time_s)
    assert never.margin_ratio == pytest.approx(0.02 / 0.01)  # tolerances twice as wide would capture
