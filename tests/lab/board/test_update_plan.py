"""What ``leaderboard update`` replays: an entry changed since its stamp (entry, rows, pool, reference, code) is
replayed, with the reason; a stamped, unchanged one is skipped; ``--full`` replays all. Built on a shipped stamped
entry, whose stamp is checked for real (its hashes against the entry and the shipped files)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from ffsr_gym.bench import stamp as stamp_module
from ffsr_gym.bench.stamp import entry_digest, rows_digest
from ffsr_gym_lab.board import update_plan

ROOT = Path(__file__).resolve().parents[3]
SHIPPED = ROOT / "leaderboards" / "v2" / "easy" / "reference_v2_default.json"
DIGEST = "ab" * 32


def _board(tmp_path: Path, *, code: str | None = DIGEST) -> Path:
    """A board with the shipped entry, its stamp bound to the code digest ``code`` (None: a stamp without one)."""
    board = tmp_path / "leaderboards"
    (board / "v2" / "easy").mkdir(parents=True)
    entry = json.loads(SHIPPED.read_text())
    stamp = entry["extra"]["verified"]
    assert stamp["entry_sha256"] == entry_digest(entry) and stamp["rows_sha256"] == rows_digest(entry["episodes"])
    stamp.pop("code_sha256", None)
    if code is not None:
        stamp["code_sha256"] = code
    (board / "v2" / "easy" / SHIPPED.name).write_text(json.dumps(entry))
    shutil.copytree(ROOT / "leaderboards" / "FFSR-v0", board / "FFSR-v0")
    return board


def _only(steps, name: str):
    [step] = [s for s in steps if s.path.name == name]
    return step


@pytest.fixture
def same_code(monkeypatch):
    monkeypatch.setattr(update_plan, "code_digest", lambda version=None: DIGEST)


def test_a_stamped_unchanged_entry_is_skipped_and_full_replays_it(tmp_path, same_code):
    board = _board(tmp_path)
    step = _only(update_plan.plan(board), SHIPPED.name)
    assert not step.replay and "unchanged since" in step.reason
    assert all(s.replay for s in update_plan.plan(board, full=True))
    frozen = [s for s in update_plan.plan(board) if s.path.parent.name == "FFSR-v0"]
    assert len(frozen) == 7 and all(s.replay and "frozen" in s.reason and "git cannot tell" in s.reason for s in frozen)


def test_a_change_of_code_entry_or_rows_since_the_stamp_is_replayed(tmp_path, same_code, monkeypatch):
    board = _board(tmp_path)
    path = board / "v2" / "easy" / SHIPPED.name
    monkeypatch.setattr(update_plan, "code_digest", lambda version=None: "cd" * 32)
    assert "code_sha256 differs" in _only(update_plan.plan(board), SHIPPED.name).reason
    monkeypatch.setattr(update_plan, "code_digest", lambda version=None: DIGEST)
    entry = json.loads(path.read_text())
    entry["episodes"][0]["score"] += 1e-9
    path.write_text(json.dumps(entry))
    step = _only(update_plan.plan(board), SHIPPED.name)
    assert step.replay and "no longer describes it" in step.reason and "changed after it was verified" in step.reason
    del entry["extra"]["verified"]
    path.write_text(json.dumps(entry))
    assert "no stamp" in _only(update_plan.plan(board), SHIPPED.name).reason


def test_a_stamp_without_the_codes_digest_is_replayed(tmp_path, same_code):
    step = _only(update_plan.plan(_board(tmp_path, code=None)), SHIPPED.name)
    assert step.replay and "predates the code's digest" in step.reason


def test_an_unreadable_file_in_a_table_folder_is_replayed_not_skipped(tmp_path, same_code):
    board = _board(tmp_path)
    (board / "v2" / "easy" / "broken.json").write_text("[1, 2]")
    (board / "v2" / "easy" / "torn.json").write_text('{"name": ')
    steps = update_plan.plan(board)
    assert _only(steps, "broken.json").replay and "not a JSON object" in _only(steps, "broken.json").reason
    assert _only(steps, "torn.json").replay


def test_the_code_digest_follows_the_replayed_files_only(tmp_path, monkeypatch):
    """The digest changes with a replayed module's bytes and not with a module outside them (the CLI)."""
    package = tmp_path / "ffsr_gym"
    for name in ("kernel/loop.py", "bench/replay.py", "cli/main.py", "kernel/__pycache__/loop.nbi"):
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(name)
    (tmp_path / "envs").mkdir()
    (tmp_path / "envs" / "rule.toml").write_text("a = 1")
    monkeypatch.setattr(stamp_module, "__file__", str(package / "bench" / "stamp.py"))
    monkeypatch.setattr("ffsr_gym.model.resources.envs_dir", lambda: tmp_path / "envs")

    def digest() -> str:
        stamp_module.code_digest.cache_clear()
        return stamp_module.code_digest()

    first = digest()
    (package / "cli" / "main.py").write_text("changed")
    (package / "kernel" / "__pycache__" / "loop.nbi").write_text("a new cache")
    assert digest() == first
    (package / "kernel" / "loop.py").write_text("changed")
    second = digest()
    assert second != first
    (tmp_path / "envs" / "rule.toml").write_text("a = 2")
    third = digest()
    assert third not in (first, second)
    (tmp_path / "envs" / "v2_best_known.json").write_text("{}")  # the lab's: no replay reads it
    assert digest() == third
    stamp_module.code_digest.cache_clear()


def test_a_versions_code_digest_leaves_out_the_other_versions_benchmark_files(tmp_path, monkeypatch):
    """Adding or changing another version's rule, spec, pool or reference file leaves a version's digest (and the
    stamps of its entries) standing; its own files, and the data every version reads, change it."""
    package = tmp_path / "ffsr_gym"
    (package / "bench").mkdir(parents=True)
    (package / "bench" / "replay.py").write_text("replay")
    benchmark = tmp_path / "envs" / "benchmark"
    benchmark.mkdir(parents=True)
    (tmp_path / "envs" / "robots").mkdir()
    (tmp_path / "envs" / "robots" / "drives.toml").write_text("a = 1")
    for name in ("v2.toml", "spec_v2.toml", "v2_tasks.json", "capture-v1.toml", "capture-v1_sweep_tasks.json"):
        (benchmark / name).write_text(name)
    monkeypatch.setattr(stamp_module, "__file__", str(package / "bench" / "stamp.py"))
    monkeypatch.setattr("ffsr_gym.model.resources.envs_dir", lambda: tmp_path / "envs")

    def digests() -> dict:
        stamp_module.code_digest.cache_clear()
        return {version: stamp_module.code_digest(version) for version in ("v2", "capture-v1", "capture-v2", None)}

    first = digests()
    assert len(set(first.values())) == 4
    (benchmark / "capture-v2_sweep_tasks.json").write_text("a new version's pool")  # not v2's, not capture-v1's
    (benchmark / "spec_capture-v2.toml").write_text("a new version's spec")
    second = digests()
    assert second["v2"] == first["v2"] and second["capture-v1"] == first["capture-v1"]
    assert second["capture-v2"] != first["capture-v2"] and second[None] != first[None]
    (benchmark / "v2_tasks.json").write_text("v2's pool changed")
    third = digests()
    assert third["v2"] != second["v2"] and third["capture-v1"] == second["capture-v1"]
    (tmp_path / "envs" / "robots" / "drives.toml").write_text("a = 2")  # every version's data
    fourth = digests()
    assert all(fourth[v] != third[v] for v in fourth)
    assert stamp_module.version_of_file("capture-v2_sweep_tasks.json", ("v2", "capture-v2")) == "capture-v2"
    assert stamp_module.version_of_file("v2_perturbed.toml", ("v2", "capture-v2")) == "v2"
    assert stamp_module.version_of_file("drives.toml", ("v2", "capture-v2")) is None
    stamp_module.code_digest.cache_clear()


def test_an_unstamped_entry_is_replayed_when_git_reports_it_changed(tmp_path, same_code):
    """In a repository: an unstamped entry the last commit holds as it is is skipped (the pull-request workflow
    replayed it when it changed); one edited or added since is replayed; without git, every unstamped one is."""
    import subprocess

    board = _board(tmp_path)
    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), *args], check=True, capture_output=True)
    git("init", "-q")
    git("-c", "user.name=t", "-c", "user.email=t@t", "add", "-A")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "board")
    steps = update_plan.plan(board)
    kept = _only(steps, "cmaes.json")
    assert not kept.replay and "unchanged since the last commit" in kept.reason
    (board / "FFSR-v0" / "cmaes.json").write_text((board / "FFSR-v0" / "cmaes.json").read_text() + "\n")
    shutil.copy(board / "FFSR-v0" / "ga_full.json", board / "FFSR-v0" / "mine.json")
    steps = update_plan.plan(board)
    for name in ("cmaes.json", "mine.json"):
        assert _only(steps, name).replay and "changed since the last commit" in _only(steps, name).reason
    assert not _only(steps, "ga_full.json").replay
    shutil.rmtree(tmp_path / ".git")
    assert all(s.replay for s in update_plan.plan(board) if s.path.parent.name == "FFSR-v0")
