// Free-floating multibody dynamics in body frames (Featherstone's articulated-body algorithm), and the servo
// plant it drives: velocity servos with torque limits, semi-implicit Euler with the drives' damping implicit.
#pragma once

#include "ffsr/physics.hpp"

namespace ffsr {

inline constexpr int kServoState = 21;  // base twist and joint rates (18), steps, saturated steps, peak |τ|/τ_max

// Scratch of one dynamics call.
struct Dynamics {
  double X[kJoints][6][6];   // parent-to-link motion transforms
  double I[kBodies][6][6];   // spatial inertias
  double vel[kBodies][6], bias[kBodies][6], acc[kBodies][6];
  double IA[kBodies][6][6], pA[kBodies][6];
  double U[kJoints][6], D[kJoints], u[kJoints];
};

// The spatial inertias of robot's bodies into dyn (once per robot).
void spatial_inertias(const Robot& robot, Dynamics& dyn);

// Accelerations (18: base in the base frame, then joints) of the free-floating robot under joint torques tau with
// armature added to each joint's inertia; q: joint angles (12), v: base twist and joint rates (18).
void aba(const Robot& robot, const double q[kJoints], const double v[18], const double tau[kJoints],
         const double armature[kJoints], Dynamics& dyn, double out[18]);

// One planner step dt of the servo plant under rate commands cmd: substeps physics steps, then the base twist set
// to the one carrying momentum h at the joint rates. x (19) and servo (21) advance; tau_log gets each joint's
// torque of largest magnitude; f and m are left at the new state.
void servo_period(const Robot& plant, double x[kStateSize], double servo[kServoState], const double cmd[kJoints],
                  double dt, int substeps, const double h[6], Dynamics& dyn, Frames& f, Momentum& m,
                  double tau_log[kJoints]);

// The servo plant under given commands, without a planner (how the dynamics are studied alone): row k of cmds
// (n, 12) [rad/s] held for physics step k of h [s]; every > 0: the base twist set back to the one carrying
// momentum h_mom after every `every` steps (0: never; the momentum then drifts as Euler lets it). x (19) and
// servo (21) advance; x_out (n + 1, 40) gets the state before each step and after the last, tau_out (n, 12) each
// step's torques.
void drive_open_loop(const Robot& plant, double x[kStateSize], double servo[kServoState], const double* cmds, long n,
                     double h, const double h_mom[6], long every, double* x_out, double* tau_out);

}  // namespace ffsr
