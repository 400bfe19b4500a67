"""The closed-loop interface that both backends implement, and its status codes.

:class:`~ffsr_gym.sim.pinocchio_backend.PinocchioRollout` (Pinocchio, the readable reference) and
:class:`~ffsr_gym.sim.compiled.KernelRollout` (the compiled kernel, equal to 1e-9) both satisfy
:class:`Rollout`; :func:`ffsr_gym.sim.simulate.make_rollout` picks one.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from ffsr_gym.model.scenario import Scenario
from ffsr_gym.sim.setup import ScenarioSetup
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array

#: What :meth:`Rollout.advance` reports: no violation, a joint over the rate limit, a collision.
STATUS = ("ok", "rate_limit", "collision")
#: Backends :func:`~ffsr_gym.sim.simulate.make_rollout` accepts.
BACKENDS = ("auto", "kernel", "pinocchio")


@runtime_checkable
class Rollout(Protocol):
    """A closed-loop run advanced in chunks of steps: ``simulate`` and the environments drive it.

    Each step plans at (t_k, q_k), records the sample and integrates to q_{k+1}; :meth:`finish`
    records the final sample at t_n (planned, never applied).

    Attributes:
        backend: ``"pinocchio"`` or ``"kernel"``.
        scenario: the scenario (validated).
        setup: what was derived from the scenario (shared, read-only).
        dt: time step [s].
        n_steps: steps in the whole run.
        k: steps taken so far.
        finished: whether :meth:`finish` recorded the final sample.
    """

    backend: str
    scenario: Scenario
    setup: ScenarioSetup
    dt: float
    n_steps: int
    k: int
    finished: bool

    @property
    def t(self) -> float:
        """Current time [s]."""

    @property
    def q(self) -> Array:
        """Current configuration (19,), Pinocchio order."""

    @property
    def method(self) -> str:
        """Planning method, one of :data:`ffsr_gym.planning.planner.METHODS`."""

    @property
    def m(self) -> float:
        """Current predefined-time shape parameter."""

    @property
    def T_c(self) -> float:
        """Current predefined time [s]."""

    def set_parameters(self, m: float, T_c: float) -> None:
        """Change (m, T_c [s]) from the next step on."""

    @property
    def timing(self) -> Array | None:
        """A commanded approach's state (command, s, ṡ, w, ẇ; docs/model.md §23), or None without one."""

    def set_command(self, command: float) -> None:
        """Command a commanded approach (u in [0, 2]) from the next step on."""

    def advance(self, n: int, residual: Array | None = None, *, stop_on_violation: bool = False) -> tuple[Array, str]:
        """Take up to ``n`` steps (fewer at the end of the run), adding ``residual`` (12,) [rad/s] to the plan.

        With ``stop_on_violation``, stop after the first step whose applied rates exceed the
        scenario's limit (``objective.max_rate_deg_s`` and ``rate_limit_scope``) or whose sample
        has a negative clearance.

        Returns:
            ``(applied, status)``: the applied rates (steps, 12) [rad/s] and one of :data:`STATUS`.
        """

    def finish(self) -> None:
        """Record the final sample (at the current time; its rates are not applied)."""

    def observation(self) -> tuple[Array, Array, Array, Array, float]:
        """Joint angles (12) [rad], EE error (6), base error (6), obstacle-relative vector (3) [m], clearance [m]."""

    def min_margin(self, last: int) -> float:
        """Smallest margin to a collision [m] over the last ``last`` recorded samples: the obstacle clearance
        minus the scenario's keep-out distance, or the arm-arm / arm-base clearance (negative: a collision)."""

    def trajectory(self) -> Trajectory:
        """The :class:`Trajectory` recorded so far."""
