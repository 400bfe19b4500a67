// Shared helpers of the native kernel's bindings: array checks that name the field, copies out to numpy.
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cmath>
#include <cstring>
#include <initializer_list>
#include <string>
#include <type_traits>
#include <vector>

#include "ffsr/capture.hpp"
#include "ffsr/loop.hpp"

namespace nb = nanobind;

namespace ffsr_bindings {

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using InInt = nb::ndarray<const int64_t, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<nb::numpy, double>;

inline std::string shape_text(const std::vector<size_t>& shape) {
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
inline Out copy_out(const double* data, std::initializer_list<size_t> shape) {
  size_t n = 1;
  for (size_t s : shape) n *= s;
  double* owned = new double[n];
  std::memcpy(owned, data, n * sizeof(double));
  nb::capsule owner(owned, [](void* p) noexcept { delete[] static_cast<double*>(p); });
  std::vector<size_t> dims(shape);
  return Out(owned, dims.size(), dims.data(), owner);
}

inline const double* state_of(const In& x) { return data_of(x, "x", {19}); }

// A loop state from x: 19 configuration floats, or 40 with the servo plant's state after them (the servo plant
// needs them).
inline void load_state(const In& x, ffsr::LoopState& st, const ffsr::PlannerSettings& s) {
  const size_t n = x.ndim() == 1 ? x.shape(0) : 0;
  if (n != 19 && n != 19 + ffsr::kServoState)
    throw nb::value_error(("x: shape (" + std::to_string(n) + ",); allowed: (19,) or (40,)").c_str());
  if (s.substeps > 0 && n == 19) throw nb::value_error("x: the servo plant needs its state, (40,)");
  std::memcpy(st.x, x.data(), sizeof st.x);
  if (n > 19) std::memcpy(st.servo, x.data() + 19, sizeof st.servo);
}

// Settings a run can follow: a target path (estimates) or a tumbling target's frames, one per step of n_total
// (n_total < 0: no run length to check).
inline void check_settings(const ffsr::PlannerSettings& s, long n_total) {
  if (s.estimates.empty() && s.frames.empty())
    throw nb::value_error("settings: no estimates and no frames; allowed: set_estimates or set_frames first");
  if (n_total >= 0 && !s.frames.empty() && static_cast<long>(s.frames.size()) < n_total + 1)
    throw nb::value_error("frames: allowed one per step, n_total + 1 of them");
  if (s.timing.enabled && s.frames.empty())
    throw nb::value_error("settings: a commanded approach (set_timing) without frames; allowed: set_frames first");
}

// A commanded approach's state (command, s, ṡ, w, ẇ) from five floats, checked: the command in [0, 2], s and w in
// [0, 1], every value finite.
inline void load_timing(const double* v, ffsr::TimingState& st) {
  for (int i = 0; i < ffsr::kTimingState; ++i)
    if (!std::isfinite(v[i])) throw nb::value_error("timing: allowed finite values (command, s, s_dot, w, w_dot)");
  if (v[0] < 0.0 || v[0] > 2.0) throw nb::value_error("timing[0] (the command): allowed [0, 2]");
  if (v[1] < 0.0 || v[1] > 1.0 || v[3] < 0.0 || v[3] > 1.0)
    throw nb::value_error("timing[1] (s) and timing[3] (w): allowed [0, 1]");
  st.command = v[0], st.s = v[1], st.s_dot = v[2], st.w = v[3], st.w_dot = v[4];
}

inline void timing_values(const ffsr::TimingState& st, double out[ffsr::kTimingState]) {
  out[0] = st.command, out[1] = st.s, out[2] = st.s_dot, out[3] = st.w, out[4] = st.w_dot;
}

inline Out state_out(const ffsr::LoopState& st) {
  double all[19 + ffsr::kServoState];
  std::memcpy(all, st.x, sizeof st.x);
  std::memcpy(all + 19, st.servo, sizeof st.servo);
  return copy_out(all, {19 + ffsr::kServoState});
}

// A new zeroed numpy array of the given shape, and its data.
inline Out zeros(std::initializer_list<size_t> shape, double*& data) {
  size_t n = 1;
  for (size_t s : shape) n *= s;
  data = new double[n]();
  nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<double*>(p); });
  std::vector<size_t> dims(shape);
  return Out(data, dims.size(), dims.data(), owner);
}

// The capture judge's bindings (bind_capture.cpp): a rule from bounds (4) and a hold window [s] at settings.dt (a
// commanded approach's settings only), what a judge says, and its state as floats and back.
ffsr::CaptureRule capture_rule(const ffsr::PlannerSettings& s, In bounds, double hold_s, double contact_m = 0.0);
nb::dict judge_dict(const ffsr::CaptureJudge& j);
Out judge_state(const ffsr::CaptureJudge& j);
void load_judge(ffsr::CaptureJudge& j, In state);

}  // namespace ffsr_bindings
