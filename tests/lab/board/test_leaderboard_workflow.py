"""The pull-request workflow of the leaderboards, run as written: its `run:` steps (but the install) on a git copy
of the leaderboards where a pull request changed one entry. An honest change passes; a forged score fails."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

yaml = pytest.importorskip("yaml")
ROOT = Path(__file__).resolve().parents[3]
WORKFLOW = ROOT / ".github" / "workflows" / "leaderboard.yml"
ENTRY = Path("leaderboards") / "v2" / "easy" / "cmaes_v2.json"  # a planner entry: its replay takes seconds


def _steps() -> list[str]:
    """The workflow's shell steps after the install, in order."""
    steps = yaml.safe_load(WORKFLOW.read_text(encoding="utf-8"))["jobs"]["verify"]["steps"]
    runs = [step for step in steps if "run" in step]
    assert runs[0]["name"].startswith("install") and len(runs) == 3
    return [step["run"] for step in runs[1:]]


def _git(repo: Path, *args: str) -> None:
    identity = ["-c", "user.name=ci", "-c", "user.email=ci@localhost"]  # a fresh machine may have none
    subprocess.run(["git", "-C", str(repo), *identity, *args], check=True, capture_output=True)


@pytest.fixture()
def pull_request(tmp_path) -> Path:
    """A repository with the committed leaderboards as the base and one entry changed on top (a re-serialised
    file: the same content, as an honest resubmission writes it)."""
    repo = tmp_path / "repo"
    shutil.copytree(ROOT / "leaderboards", repo / "leaderboards")
    shutil.copy(ROOT / "README.md", repo / "README.md")
    (repo / "docs").mkdir()
    shutil.copy(ROOT / "docs" / "baselines.md", repo / "docs" / "baselines.md")
    _git(repo, "init", "-q", "-b", "main")
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "base")
    _git(repo, "tag", "base")
    path = repo / ENTRY
    path.write_text(json.dumps(json.loads(path.read_text(encoding="utf-8")), indent=1), encoding="utf-8")
    return repo


def _run(repo: Path, script: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, BASE="base", PATH=os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]]))
    return subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=repo, env=env, capture_output=True,
                          text=True)


def test_the_workflow_passes_an_honest_change_and_fails_a_forged_score(pull_request):
    verify, check = _steps()
    _git(pull_request, "stash")  # a pull request that changes no entry (a README fix): nothing to replay
    done = _run(pull_request, verify)
    assert done.returncode == 0 and done.stdout == "", done.stderr[-2000:]
    _git(pull_request, "stash", "pop")
    done = _run(pull_request, verify)
    assert done.returncode == 0 and f"{ENTRY}: reproduced" in done.stdout, done.stderr[-2000:]
    done = _run(pull_request, check)
    assert done.returncode == 0, done.stderr[-2000:]

    path = pull_request / ENTRY
    entry = json.loads(path.read_text(encoding="utf-8"))
    entry["episodes"][3]["score"] = min(1.0, entry["episodes"][3]["score"] + 0.01)  # a forged row
    path.write_text(json.dumps(entry), encoding="utf-8")
    done = _run(pull_request, verify)
    assert done.returncode != 0 and "differs" in done.stderr


def test_the_workflow_runs_for_every_pull_request():
    """A table changes through an entry, a page's generated block, the frozen reference, a pool or the code: the
    workflow has no path filter that a pull request could fall outside."""
    triggers = yaml.safe_load(WORKFLOW.read_text(encoding="utf-8"))
    pull_request = triggers.get("on", triggers.get(True))["pull_request"]  # YAML 1.1 reads the key `on` as true
    assert not (pull_request or {}).get("paths") and not (pull_request or {}).get("paths-ignore")


def _forge(path: Path, name: str | None = None) -> dict:
    """The entry at ``path`` with one row's score raised (and renamed, when ``name`` is given)."""
    entry = json.loads(path.read_text(encoding="utf-8"))
    entry["episodes"][3]["score"] = min(1.0, entry["episodes"][3]["score"] + 0.01)
    if name is not None:
        entry["name"] = name
    return entry


def test_a_forged_entry_named_like_a_generated_file_is_replayed_and_refused(pull_request):
    verify, _ = _steps()
    _git(pull_request, "stash")
    forged = pull_request / ENTRY.parent / "aggregates.json"  # a table reads it: the workflow must replay it
    forged.write_text(json.dumps(_forge(pull_request / ENTRY, "aggregates")), encoding="utf-8")
    _git(pull_request, "add", "-A")
    _git(pull_request, "commit", "-q", "-m", "forged")
    done = _run(pull_request, verify)
    assert done.returncode == 1 and "aggregates.json: differs" in done.stderr, done.stderr[-2000:]


def test_a_renamed_and_edited_entry_is_replayed_and_refused(pull_request):
    verify, _ = _steps()
    _git(pull_request, "stash")
    new = pull_request / ENTRY.parent / "cmaes_v2_again.json"
    _git(pull_request, "mv", str(pull_request / ENTRY), str(new))
    new.write_text(json.dumps(_forge(new, "cmaes_v2_again")), encoding="utf-8")
    _git(pull_request, "commit", "-q", "-a", "-m", "renamed and edited")
    done = _run(pull_request, verify)
    assert done.returncode == 1 and "cmaes_v2_again.json: differs" in done.stderr, done.stderr[-2000:]


def test_a_pull_request_that_edits_only_a_generated_block_fails_the_check(pull_request):
    _, check = _steps()
    _git(pull_request, "stash")
    readme = pull_request / "README.md"
    text = readme.read_text(encoding="utf-8")
    start = text.index("<!-- leaderboard-v2-top3:start")
    readme.write_text(text[:start] + text[start:].replace("0.", "0.9", 1), encoding="utf-8")
    done = _run(pull_request, check)
    assert done.returncode != 0, done.stdout[-2000:]
