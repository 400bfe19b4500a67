// Bindings of the kernel's parts one at a time: what the tests compare with independent references (Pinocchio,
// coal, closed forms) and what the studies drive alone (the servo plant without a planner).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstring>
#include <memory>

#include "bindings.hpp"
#include "ffsr/collision.hpp"
#include "ffsr/dynamics.hpp"
#include "ffsr/physics.hpp"
#include "ffsr/planner.hpp"
#include "field.hpp"

using namespace nb::literals;
using namespace ffsr_bindings;

namespace {

nb::dict kinematics_from(const ffsr::Robot& robot, In kept, In x, In dq, double h) {
  auto f = std::make_unique<ffsr::Frames>();
  ffsr::kinematics(robot, data_of(kept, "kept", {19}), *f);  // keeps the cosines and sines of `kept`
  ffsr::kinematics(robot, state_of(x), *f, data_of(dq, "dq", {12}), h);
  nb::dict out;
  out["Rj"] = copy_out(&f->Rj[0][0][0], {12, 3, 3});
  out["pj"] = copy_out(&f->pj[0][0], {12, 3});
  out["Re"] = copy_out(&f->Re[0][0][0], {2, 3, 3});
  out["pe"] = copy_out(&f->pe[0][0], {2, 3});
  out["z"] = copy_out(&f->z[0][0], {12, 3});
  return out;
}

nb::tuple segment_field(In p, In a, In b) {
  double F, nearest, I0, I1;
  ffsr::segment_field(data_of(p, "p", {3}), data_of(a, "a", {3}), data_of(b, "b", {3}), F, nearest, I0, I1);
  return nb::make_tuple(F, nearest, I0, I1);
}

double box_box(In R_a, In c_a, In half_a, In R_b, In c_b, In half_b) {
  ffsr::Mat3 Ra, Rb;
  std::memcpy(Ra, data_of(R_a, "R_a", {3, 3}), sizeof Ra);
  std::memcpy(Rb, data_of(R_b, "R_b", {3, 3}), sizeof Rb);
  return ffsr::box_box(Ra, data_of(c_a, "c_a", {3}), data_of(half_a, "half_a", {3}), Rb, data_of(c_b, "c_b", {3}),
                       data_of(half_b, "half_b", {3}));
}

nb::tuple drive_open_loop(const ffsr::Robot& plant, In x, In cmds, double h, In momentum, long every) {
  if (!(h > 0.0)) throw nb::value_error("h: allowed > 0 s");
  if (every < 0) throw nb::value_error("every: allowed >= 0 (0: never)");
  const size_t n = cmds.ndim() == 2 ? cmds.shape(0) : 0;
  check_shape(cmds, "cmds", {n, 12});
  const double* start = data_of(x, "x", {40});
  double state[ffsr::kStateSize], servo[ffsr::kServoState];
  std::memcpy(state, start, sizeof state);
  std::memcpy(servo, start + ffsr::kStateSize, sizeof servo);
  double *states, *torques;
  Out out_states = zeros({n + 1, 40}, states), out_torques = zeros({n, 12}, torques);
  {
    nb::gil_scoped_release release;
    ffsr::drive_open_loop(plant, state, servo, cmds.data(), static_cast<long>(n), h, data_of(momentum, "momentum", {6}),
                          every, states, torques);
  }
  return nb::make_tuple(out_states, out_torques);
}

}  // namespace

void bind_parts(nb::module_& m) {
  m.attr("MAX_OBSTACLES") = ffsr::kMaxObstacles;
  m.def("kinematics_from", &kinematics_from, "robot"_a, "kept"_a, "x"_a, "dq"_a, "h"_a,
        "Forward kinematics of x from the cosines and sines kept at the state `kept` (x = kept advanced by dq h: "
        "the angle-sum formula; else computed afresh): Rj, pj, Re, pe, z.");
  m.def("segment_field", &segment_field, "p"_a, "a"_a, "b"_a,
        "The danger field's closed forms of segment a-b seen from p: (F, nearest, I0, I1).");
  m.def("box_box", &box_box, "R_a"_a, "c_a"_a, "half_a"_a, "R_b"_a, "c_b"_a, "half_b"_a,
        "Distance of two boxes [m] (exact when apart; <= 0 when they overlap).");
  m.def("drive_open_loop", &drive_open_loop, "plant"_a, "x"_a, "cmds"_a, "h"_a, "momentum"_a, "every"_a = 0,
        "The servo plant under commands cmds (n, 12) [rad/s], one row per physics step of h [s], no planner: "
        "(states (n + 1, 40), torques (n, 12)). every > 0: the base twist carries `momentum` again after every "
        "`every` steps.");
}
