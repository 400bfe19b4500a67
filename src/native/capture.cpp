// The capture judge (capture.hpp; docs/model.md §23).
#include "ffsr/capture.hpp"

#include <algorithm>
#include <cmath>

#include "ffsr/planner.hpp"

namespace ffsr {

void mission_jacobian(const Frames& f, Mat6& J) {
  for (int k = 0; k < 6; ++k) {
    const double dx = f.pe[0][0] - f.pj[k][0], dy = f.pe[0][1] - f.pj[k][1], dz = f.pe[0][2] - f.pj[k][2];
    J[0][k] = f.z[k][1] * dz - f.z[k][2] * dy, J[1][k] = f.z[k][2] * dx - f.z[k][0] * dz;
    J[2][k] = f.z[k][0] * dy - f.z[k][1] * dx;
    J[3][k] = f.z[k][0], J[4][k] = f.z[k][1], J[5][k] = f.z[k][2];
  }
}

void capture_quantities(const Frames& f, const double x[kStateSize], const double v[18], const Mat6& J,
                        const double p_h[3], const double q_h[4], const double V_h[6], double out[4]) {
  const Mat3& R = f.R_b;
  double vb[3], wb[3];  // the base's twist in the world frame
  for (int a = 0; a < 3; ++a) {
    vb[a] = R[a][0] * v[0] + R[a][1] * v[1] + R[a][2] * v[2];
    wb[a] = R[a][0] * v[3] + R[a][1] * v[4] + R[a][2] * v[5];
  }
  const double* pe = f.pe[0];
  const double r[3] = {pe[0] - x[0], pe[1] - x[1], pe[2] - x[2]};
  double ve[3] = {vb[0] + (wb[1] * r[2] - wb[2] * r[1]), vb[1] + (wb[2] * r[0] - wb[0] * r[2]),
                  vb[2] + (wb[0] * r[1] - wb[1] * r[0])};
  double we[3] = {wb[0], wb[1], wb[2]};
  for (int k = 0; k < 6; ++k)
    for (int a = 0; a < 3; ++a) ve[a] += J[a][k] * v[6 + k], we[a] += J[3 + a][k] * v[6 + k];
  double q_e[4];
  R_to_quat_wxyz(f.Re[0], q_e);
  // the angle between the frames, 2 atan2(|ε|, |η|) of σ_h* ⊗ σ_e (well conditioned at small angles, where the
  // 2 acos(|σ_h · σ_e|) of capture-v0's judge resolves no better than ~1e-8 rad)
  const double eta = q_h[0] * q_e[0] + q_h[1] * q_e[1] + q_h[2] * q_e[2] + q_h[3] * q_e[3];
  const double ex = q_h[0] * q_e[1] - q_e[0] * q_h[1] - q_h[2] * q_e[3] + q_h[3] * q_e[2];
  const double ey = q_h[0] * q_e[2] - q_e[0] * q_h[2] - q_h[3] * q_e[1] + q_h[1] * q_e[3];
  const double ez = q_h[0] * q_e[3] - q_e[0] * q_h[3] - q_h[1] * q_e[2] + q_h[2] * q_e[1];
  double dp = 0.0, dv = 0.0, dw = 0.0;
  for (int a = 0; a < 3; ++a) {
    dp += (pe[a] - p_h[a]) * (pe[a] - p_h[a]);
    dv += (ve[a] - V_h[a]) * (ve[a] - V_h[a]);
    dw += (we[a] - V_h[3 + a]) * (we[a] - V_h[3 + a]);
  }
  out[0] = std::sqrt(dp), out[1] = 2.0 * std::atan2(std::sqrt(ex * ex + ey * ey + ez * ez), std::fabs(eta));
  out[2] = std::sqrt(dv), out[3] = std::sqrt(dw);
}

void add_capture(CaptureJudge& j, const double q[4]) {
  const long k = j.samples++;
  double ratio[4], largest = 0.0;
  for (int i = 0; i < 4; ++i) {
    ratio[i] = q[i] / j.rule.bound[i], j.last[i] = q[i];
    largest = std::isnan(ratio[i]) || std::isnan(largest) ? std::numeric_limits<double>::quiet_NaN()
                                                          : std::max(largest, ratio[i]);
  }
  if (j.contact_at < 0 && q[0] <= j.rule.contact) j.contact_at = k, j.contact_speed = q[2];
  const double key = std::isnan(largest) ? std::numeric_limits<double>::infinity() : largest;
  while (!j.window.empty() && j.window.back().second <= key) j.window.pop_back();
  j.window.emplace_back(k, key);
  while (j.window.front().first <= k - j.rule.needed) j.window.pop_front();
  if (k + 1 >= j.rule.needed) j.margin = std::min(j.margin, j.window.front().second);
  if (!(largest <= 1.0)) {
    j.run = 0;
    for (double& w : j.run_worst) w = 0.0;
    return;
  }
  ++j.run;
  for (int i = 0; i < 4; ++i) j.run_worst[i] = std::max(j.run_worst[i], ratio[i]);
  if (j.run == j.rule.needed && j.captured_at < 0) {
    j.captured_at = k;
    for (int i = 0; i < 4; ++i) j.worst[i] = j.run_worst[i];
  }
}

}  // namespace ffsr
