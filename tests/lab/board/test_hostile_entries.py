"""An entry is data from a pull request: it runs no code, forges no table row and takes no other method's place.

One test per defect of the third hostile pass on entries (code execution, unpickled models,
Markdown injection, names not tied to files); each failed before its guard.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.bench.replay import replay_entry
from ffsr_gym.exceptions import InvalidInputError

ROOT = Path(__file__).resolve().parents[3]
INDICES = [0, 1]


def wobble(obs):
    """A policy that is code: its actions depend on what it sees (float64: the env applies them as float32)."""
    return 0.4 * np.sin(obs[:12].astype(np.float64) * 1.7)


@pytest.fixture(scope="module")
def code_entry(tmp_path_factory) -> dict:
    """A two-task residual entry of a callable policy, as ``evaluate`` records it."""
    report = ffsr_gym.evaluate(wobble, "FFSR-Residual-v2", task="easy", indices=INDICES, name="mine")
    return report.to_json()


def _write(folder: Path, entry: dict, name: str = "mine") -> Path:
    path = folder / f"{name}.json"
    path.write_text(json.dumps(entry))
    return path


def test_verify_replays_the_trace_and_never_imports_the_code_an_entry_names(tmp_path, code_entry, monkeypatch):
    monkeypatch.chdir(tmp_path)
    marker = tmp_path / "ran"
    (tmp_path / "evil.py").write_text(f"open({str(marker)!r}, 'w').write('x')\ndef act(obs):\n    return obs\n")
    for named in (str(tmp_path / "evil.py") + ":act", "evil.py:act", "os:getcwd"):
        entry = json.loads(json.dumps(code_entry))
        entry["extra"]["policy"] = {"callable": named}
        verdict = replay_entry(_write(tmp_path, entry))
        assert verdict.status == "reproduced" and "trace" in verdict.text
        del entry["extra"]["trace"]  # no trace: the code is named, and skipped
        verdict = replay_entry(_write(tmp_path, entry))
        assert verdict.status == "skipped" and f"--run-code {named!r}" in verdict.text and verdict.exit_code == 3
    assert not marker.exists()
    with pytest.raises(InvalidInputError, match="consent is given to exactly that text"):
        replay_entry(_write(tmp_path, entry), run_code="evil.py:act")


def test_a_model_an_entry_ships_is_never_unpickled_without_consent(tmp_path, code_entry, monkeypatch):
    import ffsr_gym.bench.policies as policies

    def refuse(*_args, **_kwargs):
        raise AssertionError("a model was loaded")

    monkeypatch.setattr(policies, "load_model", refuse)
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "leaderboards" / "v2" / "easy"
    folder.mkdir(parents=True)
    (folder / "model.zip").write_bytes(b"PK\x05\x06" + bytes(18))
    entry = json.loads(json.dumps(code_entry))
    entry["extra"]["policy"] = {"sb3": "leaderboards/v2/easy/model.zip", "algo": "ppo"}
    del entry["extra"]["trace"]
    assert replay_entry(_write(folder, entry)).status == "skipped"
    with pytest.raises(InvalidInputError, match="--trust-model"):  # inside the working folder too
        policies.load_policy("leaderboards/v2/easy/model.zip", "ppo")


def test_a_tampered_trace_is_caught(tmp_path, code_entry):
    from ffsr_gym.bench.trace import decode, encode

    entry = json.loads(json.dumps(code_entry))
    actions = decode(entry["extra"]["trace"]["episodes"][1], 12, where="test")
    assert actions.shape == (200, 12) and actions.dtype == np.float32
    nudged = actions.copy()
    nudged[50, 3] = np.nextafter(nudged[50, 3], np.float32(2.0))
    entry["extra"]["trace"]["episodes"][1] = encode(nudged)
    assert replay_entry(_write(tmp_path, entry)).status == "differs"
    entry["extra"]["trace"]["episodes"][1] = encode(actions[:150])  # a short trace
    assert replay_entry(_write(tmp_path, entry)).status == "differs"
    entry["extra"]["trace"]["episodes"][1] = encode(np.full((200, 12), 2.0, np.float32))
    with pytest.raises(InvalidInputError, match="outside"):
        replay_entry(_write(tmp_path, entry))


def _board(tmp_path: Path) -> Path:
    root = tmp_path / "lb"
    shutil.copytree(ROOT / "leaderboards", root)
    return root


def _summary_cell(root: Path, method: str) -> str:
    from ffsr_gym_lab.board import leaderboard

    text = leaderboard.splice_summary((ROOT / "docs" / "baselines.md").read_text(), root)
    return next(line for line in text.splitlines() if line.startswith(f"| `{method}` |"))


def test_free_text_cannot_forge_a_ranked_row(tmp_path):
    from ffsr_gym.versions.registry import spec_for_version
    from ffsr_gym_lab.board import leaderboard
    from ffsr_gym_lab.board.tables import safe

    root = _board(tmp_path)
    easy = root / "v2" / "easy"
    forged = "\n| 1 | `forged_winner` | 0.999 [0.999, 0.999] | 1.00 |"
    for field in ("training_pool", "commit"):
        entry = json.loads((easy / "cmaes_v2.json").read_text())
        if field == "commit":
            entry["provenance"]["git_commit"] = "abc" + forged
        else:
            entry["extra"]["training_pool"] = "easy/train" + forged
        entry["name"] = f"forge_{field}"
        _write(easy, entry, entry["name"])
    leaderboard.write_readme(root)
    text = (root / "README.md").read_text()
    assert not any(line.startswith("| 1 | `forged_winner`") for line in text.splitlines())
    reasons = {name: " ".join(why) for _, name, why in leaderboard.refused(leaderboard.load_entries(
        root, spec_for_version("v2")))}
    assert "line break" in reasons["forge_training_pool.json"] and "git_commit" in reasons["forge_commit.json"]
    assert leaderboard.check(root)  # not publishable
    assert safe("a|b\nc`d<!-- x -->\u2028e") == "a/b c'd&lt;!-- x --&gt; e"


def test_an_entry_is_named_after_its_file_and_one_method_has_one_row(tmp_path):
    from ffsr_gym.versions.registry import spec_for_version
    from ffsr_gym_lab.board import leaderboard

    root = _board(tmp_path)
    easy = root / "v2" / "easy"
    before = _summary_cell(root, "cmaes_residual")
    impostor = json.loads((easy / "random_residual.json").read_text())
    impostor["name"] = "cmaes_residual"
    _write(easy, impostor, "zzz")
    honest = json.loads((easy / "ppo_residual_easy.json").read_text())
    honest["name"] = "ppo_residual"  # an honest name that is also ppo_residual_easy's method name
    _write(easy, honest, "ppo_residual")
    reasons = {name: " ".join(why) for _, name, why in leaderboard.refused(leaderboard.load_entries(
        root, spec_for_version("v2")))}
    assert "not its file's name" in reasons["zzz.json"]
    assert "taken by another entry" in reasons["ppo_residual.json"] and "ppo_residual_easy.json" in reasons
    assert _summary_cell(root, "cmaes_residual") == before


@pytest.mark.parametrize("mutation, named", [
    (lambda e: e.__setitem__("extra", 5), "extra = '5'"),
    (lambda e: e["extra"].__setitem__("policy", {"fixed": 5}), "extra.policy.fixed"),
    (lambda e: e["env_kwargs"].pop("task"), "env_kwargs has no 'task'"),
    (lambda e: e["extra"].__setitem__("planner", {}), "extra.planner"),
    (lambda e: e.__setitem__("episodes", {"a": 1}), "episodes = "),
    (lambda e: e["env_kwargs"].__setitem__("max_episode_steps", 5), "env_kwargs \\['max_episode_steps'\\]"),
    (lambda e: e.__setitem__("episodes", e["episodes"] * 10_000), "repeat"),
    (lambda e: e.__setitem__("deep", None), "nested deeper than"),  # null becomes 100,000 nested arrays
])
def test_verify_names_what_is_wrong_with_a_malformed_entry(tmp_path, code_entry, mutation, named):
    entry = json.loads(json.dumps(code_entry))
    mutation(entry)
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(entry).replace('"deep": null', '"deep": ' + "[" * 100_000 + "]" * 100_000))
    with pytest.raises(InvalidInputError, match=named):
        replay_entry(path)


def test_verify_never_draws_and_files_that_are_not_regular_are_refused(tmp_path, code_entry, monkeypatch):
    import os

    from ffsr_gym.environments.env import FFSREnv
    from ffsr_gym_lab.board import leaderboard

    entry = json.loads(json.dumps(code_entry))
    entry["env_kwargs"]["render_mode"] = "human"
    monkeypatch.setattr(FFSREnv, "render", lambda self: pytest.fail("verify drew a frame"))
    assert replay_entry(_write(tmp_path, entry)).status == "reproduced"
    root = tmp_path / "lb"
    easy = root / "v2" / "easy"
    easy.mkdir(parents=True)
    os.mkfifo(easy / "fifo.json")
    (easy / "zero.json").symlink_to("/dev/zero")
    for name in ("fifo.json", "zero.json"):
        with pytest.raises(InvalidInputError, match="not a regular file"):
            replay_entry(easy / name)
    from ffsr_gym.versions.registry import spec_for_version

    reasons = {name: " ".join(why) for _, name, why in leaderboard.refused(leaderboard.load_entries(
        root, spec_for_version("v2")))}
    assert set(reasons) == {"fifo.json", "zero.json"} and all("not a regular file" in r for r in reasons.values())


def test_the_protocol_refuses_a_test_pool_to_train_on_an_overwrite_and_a_test_dataset(tmp_path):
    from ffsr_gym_lab.publish.dataset import write_dataset

    for pool in ("easy/test", "hard/test (all of it)", "nowhere/train", "easy/train\n"):
        with pytest.raises(InvalidInputError, match="training_pool"):
            ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", indices=[0], training_pool=pool)
    report = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", indices=[0], training_pool="medium/validation",
                               name="mine")
    path = report.save(tmp_path)
    with pytest.raises(InvalidInputError, match="exists: a previous result would be replaced"):
        report.save(tmp_path)
    assert report.save(tmp_path, overwrite=True) == path
    with pytest.raises(InvalidInputError, match="split 'test'"):
        write_dataset("easy", split="test", root=tmp_path)


def test_the_black_box_losses_refuse_what_evaluate_refuses():
    from ffsr_gym.bench.planner_scores import residual_training_loss, training_loss

    for m, T_c in ((0.33, 17.3), (0.0, 4.0), (0.3, float("nan"))):  # an unbounded CMA-ES found the first
        with pytest.raises(InvalidInputError, match="action box"):
            training_loss(m, T_c, tier="easy", tasks=1)
        with pytest.raises(InvalidInputError, match="action box"):
            ffsr_gym.evaluate((m, T_c), "FFSR-v2", task="easy", indices=[0])
    with pytest.raises(InvalidInputError, match="action box"):
        residual_training_loss([1.5] + [0.0] * 11, tier="easy", tasks=1)
    assert 0.0 <= training_loss(0.3, 4.0, tier="easy", tasks=1) <= 1.0


def test_a_file_policy_is_recorded_by_its_hash_and_verified_from_anywhere(tmp_path, monkeypatch, capsys):
    from ffsr_gym.cli.main import main

    maker = tmp_path / "maker"
    maker.mkdir()
    monkeypatch.chdir(maker)
    (maker / "mine.py").write_text("import numpy as np\n\ndef act(obs):\n    return 0.3 * np.sin(obs[:12])\n")
    assert main(["evaluate", "--env-id", "FFSR-Residual-v2", "--task", "easy", "--policy", "mine.py:act",
                 "--name", "mine", "--no-progress", "--leaderboard", "lb", "--training-pool", "easy/train"]) == 0
    entry = maker / "lb" / "v2" / "easy" / "mine.json"
    record = json.loads(entry.read_text())
    assert record["extra"]["policy"]["callable"] == "mine.py:act" and len(record["extra"]["policy"]["sha256"]) == 64
    assert record["provenance"]["policy"]["module"] == "mine"
    elsewhere = tmp_path / "reviewer"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["leaderboard", "verify", str(entry)]) == 0  # the trace: no code run
    assert main(["leaderboard", "verify", str(entry), "--run-code", f"{maker / 'mine.py'}:act"]) == 0
    (maker / "mine.py").write_text("import numpy as np\n\ndef act(obs):\n    return 0.2 * np.sin(obs[:12])\n")
    assert main(["leaderboard", "verify", str(entry), "--run-code", f"{maker / 'mine.py'}:act"]) == 2
    assert "consent is given to exactly that text, or to a path of the same file" in capsys.readouterr().err


def overshoot(obs):
    """A policy whose actions leave the box in the second quarter of the episode (the env clips and counts them);
    the observation's last entry is the elapsed fraction of the episode."""
    return (2.5 if 0.25 <= obs[-1] < 0.5 else 0.4) * np.sin(obs[:12].astype(np.float64) * 1.7)


def test_clipped_actions_are_counted_in_the_rows_verified_and_shown_in_the_table(tmp_path, code_entry):
    from ffsr_gym.bench.trace import decode
    from ffsr_gym_lab.board.tables import entry_cell

    entry = ffsr_gym.evaluate(overshoot, "FFSR-Residual-v2", task="easy", indices=INDICES, name="mine").to_json()
    trace = entry["extra"]["trace"]
    for k, row in enumerate(entry["episodes"]):
        # independent count: replay the stored actions' policy output by hand (the raw actions the env saw)
        env = gym.make("FFSR-Residual-v2", task="easy", split="test")
        obs, _ = env.reset(seed=row["seed"], options={"task_index": row["task_index"]})
        raw_out, done = 0, False
        while not done:
            action = overshoot(obs)
            raw_out += int(np.any(np.abs(action) > 1.0))
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        assert row["clipped_actions"] == raw_out == info["clipped_actions"] == len(trace["clipped"][k]) > 0
        actions = decode(trace["episodes"][k], 12, where="test")
        assert np.all(np.max(np.abs(actions[trace["clipped"][k]]), axis=1) == 1.0)
    assert replay_entry(_write(tmp_path, entry)).status == "reproduced"
    total = sum(row["clipped_actions"] for row in entry["episodes"])
    assert entry_cell(entry) == f"`mine` ({total:,} clipped actions)"
    assert entry_cell(code_entry) == "`mine`" and all(row["clipped_actions"] == 0 for row in code_entry["episodes"])
    forged = json.loads(json.dumps(entry))
    forged["episodes"][0]["clipped_actions"] = 0  # hiding the clipping from the table
    assert replay_entry(_write(tmp_path, forged)).status == "differs"
    forged = json.loads(json.dumps(entry))
    inside = np.flatnonzero(np.max(np.abs(decode(trace["episodes"][0], 12, where="test")), axis=1) < 1.0)
    forged["extra"]["trace"]["clipped"][0] = [int(i) for i in inside[:3]]  # decisions whose actions lie in the box
    with pytest.raises(InvalidInputError, match="boundary"):
        replay_entry(_write(tmp_path, forged))
    del forged["extra"]["trace"]["clipped"]
    assert replay_entry(_write(tmp_path, forged)).status == "differs"


@pytest.mark.slow  # half a minute or more: with -m slow (CI stays under 20 minutes)
def test_a_stamp_describes_the_rows_it_verified_and_the_table_shows_it(tmp_path):
    from ffsr_gym.cli.main import main
    from ffsr_gym.versions.registry import ranked_spec
    from ffsr_gym_lab.board import leaderboard

    root = tmp_path / "leaderboards"
    shutil.copytree(ROOT / "leaderboards", root)
    path = root / "v2" / "hard" / "cmaes_residual.json"
    assert main(["leaderboard", "verify", str(path), "--stamp"]) == 0
    stamp = json.loads(path.read_text())["extra"]["verified"]
    assert stamp["status"] == "reproduced" and stamp["verifier"].startswith("ffsr-gym ")
    assert stamp["pool_file_sha256"] == json.loads(path.read_text())["extra"]["pool_file_sha256"]
    assert leaderboard.refused(leaderboard.load_entries(root, ranked_spec())) == []
    leaderboard.write_readme(root)
    row = next(line for line in (root / "README.md").read_text().splitlines() if "| `cmaes_residual` |" in line
               and "hard/train" in line)
    assert "verified " in row.split("|")[-2]
    entry = json.loads(path.read_text())
    entry["episodes"][0]["min_clearance_m"] += 1e-3  # a row edited after verification: the stamp no longer holds
    path.write_text(json.dumps(entry))
    reasons = [r for _, name, rs in leaderboard.refused(leaderboard.load_entries(root, ranked_spec())) for r in rs
               if name == "cmaes_residual.json"]
    assert "extra.verified: the rows changed after they were verified (rows_sha256 differs)" in reasons
    entry["extra"]["verified"] = {"status": "reproduced"}  # a typed stamp
    path.write_text(json.dumps(entry))
    reasons = [r for _, name, rs in leaderboard.refused(leaderboard.load_entries(root, ranked_spec())) for r in rs
               if name == "cmaes_residual.json"]
    assert any(r.startswith("extra.verified: allowed a stamp with exactly the keys") for r in reasons)
