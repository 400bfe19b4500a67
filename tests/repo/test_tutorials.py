"""Every code block of the tutorials runs as written: each tutorial's Python and bash blocks, in order, as one
script in a fresh folder (bash lines through the shell, with this interpreter's ``ffsr-gym`` on the PATH)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.md"))
BLOCK = re.compile(r"^( *)```(\w*)\n(.*?)^\1```", flags=re.M | re.S)


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, code) of every fenced block, indentation removed."""
    return [(lang, textwrap.dedent(code)) for _, lang, code in BLOCK.findall(text)]


def script(text: str) -> str:
    """The tutorial as one Python script: its Python blocks as they are, each bash line run by the shell."""
    parts = ["import subprocess"]
    for lang, code in blocks(text):
        if lang == "python":
            parts.append(code)
        elif lang == "bash":
            parts += [f"subprocess.run({line.strip()!r}, shell=True, check=True)"
                      for line in code.splitlines() if line.strip() and not line.startswith("#")]
        else:
            raise AssertionError(f"a tutorial block in {lang or 'no language'}: only python and bash blocks run")
    return "\n".join(parts) + "\n"


def test_the_block_reader_finds_indented_blocks_and_refuses_other_languages():
    text = "1. step\n\n   ```python\n   x = 1\n   ```\n\n```bash\nffsr-gym --version\n```\n"
    assert blocks(text) == [("python", "x = 1\n"), ("bash", "ffsr-gym --version\n")]
    assert "subprocess.run('ffsr-gym --version'" in script(text)
    with pytest.raises(AssertionError, match="toml"):
        script("```toml\na = 1\n```\n")


def test_every_tutorial_is_a_page_of_the_site():
    index = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    assert TUTORIALS and all(f"tutorials/{path.stem}" in index for path in TUTORIALS)


#: Tutorials of half a minute or more: run with ``-m slow`` (the CI's 20 minutes keep the shorter ones).
LONG_TUTORIALS = {"evaluate", "robot", "sensitivity"}


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.stem in LONG_TUTORIALS else p
                                  for p in TUTORIALS], ids=lambda p: p.stem)
def test_the_tutorial_runs_as_written(path, tmp_path):
    code = script(path.read_text(encoding="utf-8"))
    (tmp_path / "tutorial.py").write_text(code)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "FFSR_GYM_QUIET_COMPILE": "1", "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, "tutorial.py"], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, f"{path.name} fails as written:\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"


def test_the_readmes_ten_lines_run(tmp_path):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    code = re.search(r"## Ten lines\n\n```python\n(.*?)```", text, flags=re.S).group(1)
    assert len(code.strip().splitlines()) <= 12
    (tmp_path / "readme.py").write_text(code)
    done = subprocess.run([sys.executable, "readme.py"], cwd=tmp_path, capture_output=True, text=True, timeout=900,
                          env={**os.environ, "FFSR_GYM_QUIET_COMPILE": "1"})
    assert done.returncode == 0, done.stderr[-3000:]
    score, success = done.stdout.split("\n")[0].split()
    assert 0.0 <= float(score) <= 1.0 and success in ("True", "False")
