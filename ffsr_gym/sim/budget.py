"""What a run will need, estimated before any work, and refused by name above a documented limit.

Every allowed setting is allowed alone, but some together need more than a machine has: a
physics step of 1e-5 s on an hour-long task keeps 360 million trajectory rows per copy (about
200 GB), a million batched copies of a 20 s task about 1 TB. Instead of a raw ``MemoryError``
after minutes of work, or a compiled step that runs for an hour and cannot be interrupted, the
run is refused before it starts:

* **memory**: the trajectory buffers (``copies x (steps + 1)`` rows of
  :data:`~ffsr_gym.sim.compiled.LOG_FIELDS`), or :data:`COPY_BYTES` per copy that keeps none, above
  ``FFSR_GYM_MEMORY_LIMIT_GIB`` (default
  :data:`DEFAULT_MEMORY_LIMIT_GIB` GiB; set the variable to raise or lower it);
* **time per decision**: more than :data:`MAX_PHYSICS_STEPS_PER_DECISION` physics steps inside one
  decision (one compiled call, which Ctrl-C cannot stop): planner steps per decision, times the
  servo plant's sub-steps per planner step.
"""

from __future__ import annotations

import math
import os

from ffsr_gym.exceptions import InvalidInputError

#: The trajectory buffers one run may allocate unless ``FFSR_GYM_MEMORY_LIMIT_GIB`` says otherwise [GiB].
DEFAULT_MEMORY_LIMIT_GIB = 8.0
#: The variable that overrides it.
MEMORY_VARIABLE = "FFSR_GYM_MEMORY_LIMIT_GIB"
#: The most physics steps one decision may take (about 3 s of compiled work at the kernel's 3 µs a step).
MAX_PHYSICS_STEPS_PER_DECISION = 1_000_000
#: Floats per trajectory row (the sum of the sizes of ``LOG_FIELDS``), 8 bytes each.
ROW_FLOATS = 73
#: What a batched copy without a trajectory holds, rounded up [bytes] (its state, totals, task and settings;
#: ``experiments/memory.py`` measures it, docs/kernel.md).
COPY_BYTES = 64 * 1024


class ResourceLimitError(InvalidInputError):
    """A run whose estimated memory or time per decision is above the documented limit."""


def memory_limit_bytes() -> float:
    """The limit on a run's trajectory buffers [bytes] (``FFSR_GYM_MEMORY_LIMIT_GIB``, else the default).

    Raises:
        InvalidInputError: the variable is set to something that is not a number > 0.
    """
    text = os.environ.get(MEMORY_VARIABLE)
    if text is None:
        return DEFAULT_MEMORY_LIMIT_GIB * 2**30
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InvalidInputError(f"{MEMORY_VARIABLE} = {text!r}; allowed: a number > 0 [GiB]")
    return value * 2**30


def check_run(*, steps: int, copies: int, steps_per_decision: int, substeps: int = 1, what: str,
              trajectories: bool = True) -> None:
    """Refuse a run of ``copies`` episodes of ``steps`` planner steps (``steps_per_decision`` per decision,
    ``substeps`` physics steps each) whose buffers or decisions are above the limits (``trajectories``: whether
    each copy records its trajectory).

    Raises:
        ResourceLimitError: naming the estimate, the limit and how to change it.
    """
    need = float(copies) * ((steps + 1) * ROW_FLOATS * 8 if trajectories else COPY_BYTES)
    limit = memory_limit_bytes()
    if need > limit:
        plural = "ies" if copies != 1 else "y"
        kept = f"x {steps + 1:,} trajectory rows" if trajectories else f"x {COPY_BYTES // 1024} kB"
        raise ResourceLimitError(f"{what}: {copies:,} cop{plural} {kept} "
                                 f"need about {need / 2**30:,.1f} GiB; allowed: at most {limit / 2**30:g} GiB (set "
                                 f"{MEMORY_VARIABLE} to change it, or use a longer dt_s, a shorter task or fewer "
                                 "copies)")
    per_decision = steps_per_decision * substeps
    if per_decision > MAX_PHYSICS_STEPS_PER_DECISION:
        raise ResourceLimitError(f"{what}: {per_decision:,} physics steps in one decision ({steps_per_decision:,} "
                                 f"planner steps x {substeps:,} plant sub-steps); allowed: at most "
                                 f"{MAX_PHYSICS_STEPS_PER_DECISION:,} (one decision is one compiled call that Ctrl-C "
                                 "cannot stop): use a longer physics_step_s or a shorter decision_interval_s")
