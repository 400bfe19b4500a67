"""Certificates: a planner setting or a residual action that passes a task's success test.

A certificate is replayed exactly as the environments of its benchmark version step: decisions
every ``env.decision_interval_s``, stop at the first violation, scored by
:func:`ffsr_gym.scoring.score.score_episode`.

* ``constant``: ``FFSR-v2`` with the same physical (m, T_c [s]) at every decision
  (``env.unwrapped.step_with_parameters(m, T_c)``);
* ``residual``: ``FFSR-Residual-v2`` with the same action (12 values in [-1, 1], exact in float32)
  at every decision, faded by the benchmark's law, on top of the default planner;
* ``timed`` (capture v1): ``FFSR-Capture-v1`` with the same (m, T_c), holding the start pose (command 0) until
  ``go_s`` [s], then commanding the insertion (command 2), as one run scored up to its capture.

From v2 on, a certificate must also succeed in every member of the rule file's ensemble
(:func:`ensemble_members`): the task at smaller steps, from starts a hair off, and on the
Pinocchio backend. :class:`Margins` keeps the worst of its margins over the members.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.benchmark import Benchmark, Ensemble, residual_rates
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.planning.planner import planner_parameters
from ffsr_gym.scoring.capture import native_capture
from ffsr_gym.scoring.score import EpisodeScore, score_episode
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import make_rollout
from ffsr_gym.sim.trajectory import Trajectory

KINDS = ("constant", "residual", "timed")


@dataclass(frozen=True)
class Certificate:
    """A replayable proof that a task is solvable.

    Attributes:
        kind: ``"constant"``, ``"residual"`` or ``"timed"``.
        m, T_c_s: the planner's (m, T_c [s]) (for ``residual``: the benchmark's default).
        residual: (12,) the constant ``FFSR-Residual-v2`` action, or None.
        go_s: (``timed``) when the insertion is commanded [s], a whole number of decisions; else None.
    """

    kind: str
    m: float
    T_c_s: float
    residual: tuple[float, ...] | None = None
    go_s: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InvalidInputError(f"certificate kind {self.kind!r}; allowed: {list(KINDS)}")
        if (self.residual is None) != (self.kind != "residual"):
            raise InvalidInputError("a 'residual' certificate needs 12 residual values; a 'constant' or 'timed' one "
                                    "none")
        if (self.go_s is None) != (self.kind != "timed") or (
                self.go_s is not None and not (math.isfinite(self.go_s) and 0.0 <= self.go_s <= 3600.0)):
            raise InvalidInputError(f"certificate go_s = {self.go_s!r}; allowed: a 'timed' certificate's time in "
                                    "[0, 3600] s, none for the other kinds")
        if self.residual is not None:
            values = np.asarray(self.residual, dtype=float)
            if values.shape != (12,) or not np.all(np.abs(values) <= 1.0):
                raise InvalidInputError(f"certificate residual must be 12 values in [-1, 1], got {self.residual!r}")
            if np.any(values.astype(np.float32).astype(float) != values):
                raise InvalidInputError("certificate residual values must be exact in float32 (they are env actions)")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict (residual omitted for a constant certificate)."""
        data: dict[str, Any] = {"kind": self.kind, "m": self.m, "T_c_s": self.T_c_s}
        if self.residual is not None:
            data["residual"] = list(self.residual)
        if self.go_s is not None:
            data["go_s"] = self.go_s
        return data

    @classmethod
    def from_dict(cls, data: Any) -> Certificate:
        """Inverse of :meth:`as_dict`.

        Raises:
            InvalidInputError: not a dict of the keys above with numbers in range.
        """
        if not isinstance(data, dict) or set(data) - {"kind", "m", "T_c_s", "residual", "go_s"}:
            raise InvalidInputError(f"certificate must be a dict with keys kind, m, T_c_s[, residual][, go_s], got "
                                    f"{data!r}")
        try:
            m, T_c = float(data["m"]), float(data["T_c_s"])
            residual = None if data.get("residual") is None else tuple(float(x) for x in data["residual"])
            go = None if data.get("go_s") is None else float(data["go_s"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidInputError(f"certificate {data!r}: {exc}") from None
        if not (0.0 < m < 1.0 and math.isfinite(T_c) and T_c > 0.0):
            raise InvalidInputError(f"certificate (m, T_c_s) = ({m}, {T_c}); allowed: m in (0, 1), T_c_s > 0")
        return cls(kind=data.get("kind"), m=m, T_c_s=T_c, residual=residual, go_s=go)


def planner_task(task: Scenario, method: str, gain_per_s: float | None) -> Scenario:
    """``task`` with the proportional planner's gain K [1/s] set (other methods: unchanged)."""
    if method != "proportional" or gain_per_s is None:
        return task
    if not (isinstance(gain_per_s, (int, float)) and math.isfinite(gain_per_s) and gain_per_s > 0):
        raise InvalidInputError(f"gain_per_s = {gain_per_s!r}; allowed: a finite number > 0 [1/s]")
    return task.replace(planner=dataclasses.replace(task.planner, proportional_gain_per_s=float(gain_per_s)))


def planner_episode(task: Scenario, benchmark: Benchmark, *, method: str, m: float | None = None,
                    T_c: float | None = None, gain_per_s: float | None = None, go_s: float | None = None,
                    backend: str = "auto") -> EpisodeScore:
    """One episode of a reference-planner variant with constant parameters, scored like every env episode.

    ``method`` is one of :data:`ffsr_gym.planning.planner.METHODS` (``predefined_time`` with
    (m, T_c [s]), ``proportional`` with gain K [1/s]); the run stops at the first violation, as
    the environments do. ``go_s`` [s] (a task with a commanded approach): hold the start pose, then command the
    insertion from the first decision at or after it (:func:`timed_run`).
    """
    played = planner_task(task, method, gain_per_s)
    if go_s is not None:
        return score_episode(timed_run(played, m, T_c, go_s, method=method, backend=backend), played, benchmark)
    return score_episode(planner_run(played, method=method, m=m, T_c=T_c, backend=backend), played, benchmark)


def planner_run(played: Scenario, *, method: str, m: float | None, T_c: float | None, backend: str = "auto") -> Trajectory:
    """The trajectory of :func:`planner_episode` (``played``: the task as :func:`planner_task` returns it)."""
    rollout = make_rollout(played, backend=backend, method=method, m=m, T_c=T_c)
    rollout.advance(played.n_steps, stop_on_violation=True)
    rollout.finish()
    return rollout.trajectory()


def replay(task: Scenario, certificate: Certificate, benchmark: Benchmark, *, backend: str = "auto") -> EpisodeScore:
    """Run ``certificate`` on ``task`` the way the environments step, and score the episode.

    A constant certificate is one run of :func:`planner_episode` (bit-identical with stepping the
    env decision by decision); a residual one steps decision by decision, fading the residual; a timed one is
    :func:`timed_run`.
    """
    if certificate.go_s is not None:
        return score_episode(timed_run(task, certificate.m, certificate.T_c_s, certificate.go_s, backend=backend),
                             task, benchmark)
    if certificate.residual is None:
        return planner_episode(task, benchmark, method="predefined_time", m=certificate.m, T_c=certificate.T_c_s,
                               backend=backend)
    m, T_c = planner_parameters(task, "predefined_time", certificate.m, certificate.T_c_s)
    rollout = make_rollout(task, backend=backend, m=m, T_c=T_c)
    per_decision = max(1, int(round(task.env.decision_interval_s / task.simulation.dt_s)))
    action = np.asarray(certificate.residual, dtype=np.float32)
    motion_time = task.desired_path.motion_time_s
    while rollout.k < rollout.n_steps:
        residual = benchmark.residual_fade(rollout.t, motion_time) * residual_rates(action, task.env.residual_rate_deg_s)
        _, status = rollout.advance(per_decision, residual, stop_on_violation=True)
        if status != "ok":
            break
    rollout.finish()
    return score_episode(rollout.trajectory(), task, benchmark)


def timed_run(task: Scenario, m: float | None, T_c: float | None, go_s: float, *, method: str = "predefined_time",
              backend: str = "auto") -> Trajectory:
    """The whole run of a timed certificate on a task with a commanded approach: the planner at (m, T_c [s]) holds
    the start pose until the first decision at or after ``go_s`` [s] (as the environments read a timed policy),
    then is commanded to the grasp frame (u = 2); it stops at a violation, not at the capture (the score ends the
    episode there; the run's remainder gives the certificate's margins)."""
    rollout = make_rollout(task, backend=backend, method=method, m=m, T_c=T_c)
    per_decision = max(1, int(round(task.env.decision_interval_s / task.simulation.dt_s)))
    wait, status = min(go_decision_of(go_s, task.env.decision_interval_s) * per_decision, task.n_steps), "ok"
    if wait:
        _, status = rollout.advance(wait, stop_on_violation=True)
    if status == "ok" and rollout.k < rollout.n_steps:
        rollout.set_command(2.0)
        rollout.advance(rollout.n_steps - rollout.k, stop_on_violation=True)
    rollout.finish()
    return rollout.trajectory()


def go_decision_of(go_s: float, interval_s: float) -> int:
    """The decision a timed policy commands the insertion at: the first at or after ``go_s`` [s], as the
    environments read it (decision k at k ``interval_s``, compared with go_s - 1e-9)."""
    return math.ceil((go_s - 1e-9) / interval_s)


def replay_with_margins(task: Scenario, certificate: Certificate, benchmark: Benchmark, *,
                        backend: str = "auto") -> tuple[EpisodeScore, Margins]:
    """:func:`replay`, and the margins of its episode. A timed certificate's capture ratio is that of its whole
    run (:func:`timed_run`: had the tolerances been that factor tighter, it would still have captured, perhaps
    later); the episode itself ends at its capture, where its own ratio is about 1 by construction."""
    if certificate.go_s is None:
        result = replay(task, certificate, benchmark, backend=backend)
        return result, Margins.worst([result])
    run = timed_run(task, certificate.m, certificate.T_c_s, certificate.go_s, backend=backend)
    result = score_episode(run, task, benchmark)
    return result, Margins.worst([dataclasses.replace(result, capture_ratio=whole_run_ratio(run, task, benchmark))])


def whole_run_ratio(run: Trajectory, task: Scenario, benchmark: Benchmark) -> float:
    """The capture ratio of a capture v1 run that goes on past its capture (its episode ends there, with a ratio
    of about 1): the margin a timed certificate, or any timed schedule, is judged on in the certificate test."""
    return native_capture(prepare(task), run, benchmark.capture).margin_ratio


@dataclass(frozen=True)
class Member:
    """One member of a certificate's ensemble: its name, the task it plays and the backend."""

    name: str
    task: Scenario
    backend: str = "kernel"


def offset_start(task: Scenario, offsets_deg: Any) -> Scenario:
    """``task`` with its 12 initial joint angles moved by ``offsets_deg`` [deg] (mission arm, then balance arm)."""
    offsets = np.asarray(offsets_deg, dtype=float)
    initial = task.initial
    moved = dataclasses.replace(
        initial, mission_joints_deg=tuple(float(a + d) for a, d in zip(initial.mission_joints_deg, offsets[:6])),
        balance_joints_deg=tuple(float(a + d) for a, d in zip(initial.balance_joints_deg, offsets[6:])))
    return dataclasses.replace(task, initial=moved)


def start_offsets(seed: int, draw: int, offset_deg: float) -> np.ndarray:
    """The ``draw``-th start offset of candidate ``seed``: ± ``offset_deg`` per joint, signs from ``default_rng([seed, 4 + draw])``."""
    return offset_deg * np.random.default_rng([int(seed), 4 + int(draw)]).choice((-1.0, 1.0), 12)


def ensemble_members(task: Scenario, seed: int, ensemble: Ensemble, *, pinocchio: bool | None = None) -> list[Member]:
    """The members of ``task``'s ensemble besides the task itself, in a fixed order: the smaller steps,
    the offset starts, a tumbling target's perturbed spin (``omega_offset_deg_s`` > 0), then (``pinocchio``,
    default: the ensemble's own setting) the Pinocchio backend."""
    dt = task.simulation.dt_s
    members = [Member(f"dt/{int(d)}", task.at_step(dt / d)) for d in ensemble.step_divisors]
    members += [Member(f"start {draw + 1}", offset_start(task, start_offsets(seed, draw, ensemble.start_offset_deg)))
                for draw in range(ensemble.start_draws)]
    body = task.tumbling_target
    if body is not None:
        members += target_members(task, seed, ensemble)
    if ensemble.pinocchio if pinocchio is None else pinocchio:
        if task.simulation.plant == "servo":
            raise InvalidInputError(f"task {task.name!r}: the servo plant runs on the kernel only, so it has no "
                                    "Pinocchio member; its last member is ffsr_gym.tasks.perturbation.confirmation_member")
        members.append(Member("pinocchio", task, "pinocchio"))
    return members


def target_members(task: Scenario, seed: int, ensemble: Ensemble) -> list[Member]:
    """The members of a task with a tumbling target whose body moves otherwise: its spin off by
    ``omega_offset_deg_s`` per component (drawn signs, or every sign pattern), then its drift off by
    ``drift_offset_m_s`` along each world axis, each way (:class:`~ffsr_gym.model.benchmark.Ensemble`)."""
    body, members = task.tumbling_target, []
    if ensemble.omega_offset_deg_s > 0.0:
        if ensemble.omega_sign_patterns:
            patterns = [(f"omega {''.join('+' if s > 0 else '-' for s in signs)}", np.array(signs))
                        for signs in itertools.product((1.0, -1.0), repeat=3)]
        else:
            patterns = [("omega" if draw == 0 else f"omega {draw + 1}",
                         np.random.default_rng([int(seed), 8] if draw == 0 else [int(seed), 8, draw]).choice(
                             (-1.0, 1.0), 3)) for draw in range(ensemble.omega_draws)]
        for name, signs in patterns:
            spin = tuple(float(w + ensemble.omega_offset_deg_s * s) for w, s in zip(body.omega_body_deg_s, signs))
            members.append(Member(name, task.replace(tumbling_target=dataclasses.replace(body, omega_body_deg_s=spin))))
    if ensemble.drift_offset_m_s > 0.0:
        for axis, sign in itertools.product(range(3), (1.0, -1.0)):
            velocity = [float(v) for v in body.velocity_m_s]
            velocity[axis] += sign * ensemble.drift_offset_m_s
            moved = dataclasses.replace(body, velocity_m_s=tuple(velocity))
            members.append(Member(f"drift {'+' if sign > 0 else '-'}{'xyz'[axis]}", task.replace(tumbling_target=moved)))
    return members


@dataclass(frozen=True)
class Margins:
    """The worst success margins of a certificate over the episodes it was replayed in.

    Attributes:
        min_clearance_m: smallest robot–obstacle clearance [m] (inf without obstacle).
        min_self_clearance_m: smallest arm-arm / arm-base clearance [m].
        peak_rate_deg_s: largest joint rate of either arm [deg/s].
        final_ee_position_error_m, final_ee_attitude_error: largest final end-effector errors.
        episodes: how many episodes these are the worst of.
        capture_ratio: under a capture rule, the largest worst value / bound of the capture quantities over the
            hold windows (None: no capture rule).
    """

    min_clearance_m: float
    min_self_clearance_m: float
    peak_rate_deg_s: float
    final_ee_position_error_m: float
    final_ee_attitude_error: float
    episodes: int
    capture_ratio: float | None = None

    @classmethod
    def worst(cls, results: list[EpisodeScore]) -> Margins:
        """The worst margins of ``results`` (at least one episode)."""
        ratios = [r.capture_ratio for r in results if r.capture_ratio is not None]
        return cls(min(r.min_clearance_m for r in results), min(r.min_self_clearance_m for r in results),
                   max(max(r.peak_rate_deg_s) for r in results), max(r.final_ee_position_error_m for r in results),
                   max(r.final_ee_attitude_error for r in results), len(results), max(ratios) if ratios else None)

    def short(self, benchmark: Benchmark) -> str | None:
        """Which margin is inside the ensemble's hair's-breadth band (None: all clear it, or no ensemble). Under a
        capture rule the capture ratio must stay within ``error_margin`` instead of the final errors."""
        ensemble = benchmark.tasks.ensemble
        if ensemble is None:
            return None
        if benchmark.capture is None:
            return ensemble.short_margin(self.peak_rate_deg_s, self.min_clearance_m, self.min_self_clearance_m,
                                         (self.final_ee_position_error_m, self.final_ee_attitude_error), benchmark.score)
        short = ensemble.short_margin(self.peak_rate_deg_s, self.min_clearance_m, self.min_self_clearance_m, (0.0, 0.0),
                                      benchmark.score)
        if short is None and (self.capture_ratio is None or self.capture_ratio > ensemble.error_margin):
            return "capture margin"
        return short

    def merge(self, other: Margins) -> Margins:
        """The worst of both."""
        ratios = [r for r in (self.capture_ratio, other.capture_ratio) if r is not None]
        return Margins(min(self.min_clearance_m, other.min_clearance_m),
                       min(self.min_self_clearance_m, other.min_self_clearance_m),
                       max(self.peak_rate_deg_s, other.peak_rate_deg_s),
                       max(self.final_ee_position_error_m, other.final_ee_position_error_m),
                       max(self.final_ee_attitude_error, other.final_ee_attitude_error), self.episodes + other.episodes,
                       max(ratios) if ratios else None)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict (an infinite clearance becomes None; the capture ratio only under a capture rule)."""
        data = dataclasses.asdict(self)
        data["min_clearance_m"] = None if math.isinf(self.min_clearance_m) else self.min_clearance_m
        if self.capture_ratio is None:
            del data["capture_ratio"]
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Margins:
        """Inverse of :meth:`as_dict`."""
        clearance, ratio = data["min_clearance_m"], data.get("capture_ratio")
        return cls(math.inf if clearance is None else float(clearance), float(data["min_self_clearance_m"]),
                   float(data["peak_rate_deg_s"]), float(data["final_ee_position_error_m"]),
                   float(data["final_ee_attitude_error"]), int(data["episodes"]),
                   None if ratio is None else float(ratio))


def replay_members(members: list[Member], certificate: Certificate, benchmark: Benchmark
                   ) -> tuple[str | None, list[EpisodeScore]]:
    """Replay ``certificate`` in each member, stopping at the first that fails.

    Returns ``(failed, results)``: the name of the member that failed (None: all succeeded) and
    the results so far.
    """
    results = []
    for member in members:
        results.append(replay(member.task, certificate, benchmark, backend=member.backend))
        if not results[-1].success:
            return member.name, results
    return None, results
