"""The public evaluation protocol: the seeds every submission is scored on, per env id."""

from __future__ import annotations

from ffsr_gym.exceptions import InvalidInputError

# Fixed public evaluation seeds. For deterministic scenarios every seed gives the same episode;
# for scenario="random" each seed draws one task. Changing these changes every leaderboard.
EVAL_SEEDS: dict[str, tuple[int, ...]] = {
    "FFSR-v0": tuple(range(10_000, 10_010)),
    "FFSR-Residual-v0": tuple(range(20_000, 20_010)),
}
BOOTSTRAP_SEED = 0
BOOTSTRAP_SAMPLES = 2000


def eval_seeds(env_id: str) -> tuple[int, ...]:
    """The public evaluation seeds of ``env_id``.

    Raises:
        InvalidInputError: unknown env id.
    """
    key = env_id.split(":")[-1]
    if key not in EVAL_SEEDS:
        raise InvalidInputError(f"no evaluation seeds for env id {env_id!r}; allowed: {sorted(EVAL_SEEDS)}")
    return EVAL_SEEDS[key]
