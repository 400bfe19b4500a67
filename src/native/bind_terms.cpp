// Bindings of the score's terms (a decision's smoothness terms, an episode's totals) and the tumbling target's
// motion.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstring>
#include <new>
#include <type_traits>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "ffsr/decision.hpp"
#include "ffsr/totals.hpp"
#include "ffsr/tumbling.hpp"

using namespace nb::literals;
using namespace ffsr_bindings;

namespace {

// Totals of a recorded trajectory: samples rows of errors (4) and clearances, its first `applied` rows of rates
// (12) applied, summed as an episode sums them.
ffsr::ScoreTotals score_totals(In rates, In err, In clear, In self_c, long applied, double danger_deg_s,
                               double tolerance_m) {
  const size_t n = clear.ndim() == 1 ? clear.shape(0) : 0;
  check_shape(rates, "rates", {n, 12});
  check_shape(err, "err", {n, 4});
  check_shape(clear, "clear", {n});
  check_shape(self_c, "self", {n});
  if (applied < 0 || applied > static_cast<long>(n)) throw nb::value_error("applied: allowed 0 to the rows");
  ffsr::ScoreTotals t;
  t.danger_deg_s = danger_deg_s, t.tolerance_m = tolerance_m;
  for (long k = 0; k < applied; ++k) ffsr::add_applied(t, rates.data() + 12 * k);
  for (size_t k = 0; k < n; ++k) ffsr::add_sample(t, err.data() + 4 * k, clear.data()[k], self_c.data()[k]);
  return t;
}

nb::tuple pair(const double v[2]) { return nb::make_tuple(v[0], v[1]); }

static_assert(std::is_trivially_copyable_v<ffsr::ScoreTotals>, "ScoreTotals pickles as its bytes");

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

  nb::class_<ffsr::ScoreTotals>(m, "ScoreTotals", "An episode's score terms, summed sample by sample (read-only).")
      .def_ro("danger_deg_s", &ffsr::ScoreTotals::danger_deg_s)
      .def_ro("tolerance_m", &ffsr::ScoreTotals::tolerance_m)
      .def_ro("samples", &ffsr::ScoreTotals::samples, "Samples seen (rows of the trajectory).")
      .def_ro("applied", &ffsr::ScoreTotals::applied, "Steps whose rates were applied.")
      .def_prop_ro("square", [](const ffsr::ScoreTotals& t) { return pair(t.square); },
                   "Σ‖Θ̇‖² of each arm [rad²/s²] over the applied steps (E = square dt).")
      .def_prop_ro("variation", [](const ffsr::ScoreTotals& t) { return pair(t.variation); },
                   "Σ‖Θ̇_k − Θ̇_{k−1}‖ of each arm [rad/s], from rest.")
      .def_prop_ro("psi", [](const ffsr::ScoreTotals& t) { return pair(t.psi); },
                   "Σ Ψ(‖Θ̇‖ [deg/s], danger rate) of each arm (the paper objective's integrand).")
      .def_prop_ro("peak", [](const ffsr::ScoreTotals& t) { return pair(t.peak); },
                   "Largest |Θ̇| of each arm [rad/s] over the applied steps.")
      .def_ro("min_clear", &ffsr::ScoreTotals::min_clear)
      .def_ro("min_self", &ffsr::ScoreTotals::min_self)
      .def_prop_ro("last_err", [](const ffsr::ScoreTotals& t) {
                     return nb::make_tuple(t.last_err[0], t.last_err[1], t.last_err[2], t.last_err[3]);
                   },
                   "The last sample's EE position, EE attitude, base position and base attitude errors.")
      .def_ro("last_above", &ffsr::ScoreTotals::last_above,
              "The last sample whose EE position error was at or above the tolerance (-1: none).")
      .def("__getstate__",
           [](const ffsr::ScoreTotals& t) {
             std::vector<double> v(sizeof t / sizeof(double));
             std::memcpy(v.data(), &t, sizeof t);
             return copy_out(v.data(), {v.size()});
           })
      .def("__setstate__", [](ffsr::ScoreTotals& t, In state) {
        new (&t) ffsr::ScoreTotals();
        std::memcpy(&t, data_of(state, "state", {sizeof t / sizeof(double)}), sizeof t);
      });
  m.def("score_totals", &score_totals, "rates"_a, "err"_a, "clear"_a, "self"_a, "applied"_a, "danger_deg_s"_a,
        "tolerance_m"_a,
        "The ScoreTotals of a recorded trajectory (rows of rates, errors, clearances; its first `applied` rates "
        "applied), summed as an episode sums them.");
}
