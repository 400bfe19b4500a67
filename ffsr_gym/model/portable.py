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

import numpy as np

from ffsr_gym.types import Array


def dot(a: Sequence[float], b: Sequence[float]) -> float:
    """a · b summed left to right: ((a₀b₀ + a₁b₁) + a₂b₂) + ..."""
    total = 0.0
    for x, y in zip(a, b, strict=True):
        total += float(x) * float(y)
    return total


def norm(a: Sequence[float]) -> float:
    """Euclidean norm √(a · a), with :func:`dot`'s order."""
    return math.sqrt(dot(a, a))


def matvec(matrix: Sequence[Sequence[float]], vector: Sequence[float]) -> list[float]:
    """A · x for a small matrix, each row's :func:`dot` left to right (numpy's ``@`` would go to the BLAS
    ``dgemv``, whose kernel and summation order the CPU decides)."""
    return [dot(row, vector) for row in matrix]


def matvec_rows(matrices: Array, vectors: Array) -> Array:
    """(N, R) products A_n x_n of (N, R, C) matrices with (N, C) vectors (or one (C,) vector for every row), each
    entry summed left to right in element-wise operations, ((A_i0 x_0 + A_i1 x_1) + A_i2 x_2) + ..., the order of
    :func:`matvec`, whatever the CPU (``np.einsum`` and ``@`` leave the order to numpy's and the BLAS's kernels)."""
    a = np.asarray(matrices, dtype=float)
    x = np.broadcast_to(np.asarray(vectors, dtype=float), (a.shape[0], a.shape[2]))
    total = a[:, :, 0] * x[:, None, 0]
    for j in range(1, a.shape[2]):
        total = total + a[:, :, j] * x[:, None, j]
    return total


def cross(a: Sequence[float], b: Sequence[float]) -> list[float]:
    """a × b of two 3-vectors in Python floats."""
    ax, ay, az = (float(c) for c in a)
    bx, by, bz = (float(c) for c in b)
    return [ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx]
