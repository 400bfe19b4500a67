// The predefined-time planner with the cumulative danger field (docs/model.md §3-8, §14, §22): its typed
// settings, its scratch, and one step that turns a state into the two arms' joint rates.
#pragma once

#include <vector>

#include "ffsr/physics.hpp"
#include "ffsr/timing.hpp"

namespace ffsr {

inline constexpr int kMaxObstacles = 8;

enum class Method { kNoAvoidance = 0, kNoFeedback = 1, kProportional = 2, kPredefinedTime = 3 };

// A target of the desired path: position [m], rotation axis from the path's start attitude, angle [rad].
struct PathTarget {
  double position[3] = {0, 0, 0};
  double axis[3] = {1, 0, 0};
  double angle = 0.0;
};

// An obstacle point: start position [m], drift velocity [m/s], radius [m].
struct Obstacle {
  double position[3];
  double velocity[3];
  double radius;
};

// One step of a tumbling target: the desired end-effector pose (attitude scalar first) and world twist of the
// approach (with a commanded approach, timing.enabled: the grasp frame's pose and twist), then the body's centre
// [m] and rotation (row by row).
struct Frame {
  double p_d[3];
  double sigma_d[4];
  double V_ed[6];
  double centre[3];
  double R[9];
};

struct PlannerSettings {
  Method method = Method::kPredefinedTime;
  bool phi_printed = false;        // the paper's printed φ (else the corrected one)
  bool phi_split = false;          // φ of position and attitude errors apart
  bool body_attitude_error = false;
  bool mu_distance = true;         // μ = min(1, d/d_s)² (else the CDF threshold law)
  bool balance_avoids = false;
  double m = 0.3, T_c = 4.0, K = 1.0;                  // φ's exponent and time [s]; proportional gain [1/s]
  double lambda_mission = 0.0, lambda_balance = 0.0;  // damping of the filtered inverses
  double eps_mission = 0.0, eps_balance = 0.0;
  double xi = 0.0, delta = 0.0, k1 = 0.0, danger_radius = 0.0;  // the danger field
  double motion_time = 10.0, accel_time = 1.0;        // the trapezoidal path [s]
  double estimate_interval = 1.0, dt = 0.01, rate_max_deg_s = 200.0;
  double start_position[3] = {0, 0, 0};
  double start_attitude[4] = {1, 0, 0, 0};  // scalar first
  PathTarget truth;                         // the true target
  std::vector<PathTarget> estimates;        // the planner's estimates, one per estimate interval (at least one)
  double base_position[3] = {0, 0, 0};      // the base's desired pose (attitude scalar first)
  double base_attitude[4] = {1, 0, 0, 0};
  double momentum[6] = {0, 0, 0, 0, 0, 0};  // [P; L about the system CoM], conserved
  std::vector<Obstacle> obstacles;          // at most kMaxObstacles
  double keep_out = 0.0;                    // a clearance below it is a collision [m]
  std::vector<Frame> frames;                // a tumbling target's, one per step from t = 0 (empty: a still target)
  double body_half[3] = {0, 0, 0};          // the tumbling body's half extents [m]
  double body_radius = 0.0;                 // its bounding radius [m]
  double body_danger = 0.0;                 // its danger radius beyond that [m] (0: not in the field)
  bool body_collides = false;               // the body is checked for collision
  bool rate_limit_balance_only = false;     // the rate limit scores the balance arm only
  int substeps = 0;                         // the servo plant's physics steps per planner step (0: kinematic plant)
  TimingSettings timing;                    // a commanded approach onto the frames (disabled: the frames' own path)
};

// What a planner step writes besides the frames and momentum matrices.
struct Plan {
  double dq[kJoints];  // joint rates, mission arm first [rad/s]
  double e1[6];        // end-effector pose error to the desired pose
  double e0[6];        // base pose error
  double e1t[6];       // end-effector pose error to the true target's desired pose (true_error)
  double mu[2], cdf[2], smin[2];
  double V0[6], x1[6], target[6], p_d[3], sigma_d[4], V_ed[6];
  double J[6][6], Jb[6][6], Jo[3][3], Jo_d[3][3];
  double dq_c[6];
  double points[7][3];
  double seg[6 * kMaxObstacles + 6][5];  // the danger field's view of each arm segment
  TimingState timing;  // the commanded approach's state (read by the step, advanced by the loop after it)
};

// Joint rates and diagnostics at (t, x) (docs/model.md §8 steps 1-8); fills f and m at x.
void plan(const Robot& robot, const PlannerSettings& s, const double x[kStateSize], double t, Frames& f, Momentum& m,
          Plan& p);

// The end-effector pose error to the true target's desired pose into p.e1t (after plan at the same state).
void true_error(const PlannerSettings& s, const Frames& f, double t, Plan& p);

// Scalar-first unit quaternion (w ≥ 0) of a rotation matrix (Shepperd's method).
void R_to_quat_wxyz(const Mat3& R, double q[4]);

}  // namespace ffsr
