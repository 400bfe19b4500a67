"""Small dense linear algebra for the compiled kernel, written as loops into caller-owned buffers.

numba sends ``@`` on 2-D arrays to BLAS, whose call overhead (~1 µs) dwarfs a 3x3 or 6x6 product,
and every small temporary array costs a heap allocation; these routines use neither. ``svd_into``
is a one-sided Jacobi SVD (accurate to machine precision, relative accuracy for small singular
values) replacing LAPACK's ~5 µs call; ``smallest_singular_value`` is a cheaper certificate for
the common well-conditioned case.
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
    """Solve A x = b (6 x 6) by Gaussian elimination with partial pivoting.

    ``M`` (6, 6) is scratch; ``x`` (6,) receives the solution. ``A`` and ``b`` are not modified.
    The size is a constant, so the compiler unrolls the loops; each pivot is inverted once and
    its reciprocal kept on the diagonal of ``M`` for the back substitution.
    """
    n = 6
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
            for j in range(c, n):
                M[c, j], M[piv, j] = M[piv, j], M[c, j]
            x[c], x[piv] = x[piv], x[c]
        inv = 1.0 / M[c, c]
        M[c, c] = inv
        for r in range(c + 1, n):
            f = M[r, c] * inv
            for j in range(c + 1, n):
                M[r, j] -= f * M[c, j]
            x[r] -= f * x[c]
    for c in range(n - 1, -1, -1):
        s = x[c]
        for j in range(c + 1, n):
            s -= M[c, j] * x[j]
        x[c] = s * M[c, c]


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


@njit(cache=True, error_model="numpy", inline="always")
def solve_sym3(a00, a01, a02, a11, a12, a22, b0, b1, b2):
    """Solution of the symmetric 3x3 system A x = b by cofactors (A well conditioned): a 3-tuple."""
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    inv = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02)
    return ((c00 * b0 + c01 * b1 + c02 * b2) * inv, (c01 * b0 + c11 * b1 + c12 * b2) * inv,
            (c02 * b0 + c12 * b1 + c22 * b2) * inv)


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


@njit(cache=True, error_model="numpy")
def smallest_singular_value(A, G, tri):
    """σ_min of a 6x6 matrix from the smallest eigenvalue of G = AᵀA, or -1 when that is not reliable.

    G is reduced to tridiagonal form T by Householder reflections. From λ = 0 one Laguerre step
    and then Newton steps on the characteristic polynomial det(T − λI) (evaluated through the
    LDLᵀ pivots of T − λI) climb to the smallest eigenvalue: for a polynomial with real roots both
    approach the smallest root monotonically from below, and every pivot stays positive on the
    way. The Laguerre step (cubic order, exact for a root of multiplicity 6) usually lands within
    a few per cent, so two or three Newton steps finish. Squaring the matrix costs accuracy for
    small σ: the error is about 1e-16 σ_max² / σ_min, so callers use the result only when σ_min
    is not far below σ_max (``kernel.planner`` asks for σ_min ≥ 1e-3 ‖A‖_F) and fall back to
    :func:`svd_into` otherwise. Returns -1 when a pivot vanishes at λ = 0 (A singular to working
    precision) or Newton does not settle. ``G`` (6, 6) and ``tri`` (2, 6; diagonal,
    off-diagonal) are scratch; ``A`` is not modified.
    """
    _gram_into(A, G)
    for k in range(4):
        _householder_step(G, tri[0], tri[1], k)
    _tridiagonal_tail(G, tri)
    lam, done, result = _laguerre_from_zero(tri[0], tri[1])
    for _ in range(100):
        if done:
            return result
        lam, done, result = _newton_step(tri[0], tri[1], lam)
    return -1.0


@njit(cache=True, error_model="numpy")
def smallest_singular_values(A, B, G, G_b, tri_a, tri_b):
    """:func:`smallest_singular_value` of two 6x6 matrices (the same numbers as two calls).

    The two reductions and the two iterations run step for step in one loop: each is a chain of
    dependent square roots and divisions, and interleaved the processor overlaps the two chains
    (the planner's two arm Jacobians are known before either filtered inverse is needed).
    """
    _gram_into(A, G)
    _gram_into(B, G_b)
    for k in range(4):
        _householder_step(G, tri_a[0], tri_a[1], k)
        _householder_step(G_b, tri_b[0], tri_b[1], k)
    _tridiagonal_tail(G, tri_a)
    _tridiagonal_tail(G_b, tri_b)
    da, ea, db, eb = tri_a[0], tri_a[1], tri_b[0], tri_b[1]
    lam_a, done_a, result_a = _laguerre_from_zero(da, ea)
    lam_b, done_b, result_b = _laguerre_from_zero(db, eb)
    for _ in range(100):
        if done_a and done_b:
            break
        if not done_a:
            lam_a, done_a, result_a = _newton_step(da, ea, lam_a)
        if not done_b:
            lam_b, done_b, result_b = _newton_step(db, eb, lam_b)
    return (result_a if done_a else -1.0), (result_b if done_b else -1.0)


@njit(cache=True, error_model="numpy", inline="always")
def _gram_into(A, G):
    """G = AᵀA (6x6, both triangles)."""
    for i in range(6):
        for j in range(i, 6):
            acc = 0.0
            for r in range(6):
                acc += A[r, i] * A[r, j]
            G[i, j] = acc
            G[j, i] = acc


@njit(cache=True, error_model="numpy", inline="always")
def _householder_step(G, d, e, k):
    """Step k (0-3) of the reduction of the symmetric ``G`` to tridiagonal form: the Householder
    reflection that zeroes column k below the subdiagonal (v kept in G[k+1:, k], w in G[k, k+1:]);
    ``d[k]``, ``e[k]`` receive the diagonal and off-diagonal entries. A column already zero below
    the subdiagonal gets the sign-flipping reflection (or none, β = 0, when it is zero altogether).
    """
    n = 6
    d[k] = G[k, k]
    below = 0.0
    for i in range(k + 2, n):
        below += G[i, k] * G[i, k]
    x0 = G[k + 1, k]
    norm = math.sqrt(x0 * x0 + below)
    alpha = -norm if x0 >= 0.0 else norm
    v0 = x0 - alpha
    den = v0 * v0 + below
    beta = 2.0 / den if den > 0.0 else 0.0
    G[k + 1, k] = v0
    half = 0.0
    for i in range(k + 1, n):  # p = β G v
        acc = 0.0
        for j in range(k + 1, n):
            acc += G[i, j] * G[j, k]
        G[k, i] = beta * acc
        half += G[k, i] * G[i, k]
    half *= 0.5 * beta
    for i in range(k + 1, n):  # w = p − (β vᵀp / 2) v
        G[k, i] -= half * G[i, k]
    for i in range(k + 1, n):  # G ← G − v wᵀ − w vᵀ
        for j in range(k + 1, i + 1):
            G[i, j] -= G[i, k] * G[k, j] + G[k, i] * G[j, k]
            G[j, i] = G[i, j]
    e[k] = alpha


@njit(cache=True, error_model="numpy", inline="always")
def _tridiagonal_tail(G, tri):
    """The last diagonal and off-diagonal entries, after the four reflections."""
    tri[0, 4], tri[0, 5], tri[1, 4] = G[4, 4], G[5, 5], G[5, 4]


@njit(cache=True, error_model="numpy", inline="always")
def _laguerre_from_zero(d, e):
    """One Laguerre step on det(T − λI) from λ = 0 (T: diagonal ``d``, off-diagonal ``e``).

    With S₁ = Σ 1/λᵢ and S₂ = Σ 1/λᵢ² (from the pivots of T and their first two derivatives in λ),
    the step is 6 / (S₁ + √(5 (6 S₂ − S₁²))). Returns ``(lam, done, result)`` as
    :func:`_newton_step`: done with -1 when a pivot of T is not positive (T singular to working
    precision).
    """
    n = 6
    q, dq, ddq = d[0], -1.0, 0.0  # pivot of T − λI at λ = 0 and its first two derivatives in λ
    if not q > 0.0:
        return 0.0, True, -1.0
    inv = 1.0 / q
    g = dq * inv
    h = -g * g
    for k in range(1, n):
        e2 = e[k - 1] * e[k - 1]
        r = e2 * inv
        ddq = r * inv * (ddq - 2.0 * dq * dq * inv)
        dq = -1.0 + r * dq * inv
        q = d[k] - r
        if not q > 0.0:
            return 0.0, True, -1.0
        inv = 1.0 / q
        gk = dq * inv
        g += gk
        h += ddq * inv - gk * gk
    s1, s2 = -g, -h  # Σ 1/λᵢ, Σ 1/λᵢ²
    return n / (s1 + math.sqrt(max((n - 1) * (n * s2 - s1 * s1), 0.0))), False, -1.0


@njit(cache=True, error_model="numpy", inline="always")
def _newton_step(d, e, lam):
    """One Newton step on det(T − λI) from ``lam`` (T: diagonal ``d``, off-diagonal ``e``).

    Returns ``(lam, done, result)``: the next λ; done when converged (result √λ) or when a pivot
    of T − λI is not positive (result √λ: at the root to working precision).
    """
    n = 6
    q, dq = d[0] - lam, -1.0  # pivot of T − λI and its derivative in λ
    if not q > 0.0:
        return lam, True, math.sqrt(lam)
    inv = 1.0 / q
    slope = dq * inv  # d/dλ log det(T − λI)
    for k in range(1, n):
        r = e[k - 1] * e[k - 1] * inv
        dq = -1.0 + r * dq * inv
        q = d[k] - lam - r
        if not q > 0.0:  # at or past the root: only by rounding, once converged
            return lam, True, math.sqrt(lam)
        inv = 1.0 / q
        slope += dq * inv
    step = -1.0 / slope
    lam += step
    if step <= 1e-12 * lam:
        return lam, True, math.sqrt(lam)
    return lam, False, -1.0
