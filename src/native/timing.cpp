// The commanded approach (timing.hpp; docs/model.md §23).
#include "ffsr/timing.hpp"

#include <algorithm>
#include <cmath>

#include "ffsr/physics.hpp"

namespace ffsr {
namespace {

// One step of y towards target (semi-implicit Euler: the rate first, then y with the new rate): the rate moves by at
// most accel dt towards the fastest speed that still stops on the target in steps of accel dt, a dt (√(1/4 +
// 2|e|/(a dt²)) − 1/2) (one step later that speed is exactly a dt less), at most speed; a step that would cross the
// target ends on it, at rest.
void profile_step(double target, double speed, double accel, double dt, double& y, double& y_dot) {
  const double e = target - y;
  if (e == 0.0 && y_dot == 0.0) return;
  const double unit = accel * dt;
  double wanted = std::min(speed, unit * (std::sqrt(0.25 + 2.0 * std::fabs(e) / (unit * dt)) - 0.5));
  if (e < 0.0) wanted = -wanted;
  const double change = std::min(std::max(wanted - y_dot, -unit), unit);
  const double rate = y_dot + change;
  const double next = y + rate * dt;
  if ((target - next) * e <= 0.0) {
    y = target, y_dot = 0.0;
  } else {
    y = next, y_dot = rate;
  }
}

void cross(const double a[3], const double b[3], double out[3]) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

void qmul(const double a[4], const double b[4], double out[4]) {
  out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
  out[1] = a[0] * b[1] + b[0] * a[1] + a[2] * b[3] - a[3] * b[2];
  out[2] = a[0] * b[2] + b[0] * a[2] + a[3] * b[1] - a[1] * b[3];
  out[3] = a[0] * b[3] + b[0] * a[3] + a[1] * b[2] - a[2] * b[1];
}

// x + a φ × x + b φ × (φ × x).
void plus_crosses(const double phi[3], const double x[3], double a, double b, double out[3]) {
  double once[3], twice[3];
  cross(phi, x, once);
  cross(phi, once, twice);
  for (int i = 0; i < 3; ++i) out[i] = x[i] + a * once[i] + b * twice[i];
}

double norm3(const double v[3]) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

// J_l(φ) x, J_l the left Jacobian of SO(3) (series to θ⁶ below θ = 0.1).
void left_jacobian_times(const double phi[3], const double x[3], double out[3]) {
  const double theta = norm3(phi);
  double a, b;
  if (theta < 0.1) {
    const double t2 = theta * theta;
    a = 0.5 - t2 / 24.0 + t2 * t2 / 720.0 - t2 * t2 * t2 / 40320.0;
    b = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0 - t2 * t2 * t2 / 362880.0;
  } else {
    a = (1.0 - std::cos(theta)) / (theta * theta), b = (theta - std::sin(theta)) / (theta * theta * theta);
  }
  plus_crosses(phi, x, a, b, out);
}

// J_l(φ)⁻¹ x = x − ½ φ × x + c φ × (φ × x), c = (1 − (θ/2) cot(θ/2)) / θ², finite up to θ = π (series below 0.1).
void left_jacobian_inverse_times(const double phi[3], const double x[3], double out[3]) {
  const double theta = norm3(phi);
  double c;
  if (theta < 0.1) {
    const double t2 = theta * theta;
    c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1209600.0;
  } else {
    const double half = 0.5 * theta;
    c = (1.0 - half / std::tan(half)) / (theta * theta);
  }
  plus_crosses(phi, x, -0.5, c, out);
}

// The rotation vector of a unit quaternion (scalar first), the shorter way round (angle in [0, π]).
void quat_log(const double q[4], double out[3]) {
  const double sign = q[0] < 0.0 ? -1.0 : 1.0;
  const double w = sign * q[0], v[3] = {sign * q[1], sign * q[2], sign * q[3]};
  const double n = norm3(v);
  const double k = n < 1e-12 ? 2.0 / w : 2.0 * std::atan2(n, w) / n;
  for (int i = 0; i < 3; ++i) out[i] = k * v[i];
}

void quat_exp(const double phi[3], double out[4]) {
  const double theta = norm3(phi), half = 0.5 * theta;
  const double k = theta < 1e-8 ? 0.5 : std::sin(half) / theta;
  out[0] = std::cos(half), out[1] = k * phi[0], out[2] = k * phi[1], out[3] = k * phi[2];
}

void rotate(const double q[4], const double v[3], double out[3]) {
  Mat3 R;
  quat_to_R(q[1], q[2], q[3], q[0], R);
  for (int i = 0; i < 3; ++i) out[i] = R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2];
}

}  // namespace

void advance_timing(const TimingSettings& g, TimingState& st, double dt) {
  const double u = st.command;
  const double s_target = std::min(std::max(u, 0.0), 1.0);
  const double w_target = s_target < 1.0 ? 0.0 : std::min(std::max(u - 1.0, 0.0), 1.0);
  const bool inserting = st.w != 0.0 || st.w_dot != 0.0;
  const bool arrived = st.s == 1.0 && st.s_dot == 0.0;
  if (inserting || (arrived && w_target > 0.0))
    profile_step(w_target, g.insert_speed, g.insert_accel, dt, st.w, st.w_dot);
  else
    profile_step(s_target, g.approach_speed, g.approach_accel, dt, st.s, st.s_dot);
}

void timed_desired(const TimingSettings& g, const TimingState& st, const double p0[3], const double q0[4],
                   const double p_h[3], const double q_h[4], const double V_h[6], double p_d[3], double q_d[4],
                   double V_d[6]) {
  const double z[3] = {0.0, 0.0, 1.0};
  double axis[3], spin[3];
  rotate(q_h, z, axis);  // the approach axis
  const double* omega = V_h + 3;
  cross(omega, axis, spin);
  const double d = g.standoff * (1.0 - st.w), d_dot = -g.standoff * st.w_dot;
  double p_g[3], v_g[3];  // the pre-grasp frame's position and velocity
  for (int i = 0; i < 3; ++i) p_g[i] = p_h[i] - d * axis[i], v_g[i] = V_h[i] - d_dot * axis[i] - d * spin[i];
  if (st.s == 1.0 && st.s_dot == 0.0) {  // arrived: the pre-grasp frame itself
    for (int i = 0; i < 3; ++i) p_d[i] = p_g[i], V_d[i] = v_g[i], V_d[3 + i] = omega[i];
    for (int i = 0; i < 4; ++i) q_d[i] = q_h[i];
    return;
  }
  const double s = st.s, s_dot = st.s_dot;
  for (int i = 0; i < 3; ++i) {
    const double chord = p_g[i] - p0[i];
    p_d[i] = p0[i] + s * chord, V_d[i] = s_dot * chord + s * v_g[i];
  }
  const double q0_conj[4] = {q0[0], -q0[1], -q0[2], -q0[3]};
  double rel[4], b[3], local[3], b_dot[3];
  qmul(q0_conj, q_h, rel);
  quat_log(rel, b);                               // the turn from the start attitude to the frame's
  rotate(q0_conj, omega, local);                  // ω_h in the start frame
  left_jacobian_inverse_times(b, local, b_dot);   // ḃ = J_l(b)⁻¹ R0ᵀ ω_h
  double sb[3], feed[3], turn[4], rate[3];
  for (int i = 0; i < 3; ++i) sb[i] = s * b[i], feed[i] = s_dot * b[i] + s * b_dot[i];
  quat_exp(sb, turn);
  qmul(q0, turn, q_d);
  left_jacobian_times(sb, feed, rate);
  rotate(q0, rate, V_d + 3);
}

}  // namespace ffsr
