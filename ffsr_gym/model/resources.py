"""Where the packaged robot and scenario files live.

The files under the repository's ``envs/`` folder are copied into the wheel as ``ffsr_gym/envs``.
In a source checkout (or an editable install) the package has no ``envs`` folder of its own, so
the repository's folder is used instead.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ffsr_gym.exceptions import RobotFileError, ScenarioError


def envs_dir() -> Path:
    """Return the folder holding ``robots/`` and ``scenarios/``.

    Returns:
        The packaged ``ffsr_gym/envs`` folder when installed from a wheel, else the checkout's
        ``envs/`` folder.
    """
    package = Path(str(resources.files("ffsr_gym")))
    packaged = package / "envs"
    if (packaged / "scenarios").is_dir():
        return packaged
    return package.parent / "envs"


def robot_dir(name: str) -> Path:
    """Return the folder of the shipped robot called ``name`` (``envs/robots/<name>``).

    Only the names of the shipped robots are accepted, never a path: a scenario file cannot
    make the package read (or hash) files outside ``envs/robots``.

    Raises:
        RobotFileError: if no such robot is shipped.
    """
    robots = envs_dir() / "robots"
    known = sorted(p.name for p in robots.iterdir() if p.is_dir())
    if not isinstance(name, str) or name not in known:
        raise RobotFileError(f"robot {name!r} is not a shipped robot; allowed: {known}")
    return robots / name


def scenario_names() -> list[str]:
    """Return the names of the shipped scenarios (file stems in ``envs/scenarios``)."""
    return sorted(p.stem for p in (envs_dir() / "scenarios").glob("*.toml"))


def scenario_path(name_or_path: str | Path) -> Path:
    """Resolve a scenario name (``"paper"``) or a path to a TOML file.

    Raises:
        ScenarioError: if the name is not shipped and the path does not exist.
    """
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.parent != Path("."):
        if candidate.is_file():
            return candidate
        raise ScenarioError(f"scenario file {str(candidate)!r} does not exist")
    path = envs_dir() / "scenarios" / f"{name_or_path}.toml"
    if not path.is_file():
        raise ScenarioError(
            f"scenario {str(name_or_path)!r} is not shipped; allowed names: {scenario_names()} "
            "or a path to a .toml file"
        )
    return path
