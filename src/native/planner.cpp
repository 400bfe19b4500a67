// The planner step (planner.hpp): pose errors, the desired path, φ, the base command, the mission task, the
// arms' Jacobians and their filtered inverses (docs/model.md §3-8).
#include "ffsr/planner.hpp"

#include <algorithm>
#include <cmath>

#include "ffsr/capture.hpp"
#include "field.hpp"

namespace ffsr {
namespace {

constexpr double kCap = 700.0;

// Hamilton product of scalar-first quaternions a ⊗ b.
void qmul(double a0, double a1, double a2, double a3, double b0, double b1, double b2, double b3, double out[4]) {
  out[0] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3;
  out[1] = a0 * b1 + b0 * a1 + a2 * b3 - a3 * b2;
  out[2] = a0 * b2 + b0 * a2 + a3 * b1 - a1 * b3;
  out[3] = a0 * b3 + b0 * a3 + a1 * b2 - a2 * b1;
}

// φ's magnitude at |x| = r (log space, capped at e^700).
double phi_scale(double r, double T_c, double m, bool printed) {
  if (r == 0.0) return 0.0;
  const double log_r = std::log(r);
  double log_mag = std::min(std::exp(m * log_r), kCap) - std::log(m * T_c);
  if (!printed) log_mag += (1.0 - m) * log_r;
  return std::exp(std::min(log_mag, kCap));
}

// The feedback term for the pose error e: 0, K e, or φ(e) (whole or split).
void feedback(const PlannerSettings& s, const double e[6], double out[6]) {
  if (s.method == Method::kNoFeedback) {
    for (int i = 0; i < 6; ++i) out[i] = 0.0;
    return;
  }
  if (s.method == Method::kProportional) {
    for (int i = 0; i < 6; ++i) out[i] = s.K * e[i];
    return;
  }
  for (int part = 0; part < (s.phi_split ? 2 : 1); ++part) {
    const int lo = s.phi_split ? 3 * part : 0, hi = s.phi_split ? 3 * part + 3 : 6;
    double norm = 0.0;
    for (int i = lo; i < hi; ++i) norm += e[i] * e[i];
    const double r = std::sqrt(norm);
    const double scale = phi_scale(r, s.T_c, s.m, s.phi_printed);
    for (int i = lo; i < hi; ++i) out[i] = r > 0.0 ? (e[i] / r) * scale : 0.0;
  }
}

// Pose error e = [p − p_d; e_o] and the attitude blocks J_o, J_od (sigma: scalar first).
void pose_error(const double p[3], const double sigma[4], const double p_d[3], const double sigma_d[4], bool body,
                double e[6], Mat3& Jo, Mat3& Jo_d) {
  double sw = sigma[0], sx = sigma[1], sy = sigma[2], sz = sigma[3];
  if (sw * sigma_d[0] + sx * sigma_d[1] + sy * sigma_d[2] + sz * sigma_d[3] < 0.0) sw = -sw, sx = -sx, sy = -sy, sz = -sz;
  for (int a = 0; a < 3; ++a) e[a] = p[a] - p_d[a];
  double q[4];
  if (body) {
    qmul(sigma_d[0], -sigma_d[1], -sigma_d[2], -sigma_d[3], sw, sx, sy, sz, q);
    const double eta = q[0], e0 = q[1], e1 = q[2], e2 = q[3];
    const double A[3][3] = {{eta, -e2, e1}, {e2, eta, -e0}, {-e1, e0, eta}};  // η I + S(ε)
    const double vv = sx * sx + sy * sy + sz * sz;
    const double Rs[3][3] = {{sw * sw - vv + 2 * sx * sx, 2 * (sx * sy - sw * sz), 2 * (sx * sz + sw * sy)},
                             {2 * (sx * sy + sw * sz), sw * sw - vv + 2 * sy * sy, 2 * (sy * sz - sw * sx)},
                             {2 * (sx * sz - sw * sy), 2 * (sy * sz + sw * sx), sw * sw - vv + 2 * sz * sz}};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        Jo[r][c] = 0.5 * (A[r][0] * Rs[c][0] + A[r][1] * Rs[c][1] + A[r][2] * Rs[c][2]);
        Jo_d[r][c] = Jo[r][c];
      }
    }
  } else {
    qmul(sw, sx, sy, sz, sigma_d[0], -sigma_d[1], -sigma_d[2], -sigma_d[3], q);
    const double eta = q[0], e0 = q[1], e1 = q[2], e2 = q[3];
    const double S[3][3] = {{0.0, -e2, e1}, {e2, 0.0, -e0}, {-e1, e0, 0.0}};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        const double diagonal = r == c ? eta : 0.0;
        Jo[r][c] = 0.5 * (diagonal - S[r][c]);
        Jo_d[r][c] = 0.5 * (diagonal + S[r][c]);
      }
    }
  }
  e[3] = q[1], e[4] = q[2], e[5] = q[3];
}

// The desired end-effector pose and world twist at t towards a target (trapezoid + SLERP).
void desired(const PlannerSettings& s, const PathTarget& target, double t, Plan& p) {
  const double t_f = s.motion_time, t_a = s.accel_time;
  const double speed = 1.0 / (t_f - t_a);
  const double acc = speed / t_a;
  double u, ud;
  if (t <= 0.0) {
    u = 0.0, ud = 0.0;
  } else if (t < t_a) {
    u = 0.5 * acc * t * t, ud = acc * t;
  } else if (t <= t_f - t_a) {
    u = 0.5 * acc * t_a * t_a + speed * (t - t_a), ud = speed;
  } else if (t < t_f) {
    const double left = t_f - t;
    u = 1.0 - 0.5 * acc * (left * left), ud = acc * (t_f - t);
  } else {
    u = 1.0, ud = 0.0;
  }
  const double ch = std::cos(0.5 * u * target.angle), sh = std::sin(0.5 * u * target.angle);
  for (int a = 0; a < 3; ++a) {
    p.p_d[a] = s.start_position[a] + u * (target.position[a] - s.start_position[a]);
    p.V_ed[a] = ud * (target.position[a] - s.start_position[a]);
    p.V_ed[3 + a] = ud * target.angle * target.axis[a];
  }
  const double* q = s.start_attitude;
  qmul(ch, sh * target.axis[0], sh * target.axis[1], sh * target.axis[2], q[0], q[1], q[2], q[3], p.sigma_d);
}

const PathTarget& estimate_at(const PlannerSettings& s, double t) {
  const long rows = static_cast<long>(s.estimates.size());
  if (rows == 1) return s.estimates[0];
  const long k = static_cast<long>(std::floor(t / s.estimate_interval + 1e-9));
  return s.estimates[static_cast<size_t>(k < rows - 1 ? k : rows - 1)];
}

// The commanded base twist V0 = −J_b⁻¹ f(e₀) (base pose error into p.e0).
void base_command(const PlannerSettings& s, const double x[kStateSize], Plan& p) {
  const double sigma[4] = {x[6], x[3], x[4], x[5]};
  pose_error(x, sigma, s.base_position, s.base_attitude, s.body_attitude_error, p.e0, p.Jo, p.Jo_d);
  feedback(s, p.e0, p.target);
  p.V0[0] = -p.target[0], p.V0[1] = -p.target[1], p.V0[2] = -p.target[2];
  double w[3];
  solve3(p.Jo, p.target[3], p.target[4], p.target[5], w);
  p.V0[3] = -w[0], p.V0[4] = -w[1], p.V0[5] = -w[2];
}

// The mission arm's task rate x₁ = J_e⁻¹(J_ed V_ed − f(e₁)) − J₀ V0 (end-effector error into p.e1).
void mission_task(const PlannerSettings& s, const double x[kStateSize], double t, const Frames& f, Plan& p) {
  if (s.timing.enabled) {  // the commanded approach onto the grasp frame (docs/model.md §23)
    const Frame& r = frame_at(s, t);
    timed_desired(s.timing, p.timing, s.start_position, s.start_attitude, r.p_d, r.sigma_d, r.V_ed, p.p_d,
                  p.sigma_d, p.V_ed);
  } else if (!s.frames.empty()) {
    const Frame& r = frame_at(s, t);
    for (int i = 0; i < 3; ++i) p.p_d[i] = r.p_d[i];
    for (int i = 0; i < 4; ++i) p.sigma_d[i] = r.sigma_d[i];
    for (int i = 0; i < 6; ++i) p.V_ed[i] = r.V_ed[i];
  } else {
    desired(s, estimate_at(s, t), t, p);
  }
  const double* pe = f.pe[0];
  double sigma[4];
  R_to_quat_wxyz(f.Re[0], sigma);
  pose_error(pe, sigma, p.p_d, p.sigma_d, s.body_attitude_error, p.e1, p.Jo, p.Jo_d);
  double* fb = p.target;
  const double* V_ed = p.V_ed;
  const double* V0 = p.V0;
  const auto& Jd = p.Jo_d;
  feedback(s, p.e1, fb);
  const double r0 = Jd[0][0] * V_ed[3] + Jd[0][1] * V_ed[4] + Jd[0][2] * V_ed[5] - fb[3];
  const double r1 = Jd[1][0] * V_ed[3] + Jd[1][1] * V_ed[4] + Jd[1][2] * V_ed[5] - fb[4];
  const double r2 = Jd[2][0] * V_ed[3] + Jd[2][1] * V_ed[4] + Jd[2][2] * V_ed[5] - fb[5];
  double w[3];
  solve3(p.Jo, r0, r1, r2, w);
  const double dx = pe[0] - x[0], dy = pe[1] - x[1], dz = pe[2] - x[2];  // J₀ V0 = [v − d × ω; ω]
  p.x1[0] = V_ed[0] - fb[0] - (V0[0] - (dy * V0[5] - dz * V0[4]));
  p.x1[1] = V_ed[1] - fb[1] - (V0[1] - (dz * V0[3] - dx * V0[5]));
  p.x1[2] = V_ed[2] - fb[2] - (V0[2] - (dx * V0[4] - dy * V0[3]));
  p.x1[3] = w[0] - V0[3], p.x1[4] = w[1] - V0[4], p.x1[5] = w[2] - V0[5];
}

// out = μ J♯ target + (Θ̇_c − μ P Θ̇_c); returns σ_min of J. J♯ damps each singular value below ε; P projects
// onto J's row space. s_min: smallest_singular_value(J), -1 when it declined.
double filtered_solve(const Mat6& J, double s_min, const double target[6], double lam_max, double eps, double mu,
                      bool avoiding, const double dq_c[6], double out[6]) {
  Mat6 Ut, Vt;
  double s[6], y[6];
  double frobenius = 0.0;
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) frobenius += J[r][c] * J[r][c];
  const bool certified = s_min >= 1e-3 * std::sqrt(frobenius);
  bool undamped = certified && s_min >= eps;
  if (!certified) {
    svd6(J, Ut, s, Vt, false);
    double s_max = 0.0;
    s_min = 1e300;
    for (int i = 0; i < 6; ++i) s_max = std::max(s_max, s[i]), s_min = std::min(s_min, s[i]);
    undamped = s_min >= eps && s_min > s_max * 6.0 * kEps;
  }
  if (undamped) {
    solve6(J, target, y);
    for (int r = 0; r < 6; ++r) out[r] = mu * y[r] + (dq_c[r] - mu * dq_c[r]);
    return s_min;
  }
  svd6(J, Ut, s, Vt, true);
  double s_max = 0.0;
  s_min = 1e300;
  for (int i = 0; i < 6; ++i) s_max = std::max(s_max, s[i]), s_min = std::min(s_min, s[i]);
  for (int i = 0; i < 6; ++i) {
    double damping = 0.0;
    if (eps > 0.0 && s[i] < eps) {
      const double ratio = s[i] / eps;
      damping = lam_max * lam_max * (1.0 - ratio * ratio);
    }
    const double denom = s[i] * s[i] + damping;
    const double gain = denom > 0.0 ? s[i] / denom : 0.0;
    double acc = 0.0;
    for (int r = 0; r < 6; ++r) acc += Ut[i][r] * target[r];
    y[i] = gain * acc;
  }
  for (int r = 0; r < 6; ++r) {
    double acc = 0.0;
    for (int i = 0; i < 6; ++i) acc += Vt[i][r] * y[i];
    out[r] = mu * acc;
  }
  if (avoiding) {
    const double tol = s_max * 6.0 * kEps;
    for (int i = 0; i < 6; ++i) {
      double acc = 0.0;
      if (s[i] > tol)
        for (int r = 0; r < 6; ++r) acc += Vt[i][r] * dq_c[r];
      y[i] = acc;
    }
    for (int r = 0; r < 6; ++r) {
      double acc = 0.0;
      for (int i = 0; i < 6; ++i) acc += Vt[i][r] * y[i];
      out[r] += dq_c[r] - mu * acc;
    }
  }
  return s_min;
}

}  // namespace

void R_to_quat_wxyz(const Mat3& R, double q[4]) {
  const double t = R[0][0] + R[1][1] + R[2][2];
  double w, x, y, z;
  if (t > 0.0) {
    const double s = std::sqrt(t + 1.0) * 2.0;
    w = 0.25 * s, x = (R[2][1] - R[1][2]) / s, y = (R[0][2] - R[2][0]) / s, z = (R[1][0] - R[0][1]) / s;
  } else if (R[0][0] > R[1][1] && R[0][0] > R[2][2]) {
    const double s = std::sqrt(1.0 + R[0][0] - R[1][1] - R[2][2]) * 2.0;
    w = (R[2][1] - R[1][2]) / s, x = 0.25 * s, y = (R[0][1] + R[1][0]) / s, z = (R[0][2] + R[2][0]) / s;
  } else if (R[1][1] > R[2][2]) {
    const double s = std::sqrt(1.0 + R[1][1] - R[0][0] - R[2][2]) * 2.0;
    w = (R[0][2] - R[2][0]) / s, x = (R[0][1] + R[1][0]) / s, y = 0.25 * s, z = (R[1][2] + R[2][1]) / s;
  } else {
    const double s = std::sqrt(1.0 + R[2][2] - R[0][0] - R[1][1]) * 2.0;
    w = (R[1][0] - R[0][1]) / s, x = (R[0][2] + R[2][0]) / s, y = (R[1][2] + R[2][1]) / s, z = 0.25 * s;
  }
  const double norm = std::sqrt(w * w + x * x + y * y + z * z) * (w < 0.0 ? -1.0 : 1.0);
  q[0] = w / norm, q[1] = x / norm, q[2] = y / norm, q[3] = z / norm;
}

void true_error(const PlannerSettings& s, const Frames& f, double t, Plan& p) {
  desired(s, s.truth, t, p);
  double sigma[4];
  R_to_quat_wxyz(f.Re[0], sigma);
  pose_error(f.pe[0], sigma, p.p_d, p.sigma_d, s.body_attitude_error, p.e1t, p.Jo, p.Jo_d);
}

void plan(const Robot& robot, const PlannerSettings& s, const double x[kStateSize], double t, Frames& f, Momentum& m,
          Plan& p) {
  kinematics(robot, x, f);
  momentum(robot, x, f, m);
  base_command(s, x, p);
  mission_task(s, x, t, f, p);
  mission_jacobian(f, p.J);  // geometric Jacobian of the mission arm (world)
  for (int r = 0; r < 6; ++r)  // the balance arm's: J_c² = −H_bm2
    for (int c = 0; c < 6; ++c) p.Jb[r][c] = -m.H_bm[1][r][c];
  double smallest[2];
  smallest_singular_values(p.J, p.Jb, smallest);
  for (int arm = 0; arm < 2; ++arm) {
    double mu = 1.0, cdf = 0.0;
    for (double& v : p.dq_c) v = 0.0;
    if (!s.obstacles.empty() || s.body_danger > 0.0) avoidance(s, f, arm, t, p, mu, cdf);
    double* target;
    if (arm == 0) {
      target = p.x1;
    } else {
      target = p.target;  // x₂ = H_bm1 Θ̇₁ + H_b V0 − C, C the momentum about the base CoM
      const double* h = s.momentum;
      const double ox = m.rg[0] - x[0], oy = m.rg[1] - x[1], oz = m.rg[2] - x[2];
      target[0] = h[0], target[1] = h[1], target[2] = h[2];
      target[3] = h[3] + oy * h[2] - oz * h[1];
      target[4] = h[4] + oz * h[0] - ox * h[2];
      target[5] = h[5] + ox * h[1] - oy * h[0];
      for (int r = 0; r < 6; ++r) {
        double acc = -target[r];
        for (int c = 0; c < 6; ++c) acc += m.H_bm[0][r][c] * p.dq[c] + m.H_b[r][c] * p.V0[c];
        target[r] = acc;
      }
    }
    p.mu[arm] = mu, p.cdf[arm] = cdf;
    p.smin[arm] = arm == 0 ? filtered_solve(p.J, smallest[0], target, s.lambda_mission, s.eps_mission, mu, mu < 1.0,
                                            p.dq_c, p.dq)
                           : filtered_solve(p.Jb, smallest[1], target, s.lambda_balance, s.eps_balance, mu, mu < 1.0,
                                            p.dq_c, p.dq + 6);
  }
}

}  // namespace ffsr
