// Collision distances in closed form: capsules against an obstacle sphere, a box (a tumbling target's body),
// each other and the base box.
#pragma once

#include <vector>

#include "ffsr/robot.hpp"

namespace ffsr {

// The capsules' axes in the world frame, at the state whose frames f holds.
struct CapsuleAxes {
  std::vector<double> A, B;  // (n, 3) end points, row by row
  // the self-clearance pair search's scratch (sized once, at the first call)
  std::vector<double> mid, half_length, bound;
  std::vector<int> first, second;
};

void capsule_axes(const Robot& robot, const Frames& f, const double p_b[3], CapsuleAxes& axes);

// Signed distance of a point to a box (rotation R, centre c, half extents) [m], negative inside.
double box_sdf(const double p[3], const Mat3& R, const double c[3], const double half[3]);

// Signed distance segment a-b to a box [m], exact (the convex SDF minimised piece by piece).
double segment_box(const double a[3], const double b[3], const Mat3& R, const double c[3], const double half[3]);

// Distance of two boxes (rotation, centre, half extents) [m] when apart, by their edges: exact then (the
// closest points of two disjoint boxes lie on an edge of one of them); overlapping boxes give a value <= 0.
double box_box(const Mat3& R_a, const double c_a[3], const double half_a[3], const Mat3& R_b, const double c_b[3],
               const double half_b[3]);

// Signed distance robot-obstacle sphere [m]; rel gets the vector robot point → obstacle point.
double obstacle_clearance(const Robot& robot, const Frames& f, const CapsuleAxes& axes, const double p_b[3],
                          const double p_o[3], double r_o, double rel[3]);

// Signed distance robot-box (rotation R_o, centre c_o, half extents half_o) [m].
double body_clearance(const Robot& robot, const Frames& f, const CapsuleAxes& axes, const double p_b[3],
                      const Mat3& R_o, const double c_o[3], const double half_o[3]);

// Smallest signed distance arm-arm and arm-base (mounting links excluded) [m].
double self_clearance(const Robot& robot, const Frames& f, CapsuleAxes& axes, const double p_b[3]);

}  // namespace ffsr
