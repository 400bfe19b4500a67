"""Small dense linear algebra for the compiled kernel, written as loops into caller-owned buffers.

numba sends ``@`` on 2-D arrays to BLAS, whose call overhead (~1 µs) dwarfs a 3x3 or 6x6 product,
and every small temporary array costs a heap allocation; these routines use neither. ``svd_into``
is a one-sided Jacobi SVD (accurate to machine precision, relative accuracy for small singular
values) replacing LAPACK's ~5 µs call.
"""

from __future__ import annotations

import math

from numba import njit

_EPS = 2.220446049250313e-16


@njit(cache=True, error_model="numpy", inline="always")
def dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, error_model="numpy")
def solve_into(A, b, M, x):
    """Solve A x = b (n x n, small n) by Gaussian elimination with partial pivoting.

    ``M`` (n, n) is scratch; ``x`` (n,) receives the solution. ``A`` and ``b`` are not modified.
    """
    n = A.shape[0]
    for r in range(n):
        x[r] = b[r]
        for c in range(n):
            M[r, c] = A[r, c]
    for c in range(n):
        piv = c
        best = abs(M[c, c])
        for r in range(c + 1, n):
            if abs(M[r, c]) > best:
                best, piv = abs(M[r, c]), r
        if piv != c:
            for j in range(n):
                M[c, j], M[piv, j] = M[piv, j], M[c, j]
            x[c], x[piv] = x[piv], x[c]
        for r in range(c + 1, n):
            f = M[r, c] / M[c, c]
            if f != 0.0:
                for j in range(c, n):
                    M[r, j] -= f * M[c, j]
                x[r] -= f * x[c]
    for c in range(n - 1, -1, -1):
        s = x[c]
        for j in range(c + 1, n):
            s -= M[c, j] * x[j]
        x[c] = s / M[c, c]


@njit(cache=True, error_model="numpy")
def solve3(A, b0, b1, b2):
    """Solution of the 3x3 system A x = b by cofactors (A well conditioned): a 3-tuple."""
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
    c10 = A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]
    c11 = A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]
    c12 = A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]
    c20 = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
    c21 = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
    c22 = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    return ((c00 * b0 + c10 * b1 + c20 * b2) / det, (c01 * b0 + c11 * b1 + c21 * b2) / det,
            (c02 * b0 + c12 * b1 + c22 * b2) / det)


def _round_robin(n: int) -> tuple:
    """Column pairs of one Jacobi sweep in round-robin order: n - 1 rounds of n / 2 disjoint pairs."""
    players, pairs = list(range(n)), []
    for _ in range(n - 1):
        pairs += [(min(players[i], players[n - 1 - i]), max(players[i], players[n - 1 - i])) for i in range(n // 2)]
        players = [players[0], players[-1], *players[1:-1]]
    return tuple(pairs)


_PAIRS_6 = _round_robin(6)


@njit(cache=True, error_model="numpy")
def svd_into(A, Ut, s, Vt, vectors=True):
    """One-sided Jacobi SVD of a 6x6 matrix: A = U diag(s) V^T (unsorted, s >= 0).

    Writes the singular vectors as rows, ``Ut`` = Uᵀ (zero rows where s = 0) and ``Vt`` = Vᵀ, and
    ``s``; ``A`` is not modified. Rows keep each vector contiguous (~20% faster than columns), and
    the sweep visits disjoint pairs one after the other (round-robin order, ~10% faster than the
    cyclic order, whose consecutive rotations share a column). With ``vectors=False`` only ``s``
    is meaningful (the same values: the rotations are the same).
    """
    n = 6
    for r in range(n):
        for c in range(n):
            Ut[c, r] = A[r, c]
            Vt[c, r] = 1.0 if r == c else 0.0
    for _sweep in range(60):
        rotated = False
        for i, j in _PAIRS_6:
            alpha = beta = gamma = 0.0
            for r in range(n):
                alpha += Ut[i, r] * Ut[i, r]
                beta += Ut[j, r] * Ut[j, r]
                gamma += Ut[i, r] * Ut[j, r]
            if gamma * gamma <= _EPS * _EPS * alpha * beta:  # columns orthogonal to working precision
                continue
            rotated = True
            zeta = (beta - alpha) / (2.0 * gamma)
            t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
            c = 1.0 / math.sqrt(1.0 + t * t)
            sn = c * t
            for r in range(n):
                ui, uj = Ut[i, r], Ut[j, r]
                Ut[i, r] = c * ui - sn * uj
                Ut[j, r] = sn * ui + c * uj
            if vectors:
                for r in range(n):
                    vi, vj = Vt[i, r], Vt[j, r]
                    Vt[i, r] = c * vi - sn * vj
                    Vt[j, r] = sn * vi + c * vj
        if not rotated:
            break
    for i in range(n):
        norm = 0.0
        for r in range(n):
            norm += Ut[i, r] * Ut[i, r]
        s[i] = math.sqrt(norm)
        if vectors:
            inv = 1.0 / s[i] if s[i] > 0.0 else 0.0
            for r in range(n):
                Ut[i, r] *= inv
