// The danger field of an arm and the settings' time-dependent records (field.cpp).
#pragma once

#include "ffsr/planner.hpp"

namespace ffsr {

// Position of an obstacle at t [s]: p + v t.
void obstacle_at(const Obstacle& o, double t, double out[3]);

// The frame record of the step t [s] falls on (a tumbling target's).
const Frame& frame_at(const PlannerSettings& s, double t);

// μ and the CDF of one arm at t; Θ̇_c (6) into p.dq_c (zero when μ = 1). Needs p.points' scratch.
void avoidance(const PlannerSettings& s, const Frames& f, int arm, double t, Plan& p, double& mu, double& cdf);

}  // namespace ffsr
