// Torque-free motion of a tumbling target's body: Euler's equations and the quaternion kinematics, RK4 with the
// quaternion renormalised after each substep.
#pragma once

namespace ffsr {

// Fill out_q (steps + 1, 4, w first) and out_w (steps + 1, 3) [rad/s] with the attitude and body rates at every
// step of dt [s] from (quaternion, omega), substeps RK4 steps per step. inertia: the principal moments [kg m²].
void propagate_tumbling(const double quaternion[4], const double omega[3], const double inertia[3], double dt,
                        int substeps, long steps, double* out_q, double* out_w);

}  // namespace ffsr
