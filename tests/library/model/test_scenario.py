"""Scenario files: shipped ones load, bad ones fail with messages naming key, value and range."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from ffsr_gym.exceptions import RobotFileError, ScenarioError
from ffsr_gym.model.resources import scenario_path
from ffsr_gym.model.scenario import ADDED_KEYS, load_scenario


@pytest.mark.parametrize("name", ["paper", "paper_as_printed", "free_space"])
def test_shipped_scenarios_load(name):
    scenario = load_scenario(name)
    assert scenario.name == name
    assert scenario.n_steps == 2000
    assert np.linalg.norm(scenario.target.quaternion_wxyz) == pytest.approx(1.0, abs=1e-15)


def test_plain_data_equals_the_standard_library_conversion():
    """``to_dict`` (which skips copying immutable leaves) against ``dataclasses.asdict``, on every shipped
    scenario and on task draws with and without perturbation sections; the hash is taken from it."""
    from ffsr_gym.model.scenario import to_dict
    from ffsr_gym.tasks.generator import draw_task
    from ffsr_gym.tasks.perturbation import perturbed_task
    from ffsr_gym.versions.registry import load_benchmark

    benchmark = load_benchmark("v2")
    scenarios = [load_scenario(name) for name in ("paper", "paper_as_printed", "free_space", "random")]
    scenarios += [draw_task(seed, benchmark) for seed in range(5)]
    for tier in ("debris", "robust"):
        scenarios += [task for seed in range(40) if (task := perturbed_task(tier, seed, benchmark)) is not None][:3]
    sections = {key for scenario in scenarios for key in to_dict(scenario)}
    assert sections >= {"obstacle", "debris", "plant", "target_noise", "randomization"}
    for scenario in scenarios:
        expected = dataclasses.asdict(scenario)
        del expected["source"]
        expected = {key: value for key, value in expected.items() if value is not None}
        expected["trajectory"] = expected.pop("desired_path")  # the attribute's key in the file
        for (table, key), default in ADDED_KEYS.items():  # left out at their default: older hashes hold
            if expected[table][key] == default:
                del expected[table][key]
        assert to_dict(scenario) == expected


def test_paper_differs_from_printed_only_in_the_obstacle():
    printed, paper = load_scenario("paper_as_printed"), load_scenario("paper")
    assert printed.obstacle.position_m == (-0.0691, 0.6037, 0.4742)
    assert paper.obstacle.position_m != printed.obstacle.position_m
    same = dataclasses.replace(paper, obstacle=printed.obstacle, name=printed.name,
                               description=printed.description, deviations=printed.deviations, source=printed.source)
    assert same == printed
    assert load_scenario("free_space").obstacle is None


def test_printed_target_quaternion_is_normalised():
    printed = np.array([0.0215, 0.9027, 0.1184, 0.4132])
    assert np.allclose(load_scenario("paper").target.quaternion_wxyz, printed / np.linalg.norm(printed))


def assert_section_rejected(tmp_path: Path, section: str, body: str, message: str) -> None:
    """``paper`` with a ``[section]`` of ``body`` appended fails to load with ``message`` in the error."""
    path = tmp_path / f"{section}.toml"
    path.write_text(scenario_path("paper").read_text() + f"\n[{section}]\n{body}\n")
    with pytest.raises(ScenarioError, match=re.escape(message)):
        load_scenario(path)


def _write_variant(tmp_path: Path, old: str, new: str) -> Path:
    text = scenario_path("paper").read_text()
    assert old in text
    path = tmp_path / "variant.toml"
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        ("dt_s = 0.01", 'dt_s = "fast"', ["simulation.dt_s", "'fast'", "must be a number"]),
        ("dt_s = 0.01", "dt_s = 0.5", ["simulation.dt_s", "0.5", "[1e-05, 0.1]"]),
        ("m = 0.1 ", "m = 1.5 ", ["planner.m", "1.5", "(0.0, 1.0)"]),
        ("T_c_s = 3.0", "T_c_s = -1.0", ["planner.T_c_s", "-1.0", "(0.0, 1000.0]"]),
        ("m = 0.1 ", "", ["missing key", "planner.m"]),
        ("[target]\n", "[target]\ncolour = 3\n", ["unknown key", "target.colour", "allowed keys"]),
        ('mu_law = "cdf"', 'mu_law = "magic"', ["planner.mu_law", "'magic'", "['cdf', 'distance']"]),
        ("balance_avoids = true", "balance_avoids = 1", ["planner.balance_avoids", "true or false"]),
        ("accel_time_s = 2.5", "accel_time_s = 6.0", ["trajectory.accel_time_s", "6.0", "(0, 5.0]"]),
        ("base_quaternion_wxyz = [1.0, 0.0, 0.0, 0.0]", "base_quaternion_wxyz = [1.0, 0.0, 0.0]",
         ["initial.base_quaternion_wxyz", "list of 4 numbers"]),
        ("base_quaternion_wxyz = [1.0, 0.0, 0.0, 0.0]", "base_quaternion_wxyz = [0.5, 0.0, 0.0, 0.0]",
         ["initial.base_quaternion_wxyz", "norm 0.5", "unit quaternion"]),
        ("mission_joints_deg = [0.0, 47.72", "mission_joints_deg = [0.0, 470.72",
         ["initial.mission_joints_deg[1]", "470.72", "[-360.0, 360.0]"]),
    ],
)
def test_bad_values_name_key_value_and_range(tmp_path, old, new, fragments):
    path = _write_variant(tmp_path, old, new)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    for fragment in fragments:
        assert fragment in message, message
    assert str(path) in message


def test_malformed_toml(tmp_path):
    path = _write_variant(tmp_path, "[target]", "[target")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(path)


def test_unknown_name_lists_the_shipped_ones():
    with pytest.raises(ScenarioError, match="free_space"):
        load_scenario("no_such_scenario")


def test_missing_robot_is_reported(tmp_path):
    path = _write_variant(tmp_path, 'robot = "ffsr_dual_arm"', 'robot = "ghost"')
    with pytest.raises(RobotFileError, match="ghost"):
        load_scenario(path)


def test_replace_revalidates():
    paper = load_scenario("paper")
    changed = paper.replace(planner=dataclasses.replace(paper.planner, m=0.2167))
    assert changed.planner.m == 0.2167 and changed.sha256() != paper.sha256()
    with pytest.raises(ScenarioError, match="planner.m"):
        paper.replace(planner=dataclasses.replace(paper.planner, m=2.0))
