"""A robot of one's own, in a folder outside the package: loaded, checked, simulated like the shipped one.

The test robot is the shipped one with a 150 kg base (inertia scaled with it) and a mission arm
whose upper link is 0.45 m instead of 0.5 m (joint placement, link CoM and capsule moved with it).
"""

from __future__ import annotations

import runpy
import shutil
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from test_kernel import assert_agree
from test_robot import _momentum_closed_form

import ffsr_gym
from ffsr_gym.exceptions import InvalidInputError, RobotFileError
from ffsr_gym.model.resources import envs_dir, scenario_path
from ffsr_gym.model.robot import load_robot
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.sim.setup import prepare, robot_assets

SHIPPED = envs_dir() / "robots" / "ffsr_dual_arm"


def make_robot(folder: Path, *, base_mass: float = 150.0, upper_link_m: float = 0.45) -> Path:
    """A copy of the shipped robot with another base mass and mission upper-link length, as the robot tutorial does."""
    folder.mkdir(parents=True)
    urdf = (SHIPPED / "ffsr_dual_arm.urdf").read_text()
    scale = base_mass / 200.0
    urdf = urdf.replace('<mass value="200.0"/>', f'<mass value="{base_mass}"/>', 1)
    urdf = urdf.replace('ixx="20.0" ixy="0" ixz="0" iyy="20.0" iyz="0" izz="20.0"',
                        f'ixx="{20 * scale}" ixy="0" ixz="0" iyy="{20 * scale}" iyz="0" izz="{20 * scale}"', 1)
    urdf = urdf.replace('<origin xyz="0.25 0 0.0" rpy="0 0 0"/>', f'<origin xyz="{upper_link_m / 2} 0 0.0" rpy="0 0 0"/>', 1)
    urdf = urdf.replace('<origin xyz="0.5 0 0" rpy="0.0 0 0"/>', f'<origin xyz="{upper_link_m} 0 0" rpy="0.0 0 0"/>', 1)
    (folder / "my_robot.urdf").write_text(urdf)
    collision = (SHIPPED / "collision.toml").read_text()
    collision = collision.replace('link = "mission_link2"\nstart_m = [0.0, 0.0, 0.0]\nend_m = [0.5, 0.0, 0.0]',
                                  f'link = "mission_link2"\nstart_m = [0.0, 0.0, 0.0]\nend_m = [{upper_link_m}, 0.0, 0.0]')
    (folder / "collision.toml").write_text(collision)
    return folder


def scenario_with_robot(folder: Path, robot: str, base: str = "free_space") -> Path:
    """The shipped ``base`` scenario naming ``robot`` (as written in the file), saved in ``folder``."""
    text = scenario_path(base).read_text().replace('robot = "ffsr_dual_arm"', f'robot = "{robot}"')
    path = folder / "mine.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def own(tmp_path_factory):
    root = tmp_path_factory.mktemp("own")
    robot = make_robot(root / "my_robot")
    return root, robot, load_scenario(scenario_with_robot(root, "./my_robot"))


def test_the_folder_loads_with_its_own_numbers(own):
    _, folder, scenario = own
    assert scenario.robot == str(folder.resolve())  # resolved against the scenario file's folder
    robot = load_robot(str(folder))
    assert robot.total_mass == pytest.approx(load_robot().total_mass - 50.0, abs=1e-9)
    q = prepare(scenario).q0
    shipped = prepare(load_scenario("free_space")).q0
    robot.update_kinematics(q)
    points, _ = robot.joint_points(0)
    assert np.linalg.norm(points[2] - points[1]) == pytest.approx(0.45, abs=1e-12)  # joint 2 -> joint 3
    assert np.allclose(q, shipped)  # same start angles, another robot


def test_momentum_matrices_and_conservation_on_the_new_robot(own):
    _, folder, scenario = own
    robot = load_robot(str(folder))
    H_b, H_bm = _momentum_closed_form(robot, prepare(scenario).q0)
    mats = robot.momentum_matrices(prepare(scenario).q0)
    assert np.max(np.abs(mats.H_b - H_b)) < 1e-10 and np.max(np.abs(mats.H_bm - H_bm)) < 1e-10
    traj = ffsr_gym.simulate(scenario.replace(simulation=scenario.simulation.__class__(duration_s=5.0, dt_s=0.01)))
    worst = max(np.linalg.norm(robot.centroidal_momentum(q, v)) for q, v in zip(traj.q, traj.v))
    assert worst < 1e-9  # zero momentum, kept by the closed loop on this robot
    com = [robot.system_com(q) for q in traj.q]
    assert np.max(np.linalg.norm(np.array(com) - com[0], axis=1)) < 1e-6


def test_kernel_agrees_with_pinocchio_on_the_new_robot(own):
    _, _, scenario = own
    short = scenario.replace(simulation=scenario.simulation.__class__(duration_s=6.0, dt_s=0.01))
    assert_agree(short, "predefined_time")


def test_an_ffsr_v2_episode_on_the_new_robot(own):
    root, _, scenario = own
    env = gym.make("FFSR-v2", task=str(root / "mine.toml"))
    assert env.unwrapped.source.custom and env.unwrapped.scenario.robot == scenario.robot
    env.reset(seed=0)
    done, info = False, {}
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        done = terminated or truncated
    assert "score" in info and 0.0 <= info["score"] <= 1.0
    assert env.unwrapped.rollout.setup.robot.total_mass == pytest.approx(load_robot().total_mass - 50.0)


def test_the_hash_follows_the_robot_files_not_their_place(own, tmp_path):
    root, folder, scenario = own
    assert scenario.sha256() != load_scenario("free_space").sha256()
    moved = tmp_path / "elsewhere"
    shutil.copytree(root, moved)
    assert load_scenario(moved / "mine.toml").sha256() == scenario.sha256()
    assert prepare(load_scenario(moved / "mine.toml")).robot.total_mass == pytest.approx(318.0)  # cached now
    (moved / "my_robot" / "my_robot.urdf").write_text((folder / "my_robot.urdf").read_text().replace(
        'value="150.0"', 'value="140.0"'))
    edited = load_scenario(moved / "mine.toml")
    assert edited.sha256() != scenario.sha256()
    assert robot_assets(edited.robot).robot.total_mass == pytest.approx(load_robot().total_mass - 60.0)
    assert prepare(edited).robot.total_mass == pytest.approx(308.0)  # not the stale 318 kg setup


def test_a_urdf_path_names_the_same_robot(own, tmp_path):
    _, folder, scenario = own
    by_file = load_scenario(scenario_with_robot(tmp_path, str(folder / "my_robot.urdf")))
    assert load_robot(by_file.robot).total_mass == load_robot(scenario.robot).total_mass
    assert by_file.sha256() == scenario.sha256()  # one robot, one hash, however the scenario names it


BROKEN = {
    "a renamed joint": ("urdf", 'name="mission_joint4"', 'name="mission_joint_four"', "mission_joint4"),
    "an extra joint": ("urdf", '</robot>', ('<link name="extra"><inertial><mass value="1"/><inertia ixx="1" ixy="0" '
                       'ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link><joint name="extra_joint" type="revolute">'
                       '<parent link="base"/><child link="extra"/><axis xyz="0 0 1"/><limit effort="1" velocity="1" '
                       'lower="-1" upper="1"/></joint></robot>'), "extra_joint"),
    "a prismatic joint": ("urdf", '<joint name="balance_joint2" type="revolute">', ('<joint name="balance_joint2" '
                          'type="prismatic">'), "balance_joint2"),
    "a non-positive inertia": ("urdf", 'ixx="0.16875"', 'ixx="-0.16875"', "mission_link2"),
    "an impossible inertia": ("urdf", 'ixx="0.16875" ixy="0" ixz="0" iyy="0.396875" iyz="0" izz="0.396875"',
                              'ixx="1.0" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"', "triangle"),
    "a zero mass": ("urdf", '<mass value="15"/>', '<mass value="0"/>', "mission_link2"),
    "a capsule on no link": ("collision", 'link = "mission_link4"', 'link = "mission_link9"', "capsule 3"),
    "a capsule on the wrong arm": ("collision", 'link = "mission_link4"', 'link = "balance_link4_x"', "capsule 3"),
    "a zero-length capsule": ("collision", 'end_m = [0.0, 0.0, 0.5]', 'end_m = [0.0, 0.0, 0.0]', "capsule 3"),
    # checked on the URDF's own links and joints, before Pinocchio merges fixed links into their parents
    "a zero joint axis": ("urdf", '<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>', "axis '0 0 0'"),
    "a negative mass on a fixed link": ("urdf", '<link name="mission_ee"/>', (
        '<link name="mission_ee"><inertial><mass value="-5"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" '
        'izz="1"/></inertial></link>'), "link 'mission_ee' has mass '-5'"),
    "a non-positive-definite inertia on a fixed link": ("urdf", '<link name="balance_ee"/>', (
        '<link name="balance_ee"><inertial><mass value="1"/><inertia ixx="-1" ixy="0" ixz="0" iyy="1" iyz="0" '
        'izz="1"/></inertial></link>'), "link 'balance_ee'"),
    "a DTD with entities": ("urdf", '<robot', '<!DOCTYPE r [<!ENTITY a "aaaa">]>\n<robot', "DTD"),
    # collision files typed strictly: no boolean or text where a number belongs, pairs of part names
    "a boolean radius": ("collision", "capsule_radius_m = 0.02", "capsule_radius_m = true", "capsule_radius_m"),
    "a radius as text": ("collision", "capsule_radius_m = 0.02", 'capsule_radius_m = "0.02"', "capsule_radius_m"),
    "ignored pairs as text": ("collision", 'ignored_pairs = [["base", "mission_link1"], ["base", "balance_link1"]]',
                              'ignored_pairs = "ab"', "ignored_pairs"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_robot_is_refused_naming_the_file_and_the_element(tmp_path, case):
    kind, old, new, named = BROKEN[case]
    folder = make_robot(tmp_path / "bad")
    path = folder / ("my_robot.urdf" if kind == "urdf" else "collision.toml")
    text = path.read_text()
    assert old in text, case
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(RobotFileError) as error:  # on load: the scenario names a broken robot
        load_scenario(scenario_with_robot(tmp_path, "bad"))
    assert "mine.toml: key 'robot'" in str(error.value), str(error.value)
    assert path.name in str(error.value) and named in str(error.value), str(error.value)
    with pytest.raises(RobotFileError, match=named):  # and wherever it is used
        robot_assets(str(folder))


def test_a_folder_without_its_files_is_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(RobotFileError, match="0 .urdf files"):
        load_scenario(scenario_with_robot(tmp_path, "empty"))
    folder = make_robot(tmp_path / "no_collision")
    (folder / "collision.toml").unlink()
    with pytest.raises(RobotFileError, match="collision.toml does not exist"):
        load_scenario(scenario_with_robot(tmp_path, "no_collision"))
    with pytest.raises(InvalidInputError, match="custom task"):
        gym.make("FFSR-v2", task=str(tmp_path / "nothing_here.toml"))


def test_the_robot_tutorial_says_what_its_steps_give(tmp_path, monkeypatch):
    text = (Path(__file__).resolve().parents[3] / "docs" / "tutorials" / "robot.md").read_text(encoding="utf-8")
    blocks = [block.split("```")[0] for block in text.split("```python\n")[1:]]
    monkeypatch.chdir(tmp_path)
    Path("make_robot.py").write_text(textwrap.dedent(blocks[0]))  # step 1 of the page, as written
    runpy.run_path("make_robot.py")
    scenario = load_scenario("mine.toml")
    assert load_robot(scenario.robot).total_mass == pytest.approx(318.0)  # as the page says
    assert load_robot().total_mass == pytest.approx(368.0)  # "50 kg less than the shipped 368 kg"
    report = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="mine.toml", name="mine_constant")
    assert report.metrics["success_rate"] == 1.0 and round(report.metrics["score_mean"], 2) == 0.72  # as the page says
    kernel = ffsr_gym.simulate("mine.toml", backend="kernel")
    reference = ffsr_gym.simulate("mine.toml", backend="pinocchio")
    assert np.abs(kernel.q - reference.q).max() < 1e-9


def test_the_page_says_why_a_shorter_arm_misses(own):
    """docs/tutorials/robot.md: with a 0.45 m upper link the free_space target is out of reach, 27 mm short."""
    root, _, _ = own
    row = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task=str(root / "mine.toml")).episodes[0]
    assert row["failure"] == "final_error" and round(1000 * row["final_ee_position_error_m"]) == 27


def test_a_continuous_joint_is_a_revolute_joint_without_limits(tmp_path):
    """docs/robots.md allows continuous joints: the same robot with one gives the same model and the same episode."""
    scores = []
    for kind in ("revolute", "continuous"):
        folder = make_robot(tmp_path / kind / "robot", base_mass=200.0, upper_link_m=0.5)  # the shipped geometry
        path = folder / "my_robot.urdf"
        old = '<joint name="mission_joint3" type="revolute">'
        assert old in path.read_text()
        path.write_text(path.read_text().replace(old, f'<joint name="mission_joint3" type="{kind}">', 1))
        robot = load_robot(str(path))
        assert robot.model.nq == 19 and robot.model.joints[int(robot.joint_ids[0, 2])].nq == 1
        task = str(scenario_with_robot(tmp_path / kind, "./robot"))
        scores.append(ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task=task, seeds=[0]).episodes[0])
    assert scores[0] == scores[1] and scores[0]["success"]


def test_an_empty_capsule_list_is_refused_by_name(tmp_path):
    """``capsule = []`` loaded, then failed inside the compiled kernel (a numba TypingError)."""
    folder = make_robot(tmp_path / "bare")
    path = folder / "collision.toml"
    head = path.read_text().split("[[capsule]]")[0]
    path.write_text(head.replace("capsule_radius_m = 0.02", "capsule_radius_m = 0.02\ncapsule = []"))
    with pytest.raises(RobotFileError, match="no capsule on the mission arm"):
        load_scenario(scenario_with_robot(tmp_path, "bare"))


@pytest.mark.parametrize("shape, count", [("chain", 4500), ("star", 100_000)])
def test_a_huge_urdf_is_refused_by_name_before_pinocchio_parses_it(tmp_path, shape, count):
    """A chain of thousands of fixed joints overflowed the URDF parser's recursion (a segfault); a star of 10^5
    links took minutes."""
    import time

    folder = make_robot(tmp_path / "huge")
    path = folder / "my_robot.urdf"
    links = "".join(f'<link name="x{k}"/><joint name="f{k}" type="fixed"><parent link="'
                    f'{("x" + str(k - 1)) if shape == "chain" and k else "base"}"/><child link="x{k}"/></joint>'
                    for k in range(count))
    path.write_text(path.read_text().replace("</robot>", links + "</robot>"))
    start = time.perf_counter()
    with pytest.raises(RobotFileError, match="a chain of more than|links; allowed: at most|bytes; allowed"):
        load_robot(str(path))
    assert time.perf_counter() - start < 5.0
