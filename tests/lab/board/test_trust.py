"""What a leaderboard must not be fooled by: cut-short episodes, protocol-changing arguments, tampered entries.

Each test fails with its guard removed (checked once per guard when it was written).
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.exceptions import InvalidInputError

INDICES = [0, 1, 2, 3]


def zero_policy(_obs):
    return np.zeros(2, dtype=np.float32)


def test_a_cut_short_episode_never_outscores_the_full_one():
    full = ffsr_gym.evaluate(zero_policy, "FFSR-v2", task="easy", indices=INDICES)
    with pytest.raises(InvalidInputError, match="max_episode_steps.*protocol"):
        ffsr_gym.evaluate(zero_policy, "FFSR-v2", task="easy", indices=INDICES, env_kwargs={"max_episode_steps": 5})
    env = gym.make("FFSR-v2", task="easy", split="test", max_episode_steps=5)  # cut after 0.5 s
    rule = env.unwrapped.engine.rule
    for index, row in zip(INDICES, full.episodes):
        env.reset(seed=index, options={"task_index": index})
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(zero_policy(None))
            done = terminated or truncated
        cut = rule.result(env.unwrapped.trajectory, env.unwrapped.scenario)  # the one scoring path
        assert cut.failure == "incomplete" and not cut.success and cut.score == 0.0 < row["score"]



def _tampered_board(tmp_path):
    """A copy of the committed leaderboards with five bad entries added to v2/easy."""
    import json
    import shutil
    from pathlib import Path

    root = tmp_path / "leaderboards"
    shutil.copytree(Path(__file__).resolve().parents[3] / "leaderboards", root)
    easy, medium = root / "v2" / "easy", root / "v2" / "medium"
    good = json.loads((easy / "reference_v2_default.json").read_text())

    def bad(name: str, change) -> None:
        entry = json.loads(json.dumps(good))
        change(entry)
        (easy / f"{name}.json").write_text(json.dumps(entry))

    bad("edited_metric", lambda e: e["metrics"].update(score_iqm=0.95))
    bad("nan_metric", lambda e: e["metrics"].update(score_mean=float("nan")))
    bad("subset", lambda e: e.update(episodes=sorted(e["episodes"], key=lambda r: -r["score"])[:10]))
    bad("train_split", lambda e: e["extra"].update(evaluation_pool="easy/train"))
    bad("forged_name", lambda e: e.update(name="x |\n| 1 | `forged`"))
    shutil.copy(medium / "reference_best_constant.json", easy / "from_medium.json")
    (easy / "truncated.json").write_text(json.dumps(good)[:5000])
    return root


def test_a_tampered_leaderboard_refuses_every_bad_entry_by_name_and_check_fails(tmp_path):
    from ffsr_gym.cli.main import main
    from ffsr_gym.versions.registry import spec_for_version
    from ffsr_gym_lab.board import leaderboard

    root = _tampered_board(tmp_path)
    reasons = {name: " ".join(why) for _, name, why in leaderboard.refused(leaderboard.load_entries(root,
                                                                                          spec_for_version("v2")))}
    assert set(reasons) == {"edited_metric.json", "nan_metric.json", "subset.json", "train_split.json",
                            "forged_name.json", "from_medium.json", "truncated.json"}
    assert "metrics.score_iqm" in reasons["edited_metric.json"]
    assert "NaN is not a JSON number" in reasons["nan_metric.json"]  # refused as it is read, before its metrics
    assert "exactly once" in reasons["subset.json"] and "easy/test" in reasons["train_split.json"]
    assert "name" in reasons["forged_name.json"] and "evaluation_pool 'medium/test'" in reasons["from_medium.json"]
    assert "not a readable JSON file" in reasons["truncated.json"]
    leaderboard.write_readme(root)
    text = (root / "README.md").read_text()
    assert "`forged`" not in text and "x |" not in text  # the forged row never reaches the table
    for name in reasons:
        assert f"refused, not ranked: `{name}`" in text
    assert main(["leaderboard", "render", "--check", "--root", str(root)]) == 1


@pytest.mark.parametrize("argv", [
    ["tasks", "build", "--chunk", "0"], ["tasks", "build", "--chunk", "-5"], ["tasks", "build", "--workers", "0"],
    ["train", "--algo", "ppo", "--timesteps", "0"], ["train", "--algo", "ppo", "--timesteps", "-5"],
    ["train", "--algo", "ppo", "--curve-every", "0"], ["train", "--algo", "ppo", "--seeds", "-1"],
    ["render", "--speed", "nan"], ["render", "--every", "0"], ["evaluate", "--env-id", "FFSR-v2", "--policy", "0.3,4",
                                                              "--workers", "0"],
])
def test_bad_numbers_are_named_before_any_work(argv, capsys):
    import time

    from ffsr_gym.cli.main import main

    start = time.perf_counter()
    assert main(argv) == 2 and time.perf_counter() - start < 1.0
    option = argv[-2]  # the option under test
    assert f"argument {option}" in capsys.readouterr().err


def test_outputs_are_checked_before_the_run(tmp_path, capsys, monkeypatch):
    from ffsr_gym.cli.main import main

    monkeypatch.chdir(tmp_path)
    assert main(["train", "--algo", "ppo", "--seeds", "0", "0"]) == 2 and "more than once" in capsys.readouterr().err
    blocker = tmp_path / "board"
    blocker.write_text("a file")
    argv = ["evaluate", "--env-id", "FFSR-v2", "--policy", "0.3,4", "--task", "easy", "--no-progress"]
    assert main([*argv, "--leaderboard", str(blocker)]) == 2 and "is a file" in capsys.readouterr().err
    assert main([*argv, "--leaderboard", "lb", "--name", "twice"]) == 0
    assert main([*argv, "--leaderboard", "lb", "--name", "twice"]) == 2 and "--force" in capsys.readouterr().err
    assert main([*argv, "--leaderboard", "lb", "--name", "twice", "--force"]) == 0
    assert main(["render", "--out", "x.txt"]) == 2 and ".gif" in capsys.readouterr().err
    assert not (tmp_path / "x.txt").exists()


def test_fixed_parameters_outside_the_action_box_or_not_numbers_are_refused():
    for policy in ((0.9, 50.0), ("0.3", "4"), (0.3, float("nan"))):
        with pytest.raises(InvalidInputError, match="action box"):
            ffsr_gym.evaluate(policy, "FFSR-v2", task="easy")


def test_policies_from_files_and_untrusted_models(tmp_path, monkeypatch):
    from ffsr_gym.bench.policies import load_policy

    monkeypatch.chdir(tmp_path)
    (tmp_path / "zero_policy.py").write_text("import numpy as np\n\ndef policy(obs):\n    return np.zeros(2, 'float32')\n")
    assert load_policy("./zero_policy.py:policy", None)(None).shape == (2,)
    (tmp_path / "broken.py").write_text("raise RuntimeError('boom')\n")
    with pytest.raises(InvalidInputError, match="broken.py.*failed to import.*boom"):
        load_policy("broken.py:policy", None)
    (tmp_path / "corrupt.zip").write_bytes(b"not a zip")
    with pytest.raises(InvalidInputError, match="not a stable-baselines3"):
        load_policy("corrupt.zip", "ppo", trust=True)
    for untrusted in ("corrupt.zip", str(tmp_path.parent / f"{tmp_path.name}_elsewhere.zip")):
        Path(untrusted).write_bytes(b"whatever")
        with pytest.raises(InvalidInputError, match="--trust-model"):  # inside the working folder or not
            load_policy(untrusted, "ppo")


def test_bad_arguments_of_the_environments_are_named():
    env = gym.make("FFSR-v2", task="easy").unwrapped
    with pytest.raises(InvalidInputError, match="reset"):
        env.step(np.zeros(2, dtype=np.float32))
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match="m = 'abc'"):
        env.step_with_parameters("abc", 3.0)
    for task in (1, b"easy", 2.5):
        with pytest.raises(InvalidInputError, match="task"):
            gym.make("FFSR-v2", task=task)


def _pool_copy(tmp_path, change):
    import json
    from pathlib import Path

    data = json.loads((Path(ffsr_gym.__file__).resolve().parent.parent / "envs" / "benchmark" / "v2_tasks.json")
                      .read_text())
    change(data["splits"]["test"])
    path = tmp_path / f"{change.__name__}.json"  # load_pools caches per path
    path.write_text(json.dumps(data))
    return str(path)


def test_pool_files_are_checked_on_load(tmp_path):
    from ffsr_gym.exceptions import ScenarioError
    from ffsr_gym.tasks.splits import pool

    def duplicate(split):
        split["pools"]["easy"][1]["seed"] = split["pools"]["easy"][0]["seed"]

    def hard_in_easy(split):
        split["pools"]["easy"][0] = split["pools"]["hard"][0]

    def float_seed(split):
        split["pools"]["easy"][0]["seed"] = float(split["pools"]["easy"][0]["seed"])

    def three_tasks(split):
        split["pools"]["easy"] = split["pools"]["easy"][:3]

    for change, message in ((duplicate, "listed twice"), (hard_in_easy, "labelled 'h'"), (float_seed, "not an integer"),
                            (three_tasks, "3 tasks; the rule asks for 100")):
        with pytest.raises(ScenarioError, match=message):
            pool("easy", "test", path=_pool_copy(tmp_path, change))
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(ScenarioError, match="not a readable pool file"):
        pool("easy", "test", path=str(deep))


def test_a_build_resumed_with_another_chunk_is_refused(tmp_path):
    import json

    from ffsr_gym.exceptions import FFSRError
    from ffsr_gym_lab.pools.build import build_split

    chunk = tmp_path / "train" / "0000000.json"
    chunk.parent.mkdir(parents=True)
    chunk.write_text(json.dumps({"split": "train", "start": 0, "stop": 100, "rule_sha256": "x", "verdicts": []}))
    with pytest.raises(FFSRError, match="100 candidates each.*--chunk 50"):
        build_split(tmp_path, "train", version="v2", chunk=50, progress=False)


def test_a_corrupt_hyperparameter_file_is_named(tmp_path):
    pytest.importorskip("yaml")
    from ffsr_gym.optim.rl import load_hyperparams

    (tmp_path / "ppo.yml").write_text("FFSR-v2: [unclosed\n")
    with pytest.raises(InvalidInputError, match="ppo.yml: not a readable hyperparameter file"):
        load_hyperparams("ppo", "FFSR-v2", tmp_path)
    (tmp_path / "ppo.yml").write_text("- a list\n")
    with pytest.raises(InvalidInputError, match="ppo.yml: allowed: a mapping"):
        load_hyperparams("ppo", "FFSR-v2", tmp_path)


def test_verify_re_runs_what_an_entry_names(tmp_path, monkeypatch, capsys):
    import json

    from ffsr_gym.cli.main import main

    monkeypatch.chdir(tmp_path)
    from ffsr_gym.bench.planner_scores import evaluate_planner

    evaluate_planner("proportional", task="hard", gain_per_s=0.5, name="planner").save(tmp_path)
    assert main(["leaderboard", "verify", "planner.json"]) == 0 and "reproduce exactly" in capsys.readouterr().out
    entry = json.loads((tmp_path / "planner.json").read_text())
    entry["episodes"][3]["score"] = 0.5  # a hand-edited row
    (tmp_path / "edited.json").write_text(json.dumps(entry))
    assert main(["leaderboard", "verify", "edited.json"]) == 1 and "row 3 differs in ['score']" in capsys.readouterr().err
    (tmp_path / "zero.py").write_text("import numpy as np\n\ndef policy(obs):\n    return np.zeros(2, 'float32')\n")
    argv = ["evaluate", "--env-id", "FFSR-v2", "--task", "easy", "--no-progress", "--leaderboard", "lb"]
    assert main([*argv, "--policy", "zero.py:policy", "--name", "callable"]) == 0
    assert main([*argv, "--policy", "0.3,4", "--name", "fixed"]) == 0
    for name in ("callable", "fixed"):
        assert main(["leaderboard", "verify", f"lb/v2/easy/{name}.json"]) == 0


def test_a_training_pool_that_cannot_be_saved_is_refused_before_the_run():
    with pytest.raises(InvalidInputError, match="training_pool"):
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", training_pool=object())


def test_the_committed_leaderboards_pass_the_check():
    from pathlib import Path

    from ffsr_gym_lab.board import leaderboard

    root = Path(ffsr_gym.__file__).resolve().parent.parent
    assert leaderboard.check(root / "leaderboards", [root / "README.md", root / "docs" / "baselines.md"]) == []
