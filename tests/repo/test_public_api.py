"""Every name the docs import, call or point to is public: it resolves, and the API reference documents it.

The code blocks of README.md and docs/ (``python`` fences, doctest prompts stripped) are parsed with ``ast``;
every ``ffsr_gym`` name they import (``import ffsr_gym.x``, ``from ffsr_gym.x import y``) or reach as an attribute
(``ffsr_gym.evaluate``) must import, and the API reference (an ``.. auto*::`` directive of the docs) must name it,
or its module with ``automodule``. The prose's dotted paths (``ffsr_gym.planning.ptsf``, ...) are held to the same
rule, or to their owner (a class's method, a module's member) being documented; the module map (docs/layout.md)
and the changelog name modules as history and layout, not as places to read, and are left out.
"""

from __future__ import annotations

import ast
import importlib
import re
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
BLOCK = re.compile(r"^([ \t]*)```(?:python|py|pycon)[ \t]*\n(.*?)^\1```", re.S | re.M)
DIRECTIVE = re.compile(r"\.\. auto(function|class|exception|module|data|method)::\s+(\S+)")


def _code_names() -> dict[str, set[str]]:
    names: dict[str, set[str]] = {}
    for page in PAGES:
        for _, code in BLOCK.findall(page.read_text(encoding="utf-8")):
            lines = textwrap.dedent(code).splitlines()
            tree = ast.parse("\n".join(line[4:] if line.startswith((">>> ", "... ")) else line for line in lines))
            for node in ast.walk(tree):
                found: list[str] = []
                if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "ffsr_gym":
                    found = [f"{node.module}.{alias.name}" for alias in node.names]
                elif isinstance(node, ast.Import):
                    found = [alias.name for alias in node.names if alias.name.split(".")[0] == "ffsr_gym"]
                elif isinstance(node, ast.Attribute):
                    parts, value = [], node
                    while isinstance(value, ast.Attribute):
                        parts.append(value.attr)
                        value = value.value
                    if isinstance(value, ast.Name) and value.id == "ffsr_gym":
                        found = ["ffsr_gym." + ".".join(reversed(parts))]
                for name in found:
                    names.setdefault(name, set()).add(str(page.relative_to(ROOT)))
    return names


NAMES = _code_names()
PROSE_PAGES = [page for page in PAGES if page.name not in ("layout.md", "changelog.md")]
DOTTED = re.compile(r"\bffsr_gym(?:\.[A-Za-z_][A-Za-z0-9_]*)+")


def _prose_names() -> dict[str, set[str]]:
    names: dict[str, set[str]] = {}
    for page in PROSE_PAGES:
        for name in DOTTED.findall(BLOCK.sub("", page.read_text(encoding="utf-8"))):
            names.setdefault(name, set()).add(str(page.relative_to(ROOT)))
    return names


PROSE = _prose_names()
DOCUMENTED = {(kind, target) for page in PAGES for kind, target in DIRECTIVE.findall(page.read_text(encoding="utf-8"))}


def _resolve(name: str):
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(name)


def test_the_docs_code_uses_some_names():
    assert {"ffsr_gym.evaluate", "ffsr_gym.simulate"} <= set(NAMES)


@pytest.mark.parametrize("name", sorted(n for n in NAMES if n != "ffsr_gym"))
def test_a_name_the_docs_code_uses_resolves_and_is_documented(name):
    if name.startswith("ffsr_gym.jax."):
        pytest.importorskip("jax")
    _resolve(name)
    targets = {target for _, target in DOCUMENTED}
    modules = {target for kind, target in DOCUMENTED if kind == "module"}
    owner = name.rsplit(".", 1)[0]
    assert name in targets or name in modules or owner in modules, (
        f"{name} (used by {sorted(NAMES[name])}) is in no '.. auto*::' directive of the API reference")


def test_the_docs_prose_points_to_modules():
    assert {"ffsr_gym.planning.ptsf", "ffsr_gym.tasks.splits.SEED_RANGES"} <= set(PROSE)


@pytest.mark.parametrize("name", sorted(PROSE))
def test_a_path_the_docs_prose_names_resolves_and_is_documented(name):
    if name.startswith("ffsr_gym.jax"):
        pytest.importorskip("jax")
    _resolve(name)
    targets = {target for _, target in DOCUMENTED}
    assert name in targets or name.rsplit(".", 1)[0] in targets, (
        f"{name} (named by {sorted(PROSE[name])}) is in no '.. auto*::' directive of the API reference, nor is its owner")
