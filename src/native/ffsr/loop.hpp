// The closed loop's checks: clearances at a state and the status of a step.
#pragma once

#include "ffsr/collision.hpp"
#include "ffsr/planner.hpp"

namespace ffsr {

enum class Status { kOk = 0, kRate = 1, kCollision = 2, kNonFinite = 3 };

// Robot-obstacle clearance at t (inf without an obstacle; a tumbling target's body is one) and the self clearance
// [m] at the state whose frames f holds; rel points from the robot to the nearest obstacle (ties keep the first).
void clearances(const Robot& robot, const PlannerSettings& s, const Frames& f, const double x[kStateSize], double t,
                CapsuleAxes& axes, double& clear, double& self_c, double rel[3]);

}  // namespace ffsr
