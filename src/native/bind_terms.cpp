// Bindings of the score's smoothness terms and the tumbling target's motion.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <string>

#include "bindings.hpp"
#include "ffsr/decision.hpp"
#include "ffsr/tumbling.hpp"

using namespace nb::literals;
using namespace ffsr_bindings;

namespace {

nb::tuple smoothness_terms(In rates, double dt, In previous) {
  const size_t rows = rates.ndim() == 2 ? rates.shape(0) : 0;
  check_shape(rates, "rates", {rows, 12});
  double out[4];
  ffsr::smoothness_terms(rates.data(), static_cast<long>(rows), dt, data_of(previous, "previous", {12}), out);
  return nb::make_tuple(copy_out(out, {2}), copy_out(out + 2, {2}));
}

double smoothness_cost(In energy, In variation, const ffsr::DecisionSettings& d) {
  const double* e = data_of(energy, "energy", {2});
  const double* v = data_of(variation, "variation", {2});
  const double terms[4] = {e[0], e[1], v[0], v[1]};
  return ffsr::smoothness_cost(terms, d);
}

nb::tuple propagate(In quaternion, In omega, In inertia, double dt, int substeps, long steps) {
  if (!(dt > 0.0)) throw nb::value_error("dt: allowed > 0 s");
  if (substeps < 1) throw nb::value_error("substeps: allowed >= 1");
  if (steps < 0) throw nb::value_error("steps: allowed >= 0");
  const double* moments = data_of(inertia, "inertia", {3});
  for (int i = 0; i < 3; ++i)
    if (!(moments[i] > 0.0)) throw nb::value_error("inertia: allowed principal moments > 0 kg m^2");
  const size_t n = static_cast<size_t>(steps) + 1;
  double *q, *w;
  Out out_q = zeros({n, 4}, q), out_w = zeros({n, 3}, w);
  ffsr::propagate_tumbling(data_of(quaternion, "quaternion", {4}), data_of(omega, "omega", {3}), moments, dt,
                           substeps, steps, q, w);
  return nb::make_tuple(out_q, out_w);
}

}  // namespace

void bind_terms(nb::module_& m) {
  m.def("smoothness_terms", &smoothness_terms, "rates"_a, "dt"_a, "previous"_a,
        "Rate energy E [rad^2/s] and rate variation V [rad/s] of each arm over rates (n, 12) held dt [s] each, from "
        "the previous rates (12): (E (2,), V (2,)), mission arm first.");
  m.def("smoothness_cost", &smoothness_cost, "energy"_a, "variation"_a, "settings"_a,
        "C = alpha (E1/E_ref + V1/V_ref) + beta (E2/E_ref + V2/V_ref) of a DecisionSettings' cost settings.");
  m.def("residual_fade", &ffsr::residual_fade, "t"_a, "motion_s"_a, "fade_s"_a,
        "The residual's weight f(t): 1, a half-cosine over the last fade_s [s] of the motion (motion_s [s]), then 0.");
  m.def("propagate_tumbling", &propagate, "quaternion"_a, "omega"_a, "inertia"_a, "dt"_a, "substeps"_a, "steps"_a,
        "Torque-free motion of a body (RK4, substeps per step, the quaternion renormalised): quaternions "
        "(steps + 1, 4), w first, and body rates (steps + 1, 3) [rad/s] at every step of dt [s].");
}
