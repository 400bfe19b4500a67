"""Several and drifting obstacles (``[debris]``): kernel against reference, the summed danger field, clearance to
the nearest obstacle where it is at time t, and nothing changed without debris."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_kernel import ARRAYS, assert_agree
from test_scenario import assert_section_rejected

from ffsr_gym import _native
from ffsr_gym.exceptions import ScenarioError
from ffsr_gym.model.collision import SphereObstacle
from ffsr_gym.model.obstacles import obstacle_field
from ffsr_gym.model.scenario import Debris, load_scenario, to_dict
from ffsr_gym.model.scenario_sections import MAX_DEBRIS
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import simulate

#: ``paper`` with its obstacle drifting and two more: one still, 0.25 m above the target, one drifting
#: across the swept path. Each of the three is the nearest at some time of the rollout.
DEBRIS = Debris(obstacle_velocity_m_s=(0.0, 0.004, -0.002),
                positions_m=((0.7147, 0.415, 0.0742), (0.66, 0.47, -0.02)),
                radii_m=(0.02, 0.01),
                velocities_m_s=((0.0, 0.0, 0.0), (0.003, -0.004, 0.002)))


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper").replace(debris=DEBRIS)


def test_kernel_slots_hold_every_obstacle_a_scenario_may_list():
    assert _native.MAX_OBSTACLES == MAX_DEBRIS + 1


@pytest.mark.parametrize("method", ["predefined_time", pytest.param("proportional", marks=pytest.mark.slow)])
def test_kernel_matches_reference_with_debris(scenario, method):
    assert_agree(scenario, method)


def test_debris_changes_the_motion_and_the_avoidance_acts(scenario):
    plain, debris = simulate("paper", backend="kernel"), simulate(scenario, backend="kernel")
    assert np.max(np.abs(debris.q - plain.q)) > 1e-3
    assert np.min(debris.mu) < 1.0


def _quadrature_cdf(points, p_o, n=20001):
    """∑ over segments of ∫₀¹ ds / ‖p_o − r(s)‖ by the trapezoid rule (independent of the closed form)."""
    s = np.linspace(0.0, 1.0, n)
    total = 0.0
    for a, b in zip(points[:-1], points[1:]):
        if np.linalg.norm(b - a) < 1e-12:
            continue
        r = a[None, :] + s[:, None] * (b - a)[None, :]
        f = 1.0 / np.linalg.norm(p_o[None, :] - r, axis=1)
        total += float(np.sum(0.5 * (f[1:] + f[:-1])) * (s[1] - s[0]))
    return total


def test_danger_field_is_the_sum_over_obstacles_where_they_are_at_t(scenario):
    """The logged CDF of each arm equals the quadrature of the field summed over p + v t, at several times."""
    trajectory = simulate(scenario, backend="pinocchio")
    setup = prepare(scenario)
    robot, field = setup.robot, obstacle_field(scenario)
    for k in (0, 400, 900, 1500):
        robot.update_kinematics(trajectory.q[k])
        positions = field.positions_m + field.velocities_m_s * trajectory.t[k]
        for arm in range(2):
            points, _ = robot.joint_points(arm)
            expected = scenario.planner.cdf_k1 * sum(_quadrature_cdf(points, p) for p in positions)
            assert trajectory.cdf[k, arm] == pytest.approx(expected, rel=1e-6)


def test_clearance_is_to_the_nearest_obstacle_where_it_is_at_t(scenario):
    """Kernel clearances against coal queried per obstacle at its drifted position; the nearest one changes."""
    trajectory = simulate(scenario, backend="kernel")
    setup = prepare(scenario)
    field = obstacle_field(scenario)
    nearest = set()
    for k in range(0, len(trajectory.t), 50):
        t = trajectory.t[k]
        collision = setup.assets.collision
        distances = [collision.obstacle_proximity(trajectory.q[k], [SphereObstacle(p + v * t, r)]).distance_m
                     for p, v, r in zip(field.positions_m, field.velocities_m_s, field.radii_m)]
        assert trajectory.clearance_m[k] == pytest.approx(min(distances), abs=1e-9)
        nearest.add(int(np.argmin(distances)))
    assert nearest == {0, 1, 2}


def test_still_empty_debris_reproduces_the_plain_scenario_bit_for_bit():
    plain = load_scenario("paper")
    with_section = plain.replace(debris=Debris())
    assert to_dict(plain) != to_dict(with_section)
    for backend in ("kernel",):
        a, b = simulate(plain, backend=backend), simulate(with_section, backend=backend)
        for name in ARRAYS:
            assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_scenario_hash_unchanged_without_debris():
    """Scenarios without a ``[debris]`` section keep their content (and so their hashes and certificates)."""
    assert "debris" not in to_dict(load_scenario("paper"))


@pytest.mark.parametrize("section, message", [
    ("positions_m = [[0.0, 0.0, 0.0]]", "same number of obstacles"),
    ("positions_m = [[0.0, 0.0]]\nradii_m = [0.0]\nvelocities_m_s = [[0.0, 0.0, 0.0]]", "'debris.positions_m[0]'"),
    ("obstacle_velocity_m_s = [0.0, 2.0, 0.0]", "'debris.obstacle_velocity_m_s[1]' = 2.0 is out of range"),
    (f"positions_m = [{', '.join(['[0.0, 0.0, 0.0]'] * (MAX_DEBRIS + 1))}]", f"at most {MAX_DEBRIS}"),
    ("radii_m = [-0.1]", "'debris.radii_m[0]' = -0.1 is out of range; allowed: [0.0, 2.0]"),
    ('velocities_m_s = "fast"', "'debris.velocities_m_s' must be a list"),
    ("spin = 1.0", "unknown key 'debris.spin'"),
])
def test_malformed_debris_is_named(tmp_path, section, message):
    assert_section_rejected(tmp_path, "debris", section, message)


def test_debris_needs_the_obstacle_section():
    scenario = load_scenario("free_space")
    with pytest.raises(ScenarioError, match="'debris' needs an 'obstacle'"):
        scenario.replace(debris=dataclasses.replace(DEBRIS))
