// The closed loop (loop.hpp).
#include "ffsr/loop.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "field.hpp"

namespace ffsr {

double nearest_clearance(const Robot& robot, const PlannerSettings& s, const Frames& f, const CapsuleAxes& axes,
                         const double x[kStateSize], double t, double rel[3]) {
  double clear = std::numeric_limits<double>::infinity();
  double r[3] = {0.0, 0.0, 0.0}, p_o[3], here[3];
  for (size_t o = 0; o < s.obstacles.size(); ++o) {
    obstacle_at(s.obstacles[o], t, p_o);
    const double value = obstacle_clearance(robot, f, axes, x, p_o, s.obstacles[o].radius, here);
    if (value < clear || o == 0) clear = value, r[0] = here[0], r[1] = here[1], r[2] = here[2];
  }
  rel[0] = r[0], rel[1] = r[1], rel[2] = r[2];
  if (s.body_collides) {
    const Frame& frame = frame_at(s, t);
    const double(&R)[3][3] = *reinterpret_cast<const double(*)[3][3]>(frame.R);
    clear = std::min(clear, body_clearance(robot, f, axes, x, R, frame.centre, s.body_half));
  }
  return clear;
}

void clearances(const Robot& robot, const PlannerSettings& s, const Frames& f, const double x[kStateSize], double t,
                CapsuleAxes& axes, double& clear, double& self_c, double rel[3]) {
  capsule_axes(robot, f, x, axes);
  clear = nearest_clearance(robot, s, f, axes, x, t, rel);
  self_c = self_clearance(robot, f, axes, x);
}

namespace {

Status violation(const PlannerSettings& s, const double dq[kJoints], double clear, double self_c) {
  const double to_deg = 180.0 / M_PI;
  for (int j = s.rate_limit_balance_only ? 6 : 0; j < kJoints; ++j)
    if (std::fabs(dq[j]) * to_deg > s.rate_max_deg_s) return Status::kRate;
  if (clear < s.keep_out || self_c < 0.0) return Status::kCollision;
  return Status::kOk;
}

double norm3(const double* e) { return std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]); }

}  // namespace

Status run(const Robot& robot, const Robot& plant, const PlannerSettings& s, LoopState& st, long k0, long n_total,
           long n_max, const double residual[kJoints], bool stop_on_violation, bool record_only, bool planned,
           const LogRows& out, long& rows, DecisionTerms* terms, ScoreTotals* totals, CaptureJudge* judge) {
  const bool mismatch = &plant != &robot;
  const double dt = s.dt;
  double* x = st.x;
  double* dq = st.p.dq;
  rows = 0;
  const long steps = record_only ? 1 : std::min(n_max, n_total - k0);
  for (long i = 0; i < steps; ++i) {
    const double t = static_cast<double>(k0 + i) * dt;
    if (i > 0 || !planned) plan(robot, s, x, t, st.f, st.m, st.p);
    const double* logged = st.p.e1;
    if (s.estimates.size() > 1) {  // the planner followed a target estimate; log the error to the true target
      true_error(s, st.f, t, st.p);
      logged = st.p.e1t;
    }
    for (int j = 0; j < kJoints; ++j) {
      dq[j] += residual[j];
      if (!std::isfinite(dq[j])) return Status::kNonFinite;
    }
    double clear, self_c;
    clearances(robot, s, st.f, x, t, st.axes, clear, self_c, st.rel);
    const long r = i * out.stride;
    double* v = out.v + 18 * r;
    double* applied = out.dq + 12 * r;
    if (s.substeps == 0) {
      if (mismatch) momentum(plant, x, st.f, st.m);  // the planner's momentum matrices were the model's
      base_velocity(x, dq, s.momentum, st.f, st.m, st.v0);
      for (int j = 0; j < 6; ++j) v[j] = st.v0[j];
      for (int j = 0; j < kJoints; ++j) v[6 + j] = dq[j], applied[j] = dq[j], out.tau[12 * r + j] = 0.0;
    } else {
      for (int j = 0; j < 18; ++j) v[j] = st.servo[j];
      for (int j = 0; j < kJoints; ++j) applied[j] = st.servo[6 + j];  // the rate at the sample
    }
    double* start = out.x + 19 * r;
    for (int j = 0; j < kStateSize; ++j) start[j] = x[j];
    double* err = out.err + 4 * r;
    err[0] = norm3(logged), err[1] = norm3(logged + 3), err[2] = norm3(st.p.e0), err[3] = norm3(st.p.e0 + 3);
    out.clear[r] = clear, out.self[r] = self_c;
    for (int arm = 0; arm < 2; ++arm)
      out.mu[2 * r + arm] = st.p.mu[arm], out.cdf[2 * r + arm] = st.p.cdf[arm], out.smin[2 * r + arm] = st.p.smin[arm];
    ++rows;
    if (totals) add_sample(*totals, err, clear, self_c);
    if (judge) {
      const Frame& grasp = frame_at(s, t);
      double q[4];
      capture_quantities(st.f, x, v, st.p.J, grasp.p_d, grasp.sigma_d, grasp.V_ed, q);
      add_capture(*judge, q);
      if (judge->rule.stop && judge->captured_at >= 0 && !record_only) return Status::kCaptured;
    }
    if (record_only) return Status::kOk;
    if (s.substeps == 0) {
      midpoint(plant, x, st.v0, dq, dt, s.momentum, st.f, st.m, x);
    } else {  // the drives follow the planned rates; the step's rates are those the joints made
      servo_period(plant, x, st.servo, dq, dt, s.substeps, s.momentum, st.dyn, st.f, st.m, out.tau + 12 * r);
      for (int j = 0; j < kJoints; ++j) dq[j] = (x[7 + j] - start[7 + j]) / dt, applied[j] = dq[j];
    }
    if (s.timing.enabled) advance_timing(s.timing, st.p.timing, dt);
    if (terms) add_step(*terms, applied, clear, self_c, s.keep_out);
    if (totals) add_applied(*totals, applied);
    if (stop_on_violation) {
      const Status status = violation(s, dq, clear, self_c);
      if (status != Status::kOk) return status;
    }
  }
  return Status::kOk;
}

}  // namespace ffsr
