// Small dense linear algebra of the kernel (linalg.hpp).
#include "ffsr/linalg.hpp"

#include <algorithm>
#include <utility>

namespace ffsr {
namespace {

// Column pairs of one Jacobi sweep of 6 columns: 5 rounds of 3 disjoint pairs (round-robin order).
struct Pairs {
  int i[15];
  int j[15];
  constexpr Pairs() : i(), j() {
    int players[6] = {0, 1, 2, 3, 4, 5};
    int k = 0;
    for (int round = 0; round < 5; ++round) {
      for (int p = 0; p < 3; ++p) {
        const int a = players[p], b = players[5 - p];
        i[k] = a < b ? a : b;
        j[k] = a < b ? b : a;
        ++k;
      }
      const int last = players[5];
      for (int p = 5; p > 1; --p) players[p] = players[p - 1];
      players[1] = last;
    }
  }
};
constexpr Pairs kPairs{};

void gram(const Mat6& A, Mat6& G) {
  for (int i = 0; i < 6; ++i) {
    for (int j = i; j < 6; ++j) {
      double acc = 0.0;
      for (int r = 0; r < 6; ++r) acc += A[r][i] * A[r][j];
      G[i][j] = acc;
      G[j][i] = acc;
    }
  }
}

// Step k (0-3) of the reduction of the symmetric G to tridiagonal form (d: diagonal, e: off-diagonal).
void householder_step(Mat6& G, double d[6], double e[6], int k) {
  const int n = 6;
  d[k] = G[k][k];
  double below = 0.0;
  for (int i = k + 2; i < n; ++i) below += G[i][k] * G[i][k];
  const double x0 = G[k + 1][k];
  const double norm = std::sqrt(x0 * x0 + below);
  const double alpha = x0 >= 0.0 ? -norm : norm;
  const double v0 = x0 - alpha;
  const double den = v0 * v0 + below;
  const double beta = den > 0.0 ? 2.0 / den : 0.0;
  G[k + 1][k] = v0;
  double half = 0.0;
  for (int i = k + 1; i < n; ++i) {  // p = β G v
    double acc = 0.0;
    for (int j = k + 1; j < n; ++j) acc += G[i][j] * G[j][k];
    G[k][i] = beta * acc;
    half += G[k][i] * G[i][k];
  }
  half *= 0.5 * beta;
  for (int i = k + 1; i < n; ++i) G[k][i] -= half * G[i][k];  // w = p − (β vᵀp / 2) v
  for (int i = k + 1; i < n; ++i) {                            // G ← G − v wᵀ − w vᵀ
    for (int j = k + 1; j <= i; ++j) {
      G[i][j] -= G[i][k] * G[k][j] + G[k][i] * G[j][k];
      G[j][i] = G[i][j];
    }
  }
  e[k] = alpha;
}

void tridiagonal(const Mat6& A, Mat6& G, double d[6], double e[6]) {
  gram(A, G);
  for (int k = 0; k < 4; ++k) householder_step(G, d, e, k);
  d[4] = G[4][4];
  d[5] = G[5][5];
  e[4] = G[5][4];
}

// The state of the climb to the smallest eigenvalue: λ, whether it is done, and its result.
struct Climb {
  double lam;
  bool done;
  double result;
};

// One Laguerre step on det(T − λI) from λ = 0.
Climb laguerre_from_zero(const double d[6], const double e[6]) {
  const int n = 6;
  double q = d[0], dq = -1.0, ddq = 0.0;
  if (!(q > 0.0)) return {0.0, true, -1.0};
  double inv = 1.0 / q;
  double g = dq * inv;
  double h = -g * g;
  for (int k = 1; k < n; ++k) {
    const double e2 = e[k - 1] * e[k - 1];
    const double r = e2 * inv;
    ddq = r * inv * (ddq - 2.0 * dq * dq * inv);
    dq = -1.0 + r * dq * inv;
    q = d[k] - r;
    if (!(q > 0.0)) return {0.0, true, -1.0};
    inv = 1.0 / q;
    const double gk = dq * inv;
    g += gk;
    h += ddq * inv - gk * gk;
  }
  const double s1 = -g, s2 = -h;
  return {n / (s1 + std::sqrt(std::max((n - 1) * (n * s2 - s1 * s1), 0.0))), false, -1.0};
}

// One Newton step on det(T − λI) from λ.
Climb newton_step(const double d[6], const double e[6], double lam) {
  const int n = 6;
  double q = d[0] - lam, dq = -1.0;
  if (!(q > 0.0)) return {lam, true, std::sqrt(lam)};
  double inv = 1.0 / q;
  double slope = dq * inv;
  for (int k = 1; k < n; ++k) {
    const double r = e[k - 1] * e[k - 1] * inv;
    dq = -1.0 + r * dq * inv;
    q = d[k] - lam - r;
    if (!(q > 0.0)) return {lam, true, std::sqrt(lam)};
    inv = 1.0 / q;
    slope += dq * inv;
  }
  const double step = -1.0 / slope;
  lam += step;
  if (step <= 1e-12 * lam) return {lam, true, std::sqrt(lam)};
  return {lam, false, -1.0};
}

}  // namespace

void solve6(const Mat6& A, const double b[6], double x[6]) {
  const int n = 6;
  Mat6 M;
  for (int r = 0; r < n; ++r) {
    x[r] = b[r];
    for (int c = 0; c < n; ++c) M[r][c] = A[r][c];
  }
  for (int c = 0; c < n; ++c) {
    int piv = c;
    double best = std::fabs(M[c][c]);
    for (int r = c + 1; r < n; ++r) {
      if (std::fabs(M[r][c]) > best) best = std::fabs(M[r][c]), piv = r;
    }
    if (piv != c) {
      for (int j = c; j < n; ++j) std::swap(M[c][j], M[piv][j]);
      std::swap(x[c], x[piv]);
    }
    const double inv = 1.0 / M[c][c];
    M[c][c] = inv;
    for (int r = c + 1; r < n; ++r) {
      const double f = M[r][c] * inv;
      for (int j = c + 1; j < n; ++j) M[r][j] -= f * M[c][j];
      x[r] -= f * x[c];
    }
  }
  for (int c = n - 1; c >= 0; --c) {
    double s = x[c];
    for (int j = c + 1; j < n; ++j) s -= M[c][j] * x[j];
    x[c] = s * M[c][c];
  }
}

void svd6(const Mat6& A, Mat6& Ut, double s[6], Mat6& Vt, bool vectors) {
  const int n = 6;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      Ut[c][r] = A[r][c];
      Vt[c][r] = r == c ? 1.0 : 0.0;
    }
  }
  for (int sweep = 0; sweep < 60; ++sweep) {
    bool rotated = false;
    for (int p = 0; p < 15; ++p) {
      const int i = kPairs.i[p], j = kPairs.j[p];
      double alpha = 0.0, beta = 0.0, gamma = 0.0;
      for (int r = 0; r < n; ++r) {
        alpha += Ut[i][r] * Ut[i][r];
        beta += Ut[j][r] * Ut[j][r];
        gamma += Ut[i][r] * Ut[j][r];
      }
      if (gamma * gamma <= kEps * kEps * alpha * beta) continue;  // orthogonal to working precision
      rotated = true;
      const double zeta = (beta - alpha) / (2.0 * gamma);
      const double t = (zeta >= 0.0 ? 1.0 : -1.0) / (std::fabs(zeta) + std::sqrt(1.0 + zeta * zeta));
      const double c = 1.0 / std::sqrt(1.0 + t * t);
      const double sn = c * t;
      for (int r = 0; r < n; ++r) {
        const double ui = Ut[i][r], uj = Ut[j][r];
        Ut[i][r] = c * ui - sn * uj;
        Ut[j][r] = sn * ui + c * uj;
      }
      if (vectors) {
        for (int r = 0; r < n; ++r) {
          const double vi = Vt[i][r], vj = Vt[j][r];
          Vt[i][r] = c * vi - sn * vj;
          Vt[j][r] = sn * vi + c * vj;
        }
      }
    }
    if (!rotated) break;
  }
  for (int i = 0; i < n; ++i) {
    double norm = 0.0;
    for (int r = 0; r < n; ++r) norm += Ut[i][r] * Ut[i][r];
    s[i] = std::sqrt(norm);
    if (vectors) {
      const double inv = s[i] > 0.0 ? 1.0 / s[i] : 0.0;
      for (int r = 0; r < n; ++r) Ut[i][r] *= inv;
    }
  }
}

double smallest_singular_value(const Mat6& A) {
  Mat6 G;
  double d[6], e[6];
  tridiagonal(A, G, d, e);
  Climb climb = laguerre_from_zero(d, e);
  for (int k = 0; k < 100; ++k) {
    if (climb.done) return climb.result;
    climb = newton_step(d, e, climb.lam);
  }
  return -1.0;
}

void smallest_singular_values(const Mat6& A, const Mat6& B, double out[2]) {
  Mat6 G, H;
  double da[6], ea[6], db[6], eb[6];
  gram(A, G);
  gram(B, H);
  for (int k = 0; k < 4; ++k) {
    householder_step(G, da, ea, k);
    householder_step(H, db, eb, k);
  }
  da[4] = G[4][4], da[5] = G[5][5], ea[4] = G[5][4];
  db[4] = H[4][4], db[5] = H[5][5], eb[4] = H[5][4];
  Climb a = laguerre_from_zero(da, ea), b = laguerre_from_zero(db, eb);
  for (int k = 0; k < 100 && !(a.done && b.done); ++k) {
    if (!a.done) a = newton_step(da, ea, a.lam);
    if (!b.done) b = newton_step(db, eb, b.lam);
  }
  out[0] = a.done ? a.result : -1.0;
  out[1] = b.done ? b.result : -1.0;
}

}  // namespace ffsr
