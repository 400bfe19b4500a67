// Score terms summed as an episode runs (totals.hpp). The sums' order is the one of smoothness_terms over rows and
// of numpy's reductions in the paper objective (row by row, joints in order), which is what makes them equal.
#include "ffsr/totals.hpp"

#include <algorithm>
#include <cmath>

namespace ffsr {
namespace {

constexpr double kDegrees = 180.0 / M_PI;  // numpy's degrees(): one product with this constant

}  // namespace

void arm_sums(const double rates[kJoints], const double before[kJoints], int arm, double& square, double& step) {
  square = 0.0, step = 0.0;
  for (int j = 6 * arm; j < 6 * arm + 6; ++j) {
    const double change = rates[j] - before[j];
    square += rates[j] * rates[j];
    step += change * change;
  }
}

void add_step(DecisionTerms& d, const double rates[kJoints], double clear, double self_c, double keep_out) {
  for (int arm = 0; arm < 2; ++arm) {
    double square, step;
    arm_sums(rates, d.previous, arm, square, step);
    d.square[arm] += square;
    d.variation[arm] += std::sqrt(step);
  }
  for (int j = 0; j < kJoints; ++j) d.peak = std::max(d.peak, std::fabs(rates[j])), d.previous[j] = rates[j];
  d.depth = std::max({d.depth, keep_out - clear, -self_c});
}

void add_applied(ScoreTotals& t, const double rates[kJoints]) {
  for (int arm = 0; arm < 2; ++arm) {
    double square, step, degrees = 0.0;
    arm_sums(rates, t.previous, arm, square, step);
    for (int j = 6 * arm; j < 6 * arm + 6; ++j) {
      const double deg = rates[j] * kDegrees;
      degrees += deg * deg;
      t.peak[arm] = std::max(t.peak[arm], std::fabs(rates[j]));
    }
    t.square[arm] += square;
    t.variation[arm] += std::sqrt(step);
    const double norm = std::sqrt(degrees);
    t.psi[arm] += norm > t.danger_deg_s ? norm : 0.0;
  }
  for (int j = 0; j < kJoints; ++j) t.previous[j] = rates[j];
  ++t.applied;
}

void add_sample(ScoreTotals& t, const double err[4], double clear, double self_c) {
  for (int i = 0; i < 4; ++i) t.last_err[i] = err[i];
  t.min_clear = std::min(t.min_clear, clear);
  t.min_self = std::min(t.min_self, self_c);
  if (err[0] >= t.tolerance_m) t.last_above = t.samples;
  ++t.samples;
}

}  // namespace ffsr
