"""The docs site builds with Sphinx, warnings as errors, and its API reference covers the package's public names."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import ffsr_gym

ROOT = Path(__file__).resolve().parents[1]
pytest.importorskip("sphinx")
pytest.importorskip("myst_parser")


def test_the_docs_build_without_a_warning_and_document_every_public_name(tmp_path):
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", str(ROOT / "docs"), str(tmp_path)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    pages = "".join(path.read_text(encoding="utf-8") for path in (tmp_path / "api").glob("*.html"))
    missing = [name for name in ffsr_gym.__all__ if f'id="ffsr_gym.{name}"' not in pages]
    assert not missing, f"public names without an API entry: {missing}"
    assert 'id="ffsr_gym.environments.vector_env.FFSRVectorEnv"' in pages
