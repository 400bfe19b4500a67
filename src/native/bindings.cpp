// Python bindings of the native kernel (module ffsr_gym._native): the typed robot and its physics.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <thread>
#include <initializer_list>
#include <string>
#include <vector>

#include "ffsr/collision.hpp"
#include "ffsr/decision.hpp"
#include "ffsr/linalg.hpp"
#include "ffsr/loop.hpp"
#include "ffsr/physics.hpp"
#include "ffsr/planner.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using InInt = nb::ndarray<const int64_t, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<nb::numpy, double>;

std::string shape_text(const std::vector<size_t>& shape) {
  std::string text = "(";
  for (size_t k = 0; k < shape.size(); ++k) text += (k ? ", " : "") + std::to_string(shape[k]);
  return text + (shape.size() == 1 ? ",)" : ")");
}

template <typename Array>
void check_shape(const Array& a, const char* name, std::initializer_list<size_t> shape) {
  std::vector<size_t> want(shape), got;
  for (size_t k = 0; k < a.ndim(); ++k) got.push_back(a.shape(k));
  if (got != want)
    throw nb::value_error((std::string(name) + ": shape " + shape_text(got) + "; allowed: " + shape_text(want)).c_str());
}

template <typename Array>
const typename std::remove_const<typename Array::Scalar>::type* data_of(const Array& a, const char* name,
                                                                         std::initializer_list<size_t> shape) {
  check_shape(a, name, shape);
  return a.data();
}

// A new numpy array holding a copy of n doubles, of the given shape.
Out copy_out(const double* data, std::initializer_list<size_t> shape) {
  size_t n = 1;
  for (size_t s : shape) n *= s;
  double* owned = new double[n];
  std::memcpy(owned, data, n * sizeof(double));
  nb::capsule owner(owned, [](void* p) noexcept { delete[] static_cast<double*>(p); });
  std::vector<size_t> dims(shape);
  return Out(owned, dims.size(), dims.data(), owner);
}

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

const double* state_of(const In& x) { return data_of(x, "x", {19}); }

// A loop state from x: 19 configuration floats, or 40 with the servo plant's state after them.
void load_state(const In& x, ffsr::LoopState& st) {
  const size_t n = x.ndim() == 1 ? x.shape(0) : 0;
  if (n != 19 && n != 19 + ffsr::kServoState)
    throw nb::value_error(("x: shape (" + std::to_string(n) + ",); allowed: (19,) or (40,)").c_str());
  std::memcpy(st.x, x.data(), sizeof st.x);
  if (n > 19) std::memcpy(st.servo, x.data() + 19, sizeof st.servo);
}

Out state_out(const ffsr::LoopState& st) {
  double all[19 + ffsr::kServoState];
  std::memcpy(all, st.x, sizeof st.x);
  std::memcpy(all + 19, st.servo, sizeof st.servo);
  return copy_out(all, {19 + ffsr::kServoState});
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
void set_frames(ffsr::PlannerSettings& s, In rows) {
  const size_t n = rows.ndim() == 2 ? rows.shape(0) : 0;
  const double* d = data_of(rows, "frames", {n, 25});
  s.frames.resize(n);
  for (size_t k = 0; k < n; ++k) std::memcpy(&s.frames[k], d + 25 * k, sizeof(ffsr::Frame));
}

nb::dict plan(const ffsr::Robot& robot, const ffsr::PlannerSettings& s, In x, double t) {
  if (s.estimates.empty() && s.frames.empty())
    throw nb::value_error("settings: no estimates and no frames; allowed: set_estimates or set_frames first");
  ffsr::Frames f{};
  ffsr::Momentum m{};
  ffsr::Plan p{};
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

// A new zeroed numpy array of the given shape, and its data.
Out zeros(std::initializer_list<size_t> shape, double*& data) {
  size_t n = 1;
  for (size_t s : shape) n *= s;
  data = new double[n]();
  nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<double*>(p); });
  std::vector<size_t> dims(shape);
  return Out(data, dims.size(), dims.data(), owner);
}

nb::tuple run(const ffsr::Robot& robot, const ffsr::PlannerSettings& s, In x, long k0, long n_total, long n_max,
              In residual, bool stop_on_violation, bool record_only, const ffsr::Robot* plant) {
  if (s.estimates.empty() && s.frames.empty())
    throw nb::value_error("settings: no estimates and no frames; allowed: set_estimates or set_frames first");
  if (k0 < 0 || n_total < k0 || n_max < 0)
    throw nb::value_error("steps: allowed 0 <= k0 <= n_total and n_max >= 0");
  if (!s.frames.empty() && static_cast<long>(s.frames.size()) < n_total + 1)
    throw nb::value_error("frames: allowed one per step, n_total + 1 of them");
  auto st = std::make_unique<ffsr::LoopState>();
  load_state(x, *st);
  if (s.substeps > 0 && x.shape(0) == 19) throw nb::value_error("x: the servo plant needs its state, (40,)");
  const size_t n = record_only ? 1 : static_cast<size_t>(std::max(0L, std::min(n_max, n_total - k0)));
  ffsr::LogRows rows_out{};
  nb::dict logs;
  logs["x"] = zeros({n, 19}, rows_out.x);
  logs["v"] = zeros({n, 18}, rows_out.v);
  logs["dq"] = zeros({n, 12}, rows_out.dq);
  logs["err"] = zeros({n, 4}, rows_out.err);
  logs["clear"] = zeros({n}, rows_out.clear);
  logs["self"] = zeros({n}, rows_out.self);
  logs["mu"] = zeros({n, 2}, rows_out.mu);
  logs["cdf"] = zeros({n, 2}, rows_out.cdf);
  logs["smin"] = zeros({n, 2}, rows_out.smin);
  logs["tau"] = zeros({n, 12}, rows_out.tau);
  long rows = 0;
  ffsr::Status status;
  {
    nb::gil_scoped_release release;
    status = ffsr::run(robot, plant ? *plant : robot, s, *st, k0, n_total, n_max, data_of(residual, "residual", {12}),
                       stop_on_violation, record_only, false, rows_out, rows);
  }
  return nb::make_tuple(state_out(*st), rows, static_cast<int>(status), logs);
}

// One environment episode on the native kernel: the robot (and plant) it steps, its settings, its state and logs.
struct NativeEpisode {
  const ffsr::Robot* robot;
  const ffsr::Robot* plant;
  ffsr::PlannerSettings s;
  ffsr::DecisionSettings d;
  std::unique_ptr<ffsr::EpisodeState> e = std::make_unique<ffsr::EpisodeState>();
  long n_total;
  std::vector<double> x, v, dq, err, clear, self, mu, cdf, smin, tau;

  NativeEpisode(const ffsr::Robot& robot_, const ffsr::PlannerSettings& s_, const ffsr::DecisionSettings& d_, In x0,
                long n_total_, const ffsr::Robot* plant_)
      : robot(&robot_), plant(plant_ ? plant_ : &robot_), s(s_), d(d_), n_total(n_total_) {
    if (n_total < 1) throw nb::value_error("n_total: allowed >= 1 step");
    if (s.estimates.empty() && s.frames.empty())
      throw nb::value_error("settings: no estimates and no frames; allowed: set_estimates or set_frames first");
    if (!s.frames.empty() && static_cast<long>(s.frames.size()) < n_total + 1)
      throw nb::value_error("frames: allowed one per step, n_total + 1 of them");
    load_state(x0, e->loop);
    if (s.substeps > 0 && x0.shape(0) == 19) throw nb::value_error("x: the servo plant needs its state, (40,)");
    const size_t n = static_cast<size_t>(n_total);
    x.assign(19 * n, 0.0), v.assign(18 * n, 0.0), dq.assign(12 * n, 0.0), err.assign(4 * n, 0.0);
    clear.assign(n, 0.0), self.assign(n, 0.0), mu.assign(2 * n, 0.0), cdf.assign(2 * n, 0.0);
    smin.assign(2 * n, 0.0), tau.assign(12 * n, 0.0);
  }

  nb::tuple decide(In action, int mode, bool stop, long k, long n_max,
                   nb::ndarray<float, nb::c_contig, nb::device::cpu> obs) {
    if (mode < 0 || mode > 2) throw nb::value_error("mode: allowed 0 (residual), 1 (parameters) or 2 (set)");
    if (k < 0 || k > n_total || n_max < 0) throw nb::value_error("steps: allowed 0 <= k <= n_total and n_max >= 0");
    if (action.ndim() != 1) throw nb::value_error("action: allowed a 1-d array");
    const int n_action = static_cast<int>(action.shape(0));
    const int n_obs = obs.ndim() == 1 ? static_cast<int>(obs.shape(0)) : 0;
    if (n_obs != ffsr::kObservation && n_obs != ffsr::kObservationTwist)
      throw nb::value_error("obs: allowed a float32 array of 53 or 59");
    const size_t r = static_cast<size_t>(k);
    ffsr::LogRows logs{x.data() + 19 * r, v.data() + 18 * r, dq.data() + 12 * r, err.data() + 4 * r,
                       clear.data() + r, self.data() + r, mu.data() + 2 * r, cdf.data() + 2 * r,
                       smin.data() + 2 * r, tau.data() + 12 * r};
    ffsr::DecisionResult out;
    {
      nb::gil_scoped_release release;
      out = ffsr::decide(*robot, *plant, s, d, *e, k, n_total, n_max, action.data(), n_action,
                         static_cast<ffsr::ActionMode>(mode), stop, logs, obs.data(), n_obs);
    }
    return nb::make_tuple(out.rows, out.status, out.clipped, out.increment, out.cost, out.clearance, out.ee_error);
  }

  nb::dict logs() const {
    const size_t n = static_cast<size_t>(n_total);
    nb::dict out;
    out["x"] = copy_out(x.data(), {n, 19});
    out["v"] = copy_out(v.data(), {n, 18});
    out["dq"] = copy_out(dq.data(), {n, 12});
    out["err"] = copy_out(err.data(), {n, 4});
    out["clear"] = copy_out(clear.data(), {n});
    out["self"] = copy_out(self.data(), {n});
    out["mu"] = copy_out(mu.data(), {n, 2});
    out["cdf"] = copy_out(cdf.data(), {n, 2});
    out["smin"] = copy_out(smin.data(), {n, 2});
    out["tau"] = copy_out(tau.data(), {n, 12});
    return out;
  }
};

Out aba(const ffsr::Robot& robot, In q, In v, In tau, In armature) {
  auto dyn = std::make_unique<ffsr::Dynamics>();
  double out[18];
  ffsr::spatial_inertias(robot, *dyn);
  ffsr::aba(robot, data_of(q, "q", {12}), data_of(v, "v", {18}), data_of(tau, "tau", {12}),
            data_of(armature, "armature", {12}), *dyn, out);
  return copy_out(out, {18});
}

// Episodes advanced together: one decision each per call, on threads, the GIL released.
struct EpisodeBatch {
  std::vector<NativeEpisode*> episodes;
  int threads;

  EpisodeBatch(std::vector<NativeEpisode*> episodes_, int threads_) : episodes(std::move(episodes_)), threads(threads_) {
    if (episodes.empty()) throw nb::value_error("episodes: allowed at least one");
    if (threads < 1) throw nb::value_error("threads: allowed >= 1");
    for (size_t e = 0; e < episodes.size(); ++e)
      for (size_t f = 0; f < e; ++f)
        if (episodes[e] == episodes[f]) throw nb::value_error("episodes: allowed each episode once");
  }

  // One decision for every active episode e from its step k[e] (which advances): out[e] = (rows, status,
  // clipped, increment, cost, clearance, EE error); obs[e] the next observation.
  void decide(In actions, nb::ndarray<const bool, nb::c_contig, nb::device::cpu> active,
              nb::ndarray<int64_t, nb::c_contig, nb::device::cpu> k, int mode, long n_max,
              nb::ndarray<float, nb::c_contig, nb::device::cpu> obs,
              nb::ndarray<double, nb::c_contig, nb::device::cpu> out) {
    const size_t n = episodes.size();
    const size_t width = actions.ndim() == 2 ? actions.shape(1) : 0;
    check_shape(actions, "actions", {n, width});
    check_shape(active, "active", {n});
    check_shape(k, "k", {n});
    const size_t n_obs = obs.ndim() == 2 ? obs.shape(1) : 0;
    if (n_obs != ffsr::kObservation && n_obs != ffsr::kObservationTwist)
      throw nb::value_error("obs: allowed a float32 array (N, 53) or (N, 59)");
    check_shape(obs, "obs", {n, n_obs});
    check_shape(out, "out", {n, 7});
    if (mode < 0 || mode > 2) throw nb::value_error("mode: allowed 0 (residual), 1 (parameters) or 2 (set)");
    for (size_t e = 0; e < n; ++e)
      if (k.data()[e] < 0 || k.data()[e] > episodes[e]->n_total)
        throw nb::value_error(("k[" + std::to_string(e) + "]: allowed 0 to the episode's n_total").c_str());
    const double* a = actions.data();
    const bool* on = active.data();
    int64_t* steps = k.data();
    float* o = obs.data();
    double* r = out.data();
    auto work = [&](size_t first, size_t stride) {
      for (size_t e = first; e < n; e += stride) {
        if (!on[e]) continue;
        NativeEpisode& ep = *episodes[e];
        const size_t row = static_cast<size_t>(steps[e]);
        ffsr::LogRows logs{ep.x.data() + 19 * row, ep.v.data() + 18 * row, ep.dq.data() + 12 * row,
                           ep.err.data() + 4 * row, ep.clear.data() + row, ep.self.data() + row,
                           ep.mu.data() + 2 * row, ep.cdf.data() + 2 * row, ep.smin.data() + 2 * row,
                           ep.tau.data() + 12 * row};
        const ffsr::DecisionResult d = ffsr::decide(*ep.robot, *ep.plant, ep.s, ep.d, *ep.e, steps[e], ep.n_total,
                                                    n_max, a + width * e, static_cast<int>(width),
                                                    static_cast<ffsr::ActionMode>(mode), true, logs, o + n_obs * e,
                                                    static_cast<int>(n_obs));
        steps[e] += d.rows;
        double* row_out = r + 7 * e;
        row_out[0] = static_cast<double>(d.rows), row_out[1] = d.status, row_out[2] = d.clipped ? 1.0 : 0.0;
        row_out[3] = d.increment, row_out[4] = d.cost, row_out[5] = d.clearance, row_out[6] = d.ee_error;
      }
    };
    nb::gil_scoped_release release;
    const size_t workers = std::min(static_cast<size_t>(threads), n);
    std::vector<std::thread> pool;
    for (size_t w = 1; w < workers; ++w) pool.emplace_back(work, w, workers);
    work(0, workers);
    for (auto& thread : pool) thread.join();
  }
};

}  // namespace

NB_MODULE(_native, m) {
  m.doc() = "The native kernel of ffsr-gym: the typed robot model and its physics, compiled at install.";
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
      .def("set_frames", &set_frames, "rows"_a,
           "A tumbling target's frames, one row per step: p_d (3), σ_d (4), V_ed (6), centre (3), R (9).");
  m.def("plan", &plan, "robot"_a, "settings"_a, "x"_a, "t"_a,
        "One planner step at (t, x): joint rates dq (mission first), pose errors e1 and e0, mu, cdf and the "
        "arms' smallest singular values.");
  m.def("clearances", &clearances, "robot"_a, "settings"_a, "x"_a, "t"_a,
        "(robot-obstacle clearance [m], self clearance [m], the vector robot → nearest obstacle) at (t, x).");
  m.def("segment_box", &segment_box, "a"_a, "b"_a, "R"_a, "c"_a, "half"_a,
        "Signed distance [m] of the segment a-b to the box of rotation R, centre c and half extents half.");
  m.def("run", &run, "robot"_a, "settings"_a, "x"_a, "k0"_a, "n_total"_a, "n_max"_a, "residual"_a,
        "stop_on_violation"_a = true, "record_only"_a = false, "plant"_a = nb::none(),
        "The closed loop on the kinematic plant from step k0: (x after, rows, status 0 ok / 1 rate / 2 collision / "
        "3 non-finite, logs of one row per step). plant: the robot the physics integrates, if not robot itself.");
  nb::class_<ffsr::DecisionSettings>(m, "DecisionSettings", "A decision's settings, by name.")
      .def(nb::init<>())
      .def_rw("rate_scale", &ffsr::DecisionSettings::rate_scale)
      .def_rw("fade_s", &ffsr::DecisionSettings::fade_s)
      .def_rw("motion_s", &ffsr::DecisionSettings::motion_s)
      .def_rw("m_lo", &ffsr::DecisionSettings::m_lo)
      .def_rw("m_hi", &ffsr::DecisionSettings::m_hi)
      .def_rw("T_lo", &ffsr::DecisionSettings::T_lo)
      .def_rw("T_hi", &ffsr::DecisionSettings::T_hi)
      .def_rw("rate_limit_deg_s", &ffsr::DecisionSettings::rate_limit_deg_s)
      .def_rw("clear_scale", &ffsr::DecisionSettings::clear_scale)
      .def_rw("alpha", &ffsr::DecisionSettings::alpha)
      .def_rw("beta", &ffsr::DecisionSettings::beta)
      .def_rw("E_ref", &ffsr::DecisionSettings::E_ref)
      .def_rw("V_ref", &ffsr::DecisionSettings::V_ref);
  nb::class_<NativeEpisode>(m, "Episode", "One environment episode on the native kernel.")
      .def(nb::init<const ffsr::Robot&, const ffsr::PlannerSettings&, const ffsr::DecisionSettings&, In, long,
                    const ffsr::Robot*>(),
           "robot"_a, "settings"_a, "decision"_a, "x"_a, "n_total"_a, "plant"_a = nb::none(), nb::keep_alive<1, 2>(),
           nb::keep_alive<1, 7>())
      .def("decide", &NativeEpisode::decide, "action"_a, "mode"_a, "stop"_a, "k"_a, "n_max"_a, "obs"_a,
           "One decision from step k: (rows, status, clipped, increment, cost, clearance, EE error); the next "
           "observation into obs (float32, 53 or 59).")
      .def("logs", &NativeEpisode::logs, "The episode's logs, one row per step (copies).")
      .def("state", [](const NativeEpisode& ep) { return state_out(ep.e->loop); }, "The state x (40, a copy).")
      .def_prop_ro("m", [](const NativeEpisode& ep) { return ep.s.m; })
      .def_prop_ro("T_c", [](const NativeEpisode& ep) { return ep.s.T_c; });
  m.def("aba", &aba, "robot"_a, "q"_a, "v"_a, "tau"_a, "armature"_a,
        "Accelerations (18) of the free-floating robot under joint torques (articulated-body algorithm).");
  nb::class_<EpisodeBatch>(m, "EpisodeBatch", "Episodes advanced together, one decision each per call, on threads.")
      .def(nb::init<std::vector<NativeEpisode*>, int>(), "episodes"_a, "threads"_a = 1, nb::keep_alive<1, 2>())
      .def("decide", &EpisodeBatch::decide, "actions"_a, "active"_a, "k"_a, "mode"_a, "n_max"_a, "obs"_a, "out"_a,
           "One decision for every active episode from its step k (advanced in place); out (N, 7): rows, status, "
           "clipped, increment, cost, clearance, EE error; obs (N, 53 or 59) float32, written in place.");
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
