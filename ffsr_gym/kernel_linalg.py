"""Small dense linear algebra for the compiled kernel, written as loops.

numba sends ``@`` on 2-D arrays to BLAS, whose call overhead (~1 µs) dwarfs a 3x3 or 6x6 product;
these loops are 10-50x faster at these sizes. ``svd`` is a one-sided Jacobi SVD (accurate to
machine precision, relative accuracy for small singular values) replacing LAPACK's ~5 µs call.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_EPS = 2.220446049250313e-16


@njit(cache=True, inline="always")
def cross(a, b):
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit(cache=True, inline="always")
def dot(a, b):
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i] * b[i]
    return s


@njit(cache=True)
def mmt(A, B):
    """A @ B.T."""
    n, k, m = A.shape[0], A.shape[1], B.shape[0]
    out = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for p in range(k):
                s += A[i, p] * B[j, p]
            out[i, j] = s
    return out


@njit(cache=True)
def mv(A, v):
    """A @ v."""
    n, k = A.shape
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for p in range(k):
            s += A[i, p] * v[p]
        out[i] = s
    return out


@njit(cache=True)
def mtv(A, v):
    """A.T @ v."""
    k, n = A.shape
    out = np.zeros(n)
    for p in range(k):
        vp = v[p]
        for i in range(n):
            out[i] += A[p, i] * vp
    return out


@njit(cache=True)
def solve(A, b):
    """Solve A x = b by Gaussian elimination with partial pivoting (small n)."""
    n = A.shape[0]
    M = A.copy()
    x = b.copy()
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
    return x


@njit(cache=True)
def svd(A):
    """One-sided Jacobi SVD of a square matrix: (U, s, V) with A = U diag(s) V^T, s descending."""
    n = A.shape[0]
    U = A.copy()
    V = np.eye(n)
    for _sweep in range(60):
        rotated = False
        for i in range(n - 1):
            for j in range(i + 1, n):
                alpha = beta = gamma = 0.0
                for r in range(n):
                    alpha += U[r, i] * U[r, i]
                    beta += U[r, j] * U[r, j]
                    gamma += U[r, i] * U[r, j]
                if abs(gamma) <= _EPS * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for r in range(n):
                    ui, uj = U[r, i], U[r, j]
                    U[r, i], U[r, j] = c * ui - s * uj, s * ui + c * uj
                    vi, vj = V[r, i], V[r, j]
                    V[r, i], V[r, j] = c * vi - s * vj, s * vi + c * vj
        if not rotated:
            break
    sig = np.empty(n)
    for i in range(n):
        sig[i] = math.sqrt(dot(U[:, i], U[:, i]))
    order = np.argsort(-sig)
    Us, Vs, ss = np.zeros((n, n)), np.zeros((n, n)), np.empty(n)
    for k in range(n):
        i = order[k]
        ss[k] = sig[i]
        for r in range(n):
            Vs[r, k] = V[r, i]
            Us[r, k] = U[r, i] / sig[i] if sig[i] > 0.0 else 0.0
    return Us, ss, Vs
