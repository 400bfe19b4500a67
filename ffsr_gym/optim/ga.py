"""The paper's genetic algorithm over (m, T_c) (Section 4, eq. 23; docs/model.md §13), resumable and executor-agnostic.

Binary encoding (16 bits per gene), roulette selection, single-point crossover with probability
P_c, one-bit mutation with probability P_m per individual, elitism (the best individual survives).
Fitness is the benchmark score B from :func:`ffsr_gym.objective_for_params` (+inf if infeasible),
which is **minimised**; eq. (23) as printed makes the selection probability proportional to B,
which favours the worst and breaks on +inf. ``selection="inverse"`` (default) uses
f = 1 / (1 + B / B_ref), f = 0 for B = +inf, B_ref the smallest positive finite B of the
generation (1 if none), uniform if every f is 0; ``selection="literal"`` keeps P ∝ B over the
finite B (infeasible ones get 0), documenting the erratum.

Written by hand rather than with pygad: the run must checkpoint every generation and resume to the
identical result, evaluate through any ``concurrent.futures.Executor`` (processes, Dask), and keep
all randomness in one seeded generator in the driver; pygad's operators would need the same
amount of wrapping and its parallelism is its own.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.bench.evaluation import objective_for_params
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.provenance import write_json_atomic
from ffsr_gym.user_files import load_json

BITS = 16
#: The largest population and run a GA takes (the paper's: 100 individuals, 100 generations).
MAX_POPULATION = 100_000
MAX_GENERATIONS = 1_000_000


@dataclass(frozen=True)
class GAConfig:
    """GA settings (paper values by default). ``T_c_fixed`` [s] set: reproduction mode (m only). ``go_bounds_s``
    [s] set: a third gene, when a timed policy commands the insertion (capture v1), and fitness takes (m, T_c, go_s).
    """

    population: int = 100
    generations: int = 100
    crossover_probability: float = 0.6
    mutation_probability: float = 0.1
    m_bounds: tuple[float, float] = (0.05, 0.95)
    T_c_bounds_s: tuple[float, float] = (1.0, 5.0)
    T_c_fixed: float | None = None
    go_bounds_s: tuple[float, float] | None = None
    selection: str = "inverse"
    seed: int = 0
    scenario: str = "paper"

    def __post_init__(self) -> None:
        if not (2 <= self.population <= MAX_POPULATION and 1 <= self.generations <= MAX_GENERATIONS):
            raise InvalidInputError(f"population {self.population}, generations {self.generations}; allowed: population "
                                    f"in [2, {MAX_POPULATION:,}], generations in [1, {MAX_GENERATIONS:,}]")
        if self.selection not in ("inverse", "literal"):
            raise InvalidInputError(f"selection {self.selection!r}; allowed: ['inverse', 'literal']")
        for name in ("crossover_probability", "mutation_probability"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise InvalidInputError(f"{name} = {getattr(self, name)} is out of range; allowed: [0, 1]")

    @property
    def genes(self) -> int:
        return 1 if self.T_c_fixed is not None else 2 if self.go_bounds_s is None else 3


def decode(bits: np.ndarray, config: GAConfig) -> tuple[float, ...]:
    """(m, T_c [s]) of a chromosome (genes of 16 bits, most significant first), and go_s [s] with a third gene."""
    scale = float(2**BITS - 1)
    values = [int("".join(map(str, bits[g * BITS:(g + 1) * BITS])), 2) / scale for g in range(config.genes)]
    m = config.m_bounds[0] + values[0] * (config.m_bounds[1] - config.m_bounds[0])
    if config.T_c_fixed is not None:
        return m, float(config.T_c_fixed)
    T_c = config.T_c_bounds_s[0] + values[1] * (config.T_c_bounds_s[1] - config.T_c_bounds_s[0])
    if config.go_bounds_s is None:
        return m, T_c
    return m, T_c, config.go_bounds_s[0] + values[2] * (config.go_bounds_s[1] - config.go_bounds_s[0])


def selection_probabilities(scores: np.ndarray, mode: str) -> np.ndarray:
    """Roulette probabilities of a generation's scores (B, minimised; +inf when infeasible)."""
    finite = np.isfinite(scores)
    if mode == "literal":
        weights = np.where(finite, scores, 0.0)
    else:
        positive = scores[finite & (scores > 0)]
        reference = float(positive.min()) if positive.size else 1.0
        weights = np.where(finite, 1.0 / (1.0 + np.where(finite, scores, 0.0) / reference), 0.0)
    total = weights.sum()
    return weights / total if total > 0 else np.full(len(scores), 1.0 / len(scores))


@dataclass
class GAState:
    """Everything needed to resume: generation, population, RNG state, history, evaluation cache."""

    config: GAConfig
    generation: int
    population: np.ndarray
    rng_state: dict
    history: list[dict] = field(default_factory=list)
    cache: dict[str, float] = field(default_factory=dict)
    wall_time_s: float = 0.0

    def to_json(self) -> dict[str, Any]:
        return {"config": asdict(self.config), "generation": self.generation, "population": self.population.tolist(),
                "rng_state": self.rng_state, "history": self.history, "wall_time_s": self.wall_time_s,
                "cache": {k: (None if math.isinf(v) else v) for k, v in self.cache.items()}}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> GAState:
        config = data["config"]
        go = config.get("go_bounds_s")
        config = GAConfig(**{**config, "m_bounds": tuple(config["m_bounds"]), "T_c_bounds_s": tuple(config["T_c_bounds_s"]),
                             "go_bounds_s": None if go is None else tuple(go)})
        cache = {k: (math.inf if v is None else v) for k, v in data["cache"].items()}
        return cls(config, data["generation"], np.array(data["population"], dtype=np.int8), data["rng_state"],
                   data["history"], cache, data.get("wall_time_s", 0.0))


def _key(*params: float) -> str:
    return ",".join(repr(x) for x in params)


def _evaluate(state: GAState, fitness: Callable, executor: Executor | None) -> np.ndarray:
    params = [decode(ind, state.config) for ind in state.population]
    todo = sorted({_key(*p): p for p in params if _key(*p) not in state.cache}.items())
    if todo:
        results = (executor.map if executor else map)(call_fitness, [fitness] * len(todo), [p for _, p in todo])
        for (key, _), score in zip(todo, results):
            state.cache[key] = float(score)
    return np.array([state.cache[_key(*p)] for p in params])


def call_fitness(fitness: Callable, params: tuple[float, ...]) -> float:
    """``fitness(m, T_c)`` (``fitness(m, T_c, go_s)`` with a third gene); module-level, so executors pickle it."""
    return fitness(*params)


def _breed(state: GAState, scores: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    config, pop = state.config, state.population
    n, length = pop.shape
    elite = pop[int(np.argmin(scores))].copy()
    parents = pop[rng.choice(n, size=n - 1, p=selection_probabilities(scores, config.selection))].copy()
    for i in range(0, n - 2, 2):
        if rng.random() < config.crossover_probability:
            cut = int(rng.integers(1, length))
            parents[i, cut:], parents[i + 1, cut:] = parents[i + 1, cut:].copy(), parents[i, cut:].copy()
    for child in parents:
        if rng.random() < config.mutation_probability:
            child[int(rng.integers(length))] ^= 1
    return np.vstack((elite, parents))


def start(config: GAConfig) -> GAState:
    """A fresh run: random initial population from ``config.seed``."""
    rng = np.random.default_rng(config.seed)
    population = rng.integers(0, 2, size=(config.population, BITS * config.genes), dtype=np.int8)
    return GAState(config, 0, population, rng.bit_generator.state)


def _resumed(path: Path) -> GAState:
    """The state a checkpoint holds, or a named error (a torn, foreign or edited file is not resumed from)."""
    try:
        state = GAState.from_json(load_json(path))
        if state.population.shape != (state.config.population, BITS * state.config.genes) \
                or not np.isin(state.population, (0, 1)).all() or not 0 <= state.generation <= state.config.generations:
            raise ValueError("its population or generation does not fit its settings")
        return state
    except FFSRError as exc:
        raise InvalidInputError(f"--checkpoint {exc}; move it away to start afresh") from None
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise InvalidInputError(f"--checkpoint {path}: not a GA checkpoint ({type(exc).__name__}: {str(exc)[:120]}); "
                                "move it away to start afresh") from None


def run(config: GAConfig | None = None, *, executor: Executor | None = None, checkpoint: str | Path | None = None,
        fitness: Callable[..., float] | None = None, progress: bool = True,
        stop_after: int | None = None) -> GAState:
    """Run (or resume from ``checkpoint``) the GA to ``config.generations``.

    Args:
        config: settings; ignored when ``checkpoint`` exists (the saved settings are used).
        executor: where evaluations run (any ``concurrent.futures.Executor``; None = in process).
            Results do not depend on it: all randomness stays in this process.
        checkpoint: JSON file written atomically after every generation; resumed if present.
        fitness: picklable ``(m, T_c) -> score`` (``(m, T_c, go_s)`` with ``go_bounds_s``); default
            ``objective_for_params`` on ``config.scenario``.
        progress: show a progress bar.
        stop_after: stop after this many generations of this call (to test resuming).
    """
    path = Path(checkpoint) if checkpoint else None
    state = _resumed(path) if path and path.exists() else start(config or GAConfig())
    fitness = fitness or partial(_scenario_fitness, scenario=state.config.scenario)
    rng = np.random.default_rng()
    rng.bit_generator.state = state.rng_state
    done_here = 0
    with tqdm(total=state.config.generations, initial=state.generation, disable=not progress, desc="GA", unit="gen") as bar:
        while state.generation < state.config.generations and (stop_after is None or done_here < stop_after):
            began = time.perf_counter()
            scores = _evaluate(state, fitness, executor)
            best = int(np.argmin(scores))
            finite = scores[np.isfinite(scores)]
            m, T_c, *go = decode(state.population[best], state.config)
            state.history.append({"generation": state.generation, "best_score": _finite(scores[best]), "best_m": m,
                                  "best_T_c_s": T_c, **({"best_go_s": go[0]} if go else {}),
                                  "mean_finite_score": _finite(float(finite.mean())) if finite.size else None,
                                  "feasible_fraction": float(np.isfinite(scores).mean())})
            state.population = _breed(state, scores, rng)
            state.generation += 1
            state.rng_state = rng.bit_generator.state
            state.wall_time_s += time.perf_counter() - began
            if path:
                write_json_atomic(path, state.to_json())
            done_here += 1
            bar.update(1)
            bar.set_postfix_str(f"best B {scores[best]:.4g} at m = {m:.4f}, T_c = {T_c:.3f}"
                                + (f", go_s = {go[0]:.2f}" if go else ""))
    return state


def best(state: GAState) -> tuple[float, float, float]:
    """The GA optimum: the best (m, T_c [s], score) of the last generation (kept by elitism)."""
    last = state.history[-1]
    score = last["best_score"]
    return last["best_m"], last["best_T_c_s"], math.inf if score is None else score


def best_go_s(state: GAState) -> float | None:
    """The GA optimum's go_s [s] (None: a run without the third gene)."""
    return state.history[-1].get("best_go_s")


def _scenario_fitness(m: float, T_c: float, *, scenario: str) -> float:
    return objective_for_params(m, T_c, scenario=scenario)


def _finite(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)
