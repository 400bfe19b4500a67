"""The docs site builds with Sphinx, warnings as errors, and its API reference covers the package's public names."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import ffsr_gym

ROOT = Path(__file__).resolve().parents[2]
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


def test_the_generated_pages_and_the_readme_table_of_ids_are_up_to_date(capsys):
    from ffsr_gym.cli.main import main

    code = main(["docs", "pages", "--docs", str(ROOT / "docs"), "--root", str(ROOT / "leaderboards"),
                 "--readme", str(ROOT / "README.md"), "--check"])
    assert code == 0, capsys.readouterr().err
    pages = {path.stem for path in (ROOT / "docs" / "ids").glob("*.md")} | {
        path.stem for path in (ROOT / "docs" / "tiers").glob("*.md")}
    assert {"FFSR-v2", "FFSR-Residual-v2", "easy", "servo"} <= pages
    gifs = {path.stem for path in (ROOT / "docs" / "_static" / "tiers").glob("*.gif")}
    assert gifs == {path.stem for path in (ROOT / "docs" / "tiers").glob("*.md")}, "run: ffsr-gym docs pages --gifs"


def test_an_id_page_states_the_spaces_of_the_live_env():
    import gymnasium as gym

    text = (ROOT / "docs" / "ids" / "FFSR-Residual-v2.md").read_text(encoding="utf-8")
    env = gym.make("FFSR-Residual-v2", task="easy")
    assert f"| action space | `Box{env.action_space.shape}, float32, [-1, 1]` |" in text
    low = env.observation_space.low
    assert f"[{low[0]:g}, 1] x 24" in text and f"[{low[24]:g}, 20] x 12" in text
    assert "`terminate_on_violation`" in text and "`dt_s`" in text


def test_the_readme_is_short_and_links_only_to_files_that_exist():
    import re

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text):
        assert (ROOT / target).exists(), f"README links to {target}, which does not exist"


def test_the_changelog_keeps_a_changelog():
    import re
    from importlib.metadata import version

    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    releases = re.findall(r"^## \[([^\]]+)\](?: - (\d{4}-\d{2}-\d{2}))?$", text, flags=re.M)
    assert releases[0] == ("Unreleased", "") and all(date for _, date in releases[1:])
    assert version("ffsr-gym") in [name for name, _ in releases], "the installed version has no section"
    headings = re.findall(r"^(#+) (.*)$", text, flags=re.M)
    allowed = {"Added", "Changed", "Deprecated", "Removed", "Fixed", "Security"}
    assert all(title in allowed for level, title in headings if level == "###"), "a category Keep a Changelog lacks"
    assert [level for level, _ in headings].count("#") == 1


def test_a_later_version_with_a_tier_name_already_paged_gets_pages_of_its_own(monkeypatch):
    """Capture v2's tiers are named as capture v1's: when both are live, v1 keeps ``tiers/sweep.md`` and v2's pages
    and GIFs are ``capture-v2-sweep``, and v2's id page links to them."""
    import dataclasses

    from ffsr_gym.versions.registry import spec_for_version
    from ffsr_gym_lab.publish import doc_pages

    v1, v2 = spec_for_version("capture-v1"), dataclasses.replace(spec_for_version("capture-v2"), status="live")
    monkeypatch.setattr(doc_pages, "ranked_specs", lambda: [v1, v2])
    keys = {key: (spec.version, tier) for key, (spec, tier) in doc_pages.tier_keys().items()}
    assert keys == {"sweep": ("capture-v1", "sweep"), "nutation": ("capture-v1", "nutation"),
                    "capture-v2-sweep": ("capture-v2", "sweep"), "capture-v2-nutation": ("capture-v2", "nutation")}
    assert set(keys) <= set(doc_pages.TIER_MEANING)
    assert doc_pages.tier_key(v2, "nutation") == "capture-v2-nutation" and doc_pages.tier_key(v1, "sweep") == "sweep"
    assert "(../tiers/capture-v2-sweep.md)" in doc_pages._tasks_text(v2)
    pages = {path.name for path in doc_pages.page_paths(ROOT / "docs") if path.parent.name == "tiers"}
    assert pages == {f"{key}.md" for key in keys}
