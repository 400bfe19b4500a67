"""When a replayed episode agrees with the row stored for it: the version's ``[replay]`` tolerances.

v0 and v2 replay bit for bit on every x86-64 machine (docs/model.md §17), and their rows are compared exactly. The
capture-v0 pools and entries were made by a set-up whose desired twist went through the CPU's BLAS kernels; that
set-up now rounds the same way everywhere, but not the way the stored rows were made, and the predefined-time
feedback turns that last bit into a different period-2 cycle at convergence (docs/model.md §17, §12). Its spec
therefore states how far a replay may move: the verdict never (seeds, indices, counts, success, failure: exactly),
the score, C and B within a relative ``score_rel_tol``, every other number within ``margin_rel_tol`` (relative) or
``margin_abs_tol`` (absolute). C's two terms per arm are such other numbers: a replay trades one against the other
(a capture-v0 residual episode moved an arm's rate variation by 6 % and C by 1.1 %), and C is what the score reads.
"""

from __future__ import annotations

import math
from typing import Any

from ffsr_gym.model.spec import ReplaySpec
from ffsr_gym.versions.registry import spec_for_version

#: Row fields the score is read from (the score, the smoothness cost C, the paper's B).
SCORE_FIELDS = frozenset({"score", "smoothness_cost", "paper_B"})


def tolerance_for(version: str) -> ReplaySpec:
    """The ``[replay]`` tolerances of a benchmark version's spec."""
    return spec_for_version(version).replay


def numbers_agree(stored: Any, replayed: Any, rel_tol: float, abs_tol: float = 0.0) -> bool:
    """Whether two row values agree: exactly, or for floats (and lists of them) within ``rel_tol`` of the stored
    value or within ``abs_tol`` (|replayed − stored| <= max(rel_tol |stored|, abs_tol)); booleans, integers, strings
    and None always exactly."""
    if isinstance(stored, list) or isinstance(replayed, list):
        return (isinstance(stored, list) and isinstance(replayed, list) and len(stored) == len(replayed)
                and all(numbers_agree(a, b, rel_tol, abs_tol) for a, b in zip(stored, replayed)))
    if isinstance(stored, bool) or isinstance(replayed, bool):
        return stored is replayed
    if type(stored) is not float or type(replayed) is not float or (rel_tol == 0.0 and abs_tol == 0.0):
        return stored == replayed
    if not (math.isfinite(stored) and math.isfinite(replayed)):
        return stored == replayed
    return abs(replayed - stored) <= max(rel_tol * abs(stored), abs_tol)


def differing_keys(stored: dict, replayed: dict, tolerance: ReplaySpec) -> list[str]:
    """The keys of two episode rows that disagree under ``tolerance`` (sorted; empty: the rows agree)."""
    keys = sorted(set(stored) | set(replayed))
    return [key for key in keys if key not in stored or key not in replayed
            or not (numbers_agree(stored[key], replayed[key], tolerance.score_rel_tol) if key in SCORE_FIELDS
                    else numbers_agree(stored[key], replayed[key], tolerance.margin_rel_tol, tolerance.margin_abs_tol))]


def score_bias(stored: list[dict], replayed: list[dict]) -> float:
    """The rows' mean signed relative score difference, (replayed − stored) / stored over the rows whose stored
    score is positive and finite (0.0 when there are none). Rounding moves scores both ways; a forged set of rows
    inflated within the per-row tolerance moves them one way."""
    shifts = [(b["score"] - a["score"]) / a["score"] for a, b in zip(stored, replayed)
              if type(a.get("score")) is float and type(b.get("score")) is float and math.isfinite(a["score"])
              and math.isfinite(b["score"]) and a["score"] > 0.0]
    return sum(shifts) / len(shifts) if shifts else 0.0


def bias_problem(stored: list[dict], replayed: list[dict], tolerance: ReplaySpec) -> str | None:
    """Why the rows as a whole do not reproduce (None: they do): under a nonzero ``score_rel_tol`` their mean
    signed score difference (:func:`score_bias`) must stay within a tenth of it."""
    if tolerance.score_rel_tol == 0.0:
        return None
    bias = score_bias(stored, replayed)
    if abs(bias) <= tolerance.score_rel_tol / 10.0:
        return None
    return (f"the stored scores are {abs(bias):.2%} {'below' if bias > 0 else 'above'} their replays on average; "
            f"allowed: {tolerance.score_rel_tol / 10.0:.2%} (rounding moves scores both ways)")
