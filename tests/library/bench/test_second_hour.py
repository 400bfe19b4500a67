"""What a new user does in their second hour: a scenario of their own, a picture of what happened, an entry
submitted. Each test is a defect found by doing exactly that."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym import failure_name
from ffsr_gym.bench.board_layout import leaderboard_table
from ffsr_gym.cli.main import build_parser, main
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.resources import scenario_path
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.scoring.score import score_episode
from ffsr_gym.sim.episode_end import episode_end
from ffsr_gym.versions.registry import load_benchmark

ROOT = Path(__file__).resolve().parents[3]
RULES = load_benchmark("v2")


def _played(scenario, m: float, T_c: float):
    """The episode score of a fixed (m, T_c) on ``scenario`` under v2's rule, from ffsr_gym.simulate (no env)."""
    task = RULES.task(scenario)
    task = task.replace(planner=dataclasses.replace(task.planner, m=m, T_c_s=T_c))
    return score_episode(ffsr_gym.simulate(task), task, RULES)


@pytest.mark.parametrize("how", ["task", "env_kwargs", "path"])
def test_evaluate_scores_a_custom_scenario_not_the_default_pool(how):
    scenario = load_scenario("free_space")
    given = {"task": {"task": scenario}, "env_kwargs": {"env_kwargs": {"task": scenario}},
             "path": {"task": str(scenario_path("free_space"))}}[how]
    report = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", **given)
    expected = _played(scenario, 0.3, 4.0)
    assert len(report.episodes) == 1 and report.episodes[0]["score"] == expected.score and expected.success
    custom = report.extra["custom_task"]
    assert (custom["name"], custom["scenario_sha256"], report.extra["evaluation_pool"]) == \
        ("free_space", scenario.sha256(), None)
    assert load_scenario(scenario_path("free_space")).replace() == scenario  # the recorded scenario round-trips
    json.dumps(report.to_json())  # the entry is JSON (the Scenario object is not stored)


def test_a_custom_task_refuses_pool_arguments_and_names_what_it_accepts():
    scenario = load_scenario("free_space")
    with pytest.raises(InvalidInputError, match="both given"):
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", env_kwargs={"task": scenario})
    for kwargs in ({"split": "test"}, {"indices": [0]}):
        with pytest.raises(InvalidInputError, match="custom task"):
            ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task=scenario, **kwargs)
    with pytest.raises(InvalidInputError) as error:
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task=object())
    assert "allowed" in str(error.value) and len(str(error.value)) < 300  # not a dataclass repr
    with pytest.raises(InvalidInputError, match="seeds"):
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", seeds=[0])
    with pytest.raises(InvalidInputError, match="unexpected keyword argument 'scenario'"):
        gym.make("FFSR-v2", scenario="free_space")  # v0's keyword: an error, never ignored


def test_cli_evaluate_and_render_play_the_custom_scenario(tmp_path, capsys):
    mine = tmp_path / "mine.toml"
    mine.write_text(scenario_path("free_space").read_text().replace('name = "free_space"', 'name = "mine"'))
    assert main(["evaluate", "--env-id", "FFSR-v2", "--scenario", str(mine), "--policy", "0.3,4", "--name", "mine",
                 "--compute", "100,2.5", "--leaderboard", str(tmp_path / "boards"), "--no-progress"]) == 0
    entry = json.loads((tmp_path / "boards" / "v2" / "custom" / "mine.json").read_text())
    assert entry["extra"]["custom_task"]["name"] == "mine" and entry["extra"]["evaluation_pool"] is None
    assert entry["episodes"][0]["score"] == _played(load_scenario(mine), 0.3, 4.0).score
    assert entry["extra"]["compute"] == {"env_steps": 100, "wall_time_s": 2.5}
    capsys.readouterr()
    assert main(["render", "--env-id", "FFSR-v2", "--scenario", str(mine), "--every", "100",
                 "--out", str(tmp_path / "mine.gif")]) == 0
    assert "task mine" in capsys.readouterr().out


def test_save_refuses_a_report_its_table_would_refuse(tmp_path):
    hard = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="hard", indices=[0, 1], name="hard_into_easy")
    with pytest.raises(InvalidInputError, match="evaluation_pool 'hard/test'"):
        hard.save(tmp_path / "v2" / "easy")
    custom = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="free_space", name="mine")
    with pytest.raises(InvalidInputError, match="custom"):
        custom.save(tmp_path / "v2" / "hard")
    assert custom.save(tmp_path / "v2" / "custom").is_file()  # not a table folder
    assert not (tmp_path / "v2" / "easy").exists() and not (tmp_path / "v2" / "hard").exists()
    assert leaderboard_table(tmp_path / "FFSR-v0")[1] == "FFSR-v0" and leaderboard_table(tmp_path / "v2") is None


def test_compute_is_a_public_argument_checked_by_name():
    report = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", indices=[0],
                               compute={"env_steps": 10, "wall_time_s": 1.0, "hardware": "2 CPU cores"})
    assert report.extra["compute"] == {"env_steps": 10, "wall_time_s": 1.0, "hardware": "2 CPU cores"}
    for bad, named in (({"env_steps": 10}, "wall_time_s"), ({"env_steps": -1, "wall_time_s": 1.0}, "env_steps"),
                       ({"env_steps": 1, "wall_time_s": float("nan")}, "wall_time_s"),
                       ({"env_steps": 1, "wall_time_s": 1.0, "gpu": 1}, "allowed")):
        with pytest.raises(InvalidInputError, match=named):
            ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", indices=[0], compute=bad)


def test_a_planner_entry_checks_its_compute_by_the_same_rule():
    """``evaluate_planner`` (the classical and optimiser baselines) records compute through the same check:
    a search's own diagnostic, such as its best training loss, belongs in ``extra``, not in ``compute``."""
    from ffsr_gym.bench.planner_scores import evaluate_planner

    with pytest.raises(InvalidInputError, match="allowed"):
        evaluate_planner("predefined_time", task="easy", m=0.3, T_c=4.0,
                         compute={"objective_evaluations": 20, "wall_time_s": 1.0, "best_training_loss": 0.7})


def test_the_frame_shows_every_obstacle_where_it_is_now():
    env = gym.make("FFSR-v2", task="debris", split="test", render_mode="rgb_array")
    env.reset(seed=0, options={"task_index": 3})
    for _ in range(40):
        env.step(np.zeros(2, dtype=np.float32))
    env.render()
    field, t = env.unwrapped.rollout.setup.obstacles, env.unwrapped.rollout.t
    drawn = [np.ravel(a._offsets3d) for a in env.unwrapped._renderer._moving if hasattr(a, "_offsets3d")]
    assert len(field) >= 2 and np.any(field.velocities_m_s)  # an obstacle and debris, moving
    expected = field.at(t)
    assert len(drawn) == len(expected)
    for got, want in zip(drawn, expected):
        assert np.allclose(np.asarray(got, dtype=float), want, atol=1e-12)
    assert not np.allclose(expected, field.at(0.0))  # t = 4 s: they have moved since the start


def test_the_last_frame_marks_the_first_violation():
    env = gym.make("FFSR-v2", task="debris", split="test", render_mode="rgb_array")
    env.reset(seed=0, options={"task_index": 3})
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        done = terminated or truncated
    traj, end = env.unwrapped.trajectory, episode_end(env.unwrapped.rollout)
    first_contact = int(np.flatnonzero(traj.self_clearance_m < 0.0)[0])  # independent of episode_end's reading
    assert failure_name(info["failure"]) == "collision" and end.kind == "self contact" and end.failed
    assert end.t_s == traj.t[first_contact] and "mission_link2 touches base" in end.text
    env.render()
    texts = [a.get_text() for a in env.unwrapped._renderer._moving if hasattr(a, "get_text")]
    assert any(end.text == text for text in texts)


def test_a_rate_violation_is_marked_at_its_joint():
    env = gym.make("FFSR-v2", task="easy", split="test")
    env.reset(seed=0, options={"task_index": 0})
    done = False
    while not done:  # the smallest m and T_c of the box: the fastest law
        _, _, terminated, truncated, info = env.unwrapped.step_with_parameters(0.05, 1.0)
        done = terminated or truncated
    traj, end = env.unwrapped.trajectory, episode_end(env.unwrapped.rollout)
    rates = np.degrees(np.abs(traj.dq_joints[:-1]))
    k = int(np.flatnonzero(rates.max(axis=1) > 200.0)[0])
    joint = int(np.argmax(rates[k]))
    assert failure_name(info["failure"]) == "rate_limit" and end.kind == "rate limit" and end.t_s == traj.t[k]
    assert f"joint {joint % 6 + 1}" in end.text and ("mission" if joint < 6 else "balance") in end.text


def test_render_defaults_and_policy_files(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["render", "--env-id", "FFSR-Residual-v2", "--every", "100", "--out", "a.gif"]) == 0  # zero residual
    Path("zero_policy.py").write_text("import numpy as np\n\ndef policy(obs):\n    return np.zeros(12, np.float32)\n")
    for spec in ("zero_policy:policy", "./zero_policy.py:policy"):  # no PYTHONPATH needed
        assert main(["render", "--env-id", "FFSR-Residual-v2", "--policy", spec, "--every", "100", "--out", "b.gif"]) == 0
    Path("broken.py").write_text("def policy(obs) return 0\n")
    capsys.readouterr()
    assert main(["render", "--env-id", "FFSR-Residual-v2", "--policy", "./broken.py:policy", "--out", "c.gif"]) == 2
    assert "failed to import (SyntaxError" in capsys.readouterr().err


def _options(parser):
    """(parser, option) of every optional argument of every (sub-)command."""
    import argparse

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _options(sub)
        elif action.option_strings and not isinstance(action, argparse._HelpAction):
            yield parser, action


def test_every_help_shows_its_defaults(capsys):
    import argparse

    missing = []
    for parser, action in _options(build_parser()):
        shown = parser._get_formatter()._get_help_string(action)
        if not (action.required or isinstance(action, (argparse._StoreTrueAction, argparse._VersionAction))) \
                and "default" not in shown:
            missing.append(f"{parser.prog} {'/'.join(action.option_strings)}")
    assert not missing, missing
    assert sum(1 for _ in _options(build_parser())) > 60
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "training seeds (default: 0 1 2 3 4)" in text and "(default: runs/rl)" in text
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "The ``ffsr-gym`` command line" not in capsys.readouterr().out


def _docs() -> dict[Path, str]:
    paths = [ROOT / "README.md", ROOT / "leaderboards" / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    return {path: path.read_text(encoding="utf-8") for path in paths}


def test_docs_cite_nothing_that_does_not_ship():
    for path, text in _docs().items():
        assert "SPEC" not in text, f"{path} cites a document that does not ship"
        for module in re.findall(r"ffsr_gym/[\w/]+\.py", text):
            assert (ROOT / module).is_file(), f"{path} names {module}, which does not exist"


def test_submit_section_commands_parse():
    text = (ROOT / "leaderboards" / "README.md").read_text(encoding="utf-8")
    section = text.split("## Submit a result")[1].split("\n## ")[0]
    commands = {line.strip() for line in section.splitlines() if line.strip().startswith("ffsr-gym ")}
    commands |= set(re.findall(r"`(ffsr-gym [^`]+)`", section))
    assert "ffsr-gym leaderboard update --root leaderboards --readme README.md docs/baselines.md" in commands
    for command in commands:
        args = build_parser().parse_args([a if "<" not in a else "entry.json" for a in command.split()[1:]])
        assert callable(args.func), command


@pytest.mark.parametrize("env_id", ["FFSR-v2", "FFSR-Residual-v2"])
def test_the_v2_table_states_the_spaces(env_id):
    text = (ROOT / "docs" / "envs.md").read_text(encoding="utf-8")
    env = gym.make(env_id, task="easy")
    assert env.observation_space.shape == (53,) and "| 52 | elapsed-time fraction" in text
    assert env.action_space.shape == ((12,) if "Residual" in env_id else (2,))


def test_a_custom_entry_replays_from_what_it_stores(tmp_path):
    from ffsr_gym.bench.replay import replay_entry

    mine = tmp_path / "mine.toml"
    mine.write_text(scenario_path("free_space").read_text().replace('name = "free_space"', 'name = "mine"'))
    path = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task=str(mine), seeds=[0, 1], name="mine").save(tmp_path / "custom")
    mine.unlink()  # the entry alone is enough
    assert replay_entry(path).text == "all 2 rows reproduce exactly (the fixed parameters)"
    entry = json.loads(path.read_text())
    entry["extra"]["custom_task"]["scenario"]["target"]["position_m"][0] += 0.01
    path.write_text(json.dumps(entry))
    with pytest.raises(InvalidInputError, match="hash differs"):
        replay_entry(path)
