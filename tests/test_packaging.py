"""The robot and scenario files ship inside the wheel and are found through importlib.resources."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

from ffsr_gym.model.resources import envs_dir

ROOT = Path(__file__).resolve().parent.parent


def test_wheel_contains_robot_and_scenarios(tmp_path):
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp_path)],
        check=True,
    )
    (wheel,) = tmp_path.glob("ffsr_gym-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    shipped = {str(p.relative_to(ROOT)) for p in (ROOT / "envs").rglob("*") if p.is_file()}
    assert shipped, "envs/ is empty"
    for path in shipped:
        assert f"ffsr_gym/{path}" in names, f"{path} missing from {wheel.name}"


def test_resources_resolve_to_existing_files():
    assert (envs_dir() / "robots" / "ffsr_dual_arm" / "ffsr_dual_arm.urdf").is_file()
    assert (envs_dir() / "scenarios" / "paper.toml").is_file()
