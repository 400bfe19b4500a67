// What a score needs of a trajectory, summed sample by sample as the episode runs (docs/kernel.md, "Memory"): a
// decision's smoothness terms, peak rate and violation depth, and an episode's totals. Each sum runs over the
// samples in their order, so it gives the bits of the same sum over a recorded trajectory.
#pragma once

#include <limits>

#include "ffsr/robot.hpp"

namespace ffsr {

// One decision's terms: rate energy Σ‖Θ̇‖² and variation Σ‖Θ̇_k − Θ̇_{k−1}‖ of each arm (mission, balance), from
// the rates applied before it; the largest |Θ̇| [rad/s]; the deepest violation [m] (keep-out minus clearance, or
// minus the self clearance).
struct DecisionTerms {
  double square[2] = {0.0, 0.0};
  double variation[2] = {0.0, 0.0};
  double previous[kJoints] = {};
  double peak = 0.0;
  double depth = 0.0;
};

// An episode's totals. Settings: the paper objective's danger rate [deg/s] (its Ψ) and the end-effector position
// tolerance [m] (the convergence time). Sums: as DecisionTerms over every applied step, plus Σ Ψ(‖Θ̇‖ in deg/s)
// and the largest |Θ̇| of each arm; over every sample: the smallest clearances, the last errors, the last sample
// whose end-effector position error was at or above the tolerance (−1: none).
struct ScoreTotals {
  double danger_deg_s = 0.0;
  double tolerance_m = 0.0;
  long samples = 0;
  long applied = 0;
  double square[2] = {0.0, 0.0};
  double variation[2] = {0.0, 0.0};
  double psi[2] = {0.0, 0.0};
  double peak[2] = {0.0, 0.0};
  double previous[kJoints] = {};
  double min_clear = std::numeric_limits<double>::infinity();
  double min_self = std::numeric_limits<double>::infinity();
  double last_err[4] = {0.0, 0.0, 0.0, 0.0};
  long last_above = -1;
};

// One step's sums over an arm's joints (6 arm .. 6 arm + 5, in order): Σ Θ̇² into square and Σ (Θ̇ − Θ̇_before)²
// into step; every smoothness sum of the kernel is made of these.
void arm_sums(const double rates[kJoints], const double before[kJoints], int arm, double& square, double& step);

// Rates applied over one step (12, mission arm first) into a decision's terms.
void add_step(DecisionTerms& d, const double rates[kJoints], double clear, double self_c, double keep_out);

// Rates applied over one step into an episode's totals.
void add_applied(ScoreTotals& t, const double rates[kJoints]);

// One sample (every row of a trajectory, the final one too): errors (EE position, EE attitude, base position,
// base attitude) and clearances [m].
void add_sample(ScoreTotals& t, const double err[4], double clear, double self_c);

}  // namespace ffsr
