// Small dense linear algebra of the kernel: fixed sizes, caller-owned storage, no allocation.
//
// Every routine keeps the operation order of the reference it replaces, so that with floating-point
// contraction off and a generic target (CMakeLists.txt) the results are the numba kernel's bits.
#pragma once

#include <cmath>

namespace ffsr {

using Mat3 = double[3][3];
using Mat6 = double[6][6];

inline constexpr double kEps = 2.220446049250313e-16;

// x = A⁻¹ b for a symmetric, well-conditioned 3x3 matrix given by its upper triangle (cofactors).
inline void solve_sym3(double a00, double a01, double a02, double a11, double a12, double a22, double b0, double b1,
                       double b2, double x[3]) {
  const double c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22, c02 = a01 * a12 - a02 * a11;
  const double c11 = a00 * a22 - a02 * a02, c12 = a01 * a02 - a00 * a12, c22 = a00 * a11 - a01 * a01;
  const double inv = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02);
  x[0] = (c00 * b0 + c01 * b1 + c02 * b2) * inv;
  x[1] = (c01 * b0 + c11 * b1 + c12 * b2) * inv;
  x[2] = (c02 * b0 + c12 * b1 + c22 * b2) * inv;
}

// x = A⁻¹ b for a well-conditioned 3x3 matrix (cofactors).
inline void solve3(const Mat3& A, double b0, double b1, double b2, double x[3]) {
  const double c00 = A[1][1] * A[2][2] - A[1][2] * A[2][1];
  const double c01 = A[1][2] * A[2][0] - A[1][0] * A[2][2];
  const double c02 = A[1][0] * A[2][1] - A[1][1] * A[2][0];
  const double det = A[0][0] * c00 + A[0][1] * c01 + A[0][2] * c02;
  const double c10 = A[0][2] * A[2][1] - A[0][1] * A[2][2];
  const double c11 = A[0][0] * A[2][2] - A[0][2] * A[2][0];
  const double c12 = A[0][1] * A[2][0] - A[0][0] * A[2][1];
  const double c20 = A[0][1] * A[1][2] - A[0][2] * A[1][1];
  const double c21 = A[0][2] * A[1][0] - A[0][0] * A[1][2];
  const double c22 = A[0][0] * A[1][1] - A[0][1] * A[1][0];
  x[0] = (c00 * b0 + c10 * b1 + c20 * b2) / det;
  x[1] = (c01 * b0 + c11 * b1 + c21 * b2) / det;
  x[2] = (c02 * b0 + c12 * b1 + c22 * b2) / det;
}

// x = A⁻¹ b (6x6) by Gaussian elimination with partial pivoting; A and b are not modified.
void solve6(const Mat6& A, const double b[6], double x[6]);

// One-sided Jacobi SVD of a 6x6 matrix, A = U diag(s) Vᵀ (unsorted, s >= 0). Writes Uᵀ and Vᵀ by rows
// (zero rows of Uᵀ where s = 0). The sweep visits the pairs of a round-robin schedule. With
// vectors = false only s is meaningful (the same values: the rotations are the same).
void svd6(const Mat6& A, Mat6& Ut, double s[6], Mat6& Vt, bool vectors = true);

// σ_min of a 6x6 matrix from the smallest eigenvalue of AᵀA (Householder tridiagonalisation, one
// Laguerre step from 0, then Newton), or -1 when that is not reliable (a pivot vanishes at λ = 0, or
// Newton does not settle): callers fall back to svd6.
double smallest_singular_value(const Mat6& A);

// The same for two matrices, their chains of dependent operations interleaved (the same numbers as
// two calls).
void smallest_singular_values(const Mat6& A, const Mat6& B, double out[2]);

}  // namespace ffsr
