// One decision of an environment step: the action checked and mapped, the physics steps, the step's
// smoothness-cost increment and violation cost, and the next observation.
#pragma once

#include "ffsr/loop.hpp"

namespace ffsr {

inline constexpr int kObservation = 53;         // sin, cos, rates, EE error, base error, relative, clearance, time
inline constexpr int kObservationTwist = 59;    // and the desired end-effector twist (a capture spec's)
inline constexpr int kObservationCapture = 76;  // and the grasp frame's relative pose, its twist, the approach state

enum class ActionMode { kResidual = 0, kParameters = 1, kSet = 2 };

// A decision's settings: the residual's scale [rad/s per unit] and fade [s] before the desired motion's end [s],
// the (m, T_c [s]) action box, the rate limit [deg/s] and the violation cost's clearance scale [m], and the
// smoothness cost's α, β, E_ref [rad²/s], V_ref [rad/s]; the paper objective's danger rate [deg/s] and the
// end-effector position tolerance [m] of the episode's totals.
struct DecisionSettings {
  double rate_scale = 0.0, fade_s = 2.0, motion_s = 10.0;
  double m_lo = 0.05, m_hi = 0.6, T_lo = 1.0, T_hi = 10.0;
  double rate_limit_deg_s = 200.0, clear_scale = 0.01;
  double alpha = 0.35, beta = 0.65, E_ref = 1.0, V_ref = 10.0;
  double danger_rate_deg_s = 0.0, tolerance_m = 0.0;  // the episode totals' settings (ScoreTotals)
  bool command_action = false;  // the action's last entry a in [-1, 1] commands the approach: u = a + 1 (§23)
};

// One episode's state between decisions: the loop state, the rates applied last, and which planner step the
// last observation computed (reused by the next decision's first physics step when state and (m, T_c) agree).
struct EpisodeState {
  LoopState loop;
  ScoreTotals totals;  // the episode's score terms so far
  CaptureJudge capture;  // a commanded approach's capture judge (capture.rule.needed = 0: none)
  double last_rates[kJoints] = {};
  bool planned = false;
  long planned_k = 0;
  double planned_m = 0.0, planned_T_c = 0.0;
};

struct DecisionResult {
  long rows = 0;
  int status = 0;  // Status, or 4: a NaN or infinite action (nothing done)
  bool clipped = false;
  double increment = 0.0, cost = 0.0, clearance = 0.0, ee_error = 0.0;
};

// The residual's weight f(t): 1, a half-cosine over the last fade_s of the motion, then 0.
double residual_fade(double t, double motion_s, double fade_s);

// Rate energy and variation of each arm over rows of rates (12 per row, held dt each), from previous:
// out = (E_mission, E_balance, V_mission, V_balance).
void smoothness_terms(const double* rates, long rows, double dt, const double previous[kJoints], double out[4]);

// C = α (E₁/E_ref + V₁/V_ref) + β (E₂/E_ref + V₂/V_ref).
double smoothness_cost(const double terms[4], const DecisionSettings& d);

// The observation at step k of n_total into obs (n_obs floats: kObservation, kObservationTwist or
// kObservationCapture, which needs a commanded approach), with the robot-obstacle clearance [m] and the
// end-effector position error [m] it shows; the plan it computed serves the next decision from step k.
void observation(const Robot& robot, const PlannerSettings& s, EpisodeState& e, long k, long n_total, float* obs,
                 int n_obs, double& clearance, double& ee_error);

// One decision from step k (logs written from their row 0, that is the episode's row k, or all over row 0 with
// stride 0); the episode's totals advance with it. Mode kParameters sets
// s.m and s.T_c from the action, kResidual adds the faded residual rates, kSet ignores the action; with
// d.command_action (modes kParameters and kResidual) the action's last entry sets the approach's command. obs:
// n_obs floats (observation).
DecisionResult decide(const Robot& robot, const Robot& plant, PlannerSettings& s, const DecisionSettings& d,
                      EpisodeState& e, long k, long n_total, long n_max, const double* action, int n_action,
                      ActionMode mode, bool stop, const LogRows& logs, float* obs, int n_obs);

// The episode's final sample at step k (its rates are not applied): one row into logs and the totals.
void finish(const Robot& robot, const Robot& plant, const PlannerSettings& s, EpisodeState& e, long k, long n_total,
            const LogRows& logs);

}  // namespace ffsr
