"""The capture task family (docs/model.md §22): a tumbling box with a grasp handle, drawn per seed and tier.

A candidate of tier ``slow`` or ``fast`` and seed s is a deterministic function of
``numpy.random.default_rng([s, 9, tier index])``:

* the grasp frame when the insertion ends (t_c = the desired motion's time plus the insertion time) is a target of
  the v2 family (``[tasks.draw]``: the mission arm's start angles plus offsets, kept when the end-effector travels
  far enough and the target configuration is well conditioned). The body's torque-free motion is run backwards
  from there to t = 0 (the same RK4 with a negative step), so the arm meets the handle where the draw made sure
  it can reach it well, whatever the body did before;
* the body is a box (edges and mass uniform in ``[tasks.capture_draw]``'s ranges, uniform density) with the grasp
  frame ``handle_standoff_m`` off the centre of one face, on its normal, the frame's z axis (the tool's approach
  axis) pointing into the body: the tool comes in from outside along the face's normal;
* it spins at a rate uniform in the tier's range, about an axis at an angle uniform in ``spin_tilt_deg`` from the
  grasp axis (azimuth uniform, either sense), and drifts at a speed uniform in ``drift_m_s`` (direction uniform);
* it is kept when it clears the target configuration by ``min_target_clearance_m`` at t_c and the robot's start
  configuration by ``min_start_clearance_m`` at t = 0.

The approach (pre-grasp standoff, insertion, the body's danger radius) is the rule file's, the same for every
task. Screening (:func:`screen_capture`) then runs the nominal motion, as v2's screening does.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model import portable
from ffsr_gym.model.benchmark import Benchmark, CaptureDraw
from ffsr_gym.model.collision import BoxObstacle
from ffsr_gym.model.quaternion import from_rotation, to_rotation
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.model.scenario_sections import Randomization, TumblingTarget
from ffsr_gym.model.tumbling import grasp_pose, propagate
from ffsr_gym.scoring.score import CAPTURE_FAILURES
from ffsr_gym.sim.setup import prepare
from ffsr_gym.tasks.generator import MAX_SEED, nominal_motion
from ffsr_gym.tasks.random_family import target_attempt
from ffsr_gym.tasks.tiers import Verdict, certify
from ffsr_gym.types import Array

#: A body draw: from the rng, the box's edges [m] (None: none admissible), its mass [kg] and its body-frame spin
#: [deg/s] at the reachable moment.
BodyDraw = Callable[[np.random.Generator], tuple[Array | None, float, tuple[float, float, float]]]
#: The capture tiers, by spin rate: the index is part of each candidate's generator seed.
CAPTURE_TIERS = ("slow", "fast")
#: Screening causes of a capture candidate, in the order they are checked.
CAPTURE_SCREEN_CAUSES = ("draw_failed", "nominal_no_capture", "mission_singularity", "balance_singularity",
                         "self_collision")
#: Why a capture candidate is not in its tier.
CAPTURE_REJECTIONS = CAPTURE_SCREEN_CAUSES + tuple(f"unsolved_{name}" for name in CAPTURE_FAILURES) + ("fragile",)


def box_inertia(mass_kg: float, size_m: Array) -> tuple[float, float, float]:
    """Principal moments [kg m²] of a uniform box of edges ``size_m`` (a, b, c): m (b² + c²) / 12 and cyclically."""
    a, b, c = (float(x) for x in size_m)
    return mass_kg * (b * b + c * c) / 12.0, mass_kg * (a * a + c * c) / 12.0, mass_kg * (a * a + b * b) / 12.0


def _spin(draw: CaptureDraw, tier: str, rng: np.random.Generator) -> tuple[float, float, float]:
    """The body-frame angular velocity [deg/s]: the tier's rate about an axis tilted from the grasp axis (body z)."""
    return tilted_spin(draw.slow_spin_deg_s if tier == "slow" else draw.fast_spin_deg_s, draw.spin_tilt_deg, rng)


def tilted_spin(rate_deg_s: tuple[float, float], tilt_deg: tuple[float, float],
                rng: np.random.Generator) -> tuple[float, float, float]:
    """A body-frame angular velocity [deg/s]: a rate uniform in ``rate_deg_s`` about an axis at an angle uniform in
    ``tilt_deg`` from the grasp axis (body z), its azimuth uniform, either sense (drawn in this order)."""
    rate = rng.uniform(*rate_deg_s)
    tilt, azimuth = math.radians(rng.uniform(*tilt_deg)), rng.uniform(0.0, 2.0 * math.pi)
    sense = rng.choice((-1.0, 1.0))
    axis = (math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt))
    return tuple(float(sense * rate * x) for x in axis)


def _drift(draw: CaptureDraw, rng: np.random.Generator) -> tuple[float, float, float]:
    direction = rng.normal(size=3)
    return tuple(float(x) for x in rng.uniform(*draw.drift_m_s) * direction / portable.norm(direction))


def capture_v0_body(draw: CaptureDraw, tier: str) -> BodyDraw:
    """capture-v0's body draw for ``tier``: edges, mass and spin (module docstring), in this order from the rng."""
    return lambda rng: (rng.uniform(*draw.size_m, 3), rng.uniform(*draw.mass_kg), _spin(draw, tier, rng))


def sample_capture(family: Scenario, spec: Randomization, draw: CaptureDraw, tier: str,
                   rng: np.random.Generator, *, reach_time_s: float | None = None,
                   body: BodyDraw | None = None) -> Scenario:
    """One member of the capture family for ``tier`` (module docstring), its ``[target]`` the grasp frame; the
    grasp frame is drawn with ``spec``'s target ranges, the body with ``draw``. ``reach_time_s`` [s]: when the grasp
    frame is where the draw made sure the arm reaches it well (default: the end of the scripted insertion, the
    desired motion's time plus ``draw.insertion_time_s``, as capture-v0 draws; the draws of ``rng`` are the same
    either way). ``body``: the body's edges [m] (None: the draw is rejected), mass [kg] and body-frame spin at the
    reachable moment [deg/s] from the rng (default: :func:`capture_v0_body`).

    Raises:
        ScenarioError: no admissible draw within ``draw.max_attempts``.
    """
    setup = prepare(family)
    robot, collision, q_start = setup.robot, setup.assets.collision, setup.q0
    dt = family.simulation.dt_s
    reach = family.desired_path.motion_time_s + draw.insertion_time_s if reach_time_s is None else reach_time_s
    capture_steps = int(round(reach / dt))
    rejected = Counter()
    for _ in range(int(draw.max_attempts)):
        drawn = target_attempt(robot, q_start, spec, rng)
        size, mass, spin = (capture_v0_body(draw, tier) if body is None else body)(rng)
        drift = _drift(draw, rng)
        if drawn is None:
            rejected["min_travel_m / min_sigma_target (the grasp pose draw)"] += 1
            continue
        if size is None:
            rejected["min_inertia_spread (the body's principal moments)"] += 1
            continue
        q_target, grasp = drawn  # where the grasp frame is when the insertion ends
        depth = size[2] / 2.0 + draw.handle_standoff_m  # the grasp point's distance from the centre
        centre = grasp.translation + grasp.rotation[:, 2] * depth
        box = BoxObstacle(centre, size, grasp.rotation, name="target body")
        if collision.obstacle_proximity(q_target, [box]).distance_m < draw.min_target_clearance_m:
            rejected["min_target_clearance_m (the body at the grasp)"] += 1
            continue
        inertia = box_inertia(mass, size)
        back = propagate(position_m=centre, velocity_m_s=np.array(drift), quaternion=from_rotation(grasp.rotation),
                         omega_body_rad_s=np.radians(spin), inertia_kg_m2=np.array(inertia), dt_s=-dt,
                         steps=capture_steps)  # the torque-free motion run backwards to t = 0
        start_centre, start_attitude = back.position_m[-1], back.quaternion[-1]
        start_box = BoxObstacle(start_centre, size, to_rotation(start_attitude), name="target body")
        if collision.obstacle_proximity(q_start, [start_box]).distance_m < draw.min_start_clearance_m:
            rejected["min_start_clearance_m (the body at the start)"] += 1
            continue
        position, attitude = grasp_pose(start_centre, start_attitude, (0.0, 0.0, -depth), (1.0, 0.0, 0.0, 0.0))
        body = TumblingTarget(size_m=tuple(float(x) for x in size), mass_kg=float(mass), inertia_kg_m2=inertia,
                              position_m=tuple(float(x) for x in start_centre),
                              quaternion_wxyz=tuple(float(x) for x in start_attitude),
                              handle_position_m=(0.0, 0.0, -float(depth)), velocity_m_s=drift,
                              omega_body_deg_s=tuple(float(x) for x in np.degrees(back.omega_body_rad_s[-1])),
                              standoff_m=draw.standoff_m, insertion_time_s=draw.insertion_time_s,
                              danger_radius_m=draw.danger_radius_m)
        target = dataclasses.replace(family.target, position_m=tuple(float(x) for x in position),
                                     quaternion_wxyz=tuple(float(x) for x in attitude))
        return family.replace(target=target, tumbling_target=body)
    causes = ", ".join(f"{cause}: {count}" for cause, count in rejected.most_common())
    raise ScenarioError(f"scenario {family.name!r}: no admissible capture draw in {int(draw.max_attempts)} attempts "
                        f"(rejected by {causes}); widen [tasks.capture_draw] or relax that constraint")


def draw_capture_task(tier: str, seed: int, benchmark: Benchmark) -> Scenario | None:
    """The ``tier`` candidate of ``seed`` (named ``<version>-<tier>-<seed>``), or None when no draw is admissible.

    Raises:
        InvalidInputError: an unknown tier, a seed that is not an integer in [0, 2**63), or a rule file without
            ``[tasks.capture_draw]``.
    """
    if tier not in CAPTURE_TIERS:
        raise InvalidInputError(f"capture tier {tier!r}; allowed: {list(CAPTURE_TIERS)}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) <= MAX_SEED:
        raise InvalidInputError(f"task seed must be an integer in [0, 2**63), got {seed!r}")
    if benchmark.tasks.capture_draw is None:
        raise InvalidInputError(f"benchmark {benchmark.version!r} has no [tasks.capture_draw]; allowed: a capture "
                                "rule file (envs/benchmark/capture-v0.toml)")
    return _draw_capture_task(tier, int(seed), benchmark)


@lru_cache(maxsize=4096)
def _draw_capture_task(tier: str, seed: int, benchmark: Benchmark) -> Scenario | None:
    """:func:`draw_capture_task` after the checks (cached: the environments draw pool tasks again and again)."""
    rule = benchmark.tasks
    rng = np.random.default_rng([seed, 9, CAPTURE_TIERS.index(tier)])
    try:
        drawn = sample_capture(capture_family(benchmark), rule.draw, rule.capture_draw, tier, rng)
    except ScenarioError:
        return None
    version = benchmark.version
    return drawn.replace(name=f"{version}-{tier}-{seed}", description=f"{version} {tier} capture candidate of seed "
                                                                        f"{seed} (ffsr_gym.tasks.capture_family).")


@lru_cache(maxsize=4)
def capture_family(benchmark: Benchmark) -> Scenario:
    """The family scenario of a capture rule file, with its settings (cached; frozen)."""
    return benchmark.task(load_scenario(benchmark.tasks.family))


@dataclass(frozen=True)
class CaptureNominal:
    """What screening measured on a capture candidate's nominal motion (the default planner, avoidance off).

    Attributes:
        capture_time_s: when its first hold window ended (None: never).
        min_mission_sigma, min_balance_sigma: smallest σ_min of each arm's matrix over the episode.
        min_self_clearance_m: smallest arm-arm / arm-base clearance [m].
        peak_rate_deg_s: its largest joint rate.
        cause: the first failed check of :data:`CAPTURE_SCREEN_CAUSES`, or None (admitted).
    """

    capture_time_s: float | None
    min_mission_sigma: float
    min_balance_sigma: float
    min_self_clearance_m: float
    peak_rate_deg_s: float
    cause: str | None


def screen_capture(task: Scenario, benchmark: Benchmark) -> CaptureNominal:
    """Run ``task``'s nominal motion and apply the screening margins: the default planner must capture with the
    avoidance off, the mission arm keep σ_min(J_m) >= ``min_mission_sigma`` (a handle that swings through the
    workspace drags it through singularities), the balance arm σ_min(J_c²) >= ``min_balance_sigma`` and the arms
    their self clearance."""
    rule = benchmark.tasks
    traj, result = nominal_motion(task, benchmark)
    mission, balance = float(np.min(traj.sigma_min[:, 0])), float(np.min(traj.sigma_min[:, 1]))
    checks = (result.capture_time_s is None, mission < rule.min_mission_sigma, balance < rule.min_balance_sigma,
              result.min_self_clearance_m < rule.min_nominal_self_clearance_m)
    cause = next((name for name, failed in zip(CAPTURE_SCREEN_CAUSES[1:], checks) if failed), None)
    return CaptureNominal(result.capture_time_s, mission, balance, result.min_self_clearance_m,
                          max(result.peak_rate_deg_s), cause)


def classify_capture(tier: str, seed: int, benchmark: Benchmark) -> Verdict:
    """The capture tier rule on the ``tier`` candidate of ``seed``: rejected when no draw is admissible or screening
    fails (:data:`CAPTURE_SCREEN_CAUSES`); else certified as v2's perturbed tiers are
    (:func:`~ffsr_gym.tasks.tiers.certify`: the default planner, the grid, the residual trials, each in every kernel
    member of the ensemble), and admitted with the first certificate found, or rejected as ``fragile`` or
    ``unsolved_<failure of the default>``. ``nominal`` holds the screening's measurements: capture time [s] (None:
    none), σ_min of the mission and the balance arm, self clearance [m], peak rate [deg/s]."""
    task = draw_capture_task(tier, seed, benchmark)
    if task is None:
        return Verdict(int(seed), None, "draw_failed", None, 0.0, None, False, (), 0)
    nominal = screen_capture(task, benchmark)
    measured = (nominal.capture_time_s, nominal.min_mission_sigma,
                nominal.min_balance_sigma, nominal.min_self_clearance_m, nominal.peak_rate_deg_s)
    if nominal.cause is not None:
        return Verdict(int(seed), None, nominal.cause, None, 0.0, None, False, measured, 1)
    found = certify(task, seed, benchmark)
    runs = found.rollouts + 1
    if found.fragile is not None:
        return Verdict(int(seed), None, "fragile", None, 0.0, found.default_failure, True, measured, runs)
    if found.certificate is None:
        return Verdict(int(seed), None, f"unsolved_{found.default_failure}", None, 0.0, found.default_failure, False,
                       measured, runs)
    return Verdict(int(seed), tier, None, found.certificate, found.result.score, found.default_failure,
                   found.constant_solvable, measured, runs, found.margins)
