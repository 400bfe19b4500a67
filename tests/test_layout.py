"""The package layout: sub-packages in data-flow order, no import circle, physics free of Gymnasium.

Run alone with ``python -m pytest tests/test_layout.py``; it reads every module's imports with
``ast`` (module level and inside functions) and also imports the physics stages in a fresh
interpreter in which gymnasium, matplotlib, stable-baselines3 and torch cannot be imported.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "ffsr_gym"
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
    "tasks": {"model", "planning", "sim", "scoring"},
    "environments": {"model", "planning", "kernel", "sim", "scoring", "tasks"},
    "bench": {"model", "planning", "kernel", "sim", "scoring", "tasks", "environments"},  # kernel: its source digest
    "report": {"model", "planning", "sim", "scoring", "tasks"},  # tasks: the tier names the figures order
    "optim": {"model", "planning", "sim", "scoring", "tasks", "environments", "bench", "report"},
    "jax": {"model", "planning", "kernel", "sim", "scoring", "tasks", "environments"},  # the loop in JAX
    "cli": {"model", "planning", "sim", "scoring", "tasks", "environments", "bench", "report", "optim"},  # the front
}
#: The lab: the benchmark's maintenance (leaderboard storage, rendering and aggregates, pool builds, best-known
#: searches, studies, docs pages), which users do not import. The library never imports it (docs/layout.md).
LAB = ({f"ffsr_gym.bench.{n}" for n in ("aggregates", "dataset", "doc_pages", "leaderboard", "normalise", "pareto",
                                        "rl_comparison", "separation", "tables", "update_plan")}
       | {f"ffsr_gym.optim.{n}" for n in ("best_known", "best_known_build", "best_known_check", "best_known_screen",
                                          "study_plan", "tune_loop", "tuning")}
       | {f"ffsr_gym.tasks.{n}" for n in ("build", "best_known", "freeze", "pool_tables")}
       | {"ffsr_gym.report.leaderboard_plots"}
       | {f"ffsr_gym.cli.{n}" for n in ("board_commands", "docs_commands", "lab_commands", "study_commands")})
PHYSICS_STAGES = ("model", "planning", "kernel", "sim", "scoring", "tasks")
FORBIDDEN_IN_PHYSICS = ("gymnasium", "stable_baselines3", "matplotlib", "torch")


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py")) if "envs" not in p.relative_to(PACKAGE).parts}


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
            names.update(member for member in members if member in MODULES or member == EXTENSION)
    return names


def project_imports(name: str) -> set[str]:
    """Project modules ``name`` imports (a ``from package import name`` counts as the module)."""
    out = set()
    for imported in imports_of(MODULES[name]):
        if (imported in MODULES or imported == EXTENSION) and imported != name:
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
    graph = {name: project_imports(name) - {"ffsr_gym"} for name in MODULES} | {EXTENSION: set()}
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
    assert LAB <= set(MODULES)
    edges = {(name, imported) for name in MODULES if name not in LAB for imported in project_imports(name)
             if imported in LAB}
    assert edges == set()


def test_the_layout_page_lists_the_lab():
    import re

    text = (PACKAGE.parent / "docs" / "layout.md").read_text(encoding="utf-8")
    section = text[text.index("## Library and lab"):]
    section = section[:section.index("\n## ") if "\n## " in section else len(section)]
    assert set(re.findall(r"`(ffsr_gym\.\w+\.\w+)`", section.split("Edges left")[0])) == LAB
