"""Where the packaged robot and scenario files live.

The files under the repository's ``envs/`` folder are copied into the wheel as ``ffsr_gym/envs``.
In a source checkout (or an editable install) the package has no ``envs`` folder of its own, so
the repository's folder is used instead.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from ffsr_gym.exceptions import RobotFileError, ScenarioError


@lru_cache(maxsize=1)
def envs_dir() -> Path:
    """Return the folder holding ``robots/`` and ``scenarios/``.

    Returns:
        The packaged ``ffsr_gym/envs`` folder when installed from a wheel, else the checkout's
        ``envs/`` folder.
    """
    package = Path(__file__).resolve().parents[1]  # the ffsr_gym folder (an editable install's is the checkout's)
    packaged = package / "envs"
    if (packaged / "scenarios").is_dir():
        return packaged
    return package.parent / "envs"


def robot_names() -> list[str]:
    """The names of the shipped robots (folders in ``envs/robots``)."""
    return list(_shipped_robots())


@lru_cache(maxsize=1)
def _shipped_robots() -> tuple[str, ...]:
    """The shipped robots, listed once per process (the package's files do not change under it)."""
    return tuple(sorted(p.name for p in (envs_dir() / "robots").iterdir() if p.is_dir()))


def is_shipped_robot(ref: str) -> bool:
    """Whether ``ref`` names a shipped robot (else it is a path to a robot of one's own)."""
    return isinstance(ref, str) and ref in _shipped_robots()


def robot_files(ref: str) -> tuple[Path, Path]:
    """The (URDF, collision file) of a robot: a shipped name, or a path to a robot folder or its URDF.

    A robot folder holds exactly one ``.urdf`` file and a ``collision.toml`` (docs/robots.md); a
    shipped robot ``<name>`` is ``envs/robots/<name>/<name>.urdf``. A path is used as given
    (scenario files resolve theirs against their own folder when they load).

    Raises:
        RobotFileError: neither a shipped name nor an existing robot folder or URDF (what is
            missing is named).
    """
    if not isinstance(ref, str) or not ref:
        raise RobotFileError(f"robot {ref!r}; allowed: a shipped robot {robot_names()} or a path to a robot folder")
    if is_shipped_robot(ref):
        folder = envs_dir() / "robots" / ref
        return folder / f"{ref}.urdf", folder / "collision.toml"
    path = Path(ref)
    if path.suffix == ".urdf" and path.is_file():
        urdf, folder = path, path.parent
    elif path.is_dir():
        urdfs = sorted(path.glob("*.urdf"))
        if len(urdfs) != 1:
            raise RobotFileError(f"robot folder {ref!r} holds {len(urdfs)} .urdf files; allowed: exactly one "
                                 "(docs/robots.md)")
        urdf, folder = urdfs[0], path
    else:
        raise RobotFileError(f"robot {ref!r} is not a shipped robot {robot_names()} and no such robot folder or "
                             ".urdf file exists")
    collision = folder / "collision.toml"
    if not collision.is_file():
        raise RobotFileError(f"robot {ref!r}: {collision} does not exist; a robot folder needs one (docs/robots.md)")
    return urdf, collision


def robot_dir(ref: str) -> Path:
    """The folder of a robot (shipped name or path): every file in it enters the scenario hash.

    Raises:
        RobotFileError: as :func:`robot_files`.
    """
    return robot_files(ref)[0].parent


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
