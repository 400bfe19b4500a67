// The closed loop's checks: clearances at a state and the status of a step.
#pragma once

#include "ffsr/capture.hpp"
#include "ffsr/collision.hpp"
#include "ffsr/dynamics.hpp"
#include "ffsr/planner.hpp"
#include "ffsr/totals.hpp"

namespace ffsr {

// kCaptured: a judge whose rule stops at capture saw the capture at the last sample (that sample is the episode's
// final one: its rates are not applied). 4 is a decision's bad action (decision.hpp).
enum class Status { kOk = 0, kRate = 1, kCollision = 2, kNonFinite = 3, kCaptured = 5 };

// Robot-obstacle clearance at t (inf without an obstacle; a tumbling target's body is one), the capsule axes
// already at the state whose frames f holds (not needed without obstacle and body); rel points to the nearest
// obstacle (zeros without one; ties keep the first).
double nearest_clearance(const Robot& robot, const PlannerSettings& s, const Frames& f, const CapsuleAxes& axes,
                         const double x[kStateSize], double t, double rel[3]);

// Robot-obstacle clearance at t (inf without an obstacle; a tumbling target's body is one) and the self clearance
// [m] at the state whose frames f holds; rel points from the robot to the nearest obstacle (ties keep the first).
void clearances(const Robot& robot, const PlannerSettings& s, const Frames& f, const double x[kStateSize], double t,
                CapsuleAxes& axes, double& clear, double& self_c, double rel[3]);

// Where a run writes one row per step (caller-owned, row-major; rows from 0), or every step over row 0 (stride 0: an
// episode that keeps no log).
struct LogRows {
  double* x;      // (n, 19) the state at the step's start
  double* v;      // (n, 18) base velocity (base frame) and joint rates
  double* dq;     // (n, 12) the rates the step applied
  double* err;    // (n, 4) end-effector position and attitude errors, base position and attitude errors
  double* clear;  // (n,) robot-obstacle clearance [m]
  double* self;   // (n,) self clearance [m]
  double* mu;     // (n, 2)
  double* cdf;    // (n, 2)
  double* smin;   // (n, 2)
  double* tau;    // (n, 12) drive torques (zero for the kinematic plant)
  long stride = 1;  // rows advanced per step: 1, or 0
};

// One copy's loop state: its configuration and the scratch a step fills.
struct LoopState {
  double x[kStateSize];
  double servo[kServoState];  // the servo plant's velocities and saturation record (unused by the kinematic plant)
  Dynamics dyn;
  Frames f;
  Momentum m;
  Plan p;
  CapsuleAxes axes;
  double v0[6];
  double rel[3];
};

// Advance up to n_max steps from step k0 of n_total, or only record one row (record_only). The kinematic plant
// applies the planned rates exactly and moves the base by the plant's momentum (plant: the robot the physics
// integrates, the planner's own unless its inertias differ); the servo plant (s.substeps > 0) takes them as its
// drives' commands, and the rates logged and checked are the ones the joints made. residual: added to the planned
// rates (12). planned: st.p already holds plan at (k0 dt, st.x). Writes rows from 0; rows: how many; returns the
// status of the last. terms, totals (either may be null): summed over the steps and samples as they are taken;
// judge (may be null; a commanded approach's settings only, whose frames are the grasp frame's): every sample's
// capture quantities.
Status run(const Robot& robot, const Robot& plant, const PlannerSettings& s, LoopState& st, long k0, long n_total,
           long n_max, const double residual[kJoints], bool stop_on_violation, bool record_only, bool planned,
           const LogRows& out, long& rows, DecisionTerms* terms = nullptr, ScoreTotals* totals = nullptr,
           CaptureJudge* judge = nullptr);

}  // namespace ffsr
