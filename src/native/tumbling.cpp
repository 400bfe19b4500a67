// Torque-free motion of a tumbling body (tumbling.hpp).
#include "ffsr/tumbling.hpp"

#include <cmath>

namespace ffsr {
namespace {

// dq = ½ q ⊗ (0, ω) and dω from Euler's equations.
void rates(const double q[4], const double w[3], const double inertia[3], double dq[4], double dw[3]) {
  dq[0] = 0.5 * (-q[1] * w[0] - q[2] * w[1] - q[3] * w[2]);
  dq[1] = 0.5 * (q[0] * w[0] + q[2] * w[2] - q[3] * w[1]);
  dq[2] = 0.5 * (q[0] * w[1] + q[3] * w[0] - q[1] * w[2]);
  dq[3] = 0.5 * (q[0] * w[2] + q[1] * w[1] - q[2] * w[0]);
  dw[0] = (inertia[1] - inertia[2]) * w[1] * w[2] / inertia[0];
  dw[1] = (inertia[2] - inertia[0]) * w[2] * w[0] / inertia[1];
  dw[2] = (inertia[0] - inertia[1]) * w[0] * w[1] / inertia[2];
}

}  // namespace

void propagate_tumbling(const double quaternion[4], const double omega[3], const double inertia[3], double dt,
                        int substeps, long steps, double* out_q, double* out_w) {
  const double h = dt / substeps;
  double sum = 0.0;
  for (int i = 0; i < 4; ++i) sum += quaternion[i] * quaternion[i];
  const double size = std::sqrt(sum);
  double q[4], w[3], kq[4][4], kw[4][3], sq[4], sw[3];
  for (int i = 0; i < 4; ++i) q[i] = quaternion[i] / size;
  for (int i = 0; i < 3; ++i) w[i] = omega[i];
  for (int i = 0; i < 4; ++i) out_q[i] = q[i];
  for (int i = 0; i < 3; ++i) out_w[i] = w[i];
  const double scales[3] = {0.5, 0.5, 1.0};
  for (long n = 0; n < steps; ++n) {
    for (int sub = 0; sub < substeps; ++sub) {
      rates(q, w, inertia, kq[0], kw[0]);
      for (int stage = 1; stage < 4; ++stage) {
        const double scale = scales[stage - 1];
        for (int i = 0; i < 4; ++i) sq[i] = q[i] + scale * h * kq[stage - 1][i];
        for (int i = 0; i < 3; ++i) sw[i] = w[i] + scale * h * kw[stage - 1][i];
        rates(sq, sw, inertia, kq[stage], kw[stage]);
      }
      for (int i = 0; i < 4; ++i) q[i] = q[i] + h / 6.0 * (kq[0][i] + 2.0 * kq[1][i] + 2.0 * kq[2][i] + kq[3][i]);
      for (int i = 0; i < 3; ++i) w[i] = w[i] + h / 6.0 * (kw[0][i] + 2.0 * kw[1][i] + 2.0 * kw[2][i] + kw[3][i]);
      const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
      for (int i = 0; i < 4; ++i) q[i] = q[i] / norm;
    }
    for (int i = 0; i < 4; ++i) out_q[4 * (n + 1) + i] = q[i];
    for (int i = 0; i < 3; ++i) out_w[3 * (n + 1) + i] = w[i];
  }
}

}  // namespace ffsr
