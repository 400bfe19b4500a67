// A commanded approach onto a tumbling target's grasp frame (docs/model.md §23): the method decides when the
// end-effector closes in on the pre-grasp frame and when the tool is inserted, through one command u in [0, 2].
#pragma once

namespace ffsr {

// The approach's settings: the pre-grasp standoff along the grasp frame's approach (z) axis [m], and each stage's
// top speed [1/s] and acceleration [1/s²] (the approach's progress s and the insertion's w both run over [0, 1]).
struct TimingSettings {
  bool enabled = false;
  double standoff = 0.0;
  double approach_speed = 0.0, approach_accel = 0.0;
  double insert_speed = 0.0, insert_accel = 0.0;
};

// The approach's state, carried from step to step: the command u (s goes to min(u, 1); past 1, w goes to u − 1 once
// s has arrived), the approach's progress s and rate ṡ, the insertion's progress w and rate ẇ.
struct TimingState {
  double command = 0.0;
  double s = 0.0, s_dot = 0.0;
  double w = 0.0, w_dot = 0.0;
};

inline constexpr int kTimingState = 5;  // command, s, ṡ, w, ẇ

// One physics step of dt [s]: s and w move towards their targets at most at their stage's speed and acceleration
// and stop on them; the insertion runs only while s rests at 1, and s moves only while w rests at 0.
void advance_timing(const TimingSettings& g, TimingState& st, double dt);

// The desired end-effector pose and world twist of the approach at state st: the grasp frame (p_h, σ_h, V_h =
// [v_h; ω_h], from a tumbling target's frame record) moved back along its z axis by the standoff d = standoff (1 −
// w) gives the pre-grasp frame (p_g, σ_h); the desired pose is s of the way from the start pose (p0, σ0) to it:
// p_d = p0 + s (p_g − p0), σ_d = σ0 ⊗ exp(s b) with b = log(σ0* ⊗ σ_h), and its twist the derivative of that.
void timed_desired(const TimingSettings& g, const TimingState& st, const double p0[3], const double q0[4],
                   const double p_h[3], const double q_h[4], const double V_h[6], double p_d[3], double q_d[4],
                   double V_d[6]);

}  // namespace ffsr
