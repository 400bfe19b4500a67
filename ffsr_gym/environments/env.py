"""Gymnasium environments ``FFSR-v0`` and ``FFSR-Residual-v0``: thin glue over :class:`Rollout`."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model import portable
from ffsr_gym.model.scenario import Scenario, load_scenario, residual_rates
from ffsr_gym.scoring.objective import ObjectiveTerms, objective_terms, rate_terms, smooth_part
from ffsr_gym.sim.rollout import BACKENDS, Rollout
from ffsr_gym.sim.simulate import make_rollout
from ffsr_gym.tasks.random_family import sample_scenario

OBS_CLIP = {"rates": 20.0, "errors": 10.0, "relative": 10.0, "clearance": 10.0}


def assemble_observation(angles: np.ndarray, last_rates: np.ndarray, ee_error: np.ndarray, base_error: np.ndarray,
                         relative: np.ndarray, clearance: Any, time_fraction: Any) -> np.ndarray:
    """The 53-dim float32 observation from its parts (see :class:`FFSREnv`); leading batch axes allowed.

    Args:
        angles: joint angles [rad] (..., 12). last_rates: joint rates applied last [rad/s] (..., 12).
        ee_error, base_error: pose errors (..., 6). relative: obstacle relative to the nearest robot
        point [m] (..., 3). clearance: robot–obstacle clearance [m] (...). time_fraction: t / duration (...).
    """
    return np.concatenate([
        np.sin(angles), np.cos(angles),
        np.clip(last_rates, -OBS_CLIP["rates"], OBS_CLIP["rates"]),
        np.clip(np.concatenate((ee_error, base_error), axis=-1), -OBS_CLIP["errors"], OBS_CLIP["errors"]),
        np.clip(relative, -OBS_CLIP["relative"], OBS_CLIP["relative"]),
        np.clip(np.asarray(clearance, dtype=float), -OBS_CLIP["clearance"], OBS_CLIP["clearance"])[..., None],
        np.minimum(1.0, np.asarray(time_fraction, dtype=float))[..., None],
    ], axis=-1).astype(np.float32)


def check_action(action: Any, shape: tuple[int, ...]) -> tuple[np.ndarray, Any]:
    """An action of ``shape`` (a batch of them: leading axis = copies) clipped to [-1, 1] as float32.

    Returns the clipped action and whether it (each row of a batch) was clipped.

    Raises:
        InvalidInputError: wrong shape, or a NaN/inf entry (naming the copies of a batch).
    """
    try:
        raw = np.asarray(action)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"action must be an array of real numbers of shape {shape} ({exc})") from None
    if raw.dtype.kind not in "biuf":
        raise InvalidInputError(f"action must hold real numbers (bool, int or float) of shape {shape}, got dtype "
                                f"{raw.dtype} ({'complex' if raw.dtype.kind == 'c' else 'not numeric'})")
    a = raw.astype(np.float64)
    if a.shape != shape:
        raise InvalidInputError(f"action must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        if a.ndim == 2:
            bad = sorted({int(i) for i in np.argwhere(~np.isfinite(a))[:, 0]})
            raise InvalidInputError(f"actions of copies {bad} are not finite; allowed range [-1, 1] per entry")
        raise InvalidInputError(f"action must be finite, got {a}; allowed range [-1, 1] per entry")
    clipped = np.clip(a, -1.0, 1.0)
    return clipped.astype(np.float32), np.any(clipped != a, axis=-1)


class FFSREnv(gym.Env):
    """Dual-arm free-floating space robot reaching a target past an obstacle.

    ## Description
    A 200 kg free-floating base carries a mission arm (tracks a desired end-effector trajectory to
    a target pose) and a balance arm (keeps the base pose through momentum conservation). The
    reference controller is the predefined-time planner of Yan & Liu with cumulative-danger-field
    avoidance (``ffsr_gym.planning.planner``). In ``FFSR-v0`` the agent chooses the planner's parameters
    (m, T_c) for every decision interval; in ``FFSR-Residual-v0`` it adds joint rates to the
    reference planner's output. The physics runs at the scenario's ``dt_s`` (0.01 s) between
    decisions. Episodes are scored with the paper's objective B (``ffsr_gym.scoring.objective``).

    ## Action Space
    ``FFSR-v0``: ``Box(-1, 1, (2,), float32)``, mapped linearly onto ``env.m_bounds`` (default
    [0.05, 0.95]) and ``env.T_c_bounds_s`` (default [0.5, 10] s). ``FFSR-Residual-v0``:
    ``Box(-1, 1, (12,), float32)``, mapped to ± ``env.residual_rate_deg_s`` (default 20 deg/s)
    per joint, mission arm first, added to the reference rates (m, T_c from the scenario).
    Out-of-range actions are clipped and counted (``info["clipped_actions"]``); NaN, inf or a wrong
    shape raise ``ValueError``.

    ## Observation Space
    ``Box(float32, (53,))``: sin (12) and cos (12) of the joint angles; joint rates applied last
    [rad/s] (12, clipped to ±20); end-effector pose error e₁ = [p_e − p_d [m]; e_o] (6) and base pose
    error e₀ (6), clipped to ±10; obstacle position relative to the nearest robot point [m] (3, zero
    without obstacle); clearance robot-obstacle [m] (1, clipped to [-10, 10], 10 without obstacle);
    elapsed-time fraction (1).

    ## Rewards
    Minus the per-interval increment of B's finite part γ(α∫Ψ¹ + β∫Ψ²), so a feasible episode sums
    to exactly −B. A rate-limit violation or a collision ends the episode (``terminated``) with an
    extra ``-env.violation_penalty``; at the horizon (``truncated``) ``-env.tolerance_penalty`` is added
    if the final end-effector errors miss the tolerances. Rewards are always finite.
    ``info`` has the terms (``objective_increment``, ``penalty``), ``cost`` (1.0 on a violation),
    ``clearance_m``, ``ee_position_error_m``, ``clipped_actions``, and on the last step ``objective``
    (B, may be inf), ``feasible`` and ``score`` (B if feasible, else inf).

    ## Starting State
    The scenario's initial state. With ``scenario="random"`` the target pose and the obstacle are
    drawn from ``self.np_random`` at every reset; ``reset(seed=...)`` fully determines the episode.

    ## Episode End
    Terminated on a joint rate above ``objective.max_rate_deg_s`` or a negative clearance;
    truncated after ``simulation.duration_s`` (20 s, 200 decisions).

    ## Arguments
    ``gymnasium.make("FFSR-v0", scenario="paper", render_mode=None)``: ``scenario`` is a shipped
    name (``paper``, ``paper_as_printed``, ``free_space``, ``random``), a TOML path, or a
    :class:`~ffsr_gym.model.scenario.Scenario`; ``backend``: ``"auto"`` (compiled kernel when numba is
    installed), ``"kernel"`` or ``"pinocchio"`` (reference implementation, same numbers to 1e-9).

    ## Version History
    * v0: initial release (scenario schema 1, robot ``ffsr_dual_arm``).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}
    residual = False

    def __init__(self, scenario: str | Scenario = "paper", render_mode: str | None = None, backend: str = "auto") -> None:
        self.family = load_scenario(scenario)
        if backend not in BACKENDS:
            raise InvalidInputError(f"backend {backend!r}; allowed: {list(BACKENDS)}")
        self.backend = backend
        self.randomised = self.family.randomization is not None
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidInputError(f"render_mode {render_mode!r}; allowed: {self.metadata['render_modes']} or None")
        self.render_mode = render_mode
        settings = self.family.env
        self.steps_per_decision = max(1, int(round(settings.decision_interval_s / self.family.simulation.dt_s)))
        size = 12 if self.residual else 2
        self.action_space = gym.spaces.Box(-1.0, 1.0, (size,), np.float32)
        high = np.concatenate([np.ones(24), np.full(12, OBS_CLIP["rates"]), np.full(12, OBS_CLIP["errors"]),
                               np.full(3, OBS_CLIP["relative"]), [OBS_CLIP["clearance"]], [1.0]]).astype(np.float32)
        low = -high
        low[-1] = 0.0
        self.observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        self.scenario = self.family
        self.rollout: Rollout | None = None
        self._renderer = None

    # -------------------------------------------------------------------------- mapping
    def action_to_parameters(self, action: np.ndarray) -> tuple[float, float]:
        """Physical (m, T_c [s]) of a (clipped) ``FFSR-v0`` action, in float64."""
        a = np.asarray(action, dtype=np.float64)
        (m_lo, m_hi), (t_lo, t_hi) = self.scenario.env.m_bounds, self.scenario.env.T_c_bounds_s
        return m_lo + 0.5 * (a[0] + 1.0) * (m_hi - m_lo), t_lo + 0.5 * (a[1] + 1.0) * (t_hi - t_lo)

    def _checked_action(self, action: Any) -> np.ndarray:
        clipped, was_clipped = check_action(action, self.action_space.shape)
        self.clipped_actions += int(was_clipped)
        return clipped

    # -------------------------------------------------------------------------- gym API
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.scenario, info = self._episode_scenario(options)
        self.rollout = make_rollout(self.scenario, backend=self.backend)
        self.clipped_actions = 0
        self.last_rates = np.zeros(12)
        obs = self._observation()
        return obs, {**info, "clearance_m": self._clearance, "ee_position_error_m": self._ee_error}

    def _episode_scenario(self, options: dict | None) -> tuple[Scenario, dict]:
        """The scenario of the episode being reset, and what ``reset``'s info says about it."""
        return (sample_scenario(self.family, self.np_random) if self.randomised else self.family), {}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        self._check_running()
        a = self._checked_action(action)
        if self.residual:
            return self._advance(None, self._residual(a))
        return self._advance(self.action_to_parameters(a), None)

    def _residual(self, action: np.ndarray) -> np.ndarray:
        """Residual joint rates [rad/s] of a (clipped) residual action at the current time."""
        return residual_rates(action, self.scenario.env)

    def step_with_parameters(self, m: float, T_c: float) -> tuple[np.ndarray, float, bool, bool, dict]:
        """A step of ``FFSR-v0`` / ``FFSR-v1`` with physical parameters m ∈ (0, 1) and T_c [s] > 0 (no float32 rounding)."""
        if self.residual:
            raise InvalidInputError("step_with_parameters is for the (m, T_c) envs (FFSR-v0, FFSR-v1), not a residual env")
        self._check_running()
        return self._advance((float(m), float(T_c)), None)

    def _check_running(self) -> None:
        """Refuse a step before the first reset or after the episode ended (Gymnasium leaves it undefined)."""
        if self.rollout is None:
            raise InvalidInputError("call reset() before step()")
        if self.rollout.finished:
            raise InvalidInputError("step() after the episode ended (terminated or truncated); call reset() first")

    def _advance(self, parameters: tuple[float, float] | None, residual: np.ndarray | None):
        rollout, objective = self.rollout, self.scenario.objective
        if parameters is not None:
            rollout.set_parameters(*parameters)
        applied, status = rollout.advance(self.steps_per_decision, residual, stop_on_violation=True)
        increment = smooth_part(*rate_terms(applied, rollout.dt, objective)[:2], objective)
        self.last_rates = applied[-1]
        terminated = status != "ok"
        truncated = not terminated and rollout.k >= rollout.n_steps
        penalty = self.scenario.env.violation_penalty if terminated else 0.0
        info: dict[str, Any] = {"objective_increment": increment, "cost": 1.0 if terminated else 0.0,
                                "clipped_actions": self.clipped_actions}
        if terminated or truncated:
            rollout.finish()
            terms = objective_terms(rollout.trajectory(), objective)
            if truncated and not terms.final_errors_ok:
                penalty += self.scenario.env.tolerance_penalty
            info.update(self._final_info(terms))
        obs = self._observation()
        info.update({"penalty": penalty, "clearance_m": self._clearance, "ee_position_error_m": self._ee_error})
        if self.render_mode == "human":
            self.render()
        return obs, float(-increment - penalty), terminated, truncated, info

    @staticmethod
    def _final_info(terms: ObjectiveTerms) -> dict[str, Any]:
        return {"objective": terms.objective, "feasible": terms.feasible, "score": terms.score,
                "rate_violation": terms.rate_violation, "collided": terms.collided}

    # ------------------------------------------------------------------------ observation
    def _observation(self) -> np.ndarray:
        angles, ee_error, base_error, relative, clearance = self.rollout.observation()
        self._clearance = float(clearance)
        self._ee_error = portable.norm(ee_error[:3])
        return assemble_observation(angles, self.last_rates, ee_error, base_error, relative, clearance,
                                    self.rollout.k / self.rollout.n_steps)

    # ----------------------------------------------------------------------------- extras
    @property
    def trajectory(self):
        """The current episode's :class:`~ffsr_gym.sim.trajectory.Trajectory` (samples so far)."""
        if self.rollout is None:
            raise InvalidInputError("no episode yet: call reset()")
        return self.rollout.trajectory()

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        from ffsr_gym.environments.render import SceneRenderer

        if self._renderer is None:
            self._renderer = SceneRenderer(interactive=self.render_mode == "human")
        return self._renderer.draw(self.rollout, self.scenario)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


class FFSRResidualEnv(FFSREnv):
    __doc__ = FFSREnv.__doc__
    residual = True
