"""The info contract: every key at reset, at every step and at the episode's end, each with one numeric dtype.

Replay buffers (tianshou, torchrl, d3rlpy) stack infos step by step and refuse a key that comes
and goes, a ``None`` or a text. So every info of an id has the same keys, from ``reset`` on, and
each key one dtype: ``int64``, ``float64`` or ``bool``. A value that only means something at the
episode's end (``score``, ``success``, ``failure``, ...) is 0 / False before it, and
``episode_end`` says when it holds. The failure is an integer code (:data:`FAILURES`,
:func:`failure_name`). The single env gives Python scalars; the batched env arrays with Gymnasium's
``_key`` masks. docs/envs.md shows the generated table (:func:`markdown_table`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError

#: Failure codes: the index of each name (0: none; ``incomplete``: a run cut short without a violation).
FAILURES = (None, "rate_limit", "collision", "final_error", "incomplete", "no_capture")
#: Per key: (unit, when it is meaningful). Keys of one rule only are listed with it.
MEANING = {
    "task_index": ("-", "always (-1: not a pool task)"),
    "task_seed": ("-", "always (-1: not a pool task)"),
    "smoothness_increment": ("1", "every step (0 at reset): this decision's share of the smoothness cost C"),
    "objective_increment": ("1", "every step (0 at reset): this decision's share of the paper's B"),
    "penalty": ("1", "every step (0 at reset): the reward's penalty of a failed end"),
    "shaping": ("1", "every step (0 at reset, or without dense_shaping)"),
    "cost": ("1", "every step (0 at reset): the graded violation of this decision (0: none)"),
    "clearance_m": ("m", "always: robot-obstacle and self clearance now"),
    "ee_position_error_m": ("m", "always: end-effector position error now"),
    "clipped_actions": ("count", "always: actions clipped into [-1, 1] so far this episode"),
    "episode_end": ("-", "always: True on the episode's last step"),
    "score": ("1", "when episode_end: the episode's score (0 before)"),
    "success": ("-", "when episode_end (False before)"),
    "failure": ("code", "when episode_end: 0 none, 1 rate_limit, 2 collision, 3 final_error, 4 incomplete, "
                        "5 no_capture (ffsr_gym.failure_name)"),
    "capture_time_s": ("s", "when episode_end: when the first hold window ended (0 before, and without a capture)"),
    "capture_ratio": ("1", "when episode_end: the factor by which every capture tolerance could shrink and the "
                           "episode still capture (> 1: no capture; inf: cut short; 0 before; capture-v1: up to "
                           "its capture, where the episode ends)"),
    "contact_speed_m_s": ("m/s", "when episode_end: the tool's speed relative to the grasp frame when it first came "
                                 "within the rule's contact distance (0 before, and without a contact)"),
    "smoothness_cost": ("1", "when episode_end: C (0 before)"),
    "paper_B": ("1", "when episode_end: the paper's B, inf when a rate exceeds the limit (0 before)"),
    "objective": ("1", "when episode_end: the paper's B, inf when infeasible (0 before)"),
    "feasible": ("-", "when episode_end (False before)"),
    "rate_violation": ("-", "when episode_end (False before)"),
    "collided": ("-", "when episode_end (False before)"),
}


def failure_code(name: str | None) -> int:
    """The code of a failure name (None: 0).

    Raises:
        InvalidInputError: an unknown name.
    """
    if name not in FAILURES:
        raise InvalidInputError(f"failure {name!r}; allowed: {list(FAILURES)}")
    return FAILURES.index(name)


def failure_name(code: Any) -> str | None:
    """The failure name of an ``info["failure"]`` code (0: None).

    Raises:
        InvalidInputError: a code outside the table.
    """
    if isinstance(code, (bool, np.bool_)) or not isinstance(code, (int, np.integer)) or not 0 <= code < len(FAILURES):
        raise InvalidInputError(f"failure code {code!r}; allowed: 0 to {len(FAILURES) - 1} ({list(FAILURES)})")
    return FAILURES[int(code)]


def info_dtypes(rule: Any) -> dict[str, type]:
    """Every info key of a score rule's envs, in order, with its dtype."""
    keys: dict[str, type] = {"task_index": np.int64, "task_seed": np.int64, rule.increment_key: np.float64,
                             "penalty": np.float64}
    if rule.shaping:
        keys["shaping"] = np.float64
    keys |= {"cost": np.float64, "clearance_m": np.float64, "ee_position_error_m": np.float64,
             "clipped_actions": np.int64, "episode_end": np.bool_}
    for key, kind in rule.end_keys.items():
        keys[key] = np.int64 if key == "failure" else np.bool_ if kind is bool else np.float64
    return keys


def blank(rule: Any, copies: int) -> dict[str, np.ndarray]:
    """Every key's array over ``copies`` at its value before anything happened (task ids -1)."""
    arrays = {key: np.zeros(copies, dtype=dtype) for key, dtype in info_dtypes(rule).items()}
    arrays["task_index"][:], arrays["task_seed"][:] = -1, -1
    return arrays


def end_values(rule: Any, result: Any) -> dict[str, Any]:
    """The episode-end keys of a rule's result, as numbers (the failure as its code)."""
    values = {key: failure_code(getattr(result, key)) if key == "failure" else getattr(result, key)
              for key in rule.end_keys}
    return {key: 0.0 if value is None else value for key, value in values.items()}  # e.g. no capture time


def scalars(arrays: dict[str, np.ndarray], i: int) -> dict[str, Any]:
    """Copy ``i``'s info as Python scalars (the single env's info)."""
    return {key: values[i].item() for key, values in arrays.items()}


def with_masks(arrays: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, Any]:
    """A batched info as Gymnasium's vector envs give it: each key's array (0 where ``mask`` is False: a copy that
    gave no info) and its ``_key`` mask."""
    out: dict[str, Any] = {}
    for key, values in arrays.items():
        out[key], out[f"_{key}"] = np.where(mask, values, np.zeros_like(values)), mask.copy()
    return out


def markdown_table(rule: Any) -> str:
    """The docs' table of a rule's info keys: name, dtype, unit and when each is meaningful."""
    lines = ["| key | dtype | unit | meaningful |", "|---|---|---|---|"]
    for key, dtype in info_dtypes(rule).items():
        unit, when = MEANING[key]
        lines.append(f"| `{key}` | {np.dtype(dtype).name} | {unit} | {when} |")
    return "\n".join(lines)


def docs_section() -> str:
    """The info tables of every version's envs (docs/envs.md, between the ``info-keys`` markers)."""
    from ffsr_gym.scoring.rules import score_rule
    from ffsr_gym.versions.registry import all_specs

    parts = []
    for spec in sorted(all_specs().values(), key=lambda s: s.version, reverse=True):
        parts += [f"`{'`, `'.join(spec.env_ids)}`:", "", markdown_table(score_rule(spec)), ""]
    return "\n".join(parts).rstrip() + "\n"
