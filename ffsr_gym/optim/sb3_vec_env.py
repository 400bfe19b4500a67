"""Moved: the batched stable-baselines3 ``VecEnv`` is :mod:`ffsr_gym.environments.sb3_vec_env`.

This name stays for one release so that scripts written against 0.1.0 keep running; reading
``BatchedVecEnv`` from it warns (``DeprecationWarning``) and gives the class itself.
"""

from __future__ import annotations

import warnings
from typing import Any


def __getattr__(name: str) -> Any:
    if name != "BatchedVecEnv":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    warnings.warn("ffsr_gym.optim.sb3_vec_env moved to ffsr_gym.environments.sb3_vec_env; import BatchedVecEnv "
                  "from there (this name goes in the next release)", DeprecationWarning, stacklevel=2)
    from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv

    return BatchedVecEnv
