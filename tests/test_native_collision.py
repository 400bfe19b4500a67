"""The native collision distances (C++) against the numba kernel's, to the bit, along trajectories that pass close
to obstacles, drifting debris and a tumbling target's body, and at random states (arm-arm and arm-base contact);
the exact segment-box distance against dense sampling of the box's signed distance (independent)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_states
from test_native_planner import _scenario

from ffsr_gym import _native
from ffsr_gym.kernel import loop, physics
from ffsr_gym.native.planner import planner_settings
from ffsr_gym.native.robot import native_robot
from ffsr_gym.sim.compiled import KernelRollout, settings_vectors
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import simulate


@pytest.mark.parametrize("name", ["paper", "v2/hard", "v2/debris", "capture-v0/slow"])
def test_clearances_are_the_numba_kernels_to_the_bit(name):
    scenario = _scenario(name)
    setup, rollout = prepare(scenario), KernelRollout(scenario)
    mdl, robot = rollout._mdl, native_robot(rollout._mdl)
    fp, ip = settings_vectors(setup, method="predefined_time", m=0.3, T_c=4.0)
    settings = planner_settings(setup, method="predefined_time", m=0.3, T_c=4.0)
    trajectory = simulate(scenario, backend="kernel")
    rng, ws = np.random.default_rng(31), physics.workspace(len(mdl.cap_radius))
    cases = [(np.concatenate((trajectory.q[k, :7], trajectory.q[k, mdl.q_index])), float(trajectory.t[k]))
             for k in np.linspace(0, len(trajectory.t) - 1, 25).astype(int)]
    cases += [(x, float(rng.uniform(0.0, 20.0))) for x in random_states(rng, 25)]
    contact = 0
    for x, t in cases:
        clear, self_c, rel = _native.clearances(robot, settings, x, t)
        physics.kinematics_into(mdl, x, ws)
        expected_clear, expected_self = loop._clearances(mdl, x, t, fp, ip, ws)
        assert clear == expected_clear and self_c == expected_self, (t, clear, expected_clear, self_c, expected_self)
        if ip[6] > 0:  # the vector to the nearest obstacle, when there is one
            assert np.array_equal(rel, ws.rel)
        contact += self_c < 0.0
    assert contact > 0  # random states bring arms into contact: the pair search ran to its end


def test_segment_box_is_the_minimum_of_the_sampled_signed_distance():
    rng = np.random.default_rng(32)
    for _ in range(200):
        q = rng.normal(size=4)
        w, x, y, z = q / np.linalg.norm(q)
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        c, half = rng.normal(scale=0.2, size=3), rng.uniform(0.05, 0.4, 3)
        a, b = rng.normal(scale=0.5, size=3), rng.normal(scale=0.5, size=3)
        ts = np.linspace(0.0, 1.0, 20001)
        local = (a + ts[:, None] * (b - a) - c) @ R
        d = np.abs(local) - half
        outside = np.linalg.norm(np.maximum(d, 0.0), axis=1)
        sampled = np.where(outside > 0.0, outside, d.max(axis=1)).min()
        exact = _native.segment_box(a, b, R, c, half)
        assert exact <= sampled + 1e-12 and sampled - exact < 1e-4 * max(1.0, np.linalg.norm(b - a))
