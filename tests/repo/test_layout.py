"""The package layout: sub-packages in data-flow order, no import circle, physics free of Gymnasium.

Run alone with ``python -m pytest tests/repo/test_layout.py``; it reads every module's imports with
``ast`` (module level and inside functions) and also imports the physics stages in a fresh
interpreter in which gymnasium, matplotlib, stable-baselines3 and torch cannot be imported.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "ffsr_gym"
FOUNDATION = {"cluster", "exceptions", "types", "provenance", "user_files"}
#: The compiled extension, a module of the kernel stage (``from ffsr_gym import _native``).
EXTENSION = "ffsr_gym._native"
#: What each stage may import of the project (besides itself and the foundation modules).
ALLOWED = {
    "model": set(),
    "planning": {"model"},
    "kernel": {"model"},
    "sim": {"model", "planning", "kernel"},
    "scoring": {"model", "kernel", "sim"},  # kernel: the score's smoothness terms
    "versions": {"model"},  # the version policy: which versions exist, which is ranked
    "tasks": {"model", "versions", "planning", "sim", "scoring"},
    "environments": {"model", "versions", "planning", "kernel", "sim", "scoring", "tasks"},
    # kernel: its source digest
    "bench": {"model", "versions", "planning", "kernel", "sim", "scoring", "tasks", "environments"},
    "report": {"model", "versions", "planning", "sim", "scoring", "tasks"},  # tasks: the tier names the figures order
    "optim": {"model", "versions", "planning", "sim", "scoring", "tasks", "environments", "bench", "report"},
    "jax": {"model", "versions", "planning", "kernel", "sim", "scoring", "tasks", "environments"},  # the loop in JAX
    # the front door
    "cli": {"model", "versions", "planning", "sim", "scoring", "tasks", "environments", "bench", "report", "optim"},
}
#: The lab (``lab/ffsr_gym_lab``, a distribution of its own): the benchmark's maintenance (leaderboard storage,
#: rendering and aggregates, pool builds, best-known searches, studies, docs pages), which users do not import. It
#: may import any of the library; the library never imports it (docs/layout.md). Its stages, in data-flow order:
LAB_PACKAGE = PACKAGE.parent / "lab" / "ffsr_gym_lab"
LAB_ALLOWED = {
    "best_known": set(),
    "pools": {"best_known"},  # the frozen reference is written from the best-known file
    "studies": set(),
    "board": {"best_known", "pools"},  # the normalised column and the records set since the freeze
    "publish": {"best_known", "board"},
    "cli": {"best_known", "pools", "studies", "board", "publish"},
}
PHYSICS_STAGES = ("model", "planning", "kernel", "sim", "scoring", "versions", "tasks")
FORBIDDEN_IN_PHYSICS = ("gymnasium", "stable_baselines3", "matplotlib", "torch")


def module_name(path: Path, package: Path = PACKAGE) -> str:
    parts = path.relative_to(package.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py")) if "envs" not in p.relative_to(PACKAGE).parts}
LAB_MODULES = {module_name(p, LAB_PACKAGE): p for p in sorted(LAB_PACKAGE.rglob("*.py"))}


def imports_of(path: Path) -> set[str]:
    """Every module ``path`` imports (absolute names), at module level or inside functions."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}: relative import"
            members = {f"{node.module}.{alias.name}" for alias in node.names}
            if not members <= {EXTENSION}:  # the extension alone: not an import of the package's __init__
                names.add(node.module)
            names.update(member for member in members
                         if member in MODULES or member in LAB_MODULES or member == EXTENSION)
    return names


def project_imports(name: str) -> set[str]:
    """Project modules ``name`` imports, the lab's included (a ``from package import name`` counts as the module)."""
    out = set()
    for imported in imports_of(MODULES.get(name) or LAB_MODULES[name]):
        if (imported in MODULES or imported in LAB_MODULES or imported == EXTENSION) and imported != name:
            out.add(imported)
    return out


def stage_of(name: str) -> str:
    if name == EXTENSION:
        return "kernel"
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_every_module_belongs_to_a_stage():
    top_level = {name.split(".")[1] for name in MODULES if name.count(".") == 1 and not (PACKAGE / name.split(".")[1]).is_dir()}
    assert top_level == FOUNDATION
    assert {n.split(".")[1] for n in MODULES if n.count(".") >= 2} == set(ALLOWED)


def test_no_import_circle():
    graph = ({name: project_imports(name) - {"ffsr_gym", "ffsr_gym_lab"} for name in MODULES | LAB_MODULES}
             | {EXTENSION: set()})
    state: dict[str, int] = {}

    def visit(node: str, stack: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycle = stack[stack.index(nxt):] + [nxt] if nxt in stack else [node, nxt]
                pytest.fail(f"import circle: {' -> '.join(cycle)}")
            if nxt not in state:
                visit(nxt, [*stack, nxt])
        state[node] = 2

    for name in graph:
        if name not in state:
            visit(name, [name])


@pytest.mark.parametrize("stage", sorted(ALLOWED))
def test_stage_imports_only_earlier_stages(stage):
    allowed = ALLOWED[stage] | {stage}
    for name in (n for n in MODULES if stage_of(n) == stage):
        for imported in project_imports(name):
            other = stage_of(imported)
            assert other in allowed or imported.split(".")[1] in FOUNDATION, f"{name} imports {imported}"


def test_subpackage_inits_import_nothing():
    for name, path in MODULES.items():
        if path.name == "__init__.py" and name != "ffsr_gym":
            assert imports_of(path) == set(), f"{name} runs imports on package import"


@pytest.mark.parametrize("stage", PHYSICS_STAGES)
def test_physics_stages_name_no_gym_plotting_or_rl(stage):
    for name in (n for n in MODULES if stage_of(n) == stage):
        for imported in imports_of(MODULES[name]):
            assert imported.split(".")[0] not in FORBIDDEN_IN_PHYSICS, f"{name} imports {imported}"


BLOCKED_IMPORT = """
import importlib.abc, importlib.util, sys
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split(".")[0] in {forbidden!r}:
            raise ImportError(f"blocked: {{name}}")
sys.meta_path.insert(0, Block())
# the top-level package registers the envs with gymnasium: create it without running its __init__
spec = importlib.util.spec_from_file_location("ffsr_gym", {package!r} + "/__init__.py",
                                              submodule_search_locations=[{package!r}])
sys.modules["ffsr_gym"] = importlib.util.module_from_spec(spec)
import importlib
for name in {modules!r}:
    importlib.import_module(name)
import ffsr_gym.sim.simulate
traj = ffsr_gym.sim.simulate.simulate("free_space", backend="pinocchio", dt=0.1)
assert traj.q.shape[0] > 1
print("ok", len({modules!r}))
"""


def test_physics_stages_import_and_simulate_without_gym_plotting_or_rl():
    modules = sorted(n for n in MODULES if stage_of(n) in PHYSICS_STAGES)
    code = BLOCKED_IMPORT.format(forbidden=set(FORBIDDEN_IN_PHYSICS), package=str(PACKAGE), modules=modules)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.startswith("ok")


def test_the_layout_page_lists_every_module_of_every_sub_package():
    import re

    text = (PACKAGE.parent / "docs" / "layout.md").read_text(encoding="utf-8")
    listed = {m.group(1): set(re.findall(r"`(\w+)`", m.group(2)))
              for m in re.finditer(r"^\| `ffsr_gym\.(\w+)` \| ([^|]*) \|", text, flags=re.M)}
    for package in sorted(p for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()):
        modules = {path.stem for path in package.glob("*.py") if path.stem != "__init__"}
        if modules:
            assert listed.get(package.name) == modules, f"docs/layout.md: ffsr_gym.{package.name}"


def test_the_library_imports_no_lab_module():
    edges = {(name, imported) for name, path in MODULES.items() for imported in imports_of(path)
             if imported.split(".")[0] == "ffsr_gym_lab"}
    assert edges == set()


def test_the_library_names_the_lab_only_in_prose():
    """No string of the library names a lab module as code would (an ``importlib`` call, a mock target)."""
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and any(isinstance(arg, ast.Constant) and str(arg.value).startswith(
                    "ffsr_gym_lab") for arg in node.args):
                pytest.fail(f"{name} calls with a lab module's name")


def test_every_lab_module_belongs_to_a_stage():
    assert {n.split(".")[1] for n in LAB_MODULES if n.count(".") >= 1} == set(LAB_ALLOWED)
    assert all(n.count(".") <= 2 for n in LAB_MODULES)


@pytest.mark.parametrize("stage", sorted(LAB_ALLOWED))
def test_lab_stage_imports_only_earlier_lab_stages(stage):
    allowed = LAB_ALLOWED[stage] | {stage}
    for name, path in LAB_MODULES.items():
        if name.split(".")[1:2] != [stage]:
            continue
        for imported in imports_of(path):
            if imported.split(".")[0] == "ffsr_gym_lab" and imported != "ffsr_gym_lab":
                assert imported.split(".")[1] in allowed, f"{name} imports {imported}"
            elif imported.split(".")[0] == "ffsr_gym":
                assert imported in MODULES or imported == EXTENSION or imported.rsplit(".", 1)[0] in MODULES, (
                    f"{name} imports {imported}, which the library does not have")


def test_the_layout_page_lists_the_lab():
    import re

    text = (PACKAGE.parent / "docs" / "layout.md").read_text(encoding="utf-8")
    section = text[text.index("## Library and lab"):]
    section = section[:section.index("\n## ") if "\n## " in section else len(section)]
    listed = {m.group(1): set(re.findall(r"`(\w+)`", m.group(2)))
              for m in re.finditer(r"^\| `ffsr_gym_lab\.(\w+)` \| ([^|]*) \|", section, flags=re.M)}
    assert listed == {stage: {n.split(".")[2] for n in LAB_MODULES if n.count(".") == 2 and n.split(".")[1] == stage}
                      for stage in LAB_ALLOWED}
