// The closed loop (loop.hpp).
#include "ffsr/loop.hpp"

#include <algorithm>
#include <limits>

#include "field.hpp"

namespace ffsr {

void clearances(const Robot& robot, const PlannerSettings& s, const Frames& f, const double x[kStateSize], double t,
                CapsuleAxes& axes, double& clear, double& self_c, double rel[3]) {
  capsule_axes(robot, f, x, axes);
  clear = std::numeric_limits<double>::infinity();
  double r[3] = {0.0, 0.0, 0.0}, p_o[3], here[3];
  for (size_t o = 0; o < s.obstacles.size(); ++o) {
    obstacle_at(s.obstacles[o], t, p_o);
    const double value = obstacle_clearance(robot, f, axes, x, p_o, s.obstacles[o].radius, here);
    if (value < clear || o == 0) clear = value, r[0] = here[0], r[1] = here[1], r[2] = here[2];
  }
  rel[0] = r[0], rel[1] = r[1], rel[2] = r[2];
  if (s.body_collides) {
    const Frame& frame = frame_at(s, t);
    const double(&R)[3][3] = *reinterpret_cast<const double(*)[3][3]>(frame.R);
    clear = std::min(clear, body_clearance(robot, f, axes, x, R, frame.centre, s.body_half));
  }
  self_c = self_clearance(robot, f, axes, x);
}

}  // namespace ffsr
