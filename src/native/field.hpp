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

// One segment a-b seen from p: the integral F of 1/ρ along it, the nearest distance, and the integrals I0, I1 of
// 1/ρ³ and s/ρ³ (a zero-length segment: F = 0, nearest = inf, I0 = I1 = 0).
void segment_field(const double p[3], const double a[3], const double b[3], double& F, double& nearest, double& I0,
                   double& I1);

}  // namespace ffsr
