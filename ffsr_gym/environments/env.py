"""The single Gymnasium environment of every benchmark version: an adapter over one engine copy."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from ffsr_gym.environments import info as info_contract
from ffsr_gym.environments.actions import (
    action_to_parameters,
    observation_bounds,
    physical_command,
    physical_parameters,
)
from ffsr_gym.environments.engine import EpisodeEngine
from ffsr_gym.environments.task_source import TaskSource
from ffsr_gym.exceptions import InvalidInputError, UnknownArgumentError
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.sim.rollout import Rollout
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.versions.registry import spec_for_version


def task_options(spec: BenchmarkSpec, options: dict[str, Any]) -> dict[str, Any]:
    """The task and reward options an environment of ``spec`` takes, checked.

    Raises:
        UnknownArgumentError: a keyword the version does not take (named, with the allowed ones).
        InvalidInputError: a flag that is not a bool.
    """
    allowed = spec.env_options()
    for name in options:
        if name not in allowed:
            raise UnknownArgumentError(f"{spec.ids.parameters} got an unexpected keyword argument {name!r}; "
                                       f"allowed: {sorted(allowed)}")
    for name in spec.reward.options:
        if name in options and not isinstance(options[name], bool):
            raise InvalidInputError(f"{name} must be True or False, got {options[name]!r}")
    return options


class FFSREnv(gym.Env):
    """Dual-arm free-floating space robot reaching a target past an obstacle (every benchmark version).

    ## Description
    A 200 kg free-floating base carries a mission arm (tracks a desired end-effector path to a
    target pose) and a balance arm (keeps the base pose through momentum conservation). The
    reference controller is the predefined-time planner of Yan & Liu with cumulative-danger-field
    avoidance (``ffsr_gym.planning.planner``). The physics runs at the task's ``dt_s`` (0.01 s)
    between decisions of 0.1 s. What a version changes (score rule, action boxes, reward, tasks) is
    its spec file ``envs/benchmark/spec_<version>.toml``; docs/envs.md has each version's tables.

    ## Action Space
    ``FFSR-v*``: ``Box(-1, 1, (2,), float32)``, mapped linearly onto the task's (m, T_c) box per
    decision. ``FFSR-Residual-v*``: ``Box(-1, 1, (12,), float32)``, ± ``residual_rate_deg_s`` per
    joint (mission arm first) added to the reference planner (faded to zero by the end of the
    desired motion where the spec says so). Out-of-range actions are clipped and counted
    (``info["clipped_actions"]``); NaN, inf or a wrong shape raise ``ValueError``.

    ## Observation Space
    ``Box(float32, (53,))``: sin (12) and cos (12) of the joint angles; joint rates applied last
    [rad/s] (12, clipped to ±20); end-effector pose error (6) and base pose error (6), clipped to
    ±10; obstacle position relative to the nearest robot point [m] (3, zero without obstacle);
    clearance robot-obstacle [m] (1, clipped to [-10, 10]); elapsed-time fraction (1).

    ## Rewards
    As the spec's score rule says (``ffsr_gym.scoring.rules``): v0, minus B's per-decision
    increment and the scenario's penalties (a feasible episode sums to −B); v2, the change of the
    episode's value 1 / (1 + C_t), so rewards sum to the score minus 1. ``info`` has the
    increment, ``penalty``, ``cost``, ``clearance_m``, ``ee_position_error_m``, ``clipped_actions``
    and, at the end, the rule's episode keys (``score`` among them), computed from the trajectory.

    ## Starting State
    The task's initial state: a fixed scenario, a draw of a seeded family, or a tier's pool task
    drawn from ``self.np_random`` (``reset(options={"task_index": i})`` picks one).

    ## Episode End
    Terminated on a joint rate above the limit or a collision (v2: an obstacle clearance below the
    1 cm keep-out distance; v0: contact); truncated at the task's
    ``simulation.duration_s`` (200 decisions).

    ## Arguments
    ``gymnasium.make(id, <task keyword>=..., render_mode=None, backend="auto", ...)``: v0 takes
    ``scenario=``; v2 ``task=``, ``split=``, ``dt_s=``, ``terminate_on_violation=``, ``dense_shaping=``.
    ``backend``: ``"auto"`` (compiled kernel), ``"kernel"`` or ``"pinocchio"`` (the reference).

    ## Version History

    * v2: verdicts of the closed loop, not of the time step: the distance blend law, a 1 cm
      keep-out distance, tiers certified over an ensemble (dt/2, dt/4, starts 1e-6 deg off,
      Pinocchio) with margins, train / validation / test pools, ``dt_s=`` for sensitivity studies.
      Tier ``servo`` (the tier tasks on the torque-level plant) added later; no other pool changed.
    * v1 (retired): bounded score that ranks, rewards that sum to it, 1 mm tolerance, fading
      residual, certified task tiers (easy / medium / hard, debris, robust); its verdicts were set
      by the 0.01 s step (docs/envs.md, Version history).
    * v0: initial release (frozen).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(self, version: str = "v2", residual: bool = False, render_mode: str | None = None,
                 backend: str = "auto", **options: Any) -> None:
        self.benchmark_spec = spec = spec_for_version(version)
        options = task_options(spec, options)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidInputError(f"render_mode {render_mode!r}; allowed: {self.metadata['render_modes']} or None")
        if not isinstance(residual, (bool, np.bool_)):
            raise InvalidInputError(f"residual = {residual!r}; allowed: True or False (each id sets it: "
                                    "FFSR-Residual-v* is the residual one)")
        self.render_mode, self.residual, self._renderer = render_mode, bool(residual), None
        rule = score_rule(spec)
        self.source = TaskSource(spec, rule, options.get(spec.tasks.keyword), options.get("split"), options.get("dt_s"))
        self.engine = EpisodeEngine(self.source, residual=self.residual, backend=backend,
                                    terminate_on_violation=options.get("terminate_on_violation", True),
                                    dense_shaping=options.get("dense_shaping", False))
        self.action_space = gym.spaces.Box(-1.0, 1.0, self.engine.action_shape, np.float32)
        self.observation_space = gym.spaces.Box(*observation_bounds(spec.target_twist, spec.grasp_observation),
                                                dtype=np.float32)
        self.family = self.scenario = self.source.family
        self.benchmark = rule.benchmark
        self.task_name, self.split, self.pool = self.source.name, self.source.split, self.source.pool
        self.steps_per_decision = self.engine.steps_per_decision
        self._started = False

    @property
    def decisions(self) -> int:
        """The decisions of one whole episode of this env's tasks: duration / decision interval."""
        return self.engine.n_steps // self.engine.steps_per_decision

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.engine.reset_copy(0, self.np_random, options)
        self.scenario, self._started = self.engine.scenarios[0], True
        return self.engine.obs[0].copy(), info_contract.scalars(self.engine.reset_info(), 0)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        if not self._started or self.engine.rollouts[0].finished:
            self._check_running()  # raises, naming the problem
        out = self.engine.step_one(action)
        if self.render_mode == "human":
            self.render()
        return out

    def step_with_parameters(self, m: float, T_c: float,
                             command: float | None = None) -> tuple[np.ndarray, float, bool, bool, dict]:
        """A step of an (m, T_c) env with physical parameters m ∈ (0, 1) and T_c [s] > 0 (no float32 rounding);
        ``command``: capture v1's approach command u ∈ [0, 2] from this step on (None: as it was)."""
        if self.residual:
            raise InvalidInputError("step_with_parameters is for the (m, T_c) envs (FFSR-v0, FFSR-v2), not a residual env")
        self._check_running()
        parameters = physical_parameters(m, T_c)
        if command is not None:
            self.engine.set_command((0,), physical_command(command, self.engine.grasp))
        out = self.engine.step_one(None, parameters=parameters)
        if self.render_mode == "human":
            self.render()
        return out

    def action_to_parameters(self, action: np.ndarray) -> tuple[float, float]:
        """Physical (m, T_c [s]) of a (clipped) (m, T_c) action, in float64."""
        return action_to_parameters(action, self.scenario)

    def _check_running(self) -> None:
        """Refuse a step before the first reset or after the episode ended (Gymnasium leaves it undefined)."""
        if not self._started:
            raise InvalidInputError("call reset() before step()")
        if self.engine.finished(0):
            raise InvalidInputError("step() after the episode ended (terminated or truncated); call reset() first")

    @property
    def compiled_step(self) -> bool:
        """Whether decisions run as one compiled call (False: the reference pipeline, see the engine)."""
        return self.engine.compiled

    @compiled_step.setter
    def compiled_step(self, value: bool) -> None:
        if value is not self.engine.compiled:
            if value:
                raise InvalidInputError("compiled_step can only be switched off (right after reset)")
            self.engine.use_reference_pipeline()

    @property
    def rollout(self) -> Rollout:
        """The current episode's rollout (state, time, trajectory buffers)."""
        return self.engine.rollout(0)

    @property
    def trajectory(self) -> Trajectory:
        """The current episode's :class:`~ffsr_gym.sim.trajectory.Trajectory` (samples so far)."""
        return self.engine.trajectory(0)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        from ffsr_gym.environments.render import SceneRenderer, ending

        if self._renderer is None:
            self._renderer = SceneRenderer(interactive=self.render_mode == "human")
        end = ending(self.engine) if self._started else None
        return self._renderer.draw(self.rollout, self.scenario, end)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

