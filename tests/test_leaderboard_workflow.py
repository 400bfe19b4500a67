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
ROOT = Path(__file__).resolve().parents[1]
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
