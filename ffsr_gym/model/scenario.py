"""Scenario files: TOML in ``envs/scenarios/`` loaded into frozen, validated dataclasses.

A scenario holds every number of one experiment: robot, initial state, target, desired path,
obstacle, planner settings and time step. Keys carry their units (``dt_s``, ``joints_deg``).
Quaternions are scalar-first ``[w, x, y, z]``, as the paper prints them. Validation happens on
load: a wrong type, a missing or unknown key, or an out-of-range value raises
:class:`~ffsr_gym.exceptions.ScenarioError` naming the key, the value and what is allowed.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import FFSRError, InvalidInputError, RobotFileError, ScenarioError
from ffsr_gym.model import portable
from ffsr_gym.model.drives import drives_path
from ffsr_gym.model.resources import is_shipped_robot, robot_dir, scenario_path
from ffsr_gym.model.scenario_sections import (
    CommandedApproach,
    Debris,
    EnvSettings,
    InitialState,
    ObjectiveSettings,
    Obstacle,
    PlannerSettings,
    Plant,
    Randomization,
    ReferencePath,
    ServoSettings,
    Simulation,
    Target,
    TargetNoise,
    TumblingTarget,
    tumbling_scenario_problems,
)
from ffsr_gym.model.schema import (
    TEXT,
    TEXTS,
    Vec,
    build_table,
    check_action_bounds,
    check_number,
    episode_steps_problem,
    file_key,
    integer,
    section,
)
from ffsr_gym.user_files import check_depth, hash_files, read_text

SCHEMA_VERSION = 1


@dataclass(frozen=True)
class Scenario:
    """One experiment, loaded from a TOML file. See the module docstring for conventions."""

    name: str = field(metadata=TEXT)
    description: str = field(metadata=TEXT)
    robot: str = field(metadata=TEXT)
    simulation: Simulation = field(metadata=section(Simulation))
    initial: InitialState = field(metadata=section(InitialState))
    target: Target = field(metadata=section(Target))
    desired_path: ReferencePath = field(metadata=section(ReferencePath, key="trajectory"))
    planner: PlannerSettings = field(metadata=section(PlannerSettings))
    obstacle: Obstacle | None = field(default=None, metadata=section(Obstacle))
    debris: Debris | None = field(default=None, metadata=section(Debris))
    plant: Plant | None = field(default=None, metadata=section(Plant))
    servo: ServoSettings | None = field(default=None, metadata=section(ServoSettings))
    target_noise: TargetNoise | None = field(default=None, metadata=section(TargetNoise))
    tumbling_target: TumblingTarget | None = field(default=None, metadata=section(TumblingTarget))
    commanded_approach: CommandedApproach | None = field(default=None, metadata=section(CommandedApproach))
    objective: ObjectiveSettings = field(default=ObjectiveSettings(), metadata=section(ObjectiveSettings))
    env: EnvSettings = field(default=EnvSettings(), metadata=section(EnvSettings))
    randomization: Randomization | None = field(default=None, metadata=section(Randomization))
    deviations: tuple[str, ...] = field(default=(), metadata=TEXTS)
    schema_version: int = field(default=SCHEMA_VERSION, metadata=integer(1))
    source: str = field(default="", compare=False)

    @property
    def n_steps(self) -> int:
        """Number of planner steps of one episode, ``round(duration_s / dt_s)``."""
        return int(round(self.simulation.duration_s / self.simulation.dt_s))

    def replace(self, **sections: Any) -> Scenario:
        """Return a copy with whole sections replaced, validated like a loaded file.

        Example: ``scenario.replace(planner=dataclasses.replace(scenario.planner, m=0.2))``.
        """
        data = to_dict(dataclasses.replace(self, **sections))
        return _from_dict(data, source=self.source)

    def at_step(self, dt_s: Any) -> Scenario:
        """This scenario with the physics step ``dt_s`` [s]; every other value is kept bit for bit.

        The decision interval and the duration stay, so each must be a whole number of the new steps (a
        sensitivity study runs the same task, with the same decisions, at dt/2, dt/4).

        Raises:
            InvalidInputError: ``dt_s`` not in [1e-5, 0.1] s, not dividing the interval and duration, or too many steps.
        """
        meta = next(f.metadata for f in dataclasses.fields(Simulation) if f.name == "dt_s")
        try:
            dt = check_number("dt_s", dt_s, meta)
        except ScenarioError as exc:
            raise InvalidInputError(f"{exc} [s]") from None
        for name, span in (("env.decision_interval_s", self.env.decision_interval_s),
                           ("simulation.duration_s", self.simulation.duration_s)):
            steps = span / dt
            if abs(steps - round(steps)) > 1e-9 * max(1.0, steps):
                raise InvalidInputError(f"dt_s = {dt_s!r} does not divide {name} = {span} s into whole steps; allowed: "
                                        f"{span} / n for a whole n, at most 0.1 s (the benchmark's own: "
                                        f"{self.simulation.dt_s} s)")
        if episode_steps_problem(self.simulation.duration_s, dt):
            raise InvalidInputError(f"dt_s = {dt_s!r}: {episode_steps_problem(self.simulation.duration_s, dt)}")
        return dataclasses.replace(self, simulation=dataclasses.replace(self.simulation, dt_s=dt))

    @property
    def servo_settings(self) -> ServoSettings:
        """The ``[servo]`` section, or its defaults when the file has none."""
        return self.servo if self.servo is not None else ServoSettings()

    @property
    def physics_substeps(self) -> int:
        """Physics steps per planner step: 0 for the kinematic plant, else the fewest whose length is at most
        ``servo.physics_step_s`` (a ratio within 1e-9 of a whole number counts as that number)."""
        if self.simulation.plant != "servo":
            return 0
        ratio = self.simulation.dt_s / self.servo_settings.physics_step_s
        return max(1, round(ratio) if abs(ratio - round(ratio)) <= 1e-9 * ratio else math.ceil(ratio))

    def sha256(self) -> str:
        """Hash of the scenario's content and of its robot's files (provenance, staleness).

        Computed once per instance (the scenario is immutable; the robot files are read then).
        """
        cached = self.__dict__.get("_sha256")
        if cached is None:
            data, folder = to_dict(self), robot_dir(self.robot)
            if not is_shipped_robot(self.robot):  # a robot folder: its name and files, wherever it lies
                data["robot"] = folder.name
            digest = hashlib.sha256(json.dumps(data, sort_keys=True).encode())
            try:
                hash_files(digest, [path for path in sorted(folder.iterdir()) if path.is_file()])
                if self.simulation.plant == "servo":  # the drives, apart: kinematic scenarios' hashes do not see them
                    hash_files(digest, [drives_path(folder)], names=False)
            except FFSRError as exc:
                raise RobotFileError(f"robot folder {exc}") from None
            cached = digest.hexdigest()
            object.__setattr__(self, "_sha256", cached)
        return cached


#: Keys added after schema version 1, with their defaults. At the default they are left out of
#: :func:`to_dict`, so a scenario that does not set them keeps the layout, and the hash, it had
#: before they existed.
ADDED_KEYS = {("objective", "keep_out_m"): 0.0, ("simulation", "plant"): "kinematic"}


def to_dict(scenario: Scenario) -> dict[str, Any]:
    """Return the scenario as plain data (the TOML layout), without its source path."""
    data = _plain(scenario)
    data.pop("source")
    for optional in ("obstacle", "debris", "plant", "servo", "target_noise", "tumbling_target", "commanded_approach",
                     "randomization"):
        if data[optional] is None:
            data.pop(optional)
    for (table, key), default in ADDED_KEYS.items():
        if data[table][key] == default:
            data[table].pop(key)
    return data


def _plain(value: Any) -> Any:
    """``dataclasses.asdict`` for a scenario's values: the same data, about 3x faster (a first task
    draw converts its scenario three times: two validated copies and the hash).

    The scenario's leaves are validated numbers, text, booleans and tuples of them, all immutable,
    so they are not deep-copied (``asdict`` copies every leaf); anything else is, as there.
    """
    kind = type(value)
    if kind in (float, int, str, bool) or value is None:
        return value
    if kind is tuple or kind is list:
        return kind(_plain(item) for item in value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {key: _plain(getattr(value, name)) for name, key in _field_keys(kind)}
    if kind is dict:
        return {_plain(key): _plain(item) for key, item in value.items()}
    return copy.deepcopy(value)


@functools.lru_cache(maxsize=None)
def _field_keys(cls: type) -> tuple[tuple[str, str], ...]:
    """(attribute, key in the file) of each field: the plain data uses the file's layout."""
    return tuple((f.name, file_key(f)) for f in dataclasses.fields(cls))


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and validate a scenario.

    Args:
        name_or_path: a shipped scenario name (``"paper"``, ``"paper_as_printed"``,
            ``"free_space"``) or a path to a TOML file.

    Returns:
        The frozen, validated :class:`Scenario`. Quaternions are normalised. Loading the same file
        again (same size and modification time) returns the same object when its robot is a
        shipped one (a robot folder's files may change under the scenario's hash).

    Raises:
        ScenarioError: unknown name, unreadable TOML, or any invalid key (the message names the
            key, the value and the allowed values).
    """
    if isinstance(name_or_path, Scenario):
        return name_or_path
    path = scenario_path(name_or_path)
    try:
        stat = path.stat()
        key = (str(path), stat.st_size, stat.st_mtime_ns)
    except OSError:
        key = None
    if key in _LOADED:
        return _LOADED[key]
    try:
        text = read_text(path)
        check_depth(text, str(path))
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML ({exc})") from exc
    except FFSRError as exc:
        raise ScenarioError(f"{exc}; a scenario is a TOML text file") from None
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot be read ({exc.strerror})") from None
    scenario = _from_dict(data, source=str(path))
    if key is not None and is_shipped_robot(scenario.robot):  # a robot folder's files may change under its hash
        if len(_LOADED) >= 64:
            _LOADED.clear()
        _LOADED[key] = scenario
    return scenario


#: Scenarios loaded from files, by (path, size, modification time): loading parses and validates the TOML
#: (about a millisecond), and a scenario is immutable. Only those on a shipped robot are kept.
_LOADED: dict[tuple, Scenario] = {}


def scenario_from_dict(data: Any, source: str = "") -> Scenario:
    """A scenario from plain data in the TOML layout (:func:`to_dict`'s output, e.g. one stored in an entry).

    Raises:
        ScenarioError: not a table, or any invalid key (named); RobotFileError: its robot is missing.
    """
    if not isinstance(data, dict):
        raise ScenarioError(f"{source or 'scenario'}: not a table of scenario keys ({type(data).__name__})")
    return _from_dict(copy.deepcopy(data), source=source)


def _from_dict(data: dict[str, Any], *, source: str) -> Scenario:
    where = f"{source}: " if source else ""
    try:
        scenario = build_table(Scenario, data)
    except ScenarioError as exc:
        raise ScenarioError(where + str(exc)) from None
    scenario = dataclasses.replace(scenario, source=source, robot=_robot_reference(scenario.robot, source))
    _check_cross_fields(scenario, where)
    return _normalised(scenario)


def _robot_reference(robot: str, source: str) -> str:
    """A shipped robot's name as it is; a robot path made absolute, against the scenario file's folder (or the
    working folder for a scenario built in code), so the scenario means the same robot from any folder."""
    if is_shipped_robot(robot):
        return robot
    path = Path(robot).expanduser()
    if not path.is_absolute():
        path = (Path(source).parent if source else Path.cwd()) / path
    return str(path.resolve())


def whole(span: float, step: float) -> bool:
    """Whether ``span`` is a whole number (>= 1) of ``step``, to 1e-9 relative (``0.3 / 0.1`` is 3)."""
    count = span / step
    return round(count) >= 1 and abs(count - round(count)) <= 1e-9 * max(1.0, count)


def _check_whole_steps(s: Scenario, where: str) -> None:
    """One rule for an episode's length: the duration is a whole number of decisions, a decision a whole number of
    physics steps (else the episode would be cut or stretched silently, differently on each path)."""
    sim, interval = s.simulation, s.env.decision_interval_s
    for key, span, step, unit in (("env.decision_interval_s", interval, sim.dt_s, "simulation.dt_s"),
                                  ("simulation.duration_s", sim.duration_s, interval, "env.decision_interval_s")):
        if not whole(span, step):
            raise ScenarioError(f"{where}key '{key}' = {span} is not a whole number of {unit} = {step} s; allowed: "
                                f"a whole multiple of it (e.g. {max(1, round(span / step)) * step:.6g} s)")


def _check_cross_fields(s: Scenario, where: str) -> None:
    path = s.desired_path
    if path.accel_time_s > path.motion_time_s / 2:
        raise ScenarioError(
            f"{where}key 'trajectory.accel_time_s' = {path.accel_time_s} is out of range; "
            f"allowed: (0, motion_time_s / 2] = (0, {path.motion_time_s / 2}]"
        )
    if s.simulation.dt_s > s.simulation.duration_s:
        raise ScenarioError(
            f"{where}key 'simulation.dt_s' = {s.simulation.dt_s} is out of range; "
            f"allowed: (0, duration_s] = (0, {s.simulation.duration_s}]"
        )
    _check_whole_steps(s, where)
    body = s.tumbling_target
    for key, quat in (
        ("initial.base_quaternion_wxyz", s.initial.base_quaternion_wxyz),
        ("target.quaternion_wxyz", s.target.quaternion_wxyz),
        *(() if body is None else (("tumbling_target.quaternion_wxyz", body.quaternion_wxyz),
                                   ("tumbling_target.handle_quaternion_wxyz", body.handle_quaternion_wxyz))),
    ):
        norm = portable.norm(quat)
        if abs(norm - 1.0) > 1e-2:
            raise ScenarioError(
                f"{where}key {key!r} = {list(quat)} has norm {norm:.6f}; allowed: a unit "
                "quaternion [w, x, y, z] within 1e-2 of norm 1 (it is normalised on load)"
            )
    check_action_bounds(s.env.m_bounds, s.env.T_c_bounds_s, section="env", where=where)
    if episode_steps_problem(s.simulation.duration_s, s.simulation.dt_s):
        raise ScenarioError(f"{where}keys 'simulation.duration_s' / 'simulation.dt_s': "
                            f"{episode_steps_problem(s.simulation.duration_s, s.simulation.dt_s)}")
    if s.debris is not None:
        if s.obstacle is None:
            raise ScenarioError(f"{where}section 'debris' needs an 'obstacle' section (its danger radius is shared)")
        counts = {name: len(getattr(s.debris, name)) for name in ("positions_m", "radii_m", "velocities_m_s")}
        if len(set(counts.values())) > 1:
            raise ScenarioError(f"{where}keys 'debris.positions_m', 'debris.radii_m' and 'debris.velocities_m_s' "
                                f"must list the same number of obstacles, got {counts}")
    if s.plant is not None and len(s.plant.com_offset_m) not in (0, 12):
        raise ScenarioError(f"{where}key 'plant.com_offset_m' lists {len(s.plant.com_offset_m)} rows; allowed: none, "
                            "or one [x, y, z] per link (12)")
    _check_servo(s, where)
    _check_tumbling(s, where)
    if s.randomization is not None and s.obstacle is None:
        raise ScenarioError(f"{where}section 'randomization' needs an 'obstacle' section (its radii are used)")
    try:
        robot_dir(s.robot)
        if not is_shipped_robot(s.robot):  # a robot of one's own is checked as it loads (the shipped one by its tests)
            from ffsr_gym.model.robot_check import check_robot_folder

            check_robot_folder(s.robot)
    except RobotFileError as exc:
        raise RobotFileError(f"{where}key 'robot': {exc}") from None


def _check_servo(s: Scenario, where: str) -> None:
    """The ``[servo]`` section only with the servo plant, and the servo plant only with its robot's drive file."""
    if s.servo is not None and s.simulation.plant != "servo":
        raise ScenarioError(f"{where}section 'servo' needs key 'simulation.plant' = 'servo' (it is "
                            f"{s.simulation.plant!r})")
    if s.simulation.plant == "servo":
        try:
            path = drives_path(robot_dir(s.robot))
        except RobotFileError:
            return  # the robot key's own check names the problem
        if not path.is_file():
            raise RobotFileError(f"{where}key 'simulation.plant' = 'servo' needs the robot's drive file {str(path)!r}, "
                                 "which does not exist (docs/robots.md)")


def _check_tumbling(s: Scenario, where: str) -> None:
    """A ``[tumbling_target]`` of a real body, whose grasp frame at t = 0 is the scenario's ``[target]``, and a
    ``[commanded_approach]`` only with one (:func:`tumbling_scenario_problems`)."""
    problems = tumbling_scenario_problems(s.tumbling_target, s.commanded_approach, s.target,
                                          s.target_noise is not None, s.desired_path.motion_time_s,
                                          s.simulation.duration_s)
    if problems:
        raise ScenarioError(where + "; ".join(problems))


def _normalised(s: Scenario) -> Scenario:
    def unit(q: Vec) -> Vec:
        norm = portable.norm(q)
        return tuple(c / norm for c in q)

    initial = dataclasses.replace(s.initial, base_quaternion_wxyz=unit(s.initial.base_quaternion_wxyz))
    target = dataclasses.replace(s.target, quaternion_wxyz=unit(s.target.quaternion_wxyz))
    body = s.tumbling_target
    if body is not None:
        body = dataclasses.replace(body, quaternion_wxyz=unit(body.quaternion_wxyz),
                                   handle_quaternion_wxyz=unit(body.handle_quaternion_wxyz))
    return dataclasses.replace(s, initial=initial, target=target, tumbling_target=body)
