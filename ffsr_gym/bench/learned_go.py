"""A timing learned from simulated outcomes (capture v1; docs/baselines.md): go in when a regressor says it pays.

:class:`LearnedGo` is a policy of ``FFSR-Capture-v1`` that acts on the observation alone. It holds the start pose
with the default planner's (m, T_c) and, at every decision, predicts from the 76 observed floats the score that
going in now would earn (a small network, :class:`Regressor`, fitted to the outcomes of going in at every moment
of a grid on the tier's *training* tasks, simulated; ``baselines/learned_go.py``). It commands the insertion at the
first decision whose prediction has reached ``threshold`` at ``confirm`` consecutive decisions (with more than one,
not a window's first moment, whose edge another time step moves; both tuned on the validation pool), and at the latest
when only the approach's time is left. It decides only every ``every_s`` seconds, the grid its data were simulated
on, so that its validation score is read exactly off those data. Once going it keeps going. It is supervised
learning of the one decision the tuned constants and PPO never make per task: when.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ffsr_gym.bench.capture_heuristic import PlannerTiming
from ffsr_gym.exceptions import InvalidInputError


@dataclass(frozen=True)
class Regressor:
    """A fully connected network with ReLU hidden layers, on inputs standardised by ``mean`` and ``scale``:
    ``weights[i]`` of shape (inputs, outputs), ``biases[i]`` (outputs,); one output."""

    mean: np.ndarray
    scale: np.ndarray
    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]

    def __post_init__(self) -> None:
        width = len(self.mean)
        if self.scale.shape != (width,) or not np.all(self.scale > 0) or len(self.weights) != len(self.biases):
            raise InvalidInputError("Regressor: mean and scale of one width, scale > 0, a bias per weight matrix")
        for w, b in zip(self.weights, self.biases):
            if w.ndim != 2 or w.shape[0] != width or b.shape != (w.shape[1],):
                raise InvalidInputError(f"Regressor: a layer of shape {w.shape} after width {width}")
            width = w.shape[1]
        if width != 1:
            raise InvalidInputError(f"Regressor: {width} outputs; allowed: 1")

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The predictions for the rows of ``x`` (or one observation)."""
        h = (np.atleast_2d(np.asarray(x, dtype=np.float64)) - self.mean) / self.scale
        for k, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = h @ w + b
            if k < len(self.weights) - 1:
                h = np.maximum(h, 0.0)
        return h[:, 0]

    def as_dict(self) -> dict:
        """The network as JSON-ready lists (what :meth:`from_dict` reads back)."""
        return {"mean": self.mean.tolist(), "scale": self.scale.tolist(),
                "weights": [w.tolist() for w in self.weights], "biases": [b.tolist() for b in self.biases]}

    @classmethod
    def from_dict(cls, data: dict) -> Regressor:
        """The network :meth:`as_dict` wrote.

        Raises:
            InvalidInputError: a key missing, a value that is no list of numbers, or shapes that do not chain.
        """
        try:
            return cls(np.asarray(data["mean"], float), np.asarray(data["scale"], float),
                       tuple(np.asarray(w, float) for w in data["weights"]),
                       tuple(np.asarray(b, float) for b in data["biases"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidInputError(f"Regressor: {exc}; allowed: mean, scale, weights, biases as lists") from None


@dataclass(kw_only=True)
class LearnedGo(PlannerTiming):
    """See the module docstring and :class:`~ffsr_gym.bench.capture_heuristic.PlannerTiming`; ``interval_s``: the
    env's decision interval."""

    regressor: Regressor
    threshold: float
    confirm: int = 1
    every_s: float = 0.5
    interval_s: float = 0.1

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        obs, t, state = self.episode(observation, going=False, above=0)
        decision = int(round(t / self.interval_s))
        if not state["going"] and decision % int(round(self.every_s / self.interval_s)) == 0:
            state["above"] = state["above"] + 1 if float(self.regressor(obs)[0]) >= self.threshold else 0
            state["going"] = self.late(t) or state["above"] >= self.confirm
        return self.action(2.0 if state["going"] else 0.0)
