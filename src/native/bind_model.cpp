// Bindings of the typed robot, the planner's settings and the physics routines (module ffsr_gym._native).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bindings.hpp"
#include "field.hpp"
#include "ffsr/collision.hpp"
#include "ffsr/decision.hpp"
#include "ffsr/dynamics.hpp"
#include "ffsr/linalg.hpp"
#include "ffsr/loop.hpp"
#include "ffsr/physics.hpp"
#include "ffsr/planner.hpp"

using namespace nb::literals;
using namespace ffsr_bindings;

namespace {

ffsr::Robot make_robot(InInt parent, In placement_R, In placement_p, In axis, InInt axis_code, In mass, In lever,
                       In inertia, InInt ee_parent, In ee_R, In ee_p, InInt cap_parent, In cap_a, In cap_b,
                       In cap_radius, InInt cap_arm, InInt cap_vs_base, In box_half, std::optional<In> drive) {
  ffsr::Robot r{};
  if (drive) std::memcpy(r.drive, data_of(*drive, "drive", {12, 4}), sizeof r.drive);
  const size_t n_caps = cap_parent.ndim() == 1 ? cap_parent.shape(0) : 0;
  const int64_t* cp = data_of(cap_parent, "cap_parent", {n_caps});
  const double* ca = data_of(cap_a, "cap_a", {n_caps, 3});
  const double* cb = data_of(cap_b, "cap_b", {n_caps, 3});
  const double* cr = data_of(cap_radius, "cap_radius", {n_caps});
  const int64_t* arm = data_of(cap_arm, "cap_arm", {n_caps});
  const int64_t* vs = data_of(cap_vs_base, "cap_vs_base", {n_caps});
  for (size_t i = 0; i < n_caps; ++i) {
    if (cp[i] < -1 || cp[i] >= ffsr::kJoints)
      throw nb::value_error(("cap_parent[" + std::to_string(i) + "] = " + std::to_string(cp[i]) +
                             "; allowed: -1 (the base) to 11").c_str());
    if (arm[i] != 0 && arm[i] != 1)
      throw nb::value_error(("cap_arm[" + std::to_string(i) + "] = " + std::to_string(arm[i]) +
                             "; allowed: 0 (mission) or 1 (balance)").c_str());
    if (!(cr[i] >= 0.0))
      throw nb::value_error(("cap_radius[" + std::to_string(i) + "]: allowed >= 0 m").c_str());
    ffsr::Capsule c{static_cast<int>(cp[i]), {ca[3 * i], ca[3 * i + 1], ca[3 * i + 2]},
                    {cb[3 * i], cb[3 * i + 1], cb[3 * i + 2]}, cr[i], static_cast<int>(arm[i]), vs[i] != 0};
    r.capsules.push_back(c);
  }
  std::memcpy(r.box_half, data_of(box_half, "box_half", {3}), sizeof r.box_half);
  const int64_t* par = data_of(parent, "parent", {12});
  const int64_t* code = data_of(axis_code, "axis_code", {12});
  const int64_t* ee = data_of(ee_parent, "ee_parent", {2});
  for (int k = 0; k < ffsr::kJoints; ++k) {
    if (par[k] < -1 || par[k] >= k || (par[k] >= 0 && par[k] / 6 != k / 6))
      throw nb::value_error(("parent[" + std::to_string(k) + "] = " + std::to_string(par[k]) +
                             "; allowed: -1 (the base) or an earlier joint of the same arm")
                                .c_str());
    if (code[k] < -1 || code[k] > 2)
      throw nb::value_error(("axis_code[" + std::to_string(k) + "] = " + std::to_string(code[k]) +
                             "; allowed: -1, 0, 1 or 2")
                                .c_str());
    r.parent[k] = static_cast<int>(par[k]);
    r.axis_code[k] = static_cast<int>(code[k]);
  }
  for (int a = 0; a < 2; ++a) {
    if (ee[a] < 0 || ee[a] >= ffsr::kJoints)
      throw nb::value_error(("ee_parent[" + std::to_string(a) + "] = " + std::to_string(ee[a]) +
                             "; allowed: a joint, 0 to 11")
                                .c_str());
    r.ee_parent[a] = static_cast<int>(ee[a]);
  }
  std::memcpy(r.placement_R, data_of(placement_R, "placement_R", {12, 3, 3}), sizeof r.placement_R);
  std::memcpy(r.placement_p, data_of(placement_p, "placement_p", {12, 3}), sizeof r.placement_p);
  std::memcpy(r.axis, data_of(axis, "axis", {12, 3}), sizeof r.axis);
  std::memcpy(r.mass, data_of(mass, "mass", {13}), sizeof r.mass);
  std::memcpy(r.lever, data_of(lever, "lever", {13, 3}), sizeof r.lever);
  std::memcpy(r.inertia, data_of(inertia, "inertia", {13, 3, 3}), sizeof r.inertia);
  std::memcpy(r.ee_R, data_of(ee_R, "ee_R", {2, 3, 3}), sizeof r.ee_R);
  std::memcpy(r.ee_p, data_of(ee_p, "ee_p", {2, 3}), sizeof r.ee_p);
  for (double m : r.mass)
    if (!(m > 0.0)) throw nb::value_error("mass: every body's mass must be > 0 kg");
  return r;
}

nb::dict kinematics(const ffsr::Robot& robot, In x) {
  ffsr::Frames f{};
  ffsr::kinematics(robot, state_of(x), f);
  nb::dict out;
  out["Rj"] = copy_out(&f.Rj[0][0][0], {12, 3, 3});
  out["pj"] = copy_out(&f.pj[0][0], {12, 3});
  out["R_b"] = copy_out(&f.R_b[0][0], {3, 3});
  out["Re"] = copy_out(&f.Re[0][0][0], {2, 3, 3});
  out["pe"] = copy_out(&f.pe[0][0], {2, 3});
  out["z"] = copy_out(&f.z[0][0], {12, 3});
  return out;
}

nb::dict momentum(const ffsr::Robot& robot, In x) {
  ffsr::Frames f{};
  ffsr::Momentum m{};
  ffsr::kinematics(robot, state_of(x), f);
  ffsr::momentum(robot, state_of(x), f, m);
  nb::dict out;
  out["H_b"] = copy_out(&m.H_b[0][0], {6, 6});
  out["H_bm"] = copy_out(&m.H_bm[0][0][0], {2, 6, 6});
  out["rg"] = copy_out(m.rg, {3});
  return out;
}

Out base_velocity(const ffsr::Robot& robot, In x, In dq, In h) {
  ffsr::Frames f{};
  ffsr::Momentum m{};
  double v[6];
  ffsr::kinematics(robot, state_of(x), f);
  ffsr::momentum(robot, state_of(x), f, m);
  ffsr::base_velocity(state_of(x), data_of(dq, "dq", {12}), data_of(h, "h", {6}), f, m, v);
  return copy_out(v, {6});
}

Out midpoint_step(const ffsr::Robot& robot, In x, In v0, In dq, double dt, In h) {
  if (!(dt > 0.0)) throw nb::value_error("dt: allowed > 0 s");
  ffsr::Frames f{};
  ffsr::Momentum m{};
  double out[ffsr::kStateSize];
  ffsr::kinematics(robot, state_of(x), f);  // keeps the cosines the half step turns on
  ffsr::midpoint(robot, state_of(x), data_of(v0, "v0", {6}), data_of(dq, "dq", {12}), dt, data_of(h, "h", {6}), f,
                 m, out);
  return copy_out(out, {19});
}

void copy6(const In& a, const char* name, ffsr::Mat6& out) {
  std::memcpy(out, data_of(a, name, {6, 6}), sizeof(ffsr::Mat6));
}

nb::tuple svd6(In A, bool vectors) {
  ffsr::Mat6 a, Ut, Vt;
  double s[6];
  copy6(A, "A", a);
  ffsr::svd6(a, Ut, s, Vt, vectors);
  return nb::make_tuple(copy_out(&Ut[0][0], {6, 6}), copy_out(s, {6}), copy_out(&Vt[0][0], {6, 6}));
}

double smallest_singular_value(In A) {
  ffsr::Mat6 a;
  copy6(A, "A", a);
  return ffsr::smallest_singular_value(a);
}

nb::tuple smallest_singular_values(In A, In B) {
  ffsr::Mat6 a, b;
  double out[2];
  copy6(A, "A", a);
  copy6(B, "B", b);
  ffsr::smallest_singular_values(a, b, out);
  return nb::make_tuple(out[0], out[1]);
}

// A fixed-size array field of the settings, read and written as a numpy array of its shape.
template <size_t N>
void set_array(double (&field)[N], const In& value, const char* name) {
  std::memcpy(field, data_of(value, name, {N}), sizeof field);
}

void set_obstacles(ffsr::PlannerSettings& s, In positions, In velocities, In radii) {
  const size_t n = positions.ndim() == 2 ? positions.shape(0) : 0;
  if (n > static_cast<size_t>(ffsr::kMaxObstacles))
    throw nb::value_error(("obstacles: " + std::to_string(n) + "; allowed: at most " +
                           std::to_string(ffsr::kMaxObstacles)).c_str());
  const double* p = data_of(positions, "positions", {n, 3});
  const double* v = data_of(velocities, "velocities", {n, 3});
  const double* r = data_of(radii, "radii", {n});
  s.obstacles.resize(n);
  for (size_t k = 0; k < n; ++k) {
    for (int a = 0; a < 3; ++a) s.obstacles[k].position[a] = p[3 * k + a], s.obstacles[k].velocity[a] = v[3 * k + a];
    s.obstacles[k].radius = r[k];
  }
}

ffsr::PathTarget path_target(const double* row) {
  ffsr::PathTarget target;
  for (int a = 0; a < 3; ++a) target.position[a] = row[a], target.axis[a] = row[3 + a];
  target.angle = row[6];
  return target;
}

// Targets as rows of (position (3), axis (3), angle).
void set_estimates(ffsr::PlannerSettings& s, In rows) {
  const size_t n = rows.ndim() == 2 ? rows.shape(0) : 0;
  if (n == 0) throw nb::value_error("estimates: allowed at least one row of (position, axis, angle)");
  const double* d = data_of(rows, "estimates", {n, 7});
  s.estimates.clear();
  for (size_t k = 0; k < n; ++k) s.estimates.push_back(path_target(d + 7 * k));
}

void set_truth(ffsr::PlannerSettings& s, In row) { s.truth = path_target(data_of(row, "truth", {7})); }

// Frames as rows of (p_d (3), σ_d (4), V_ed (6), centre (3), R (9)).
void set_timing(ffsr::PlannerSettings& s, double standoff, double approach_speed, double approach_accel,
                double insert_speed, double insert_accel) {
  if (!(standoff >= 0.0 && standoff <= 1.0)) throw nb::value_error("standoff: allowed [0, 1] m");
  const double rates[4] = {approach_speed, approach_accel, insert_speed, insert_accel};
  for (double r : rates)
    if (!(r > 0.0 && r <= 1e3))
      throw nb::value_error("approach_speed, approach_accel, insert_speed, insert_accel: allowed (0, 1000]");
  s.timing = {true, standoff, approach_speed, approach_accel, insert_speed, insert_accel};
}

void set_frames(ffsr::PlannerSettings& s, In rows) {
  const size_t n = rows.ndim() == 2 ? rows.shape(0) : 0;
  const double* d = data_of(rows, "frames", {n, 25});
  s.frames.resize(n);
  for (size_t k = 0; k < n; ++k) std::memcpy(&s.frames[k], d + 25 * k, sizeof(ffsr::Frame));
}

nb::dict plan(const ffsr::Robot& robot, const ffsr::PlannerSettings& s, In x, double t, std::optional<In> timing) {
  check_settings(s, -1);
  ffsr::Frames f{};
  ffsr::Momentum m{};
  ffsr::Plan p{};
  if (timing) load_timing(data_of(*timing, "timing", {ffsr::kTimingState}), p.timing);
  ffsr::plan(robot, s, state_of(x), t, f, m, p);
  nb::dict out;
  out["dq"] = copy_out(p.dq, {12});
  out["e1"] = copy_out(p.e1, {6});
  out["e0"] = copy_out(p.e0, {6});
  out["mu"] = copy_out(p.mu, {2});
  out["cdf"] = copy_out(p.cdf, {2});
  out["smin"] = copy_out(p.smin, {2});
  return out;
}

// The commanded approach's desired pose and twist at state `timing` and time t.
nb::dict timed_desired(const ffsr::PlannerSettings& s, In timing, double t) {
  if (!s.timing.enabled) throw nb::value_error("settings: no commanded approach; allowed: set_timing first");
  check_settings(s, -1);
  ffsr::TimingState st;
  load_timing(data_of(timing, "timing", {ffsr::kTimingState}), st);
  const ffsr::Frame& r = ffsr::frame_at(s, t);
  double p_d[3], q_d[4], V_d[6];
  ffsr::timed_desired(s.timing, st, s.start_position, s.start_attitude, r.p_d, r.sigma_d, r.V_ed, p_d, q_d, V_d);
  nb::dict out;
  out["p_d"] = copy_out(p_d, {3});
  out["sigma_d"] = copy_out(q_d, {4});
  out["V_ed"] = copy_out(V_d, {6});
  return out;
}

// The commanded approach's state over `steps` physics steps of settings.dt from `timing`: (steps + 1, 5).
Out timing_profile(const ffsr::PlannerSettings& s, In timing, long steps) {
  if (!s.timing.enabled) throw nb::value_error("settings: no commanded approach; allowed: set_timing first");
  if (steps < 0 || steps > 10000000) throw nb::value_error("steps: allowed [0, 10000000]");
  ffsr::TimingState st;
  load_timing(data_of(timing, "timing", {ffsr::kTimingState}), st);
  double* out;
  Out rows = zeros({static_cast<size_t>(steps) + 1, static_cast<size_t>(ffsr::kTimingState)}, out);
  timing_values(st, out);
  for (long k = 1; k <= steps; ++k) {
    ffsr::advance_timing(s.timing, st, s.dt);
    timing_values(st, out + ffsr::kTimingState * k);
  }
  return rows;
}

nb::tuple clearances(const ffsr::Robot& robot, const ffsr::PlannerSettings& s, In x, double t) {
  ffsr::Frames f{};
  ffsr::CapsuleAxes axes;
  double clear, self_c, rel[3];
  ffsr::kinematics(robot, state_of(x), f);
  ffsr::clearances(robot, s, f, state_of(x), t, axes, clear, self_c, rel);
  return nb::make_tuple(clear, self_c, copy_out(rel, {3}));
}

double segment_box(In a, In b, In R, In c, In half) {
  ffsr::Mat3 rot;
  std::memcpy(rot, data_of(R, "R", {3, 3}), sizeof rot);
  return ffsr::segment_box(data_of(a, "a", {3}), data_of(b, "b", {3}), rot, data_of(c, "c", {3}),
                           data_of(half, "half", {3}));
}

Out aba(const ffsr::Robot& robot, In q, In v, In tau, In armature) {
  auto dyn = std::make_unique<ffsr::Dynamics>();
  double out[18];
  ffsr::spatial_inertias(robot, *dyn);
  ffsr::aba(robot, data_of(q, "q", {12}), data_of(v, "v", {18}), data_of(tau, "tau", {12}),
            data_of(armature, "armature", {12}), *dyn, out);
  return copy_out(out, {18});
}

}  // namespace

void bind_model(nb::module_& m) {
  nb::class_<ffsr::Robot>(m, "Robot", "The robot as the kernel reads it (joints in the paper's order).")
      .def(nb::init<>())
      .def_static("from_arrays", &make_robot, "parent"_a, "placement_R"_a, "placement_p"_a, "axis"_a,
                  "axis_code"_a, "mass"_a, "lever"_a, "inertia"_a, "ee_parent"_a, "ee_R"_a, "ee_p"_a,
                  "cap_parent"_a, "cap_a"_a, "cap_b"_a, "cap_radius"_a, "cap_arm"_a, "cap_vs_base"_a, "box_half"_a,
                  "drive"_a = nb::none(),
                  "A robot from the arrays of ffsr_gym.kernel.arrays.extract; a wrong shape or index is a "
                  "ValueError naming the field.")
      .def_prop_ro("total_mass", [](const ffsr::Robot& r) {
        double total = 0.0;
        for (double m : r.mass) total += m;
        return total;
      });
  nb::enum_<ffsr::Method>(m, "Method", "The planner's method.")
      .value("no_avoidance", ffsr::Method::kNoAvoidance)
      .value("no_feedback", ffsr::Method::kNoFeedback)
      .value("proportional", ffsr::Method::kProportional)
      .value("predefined_time", ffsr::Method::kPredefinedTime);
  nb::class_<ffsr::PlannerSettings> settings(m, "PlannerSettings", "The planner's settings, by name.");
  settings.def(nb::init<>())
      .def_rw("method", &ffsr::PlannerSettings::method)
      .def_rw("phi_printed", &ffsr::PlannerSettings::phi_printed)
      .def_rw("phi_split", &ffsr::PlannerSettings::phi_split)
      .def_rw("body_attitude_error", &ffsr::PlannerSettings::body_attitude_error)
      .def_rw("mu_distance", &ffsr::PlannerSettings::mu_distance)
      .def_rw("balance_avoids", &ffsr::PlannerSettings::balance_avoids)
      .def_rw("m", &ffsr::PlannerSettings::m)
      .def_rw("T_c", &ffsr::PlannerSettings::T_c)
      .def_rw("K", &ffsr::PlannerSettings::K)
      .def_rw("lambda_mission", &ffsr::PlannerSettings::lambda_mission)
      .def_rw("lambda_balance", &ffsr::PlannerSettings::lambda_balance)
      .def_rw("eps_mission", &ffsr::PlannerSettings::eps_mission)
      .def_rw("eps_balance", &ffsr::PlannerSettings::eps_balance)
      .def_rw("xi", &ffsr::PlannerSettings::xi)
      .def_rw("delta", &ffsr::PlannerSettings::delta)
      .def_rw("k1", &ffsr::PlannerSettings::k1)
      .def_rw("danger_radius", &ffsr::PlannerSettings::danger_radius)
      .def_rw("motion_time", &ffsr::PlannerSettings::motion_time)
      .def_rw("accel_time", &ffsr::PlannerSettings::accel_time)
      .def_rw("estimate_interval", &ffsr::PlannerSettings::estimate_interval)
      .def_rw("dt", &ffsr::PlannerSettings::dt)
      .def_rw("rate_max_deg_s", &ffsr::PlannerSettings::rate_max_deg_s)
      .def_rw("keep_out", &ffsr::PlannerSettings::keep_out)
      .def_rw("body_radius", &ffsr::PlannerSettings::body_radius)
      .def_rw("body_danger", &ffsr::PlannerSettings::body_danger)
      .def_rw("body_collides", &ffsr::PlannerSettings::body_collides)
      .def_rw("rate_limit_balance_only", &ffsr::PlannerSettings::rate_limit_balance_only)
      .def_rw("substeps", &ffsr::PlannerSettings::substeps)
      .def("set_start", [](ffsr::PlannerSettings& s, In position, In attitude) {
        set_array(s.start_position, position, "start_position");
        set_array(s.start_attitude, attitude, "start_attitude");
      }, "position"_a, "attitude"_a, "The path's start: position [m] and attitude (scalar first).")
      .def("set_base_target", [](ffsr::PlannerSettings& s, In position, In attitude) {
        set_array(s.base_position, position, "base_position");
        set_array(s.base_attitude, attitude, "base_attitude");
      }, "position"_a, "attitude"_a, "The base's desired pose: position [m] and attitude (scalar first).")
      .def("set_momentum", [](ffsr::PlannerSettings& s, In h) { set_array(s.momentum, h, "momentum"); }, "h"_a,
           "The conserved momentum [P; L about the system CoM].")
      .def("set_body_half", [](ffsr::PlannerSettings& s, In half) { set_array(s.body_half, half, "body_half"); },
           "half"_a, "The tumbling body's half extents [m].")
      .def("set_truth", &set_truth, "row"_a, "The true target: (position (3), axis (3), angle).")
      .def("set_estimates", &set_estimates, "rows"_a, "The planner's target estimates, rows like set_truth's.")
      .def("set_obstacles", &set_obstacles, "positions"_a, "velocities"_a, "radii"_a,
           "Obstacle points: start positions (n, 3) [m], drift velocities (n, 3) [m/s], radii (n,) [m].")
      .def("set_timing", &set_timing, "standoff"_a, "approach_speed"_a, "approach_accel"_a, "insert_speed"_a,
           "insert_accel"_a,
           "A commanded approach onto the frames (docs/model.md §23; the frames then hold the grasp frame's pose and "
           "twist): the pre-grasp standoff [m], the approach's and the insertion's top speeds [1/s] and "
           "accelerations [1/s²].")
      .def_prop_ro("timed", [](const ffsr::PlannerSettings& s) { return s.timing.enabled; },
                   "Whether the approach is commanded (set_timing).")
      .def("set_frames", &set_frames, "rows"_a,
           "A tumbling target's frames, one row per step: p_d (3), σ_d (4), V_ed (6), centre (3), R (9).");
  m.def("plan", &plan, "robot"_a, "settings"_a, "x"_a, "t"_a, "timing"_a = nb::none(),
        "One planner step at (t, x): joint rates dq (mission first), pose errors e1 and e0, mu, cdf and the "
        "arms' smallest singular values. timing: a commanded approach's state (5: command, s, ṡ, w, ẇ).");
  m.def("timed_desired", &timed_desired, "settings"_a, "timing"_a, "t"_a,
        "A commanded approach's desired end-effector pose and world twist at state timing (5) and t [s]: p_d, "
        "sigma_d (scalar first), V_ed.");
  m.def("timing_profile", &timing_profile, "settings"_a, "timing"_a, "steps"_a,
        "A commanded approach's state (command, s, ṡ, w, ẇ) at every physics step of settings.dt from timing: "
        "(steps + 1, 5).");
  m.def("clearances", &clearances, "robot"_a, "settings"_a, "x"_a, "t"_a,
        "(robot-obstacle clearance [m], self clearance [m], the vector robot → nearest obstacle) at (t, x).");
  m.def("segment_box", &segment_box, "a"_a, "b"_a, "R"_a, "c"_a, "half"_a,
        "Signed distance [m] of the segment a-b to the box of rotation R, centre c and half extents half.");
  m.def("aba", &aba, "robot"_a, "q"_a, "v"_a, "tau"_a, "armature"_a,
        "Accelerations (18) of the free-floating robot under joint torques (articulated-body algorithm).");
  m.def("kinematics", &kinematics, "robot"_a, "x"_a, "Forward kinematics of the state x (19,), world frame.");
  m.def("momentum", &momentum, "robot"_a, "x"_a, "H_b, H_bm about the base CoM and the system CoM rg at x.");
  m.def("base_velocity", &base_velocity, "robot"_a, "x"_a, "dq"_a, "h"_a,
        "The base velocity (base frame) that conserves h = [P; L_G] with joint rates dq.");
  m.def("midpoint_step", &midpoint_step, "robot"_a, "x"_a, "v0"_a, "dq"_a, "dt"_a, "h"_a,
        "The state after one explicit-midpoint step of dt from x (base velocity v0 at x).");
  m.def("svd6", &svd6, "A"_a, "vectors"_a = true, "One-sided Jacobi SVD of a 6x6 matrix: (Uᵀ, s, Vᵀ), unsorted.");
  m.def("smallest_singular_value", &smallest_singular_value, "A"_a,
        "σ_min of a 6x6 matrix, or -1 when the fast path cannot certify it.");
  m.def("smallest_singular_values", &smallest_singular_values, "A"_a, "B"_a,
        "smallest_singular_value of two 6x6 matrices, interleaved.");
}
