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
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import FFSRError, InvalidInputError, RobotFileError, ScenarioError
from ffsr_gym.model import portable
from ffsr_gym.model.drives import drives_path
from ffsr_gym.model.resources import is_shipped_robot, robot_dir, scenario_path
from ffsr_gym.model.schema import (
    BOOL,
    TEXT,
    TEXTS,
    Vec,
    build_table,
    check_action_bounds,
    check_number,
    choice,
    file_key,
    integer,
    natural,
    number,
    rows,
    section,
    vector,
)
from ffsr_gym.user_files import check_depth, hash_files, read_text

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

SCHEMA_VERSION = 1


@dataclass(frozen=True)
class Simulation:
    """Time settings and plant. ``duration_s`` [s] is the episode length, ``dt_s`` [s] the planner step.

    ``plant``: ``"kinematic"`` (the default: the joints move exactly at the planned rates, the base by
    momentum conservation) or ``"servo"`` (the planned rates command torque-limited joint servos
    driving the free-floating multibody dynamics; section ``[servo]``, docs/model.md "Dynamics").
    """

    duration_s: float = field(metadata=number(0.0, 3600.0, lo_open=True))
    dt_s: float = field(metadata=number(1e-5, 0.1))
    plant: str = field(default="kinematic", metadata=choice("kinematic", "servo"))


@dataclass(frozen=True)
class ServoSettings:
    """The servo plant (beyond the paper; docs/model.md "Dynamics"); used with ``simulation.plant = "servo"``.

    The drives are the robot's ``drives/servo.toml``. ``physics_step_s`` [s]: the longest physics
    step; the plant takes ``dt_s / n`` with the smallest whole n that is no longer (so a planner
    step of another length, ``Scenario.at_step``, keeps a whole number of them); ``gain_scale``
    multiplies every servo gain;
    ``torque_limited = false`` lifts the torque limits (a study of the kinematic limit).
    """

    physics_step_s: float = field(default=0.001, metadata=number(1e-6, 0.1))
    gain_scale: float = field(default=1.0, metadata=number(0.0, 1e6, lo_open=True))
    torque_limited: bool = field(default=True, metadata=BOOL)


@dataclass(frozen=True)
class InitialState:
    """Initial base pose [m, wxyz], joint angles [deg] and centroidal momentum.

    ``momentum`` is ``[P; L_G]``: linear momentum [kg m/s] and angular momentum about the
    system centre of mass [kg m^2/s], both in the inertial frame. The paper sets it to zero.
    """

    base_position_m: Vec = field(metadata=vector(3, -100.0, 100.0))
    base_quaternion_wxyz: Vec = field(metadata=vector(4, -1.01, 1.01))
    mission_joints_deg: Vec = field(metadata=vector(6, -360.0, 360.0))
    balance_joints_deg: Vec = field(metadata=vector(6, -360.0, 360.0))
    momentum: Vec = field(default=(0.0,) * 6, metadata=vector(6, -1e3, 1e3))


@dataclass(frozen=True)
class Target:
    """Target end-effector pose: position [m] and scalar-first attitude (normalised on load)."""

    position_m: Vec = field(metadata=vector(3, -100.0, 100.0))
    quaternion_wxyz: Vec = field(metadata=vector(4, -1.01, 1.01))


@dataclass(frozen=True)
class ReferencePath:
    """The desired end-effector path (file section ``[trajectory]``): trapezoidal velocity, motion time t_f [s],
    acceleration time t_a [s] (docs/model.md)."""

    motion_time_s: float = field(metadata=number(0.0, 3600.0, lo_open=True))
    accel_time_s: float = field(metadata=number(0.0, 1800.0, lo_open=True))


@dataclass(frozen=True)
class Obstacle:
    """A point obstacle: position [m], physical radius [m] (0 = a point) and danger radius [m]."""

    position_m: Vec = field(metadata=vector(3, -100.0, 100.0))
    radius_m: float = field(default=0.0, metadata=number(0.0, 2.0))
    danger_radius_m: float = field(default=0.2, metadata=number(0.0, 5.0, lo_open=True))


#: Most obstacles besides ``[obstacle]`` a scenario may list in ``[debris]`` (the kernel's fixed slots).
MAX_DEBRIS = 7


@dataclass(frozen=True)
class Debris:
    """Further obstacles, and straight-line drift of every obstacle (beyond the paper; docs/model.md §14).

    An obstacle at ``p`` drifting at ``v`` is at ``p + v t`` at time t [s]. ``obstacle_velocity_m_s``
    is the drift of ``[obstacle]``; ``positions_m``, ``radii_m`` and ``velocities_m_s`` list up to
    :data:`MAX_DEBRIS` further obstacles (one row each, equally long lists). They share
    ``[obstacle]``'s danger radius. The danger field is the sum over all obstacles (the CDF is
    cumulative), the μ distance the smallest, and clearance is taken to the nearest one.
    """

    obstacle_velocity_m_s: Vec = field(default=(0.0,) * 3, metadata=vector(3, -1.0, 1.0))
    positions_m: tuple[Vec, ...] = field(default=(), metadata=rows(3, -100.0, 100.0, MAX_DEBRIS))
    radii_m: Vec = field(default=(), metadata=rows(0, 0.0, 2.0, MAX_DEBRIS))
    velocities_m_s: tuple[Vec, ...] = field(default=(), metadata=rows(3, -1.0, 1.0, MAX_DEBRIS))


@dataclass(frozen=True)
class Plant:
    """The robot the physics integrates, where it differs from the planner's model (docs/model.md §15).

    Bodies in kernel order: 0 the base, 1-6 the mission links, 7-12 the balance links. Each
    body's mass and its rotational inertia about its centre of mass are multiplied by the
    factors; each link's centre of mass moves by ``com_offset_m`` in its joint frame (12 rows, or
    none: the base's frame is its centre of mass and stays so). The planner keeps the nominal
    model (the robot's URDF); momentum is conserved for the plant's parameters.
    """

    mass_scale: Vec = field(default=(1.0,) * 13, metadata=vector(13, 0.5, 2.0))
    inertia_scale: Vec = field(default=(1.0,) * 13, metadata=vector(13, 0.5, 2.0))
    com_offset_m: tuple[Vec, ...] = field(default=(), metadata=rows(3, -0.1, 0.1, 12))


@dataclass(frozen=True)
class TargetNoise:
    """What the planner sees of the target pose (beyond the paper; docs/model.md §16).

    The planner's estimate is held over each ``interval_s`` (row k for t in [k, k + 1) · interval):
    position p_t + b_p + σ_p n_k, attitude exp(b_θ + σ_θ n'_k) ⊗ σ_t (a rotation vector in the
    world frame), with n_k, n'_k standard normal 3-vectors drawn once per task from
    ``numpy.random.default_rng(seed)``. The planner's desired path runs from the start pose to the
    current estimate; the logged end-effector errors and the success test use the true target.
    """

    position_bias_m: Vec = field(default=(0.0,) * 3, metadata=vector(3, -0.01, 0.01))
    attitude_bias_rad: Vec = field(default=(0.0,) * 3, metadata=vector(3, -0.01, 0.01))
    position_sigma_m: float = field(default=0.0, metadata=number(0.0, 0.01))
    attitude_sigma_rad: float = field(default=0.0, metadata=number(0.0, 0.01))
    interval_s: float = field(default=0.1, metadata=number(0.001, 100.0))
    seed: int = field(default=0, metadata=natural(2**63 - 1))


@dataclass(frozen=True)
class PlannerSettings:
    """Planner parameters (docs/model.md §3-8). Symbols follow the paper; see docs/model.md."""

    m: float = field(metadata=number(0.0, 1.0, lo_open=True, hi_open=True))
    T_c_s: float = field(metadata=number(0.0, 1000.0, lo_open=True))
    phi_form: str = field(default="sanchez_torres", metadata=choice("sanchez_torres", "printed"))
    phi_split: bool = field(default=False, metadata=BOOL)
    attitude_error: str = field(default="world", metadata=choice("world", "body"))
    lambda_max_mission: float = field(default=0.08, metadata=number(0.0, 10.0))
    lambda_max_balance: float = field(default=0.08, metadata=number(0.0, 10.0))
    epsilon_mission: float = field(default=0.02, metadata=number(0.0, 10.0))
    epsilon_balance: float = field(default=0.02, metadata=number(0.0, 10.0))
    proportional_gain_per_s: float = field(default=1.0, metadata=number(0.0, 1e3, lo_open=True))
    cdf_xi: float = field(default=0.1, metadata=number(0.0, 1e3))
    cdf_delta: float = field(default=17.25, metadata=number(0.0, 1e6, lo_open=True))
    cdf_k1: float = field(default=1.0, metadata=number(0.0, 1e3, lo_open=True))
    mu_law: str = field(default="cdf", metadata=choice("cdf", "distance"))
    balance_avoids: bool = field(default=True, metadata=BOOL)


@dataclass(frozen=True)
class ObjectiveSettings:
    """The benchmark objective B (paper eqs. 21-22; docs/model.md §13) and the feasibility tolerances.

    Rates are compared in deg/s. ``rate_limit_scope``: ``"both_arms"`` (default) or the literal
    eq. (22) reading ``"balance_arm"``. ``keep_out_m``: a robot–obstacle clearance below it is a
    collision (0, the default: contact; benchmark v2 sets it). Arm-arm and arm-base contact stays
    the collision test of the robot's own parts.
    """

    alpha: float = field(default=0.35, metadata=number(0.0, 1e6))
    beta: float = field(default=0.65, metadata=number(0.0, 1e6))
    gamma: float = field(default=1e-4, metadata=number(0.0, 1e6))
    danger_rate_deg_s: float = field(default=150.0, metadata=number(0.0, 1e5))
    max_rate_deg_s: float = field(default=200.0, metadata=number(0.0, 1e5, lo_open=True))
    rate_limit_scope: str = field(default="both_arms", metadata=choice("both_arms", "balance_arm"))
    ee_position_tolerance_m: float = field(default=1e-6, metadata=number(0.0, 10.0, lo_open=True))
    ee_attitude_tolerance: float = field(default=1e-6, metadata=number(0.0, 1.0, lo_open=True))
    keep_out_m: float = field(default=0.0, metadata=number(0.0, 1.0))


@dataclass(frozen=True)
class EnvSettings:
    """Settings of the Gymnasium environments (bounds of the action mapping, decision interval)."""

    m_bounds: Vec = field(default=(0.05, 0.95), metadata=vector(2, 0.0, 1.0))
    T_c_bounds_s: Vec = field(default=(0.5, 10.0), metadata=vector(2, 1e-3, 1000.0))
    decision_interval_s: float = field(default=0.1, metadata=number(0.0, 3600.0, lo_open=True))
    residual_rate_deg_s: float = field(default=20.0, metadata=number(0.0, 1e4))
    violation_penalty: float = field(default=1.0, metadata=number(0.0, 1e9))
    tolerance_penalty: float = field(default=1.0, metadata=number(0.0, 1e9))


@dataclass(frozen=True)
class Randomization:
    """Ranges of the randomised scenario family (used by ``scenario="random"``).

    The target is the forward kinematics of the initial mission-arm angles plus offsets drawn
    uniformly in ``±mission_joint_offsets_deg``; it is kept when the end-effector travels at least
    ``min_travel_m`` and the target configuration has ``σ_min(J_m) >= min_sigma_target``. The
    obstacle is put on the desired straight path at a fraction drawn in ``path_fraction`` plus a
    lateral offset up to ``lateral_offset_m``; it is kept when both arms start at least the danger
    radius away and the target configuration clears it by ``min_final_distance_m``.
    """

    mission_joint_offsets_deg: Vec = field(metadata=vector(6, 0.0, 180.0))
    min_travel_m: float = field(default=0.2, metadata=number(0.0, 10.0))
    min_sigma_target: float = field(default=0.05, metadata=number(0.0, 10.0))
    path_fraction: Vec = field(default=(0.4, 0.7), metadata=vector(2, 0.0, 1.0))
    lateral_offset_m: float = field(default=0.02, metadata=number(0.0, 1.0))
    min_final_distance_m: float = field(default=0.1, metadata=number(0.0, 10.0))
    min_self_clearance_m: float = field(default=0.02, metadata=number(0.0, 10.0))
    max_attempts: float = field(default=1000, metadata=number(1, 1e6))


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

        The decision interval and the duration stay as they are, so each must be a whole number of
        the new steps (a sensitivity study runs the same task, with the same decisions, at dt/2, dt/4).

        Raises:
            InvalidInputError: ``dt_s`` not a number in [1e-5, 0.1] s, or not dividing the decision
                interval and the duration into whole steps.
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
    for optional in ("obstacle", "debris", "plant", "servo", "target_noise", "randomization"):
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
    for key, quat in (
        ("initial.base_quaternion_wxyz", s.initial.base_quaternion_wxyz),
        ("target.quaternion_wxyz", s.target.quaternion_wxyz),
    ):
        norm = portable.norm(quat)
        if abs(norm - 1.0) > 1e-2:
            raise ScenarioError(
                f"{where}key {key!r} = {list(quat)} has norm {norm:.6f}; allowed: a unit "
                "quaternion [w, x, y, z] within 1e-2 of norm 1 (it is normalised on load)"
            )
    check_action_bounds(s.env.m_bounds, s.env.T_c_bounds_s, section="env", where=where)
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


def _normalised(s: Scenario) -> Scenario:
    def unit(q: Vec) -> Vec:
        norm = portable.norm(q)
        return tuple(c / norm for c in q)

    initial = dataclasses.replace(s.initial, base_quaternion_wxyz=unit(s.initial.base_quaternion_wxyz))
    target = dataclasses.replace(s.target, quaternion_wxyz=unit(s.target.quaternion_wxyz))
    return dataclasses.replace(s, initial=initial, target=target)
