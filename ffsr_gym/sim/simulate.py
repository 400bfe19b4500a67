"""``simulate``: run one scenario's closed loop to the end, on the backend :func:`make_rollout` picks."""

from __future__ import annotations

import dataclasses
from typing import Any

from tqdm.auto import tqdm

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.sim.compiled import KernelRollout
from ffsr_gym.sim.pinocchio_backend import PinocchioRollout
from ffsr_gym.sim.rollout import BACKENDS, Rollout
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array


def make_rollout(scenario: Scenario, *, backend: str = "auto", **kwargs: Any) -> Rollout:
    """A rollout on the requested backend: ``"kernel"`` (the native kernel; also ``"auto"``) or ``"pinocchio"``
    (the reference implementation).

    Keyword arguments are those of the backends (``method``, ``m``, ``T_c``, ``q0``).
    """
    if backend not in BACKENDS:
        raise InvalidInputError(f"backend {backend!r}; allowed: {list(BACKENDS)}")
    if scenario.simulation.plant == "servo" and backend == "pinocchio":
        raise InvalidInputError(f"scenario {scenario.name!r}: the servo plant (simulation.plant = 'servo') runs on the "
                                "kernel backend only; backend 'kernel' or 'auto'")
    if backend == "pinocchio":
        return PinocchioRollout(scenario, **kwargs)
    return KernelRollout(scenario, **kwargs)


def simulate(scenario: Scenario | str, *, method: str = "predefined_time", m: float | None = None,
             T_c: float | None = None, dt: float | None = None, q0: Array | None = None,
             backend: str = "auto", progress: bool = False, stop_on_violation: bool = False) -> Trajectory:
    """Run the closed loop planner → robot for one scenario.

    Args:
        scenario: a :class:`Scenario` or a scenario name/path.
        method: planning method, one of :data:`ffsr_gym.planning.planner.METHODS`.
        m: predefined-time shape parameter in (0, 1); default: the scenario's.
        T_c: predefined time [s]; default: the scenario's.
        dt: time step [s]; default: the scenario's ``simulation.dt_s``.
        q0: start from this configuration (19,) instead of the scenario's initial state. The
            desired path and the base set-point still come from the scenario's initial state, so
            this is how an initial pose error is imposed.
        backend: ``"auto"`` or ``"kernel"`` (the native kernel), or ``"pinocchio"`` (the reference
            implementation).
        progress: show a progress bar.
        stop_on_violation: end the run after the first step that exceeds the rate limit or
            collides (the trajectory then ends one sample after it; its score is +inf either way).

    Returns:
        The :class:`Trajectory`, sampled at every step.
    """
    scenario = load_scenario(scenario)
    if dt is not None:
        scenario = scenario.replace(simulation=dataclasses.replace(scenario.simulation, dt_s=float(dt)))
    rollout = make_rollout(scenario, backend=backend, method=method, m=m, T_c=T_c, q0=q0)
    chunk = max(1, rollout.n_steps // 100) if progress else rollout.n_steps
    with tqdm(total=rollout.n_steps, disable=not progress, desc=f"{scenario.name}/{method}", unit="step") as bar:
        while rollout.k < rollout.n_steps:
            applied, status = rollout.advance(chunk, stop_on_violation=stop_on_violation)
            bar.update(len(applied))
            if status != "ok":
                break
    rollout.finish()
    return rollout.trajectory()
