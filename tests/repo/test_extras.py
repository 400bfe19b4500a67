"""Each extra installs what the imports the docs attach to it need: a fresh venv per extra holds the package with that
extra alone, and imports every module the docs send its users to. Slow (a fresh install per extra, a few minutes
each); run with ``-m slow``."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: The modules (and third-party packages) the docs attach to each extra, imported in its venv alone.
DOCUMENTED = {
    "jax": ["ffsr_gym.jax.vector", "ffsr_gym.jax.pool_env", "ffsr_gym.jax.episode", "ffsr_gym.jax.gradient"],
    "brax": ["ffsr_gym.jax.brax_env", "brax.training.agents.ppo.train"],
    "analysis": ["ffsr_gym_lab.board.aggregates", "rliable.library"],
    "dataset": ["ffsr_gym_lab.publish.dataset", "minari"],
    "dask": ["ffsr_gym.cluster", "distributed"],
    "rl": ["ffsr_gym.optim.rl", "ffsr_gym.environments.sb3_vec_env", "stable_baselines3"],
}


@pytest.mark.slow
@pytest.mark.parametrize("extra", sorted(DOCUMENTED))
def test_an_extra_alone_holds_what_its_documented_imports_need(extra, tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    python = str(venv / "bin" / "python")
    if extra == "rl":  # the CPU build this machine has; never a CUDA one
        subprocess.run([python, "-m", "pip", "install", "-q", "torch==2.13.0"], check=True)
    subprocess.run([python, "-m", "pip", "install", "-q", "-e", f"{ROOT}[{extra}]"], check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    code = "import importlib\n" + "".join(f"importlib.import_module({name!r})\n" for name in DOCUMENTED[extra])
    done = subprocess.run([python, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True, check=False)
    assert done.returncode == 0, f"[{extra}]: {done.stderr[-2000:]}"
