"""Dot products and norms of small vectors that round the same way on every machine.

numpy sends ``a @ b`` and ``np.linalg.norm(a)`` of a float vector to the BLAS ``ddot``, and
OpenBLAS picks that kernel at run time by CPU (Haswell, SkylakeX, ...); numpy's ``arctan2``,
``arccos``, ``exp`` and ``log`` switch to AVX-512 code on CPUs that have it. The last bits of
their results differ between machines, and through the planner's non-Lipschitz feedback a last
bit in a task's desired path can change a grazing episode's score in the second digit
(docs/model.md §17). Everything that feeds the kernel, the task draws or the score therefore
uses these left-to-right sums and Python's ``math`` (the C library's functions, the same ones the
compiled kernel calls).
"""

from __future__ import annotations

import math
from collections.abc import Sequence


def dot(a: Sequence[float], b: Sequence[float]) -> float:
    """a · b summed left to right: ((a₀b₀ + a₁b₁) + a₂b₂) + ..."""
    total = 0.0
    for x, y in zip(a, b, strict=True):
        total += float(x) * float(y)
    return total


def norm(a: Sequence[float]) -> float:
    """Euclidean norm √(a · a), with :func:`dot`'s order."""
    return math.sqrt(dot(a, a))
