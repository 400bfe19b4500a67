// Physics of the free-floating dual-arm robot: kinematics, momentum, the momentum-conserving base
// velocity and the SE(3) integrator (docs/model.md §2, §12).
#pragma once

#include "ffsr/robot.hpp"

namespace ffsr {

// Rotation by the angle of cosine c and sine s about the unit axis.
void rot_about(const double axis[3], double c, double s, Mat3& out);

// Rotation matrix of the unit quaternion (x, y, z, w).
void quat_to_R(double qx, double qy, double qz, double qw, Mat3& R);

// Forward kinematics of x into f. With h = 0 the joints' cosines and sines are kept in f.cs; with
// h != 0, x is the state the kept one advances by dq h, and the kept values are rotated on by the
// angle-sum formula (a short series for a small increment) unless they belong to another state.
void kinematics(const Robot& robot, const double x[kStateSize], Frames& f, const double* dq = nullptr,
                double h = 0.0);

// H_b, H_bm about the base CoM and the system CoM at x (after kinematics of x), by one pass over
// composite bodies from the tips to the base.
void momentum(const Robot& robot, const double x[kStateSize], const Frames& f, Momentum& m);

// Base velocity (base frame, linear then angular) that conserves h = [P; L about the system CoM]
// with joint rates dq, by the Schur complement of H_b.
void base_velocity(const double x[kStateSize], const double dq[kJoints], const double h[6], const Frames& f,
                   const Momentum& m, double out[6]);

// out = x ⊕ (v dt): base by the SE(3) exponential of the base-frame twist, joints additively. out may be x.
void integrate(const double x[kStateSize], const double v[6], const double dq[kJoints], double dt,
               double out[kStateSize]);

// Explicit midpoint on SE(3) with the momentum re-solved at the half step; v0 is the base velocity
// at x. Leaves f and m at the half step. out may be x.
void midpoint(const Robot& robot, const double x[kStateSize], const double v0[6], const double dq[kJoints],
              double dt, const double h[6], Frames& f, Momentum& m, double out[kStateSize]);

}  // namespace ffsr
