// One decision of an environment step (decision.hpp).
#include "ffsr/decision.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "field.hpp"

namespace ffsr {
namespace {

constexpr double kObsRate = 20.0, kObsError = 10.0, kObsRelative = 10.0, kObsClearance = 10.0, kObsTwist = 10.0;

double clip(double value, double bound) { return std::min(std::max(value, -bound), bound); }

// The clearance the observation shows (robot-obstacle, or the tumbling body; inf without either) after a plan at
// (t, x); rel: the vector to the nearest obstacle.
double observe(const Robot& robot, const PlannerSettings& s, LoopState& st, double t, double rel[3]) {
  plan(robot, s, st.x, t, st.f, st.m, st.p);
  if (!s.obstacles.empty() || s.body_collides) capsule_axes(robot, st.f, st.x, st.axes);
  return nearest_clearance(robot, s, st.f, st.axes, st.x, t, rel);
}

// The grasp frame as the end-effector sees it, into 17 floats: its position minus the end-effector's (world) [m],
// the vector 2 sign(η) ε of σ_e* ⊗ σ_h (the rotation from the end-effector to the grasp frame, in the end-effector's
// frame; its angle for small ones) [rad], its world twist [m/s, rad/s], and the approach's state (u, s, ṡ, w, ẇ).
void grasp_observation(const PlannerSettings& s, const LoopState& st, double t, float* out) {
  const Frame& h = frame_at(s, t);
  const double* pe = st.f.pe[0];
  double q_e[4];
  R_to_quat_wxyz(st.f.Re[0], q_e);
  const double* q_h = h.sigma_d;
  const double eta = q_e[0] * q_h[0] + q_e[1] * q_h[1] + q_e[2] * q_h[2] + q_e[3] * q_h[3];
  const double sign = eta < 0.0 ? -2.0 : 2.0;
  const double eps[3] = {q_e[0] * q_h[1] - q_h[0] * q_e[1] - q_e[2] * q_h[3] + q_e[3] * q_h[2],
                         q_e[0] * q_h[2] - q_h[0] * q_e[2] - q_e[3] * q_h[1] + q_e[1] * q_h[3],
                         q_e[0] * q_h[3] - q_h[0] * q_e[3] - q_e[1] * q_h[2] + q_e[2] * q_h[1]};
  for (int a = 0; a < 3; ++a) {
    out[a] = static_cast<float>(clip(h.p_d[a] - pe[a], kObsRelative));
    out[3 + a] = static_cast<float>(clip(sign * eps[a], kObsError));
  }
  for (int j = 0; j < 6; ++j) out[6 + j] = static_cast<float>(clip(h.V_ed[j], kObsTwist));
  const TimingState& g = st.p.timing;
  const double timing[5] = {g.command, g.s, g.s_dot, g.w, g.w_dot};
  for (int j = 0; j < 5; ++j) out[12 + j] = static_cast<float>(clip(timing[j], kObsRate));
}

}  // namespace

double residual_fade(double t, double motion_s, double fade_s) {
  const double start = motion_s - fade_s;
  if (t <= start) return 1.0;
  if (t >= motion_s) return 0.0;
  return 0.5 * (1.0 + std::cos(M_PI * (t - start) / fade_s));
}

void smoothness_terms(const double* rates, long rows, double dt, const double previous[kJoints], double out[4]) {
  for (int arm = 0; arm < 2; ++arm) {
    double energy = 0.0, variation = 0.0;
    for (long k = 0; k < rows; ++k) {
      double square, step;
      arm_sums(rates + 12 * k, k == 0 ? previous : rates + 12 * (k - 1), arm, square, step);
      energy += square;
      variation += std::sqrt(step);
    }
    out[arm] = energy * dt, out[2 + arm] = variation;
  }
}

double smoothness_cost(const double terms[4], const DecisionSettings& d) {
  const double mission = terms[0] / d.E_ref + terms[2] / d.V_ref;
  const double balance = terms[1] / d.E_ref + terms[3] / d.V_ref;
  return d.alpha * mission + d.beta * balance;
}

void observation(const Robot& robot, const PlannerSettings& s, EpisodeState& e, long k, long n_total, float* obs,
                 int n_obs, double& clearance, double& ee_error) {
  double rel[3] = {0.0, 0.0, 0.0};
  clearance = observe(robot, s, e.loop, static_cast<double>(k) * s.dt, rel);
  e.planned = true, e.planned_k = k, e.planned_m = s.m, e.planned_T_c = s.T_c;
  const Plan& p = e.loop.p;
  if (n_obs > kObservation)
    for (int j = 0; j < 6; ++j) obs[kObservation + j] = static_cast<float>(clip(p.V_ed[j], kObsTwist));
  if (n_obs == kObservationCapture) grasp_observation(s, e.loop, static_cast<double>(k) * s.dt, obs + kObservationTwist);
  for (int j = 0; j < kJoints; ++j) {
    obs[j] = static_cast<float>(std::sin(e.loop.x[7 + j]));
    obs[12 + j] = static_cast<float>(std::cos(e.loop.x[7 + j]));
    obs[24 + j] = static_cast<float>(clip(e.last_rates[j], kObsRate));
  }
  for (int j = 0; j < 6; ++j) {
    obs[36 + j] = static_cast<float>(clip(p.e1[j], kObsError));
    obs[42 + j] = static_cast<float>(clip(p.e0[j], kObsError));
  }
  for (int j = 0; j < 3; ++j) obs[48 + j] = static_cast<float>(clip(rel[j], kObsRelative));
  obs[51] = static_cast<float>(clip(clearance, kObsClearance));
  obs[52] = static_cast<float>(std::min(1.0, static_cast<double>(k) / static_cast<double>(n_total)));
  ee_error = std::sqrt(p.e1[0] * p.e1[0] + p.e1[1] * p.e1[1] + p.e1[2] * p.e1[2]);
}

DecisionResult decide(const Robot& robot, const Robot& plant, PlannerSettings& s, const DecisionSettings& d,
                      EpisodeState& e, long k, long n_total, long n_max, const double* action, int n_action,
                      ActionMode mode, bool stop, const LogRows& logs, float* obs, int n_obs) {
  DecisionResult result;
  for (int j = 0; j < n_action; ++j) {
    if (!std::isfinite(action[j])) {
      result.status = 4;
      return result;
    }
  }
  const double dt = s.dt;
  double residual[kJoints] = {};
  const int last = d.command_action && mode != ActionMode::kSet ? n_action - 1 : -1;  // the command's entry
  for (int j = 0; j < n_action; ++j) {  // clip, map
    const double raw = action[j];
    const double value = std::min(std::max(raw, -1.0), 1.0);
    result.clipped = result.clipped || value != raw;
    if (j == last)
      e.loop.p.timing.command = value + 1.0;
    else if (mode == ActionMode::kResidual)
      residual[j] = value;
    else if (mode == ActionMode::kParameters && j == 0)
      s.m = d.m_lo + 0.5 * (value + 1.0) * (d.m_hi - d.m_lo);
    else if (mode == ActionMode::kParameters && j == 1)
      s.T_c = d.T_lo + 0.5 * (value + 1.0) * (d.T_hi - d.T_lo);
  }
  if (mode == ActionMode::kResidual) {
    const double fade = residual_fade(static_cast<double>(k) * dt, d.motion_s, d.fade_s);
    for (int j = 0; j < kJoints; ++j) residual[j] = fade * (d.rate_scale * residual[j]);
  } else {
    for (double& r : residual) r = 0.0;
  }
  const bool planned = e.planned && e.planned_k == k && e.planned_m == s.m && e.planned_T_c == s.T_c;
  e.planned = false;
  long rows = 0;
  DecisionTerms terms;
  std::copy(e.last_rates, e.last_rates + kJoints, terms.previous);
  CaptureJudge* judge = e.capture.rule.needed > 0 ? &e.capture : nullptr;
  const Status status = run(robot, plant, s, e.loop, k, n_total, n_max, residual, stop, false, planned, logs, rows,
                            &terms, &e.totals, judge);
  result.rows = rows, result.status = static_cast<int>(status);
  if (rows == 0 || status == Status::kNonFinite) return result;
  const double sums[4] = {terms.square[0] * dt, terms.square[1] * dt, terms.variation[0], terms.variation[1]};
  result.increment = smoothness_cost(sums, d);
  const double excess = std::max(0.0, terms.peak * (180.0 / M_PI) / d.rate_limit_deg_s - 1.0);
  result.cost = terms.depth / d.clear_scale + excess;
  std::copy(terms.previous, terms.previous + kJoints, e.last_rates);
  observation(robot, s, e, k + rows, n_total, obs, n_obs, result.clearance, result.ee_error);
  return result;
}

void finish(const Robot& robot, const Robot& plant, const PlannerSettings& s, EpisodeState& e, long k, long n_total,
            const LogRows& logs) {
  const double none[kJoints] = {};
  long rows = 0;
  e.planned = false;
  run(robot, plant, s, e.loop, k, n_total, 1, none, false, true, false, logs, rows, nullptr, &e.totals,
      e.capture.rule.needed > 0 ? &e.capture : nullptr);
}

}  // namespace ffsr
