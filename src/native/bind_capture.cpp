// Bindings of the capture judge (docs/model.md §23): a rule for an episode, what it says, its state for pickling,
// and the same judge over a recorded trajectory.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cmath>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "ffsr/capture.hpp"
#include "field.hpp"

using namespace nb::literals;

namespace ffsr_bindings {

ffsr::CaptureRule capture_rule(const ffsr::PlannerSettings& s, In bounds, double hold_s, double contact_m) {
  if (!s.timing.enabled)
    throw nb::value_error("settings: the capture judge needs a commanded approach (set_timing), whose frames are "
                          "the grasp frame's");
  const double* b = data_of(bounds, "bounds", {4});
  ffsr::CaptureRule rule;
  for (int i = 0; i < 4; ++i) {
    if (!(b[i] > 0.0 && std::isfinite(b[i])))
      throw nb::value_error("bounds: allowed four finite numbers > 0 (position [m], attitude [rad], linear [m/s] "
                            "and angular velocity [rad/s])");
    rule.bound[i] = b[i];
  }
  if (!(hold_s >= 0.0 && hold_s <= 600.0)) throw nb::value_error("hold_s: allowed [0, 600] s");
  rule.needed = std::lround(hold_s / s.dt) + 1;
  if (!(contact_m >= 0.0 && contact_m <= 1.0)) throw nb::value_error("contact_m: allowed [0, 1] m");
  rule.contact = contact_m;
  return rule;
}

nb::dict judge_dict(const ffsr::CaptureJudge& j) {
  nb::dict out;
  out["samples"] = j.samples;
  out["captured_at"] = j.captured_at;
  out["worst"] = copy_out(j.worst, {4});
  out["margin"] = j.margin;
  out["last"] = copy_out(j.last, {4});
  out["contact_at"] = j.contact_at;
  out["contact_speed"] = j.contact_speed;
  return out;
}

// The judge's state as floats: the rule (needed, 4 bounds), samples, run, run_worst (4), captured_at, worst (4),
// margin, last (4), the rule's contact and stop, contact_at, contact_speed, then the window's (sample, largest
// ratio) pairs.
constexpr size_t kJudgeHead = 25;

Out judge_state(const ffsr::CaptureJudge& j) {
  std::vector<double> v = {static_cast<double>(j.rule.needed)};
  v.insert(v.end(), j.rule.bound, j.rule.bound + 4);
  v.push_back(static_cast<double>(j.samples));
  v.push_back(static_cast<double>(j.run));
  v.insert(v.end(), j.run_worst, j.run_worst + 4);
  v.push_back(static_cast<double>(j.captured_at));
  v.insert(v.end(), j.worst, j.worst + 4);
  v.push_back(j.margin);
  v.insert(v.end(), j.last, j.last + 4);
  v.push_back(j.rule.contact);
  v.push_back(j.rule.stop ? 1.0 : 0.0);
  v.push_back(static_cast<double>(j.contact_at));
  v.push_back(j.contact_speed);
  for (const auto& [k, value] : j.window) v.push_back(static_cast<double>(k)), v.push_back(value);
  return copy_out(v.data(), {v.size()});
}

void load_judge(ffsr::CaptureJudge& j, In state) {
  const size_t n = state.ndim() == 1 ? state.shape(0) : 0;
  if (n < kJudgeHead || (n - kJudgeHead) % 2 != 0)
    throw nb::value_error("capture_state: allowed a state read from capture_state");
  const double* v = state.data();
  ffsr::CaptureJudge loaded;
  loaded.rule.needed = static_cast<long>(v[0]);
  std::copy(v + 1, v + 5, loaded.rule.bound);
  loaded.samples = static_cast<long>(v[5]), loaded.run = static_cast<long>(v[6]);
  std::copy(v + 7, v + 11, loaded.run_worst);
  loaded.captured_at = static_cast<long>(v[11]);
  std::copy(v + 12, v + 16, loaded.worst);
  loaded.margin = v[16];
  std::copy(v + 17, v + 21, loaded.last);
  loaded.rule.contact = v[21], loaded.rule.stop = v[22] != 0.0;
  loaded.contact_at = static_cast<long>(v[23]), loaded.contact_speed = v[24];
  if ((n - kJudgeHead) / 2 > static_cast<size_t>(std::max(loaded.rule.needed, 0L)))
    throw nb::value_error("capture_state: a window longer than the hold window");
  for (size_t i = kJudgeHead; i + 1 < n; i += 2) loaded.window.emplace_back(static_cast<long>(v[i]), v[i + 1]);
  j = std::move(loaded);
}

}  // namespace ffsr_bindings

namespace {

using namespace ffsr_bindings;

// The judge over a recorded trajectory: its states (n, 19 or more) and velocities (n, 18: the base's twist in its
// own frame, then the joint rates), the samples of steps 0 .. n − 1.
nb::dict capture_of(const ffsr::Robot& robot, const ffsr::PlannerSettings& s, In x, In v, In bounds, double hold_s,
                    double contact_m) {
  ffsr::CaptureJudge judge;
  judge.rule = capture_rule(s, bounds, hold_s, contact_m);
  const size_t n = x.ndim() == 2 ? x.shape(0) : 0, width = x.ndim() == 2 ? x.shape(1) : 0;
  if (width < 19) throw nb::value_error("x: allowed (n, 19) or wider states");
  check_settings(s, static_cast<long>(n) - 1);
  const double* rows = x.data();
  const double* rates = data_of(v, "v", {n, 18});
  ffsr::Frames f{};
  ffsr::Mat6 J;
  for (size_t k = 0; k < n; ++k) {
    const double* state = rows + width * k;
    ffsr::kinematics(robot, state, f);
    ffsr::mission_jacobian(f, J);
    const ffsr::Frame& grasp = ffsr::frame_at(s, static_cast<double>(k) * s.dt);
    double q[4];
    ffsr::capture_quantities(f, state, rates + 18 * k, J, grasp.p_d, grasp.sigma_d, grasp.V_ed, q);
    ffsr::add_capture(judge, q);
  }
  return judge_dict(judge);
}

}  // namespace

void bind_capture(nb::module_& m) {
  m.def("capture_of", &capture_of, "robot"_a, "settings"_a, "x"_a, "v"_a, "bounds"_a, "hold_s"_a, "contact_m"_a = 0.0,
        "The capture judge over a recorded trajectory (docs/model.md §23): states x (n, >= 19) and velocities v "
        "(n, 18: the base's twist in its own frame, then the joint rates) against a commanded approach's grasp "
        "frame; bounds: position [m], attitude [rad], linear [m/s] and angular velocity [rad/s]; hold_s: the hold "
        "window [s]. Returns samples, captured_at (the sample that ended the first hold window, -1: none), worst "
        "(4: each quantity's largest value / bound over it), margin (the smallest largest ratio of any window), "
        "last (4: the last sample's quantities), contact_at (the first sample within contact_m of the grasp frame, "
        "-1: none) and contact_speed (the relative linear speed there [m/s]; NaN: none).");
}
