// Bindings of the closed loop, one episode's decisions and batches of episodes on threads.
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

nb::tuple run(const ffsr::Robot& robot, const ffsr::PlannerSettings& s, In x, long k0, long n_total, long n_max,
              In residual, bool stop_on_violation, bool record_only, const ffsr::Robot* plant) {
  if (k0 < 0 || n_total < k0 || n_max < 0)
    throw nb::value_error("steps: allowed 0 <= k0 <= n_total and n_max >= 0");
  check_settings(s, n_total);
  auto st = std::make_unique<ffsr::LoopState>();
  load_state(x, *st, s);
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
    check_settings(s, n_total);
    load_state(x0, e->loop, s);
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

void bind_episode(nb::module_& m) {
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
  nb::class_<EpisodeBatch>(m, "EpisodeBatch", "Episodes advanced together, one decision each per call, on threads.")
      .def(nb::init<std::vector<NativeEpisode*>, int>(), "episodes"_a, "threads"_a = 1, nb::keep_alive<1, 2>())
      .def("decide", &EpisodeBatch::decide, "actions"_a, "active"_a, "k"_a, "mode"_a, "n_max"_a, "obs"_a, "out"_a,
           "One decision for every active episode from its step k (advanced in place); out (N, 7): rows, status, "
           "clipped, increment, cost, clearance, EE error; obs (N, 53 or 59) float32, written in place.");
}
