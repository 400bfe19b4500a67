"""The perturbed tiers: ``debris`` and ``robust`` tasks drawn on top of a version's tier tasks.

A candidate of a perturbed tier is a task of a base tier (easy, medium or hard; the version's pool
file's labels say which seeds are), perturbed with draws from ``numpy.random.default_rng([seed, stream])``
within the ranges of ``envs/benchmark/<version>_perturbed.toml`` (docs/envs.md "Perturbed tiers"):

* ``debris`` (stream 2): the obstacle drifts, and 1-3 more obstacles cross the desired path near
  the time the end effector passes there (``[debris]``, docs/model.md §14);
* ``robust`` (stream 3): the plant's masses, inertias and centres of mass differ from the
  planner's model (``[plant]``, §15), the robot starts with momentum C (eq. 12), and the planner
  sees the target through a bias and white noise (``[target_noise]``, §16);
* ``servo`` (nothing drawn): the task on the servo plant, torque-limited joint servos driving the
  free-floating multibody dynamics (``simulation.plant = "servo"``, §21), with the settings of
  ``envs/benchmark/<version>_servo.toml``. Its certificates' Pinocchio member, which the servo
  plant does not have, becomes the task at a finer physics step (:func:`confirmation_member`).

With every range collapsed to zero (:meth:`PerturbedRule.zero`) a perturbed task moves exactly as
its base task (``tests/library/tasks/test_tiers_perturbed.py``).
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model import portable
from ffsr_gym.model.benchmark import Benchmark
from ffsr_gym.model.collision import SphereObstacle
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.model.scenario import Debris, Plant, Scenario, ServoSettings, TargetNoise
from ffsr_gym.model.schema import count, interval, load_table, number, section, vector
from ffsr_gym.sim.setup import prepare
from ffsr_gym.tasks.certificate import Member
from ffsr_gym.tasks.generator import draw_task

#: The perturbed tiers whose perturbation is drawn per task.
DRAWN_TIERS = ("debris", "robust")
#: Every tier built on top of a version's tier tasks (``servo``: the same tasks on the servo plant).
PERTURBED_TIERS = DRAWN_TIERS + ("servo",)
#: The generator stream of each drawn tier (stream 1 draws the residual trials of the tier rule).
STREAMS = {"debris": 2, "robust": 3}


@dataclass(frozen=True)
class DebrisDraw:
    """Ranges of the ``debris`` tier (see ``<version>_perturbed.toml``)."""

    extra_obstacles: tuple[float, ...] = field(metadata=vector(2, 0, 7))
    radius_m: tuple[float, ...] = field(metadata=interval(0.0, 0.5))
    obstacle_speed_m_s: tuple[float, ...] = field(metadata=interval(0.0, 0.5))
    debris_speed_m_s: tuple[float, ...] = field(metadata=interval(0.0, 0.5))
    crossing_time_fraction: tuple[float, ...] = field(metadata=interval(0.0, 1.0))
    lateral_offset_m: tuple[float, ...] = field(metadata=interval(0.0, 1.0))
    min_final_distance_m: float = field(metadata=number(0.0, 2.0))
    max_attempts: float = field(metadata=count(1, 100_000))


@dataclass(frozen=True)
class RobustDraw:
    """Ranges of the ``robust`` tier (see ``<version>_perturbed.toml``)."""

    mass_scale: tuple[float, ...] = field(metadata=vector(2, 0.5, 2.0))
    inertia_scale: tuple[float, ...] = field(metadata=vector(2, 0.5, 2.0))
    com_offset_m: float = field(metadata=number(0.0, 0.1))
    linear_momentum_kg_m_s: float = field(metadata=number(0.0, 100.0))
    angular_momentum_kg_m2_s: float = field(metadata=number(0.0, 100.0))
    position_bias_m: float = field(metadata=number(0.0, 0.01))
    attitude_bias_rad: float = field(metadata=number(0.0, 0.01))
    position_sigma_m: float = field(metadata=number(0.0, 0.01))
    attitude_sigma_rad: float = field(metadata=number(0.0, 0.01))
    interval_s: float = field(metadata=number(0.001, 100.0))


@dataclass(frozen=True)
class PerturbedRule:
    """``envs/benchmark/<version>_perturbed.toml``: pool sizes and the draw ranges of each perturbed tier."""

    schema_version: int = field(metadata={"kind": "integer", "options": (1,)})
    train_tasks: float = field(metadata=number(1, 1e5))
    test_tasks: float = field(metadata=number(1, 1e5))
    debris: DebrisDraw = field(metadata=section(DebrisDraw))
    robust: RobustDraw = field(metadata=section(RobustDraw))
    validation_tasks: float = field(default=0, metadata=number(0, 1e5))

    def tasks_in(self, split: str) -> int:
        """How many tasks each perturbed tier's ``split`` pool holds."""
        return int({"train": self.train_tasks, "validation": self.validation_tasks, "test": self.test_tasks}[split])

    def zero(self) -> PerturbedRule:
        """This rule with every perturbation range collapsed to nothing (the base task itself)."""
        return dataclasses.replace(
            self,
            debris=dataclasses.replace(self.debris, extra_obstacles=(0.0, 0.0), obstacle_speed_m_s=(0.0, 0.0),
                                       debris_speed_m_s=(0.0, 0.0)),
            robust=dataclasses.replace(self.robust, mass_scale=(1.0, 1.0), inertia_scale=(1.0, 1.0), com_offset_m=0.0,
                                       linear_momentum_kg_m_s=0.0, angular_momentum_kg_m2_s=0.0, position_bias_m=0.0,
                                       attitude_bias_rad=0.0, position_sigma_m=0.0, attitude_sigma_rad=0.0))


def rule_path(version: str) -> str:
    """The shipped perturbed-tier rule file of benchmark ``version``."""
    return str(envs_dir() / "benchmark" / f"{version}_perturbed.toml")


def perturbed_rule_sha256(version: str) -> str:
    """Hash of ``version``'s perturbed-tier rule file (the draw ranges and pool sizes)."""
    with open(rule_path(version), "rb") as handle:
        return hashlib.sha256(handle.read()).hexdigest()


@lru_cache(maxsize=4)
def load_perturbed_rule(version: str) -> PerturbedRule:
    """The shipped :class:`PerturbedRule` of benchmark ``version``.

    Raises:
        ScenarioError: unreadable file, or a key missing, unknown or out of range (named).
    """
    path = rule_path(version)
    rule = load_table(PerturbedRule, path)
    if any(v != int(v) for v in rule.debris.extra_obstacles):
        raise ScenarioError(f"{path}: key 'debris.extra_obstacles' = {list(rule.debris.extra_obstacles)}; "
                            "allowed: two integers in [0, 7]")
    for name, pair in (("debris.extra_obstacles", rule.debris.extra_obstacles),
                       ("debris.radius_m", rule.debris.radius_m), ("robust.mass_scale", rule.robust.mass_scale)):
        if pair[0] > pair[1]:
            raise ScenarioError(f"{path}: key {name!r} = {list(pair)}; allowed: [low, high] with low <= high")
    return rule


@dataclass(frozen=True)
class ServoTierRule:
    """``envs/benchmark/<version>_servo.toml``: the plant of the ``servo`` tier's tasks and its ensemble's
    physics-step member (pool sizes: the perturbed rule's)."""

    schema_version: int = field(metadata={"kind": "integer", "options": (1,)})
    physics_step_divisor: float = field(metadata=number(1.0, 64.0, lo_open=True))
    servo: ServoSettings = field(metadata=section(ServoSettings))


def servo_rule_path(version: str) -> str:
    """The shipped ``servo`` tier rule file of benchmark ``version``."""
    return str(envs_dir() / "benchmark" / f"{version}_servo.toml")


@lru_cache(maxsize=4)
def load_servo_rule(version: str) -> ServoTierRule:
    """The shipped :class:`ServoTierRule` of benchmark ``version``.

    Raises:
        ScenarioError: unreadable file, or a key missing, unknown or out of range (named).
    """
    return load_table(ServoTierRule, servo_rule_path(version))


def on_servo_plant(task: Scenario, settings: ServoSettings) -> Scenario:
    """``task`` played on the servo plant with ``settings``; every other value kept bit for bit."""
    return with_sections(task, simulation=dataclasses.replace(task.simulation, plant="servo"), servo=settings)


def confirmation_member(task: Scenario, version: str) -> Member:
    """The ensemble member a pool candidate is confirmed in after the kernel members: the Pinocchio backend, or,
    for a servo-plant task (kernel only), the task at its physics step divided by the servo rule's
    ``physics_step_divisor``."""
    if task.simulation.plant != "servo":
        return Member("pinocchio", task, "pinocchio")
    divisor = load_servo_rule(version).physics_step_divisor
    settings = task.servo_settings
    finer = dataclasses.replace(settings, physics_step_s=settings.physics_step_s / divisor)
    return Member(f"physics step/{divisor:g}", with_sections(task, servo=finer))


def with_sections(base: Scenario, **sections: Any) -> Scenario:
    """``base`` with whole sections replaced, validated like :meth:`Scenario.replace`, but keeping
    ``base``'s quaternions bit for bit (``replace`` normalises them again, which can move a last bit)."""
    base.replace(**sections)  # validation (ranges, cross-field checks); its normalised copy is not kept
    return dataclasses.replace(base, **sections)


def _unit(rng: np.random.Generator) -> np.ndarray:
    direction = rng.normal(size=3)
    return direction / portable.norm(direction)


def _segment_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance [m] from ``point`` to the segment a-b."""
    ab = b - a
    length2 = portable.dot(ab, ab)
    u = 0.0 if length2 == 0.0 else min(1.0, max(0.0, portable.dot(point - a, ab) / length2))
    return portable.norm(point - (a + u * ab))


def draw_debris(task: Scenario, rng: np.random.Generator, spec: DebrisDraw) -> Debris | None:
    """A ``[debris]`` section for ``task`` (None: no admissible draw within ``max_attempts``).

    The obstacle drifts at a speed drawn from ``obstacle_speed_m_s`` in a uniform direction. Each
    extra obstacle (a sphere, radius from ``radius_m``) crosses the point of the desired path
    reached at a time drawn from ``crossing_time_fraction`` of the motion time, offset sideways
    by ``lateral_offset_m`` in a uniform direction, at that time, drifting at a speed from
    ``debris_speed_m_s``. A draw is kept when every obstacle clears the start configuration by
    the danger radius and stays ``min_final_distance_m`` (plus its radius) from the target
    position from the end of the motion to the end of the episode.
    """
    setup = prepare(task)
    path, collision, danger = setup.path, setup.assets.collision, task.obstacle.danger_radius_m
    t_f, horizon = path.motion_time, task.simulation.duration_s
    low, high = (int(v) for v in spec.extra_obstacles)
    main, main_radius = np.array(task.obstacle.position_m), task.obstacle.radius_m
    for _ in range(int(spec.max_attempts)):
        main_velocity = rng.uniform(*spec.obstacle_speed_m_s) * _unit(rng)
        count = int(rng.integers(low, high + 1))
        positions, velocities, radii = [], [], []
        for _ in range(count):
            crossing = rng.uniform(*spec.crossing_time_fraction) * t_f
            point = path.at(crossing)[0] + rng.uniform(*spec.lateral_offset_m) * _unit(rng)
            velocity = rng.uniform(*spec.debris_speed_m_s) * _unit(rng)
            positions.append(point - velocity * crossing)
            velocities.append(velocity)
            radii.append(float(rng.uniform(*spec.radius_m)))
        starts = [main, *positions]
        drifts = [main_velocity, *velocities]
        sizes = [main_radius, *radii]
        spheres = [SphereObstacle(p, r) for p, r in zip(starts, sizes)]
        if spheres and collision.obstacle_proximity(setup.q0, spheres).distance_m < danger:
            continue
        if any(_segment_distance(path.target_position, p + v * t_f, p + v * horizon) - r < spec.min_final_distance_m
               for p, v, r in zip(starts, drifts, sizes)):
            continue
        return Debris(obstacle_velocity_m_s=tuple(float(v) for v in main_velocity),
                      positions_m=tuple(tuple(float(x) for x in p) for p in positions), radii_m=tuple(radii),
                      velocities_m_s=tuple(tuple(float(x) for x in v) for v in velocities))
    return None


def draw_robust(task: Scenario, rng: np.random.Generator, spec: RobustDraw) -> Scenario:
    """``task`` with a drawn plant (``[plant]``), initial momentum and a noisy target (``[target_noise]``).

    Per body: mass and inertia factors uniform in ``mass_scale`` / ``inertia_scale``; per link:
    a CoM offset uniform in ± ``com_offset_m`` per axis. C: each linear (angular) component
    uniform in ± ``linear_momentum_kg_m_s`` (``angular_momentum_kg_m2_s``). Target: bias
    components uniform in ± ``position_bias_m`` / ``attitude_bias_rad``; the white noise's σ and
    interval as given, its seed drawn.
    """
    plant = Plant(mass_scale=tuple(float(x) for x in rng.uniform(*spec.mass_scale, 13)),
                  inertia_scale=tuple(float(x) for x in rng.uniform(*spec.inertia_scale, 13)),
                  com_offset_m=tuple(tuple(float(x) for x in row)
                                     for row in rng.uniform(-spec.com_offset_m, spec.com_offset_m, (12, 3))))
    momentum = np.concatenate((rng.uniform(-spec.linear_momentum_kg_m_s, spec.linear_momentum_kg_m_s, 3),
                               rng.uniform(-spec.angular_momentum_kg_m2_s, spec.angular_momentum_kg_m2_s, 3)))
    position_bias = rng.uniform(-spec.position_bias_m, spec.position_bias_m, 3)
    attitude_bias = rng.uniform(-spec.attitude_bias_rad, spec.attitude_bias_rad, 3)
    noise = TargetNoise(position_bias_m=tuple(float(x) for x in position_bias),
                        attitude_bias_rad=tuple(float(x) for x in attitude_bias),
                        position_sigma_m=spec.position_sigma_m, attitude_sigma_rad=spec.attitude_sigma_rad,
                        interval_s=spec.interval_s, seed=int(rng.integers(2**63 - 1)))
    initial = dataclasses.replace(task.initial, momentum=tuple(float(x) for x in momentum))
    return with_sections(task, plant=plant, initial=initial, target_noise=noise)


def perturbed_task(tier: str, seed: int, benchmark: Benchmark, rule: PerturbedRule | None = None) -> Scenario | None:
    """The ``tier`` candidate on top of the candidate task of ``seed`` (None: no admissible debris draw).

    Raises:
        InvalidInputError: unknown tier, or a seed outside [0, 2**63).
    """
    if tier not in PERTURBED_TIERS:
        raise InvalidInputError(f"perturbed tier {tier!r}; allowed: {list(PERTURBED_TIERS)}")
    draw_task(seed, benchmark)  # checks the seed
    return _perturbed_task(tier, int(seed), benchmark, rule or load_perturbed_rule(benchmark.version))


@lru_cache(maxsize=1024)
def _perturbed_task(tier: str, seed: int, benchmark: Benchmark, rule: PerturbedRule) -> Scenario | None:
    base = draw_task(seed, benchmark)
    if tier == "servo":
        task = on_servo_plant(base, load_servo_rule(benchmark.version).servo)
    elif tier == "robust":
        rng = np.random.default_rng([seed, STREAMS[tier]])
        task = draw_robust(base, rng, rule.robust)
    else:
        debris = draw_debris(base, np.random.default_rng([seed, STREAMS[tier]]), rule.debris)
        if debris is None:
            return None
        task = with_sections(base, debris=debris)
    version = benchmark.version
    description = f"Benchmark {version} {tier} candidate task of seed {seed} (ffsr_gym.tasks.perturbation)."
    return with_sections(task, name=f"{version}-{tier}-{seed}", description=description)
