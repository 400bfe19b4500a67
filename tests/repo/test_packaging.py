"""The robot and scenario files ship inside the wheel and are found through importlib.resources."""

from __future__ import annotations

import fnmatch
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from ffsr_gym.model.resources import envs_dir
from ffsr_gym.provenance import LAB_DATA

ROOT = Path(__file__).resolve().parents[2]


def test_wheel_contains_robot_and_scenarios(tmp_path):
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp_path)],
        check=True,
    )
    (wheel,) = tmp_path.glob("ffsr_gym-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    files = {str(p.relative_to(ROOT)) for p in (ROOT / "envs").rglob("*") if p.is_file()}
    lab = {path for path in files if fnmatch.fnmatch(Path(path).name, LAB_DATA)}
    assert files and lab, "envs/ is empty, or holds no best-known file"
    for path in files - lab:
        assert f"ffsr_gym/{path}" in names, f"{path} missing from {wheel.name}"
    assert not {f"ffsr_gym/{path}" for path in lab} & names, "the lab's best-known files are in the library's wheel"
    assert not [n for n in names if n.startswith("ffsr_gym_lab")], "the lab's modules are in the library's wheel"


def test_resources_resolve_to_existing_files():
    assert (envs_dir() / "robots" / "ffsr_dual_arm" / "ffsr_dual_arm.urdf").is_file()
    assert (envs_dir() / "scenarios" / "paper.toml").is_file()


@pytest.mark.slow
def test_the_wheel_alone_runs_the_main_job_evaluate_and_train(tmp_path):
    """The built wheel in a fresh venv, used from a folder outside the repository: everything it needs ships in it,
    and the lab's commands are not there. Slow (a fresh install, and the kernel compiles in it: about 15 min on 2
    cores)."""
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(tmp_path / "dist")], check=True)
    (wheel,) = (tmp_path / "dist").glob("ffsr_gym-*.whl")
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip, bin_ = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q"], venv / "bin"
    subprocess.run([*pip, "torch==2.13.0"], check=True)  # the CPU build this machine has; never a CUDA one
    subprocess.run([*pip, f"{wheel}[rl]"], check=True)
    work = tmp_path / "outside"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}

    def run(*args: str) -> str:
        done = subprocess.run([str(a) for a in args], cwd=work, env=env, capture_output=True, text=True)
        assert done.returncode == 0, f"{args}: {done.stderr[-2000:]}"
        return done.stdout

    assert str(venv) in run(bin_ / "python", "-c", "import ffsr_gym; print(ffsr_gym.__file__)")  # the wheel's copy
    run(bin_ / "ffsr-gym", "reproduce", "--out", "runs/paper", "--duration", "2", "--no-progress")
    assert (work / "runs" / "paper" / "reproduction.md").is_file()
    out = run(bin_ / "python", "-c", "import ffsr_gym; r = ffsr_gym.evaluate((0.3, 4.0), 'FFSR-v2', task='easy'); "
                                     "print(r.metrics['episodes'], ffsr_gym.__version__)")
    assert out.split()[0] == "100"
    run(bin_ / "ffsr-gym", "train", "--algo", "ppo", "--env-id", "FFSR-v2", "--task", "easy", "--seeds", "0",
        "--timesteps", "256", "--curve-every", "128", "--out", "runs/rl", "--no-progress")
    assert "{list,info,reproduce,ga,evaluate,render,train,leaderboard}" in run(bin_ / "ffsr-gym", "--help")
    listed = run(bin_ / "python", "-m", "pip", "list")
    assert "nvidia" not in listed.lower()


def test_the_citation_file_names_the_software_and_the_paper():
    yaml = pytest.importorskip("yaml")
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software" and cff["authors"]
    assert "version" not in cff  # one source of the version: pyproject.toml
    (paper,) = cff["references"]
    assert paper["title"] == "Optimal Predefined-time Trajectory Planning for a Space Robot"
    assert [a["family-names"] for a in paper["authors"]] == ["Yan", "Liu"]
