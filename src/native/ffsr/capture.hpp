// The capture rule judged sample by sample as an episode runs (docs/model.md §23): the mission end-effector's pose
// and twist against a tumbling target's grasp frame, held within bounds over a window of consecutive samples.
#pragma once

#include <deque>
#include <limits>
#include <utility>

#include "ffsr/physics.hpp"

namespace ffsr {

// The rule: a bound on each quantity (position [m], attitude [rad], linear velocity [m/s], angular velocity
// [rad/s]) and the samples of a hold window (round(hold / dt) + 1); needed = 0: no judge. contact [m]: the
// distance at which the tool meets the handle (its first sample within it records the relative speed there; 0:
// none); stop: an episode ends at its capture (capture v1).
struct CaptureRule {
  double bound[4] = {0.0, 0.0, 0.0, 0.0};
  long needed = 0;
  double contact = 0.0;
  bool stop = false;
};

// What the samples so far say: the first hold window inside every bound (its last sample, −1 while none, and each
// quantity's largest value / bound over it), the smallest largest-ratio of any window of `needed` samples so far
// (the factor every bound could be scaled by and a window still be inside), and the last sample's quantities.
struct CaptureJudge {
  CaptureRule rule;
  long samples = 0;
  long run = 0;  // consecutive samples inside every bound, up to the last one
  double run_worst[4] = {0.0, 0.0, 0.0, 0.0};
  long captured_at = -1;
  double worst[4] = {0.0, 0.0, 0.0, 0.0};
  double margin = std::numeric_limits<double>::infinity();
  double last[4] = {0.0, 0.0, 0.0, 0.0};
  long contact_at = -1;  // the first sample within the contact distance (-1: none yet)
  double contact_speed = std::numeric_limits<double>::quiet_NaN();  // the relative linear speed there [m/s]
  std::deque<std::pair<long, double>> window;  // the last `needed` samples' largest ratios, decreasing (sliding max)
};

// The capture quantities at a sample: the end-effector's pose (frames f at the sample's state x) and twist (v: the
// base's twist in the base frame, then the joint rates, mission arm first; J: the mission arm's world Jacobian at
// x, mission_jacobian) against the grasp frame's position p_h, attitude q_h (scalar first) and world twist V_h.
void capture_quantities(const Frames& f, const double x[kStateSize], const double v[18], const Mat6& J,
                        const double p_h[3], const double q_h[4], const double V_h[6], double out[4]);

// The geometric Jacobian of the mission arm's end-effector (world frame, [linear; angular] per joint) at the state
// whose frames f holds.
void mission_jacobian(const Frames& f, Mat6& J);

// One sample's quantities into the judge.
void add_capture(CaptureJudge& j, const double q[4]);

}  // namespace ffsr
