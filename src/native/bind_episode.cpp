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
#include "ffsr/totals.hpp"

using namespace nb::literals;
using namespace ffsr_bindings;

namespace {

// The log fields of an episode, their widths (0: one float per row, the array one-dimensional).
constexpr const char* kLogNames[10] = {"x", "v", "dq", "err", "clear", "self", "mu", "cdf", "smin", "tau"};
constexpr size_t kLogWidths[10] = {19, 18, 12, 4, 0, 0, 2, 2, 2, 12};

// The ten log arrays of a dict (float64, C order, at least `rows` rows each, or exactly with `exact`) into their
// first-row pointers.
void log_arrays(const nb::dict& logs, size_t rows, double* out[10], bool exact = false) {
  for (size_t f = 0; f < 10; ++f) {
    if (!logs.contains(kLogNames[f]))
      throw nb::value_error((std::string("logs: no '") + kLogNames[f] + "'; allowed: a dict of the ten log arrays")
                                .c_str());
    auto array = nb::cast<nb::ndarray<double, nb::c_contig, nb::device::cpu>>(logs[kLogNames[f]]);
    const size_t have = array.ndim() > 0 ? array.shape(0) : 0;
    if (kLogWidths[f] == 0)
      check_shape(array, kLogNames[f], {have});
    else
      check_shape(array, kLogNames[f], {have, kLogWidths[f]});
    if (have < rows || (exact && have != rows))
      throw nb::value_error((std::string("logs['") + kLogNames[f] + "']: " + std::to_string(have) + " rows; allowed: " +
                             (exact ? "n_total + 1 = " : "at least ") + std::to_string(rows)).c_str());
    out[f] = array.data();
  }
}

// An observation's length n_obs, checked: 53, 59, or 76 (which needs a commanded approach).
int checked_observation(int n_obs, const ffsr::PlannerSettings& s) {
  if (n_obs != ffsr::kObservation && n_obs != ffsr::kObservationTwist && n_obs != ffsr::kObservationCapture)
    throw nb::value_error("obs: allowed a float32 array of 53, 59 or 76 per copy");
  if (n_obs == ffsr::kObservationCapture && !s.timing.enabled)
    throw nb::value_error("obs: 76 floats show a commanded approach's grasp frame; these settings have none");
  return n_obs;
}

// The closed loop from step k0; its rows go into `logs` (the ten arrays, from their first row) or new arrays.
using Timing = nb::ndarray<double, nb::c_contig, nb::device::cpu>;

nb::tuple run(const ffsr::Robot& robot, const ffsr::PlannerSettings& s, In x, long k0, long n_total, long n_max,
              In residual, bool stop_on_violation, bool record_only, const ffsr::Robot* plant,
              std::optional<nb::dict> logs, std::optional<Timing> timing) {
  if (k0 < 0 || n_total < k0 || n_max < 0)
    throw nb::value_error("steps: allowed 0 <= k0 <= n_total and n_max >= 0");
  check_settings(s, n_total);
  auto st = std::make_unique<ffsr::LoopState>();
  load_state(x, *st, s);
  if (s.timing.enabled && !timing)
    throw nb::value_error("timing: a commanded approach needs its state (5: command, s, s_dot, w, w_dot)");
  if (timing) load_timing(data_of(*timing, "timing", {ffsr::kTimingState}), st->p.timing);
  const size_t n = record_only ? 1 : static_cast<size_t>(std::max(0L, std::min(n_max, n_total - k0)));
  nb::dict out;
  double* field[10];
  if (logs) {
    log_arrays(*logs, n, field);
    out = *logs;
  } else {
    for (size_t f = 0; f < 10; ++f)
      out[kLogNames[f]] = kLogWidths[f] == 0 ? zeros({n}, field[f]) : zeros({n, kLogWidths[f]}, field[f]);
  }
  const ffsr::LogRows rows_out{field[0], field[1], field[2], field[3], field[4],
                               field[5], field[6], field[7], field[8], field[9]};
  long rows = 0;
  ffsr::Status status;
  {
    nb::gil_scoped_release release;
    status = ffsr::run(robot, plant ? *plant : robot, s, *st, k0, n_total, n_max, data_of(residual, "residual", {12}),
                       stop_on_violation, record_only, false, rows_out, rows);
  }
  if (timing) timing_values(st->p.timing, timing->data());
  return nb::make_tuple(state_out(*st), rows, static_cast<int>(status), out);
}

// One environment episode on the native kernel: the robot (and plant) it steps, its settings, its state and score
// totals, and its log: the caller's numpy arrays of n_total + 1 rows (the last for the final sample), or none (one
// scratch row of its own, written over at every step).
struct NativeEpisode {
  const ffsr::Robot* robot;
  const ffsr::Robot* plant;
  ffsr::PlannerSettings s;
  ffsr::DecisionSettings d;
  std::unique_ptr<ffsr::EpisodeState> e = std::make_unique<ffsr::EpisodeState>();
  long n_total;
  std::vector<double> scratch;  // the row of an episode without a log
  double* log[10] = {};
  nb::object keep;  // the caller's log arrays, alive as long as the episode

  NativeEpisode(const ffsr::Robot& robot_, const ffsr::PlannerSettings& s_, const ffsr::DecisionSettings& d_, In x0,
                long n_total_, const ffsr::Robot* plant_, std::optional<nb::dict> logs)
      : robot(&robot_), plant(plant_ ? plant_ : &robot_), s(s_), d(d_), n_total(n_total_) {
    if (n_total < 1) throw nb::value_error("n_total: allowed >= 1 step");
    check_settings(s, n_total);
    load_state(x0, e->loop, s);
    e->totals.danger_deg_s = d.danger_rate_deg_s, e->totals.tolerance_m = d.tolerance_m;
    if (!logs) {
      size_t total = 0;
      for (size_t f = 0; f < 10; ++f) total += std::max<size_t>(kLogWidths[f], 1);
      scratch.assign(total, 0.0);
      double* next = scratch.data();
      for (size_t f = 0; f < 10; ++f) log[f] = next, next += std::max<size_t>(kLogWidths[f], 1);
      return;
    }
    log_arrays(*logs, static_cast<size_t>(n_total) + 1, log, true);  // exactly the episode's rows
    keep = *logs;
  }

  bool recording() const { return scratch.empty(); }

  ffsr::LogRows rows_from(long k) const {
    const size_t r = recording() ? static_cast<size_t>(k) : 0;
    return ffsr::LogRows{log[0] + 19 * r, log[1] + 18 * r, log[2] + 12 * r, log[3] + 4 * r, log[4] + r, log[5] + r,
                         log[6] + 2 * r, log[7] + 2 * r, log[8] + 2 * r, log[9] + 12 * r, recording() ? 1L : 0L};
  }

  int observation_size(const nb::ndarray<float, nb::c_contig, nb::device::cpu>& obs) const {
    return checked_observation(obs.ndim() == 1 ? static_cast<int>(obs.shape(0)) : 0, s);
  }

  void check_step(long k) const {
    if (k < 0 || k > n_total) throw nb::value_error("k: allowed 0 <= k <= n_total");
  }

  nb::tuple decide(In action, int mode, bool stop, long k, long n_max,
                   nb::ndarray<float, nb::c_contig, nb::device::cpu> obs) {
    if (mode < 0 || mode > 2) throw nb::value_error("mode: allowed 0 (residual), 1 (parameters) or 2 (set)");
    check_step(k);
    if (n_max < 0) throw nb::value_error("n_max: allowed >= 0");
    if (action.ndim() != 1) throw nb::value_error("action: allowed a 1-d array");
    const int n_action = static_cast<int>(action.shape(0));
    const int n_obs = observation_size(obs);
    ffsr::DecisionResult out;
    {
      nb::gil_scoped_release release;
      out = ffsr::decide(*robot, *plant, s, d, *e, k, n_total, n_max, action.data(), n_action,
                         static_cast<ffsr::ActionMode>(mode), stop, rows_from(k), obs.data(), n_obs);
    }
    return nb::make_tuple(out.rows, out.status, out.clipped, out.increment, out.cost, out.clearance, out.ee_error);
  }

  nb::tuple observe(long k, nb::ndarray<float, nb::c_contig, nb::device::cpu> obs) {
    check_step(k);
    const int n_obs = observation_size(obs);
    double clearance = 0.0, ee_error = 0.0;
    ffsr::observation(*robot, s, *e, k, n_total, obs.data(), n_obs, clearance, ee_error);
    return nb::make_tuple(clearance, ee_error);
  }

  void set_parameters(double m, double T_c) {
    if (!(m > 0.0 && m < 1.0) || !(T_c > 0.0)) throw nb::value_error("(m, T_c): allowed 0 < m < 1 and T_c > 0 s");
    s.m = m, s.T_c = T_c;
  }

  void finish(long k) {
    check_step(k);
    if (e->totals.samples != k)
      throw nb::value_error("k: allowed the episode's next sample (finish once, after its last decision)");
    ffsr::finish(*robot, *plant, s, *e, k, n_total, rows_from(k));
  }
};

// Episodes advanced together: one slot per copy, each holding an episode (set when the copy resets); one
// decision each per call, on threads, the GIL released.
struct EpisodeBatch {
  std::vector<NativeEpisode*> episodes;
  std::vector<nb::object> keep;  // the slots' episodes, alive as long as they are in the batch
  int threads;

  EpisodeBatch(size_t n, int threads_) : episodes(n, nullptr), keep(n), threads(threads_) {
    if (n < 1) throw nb::value_error("n: allowed at least one slot");
    if (threads < 1) throw nb::value_error("threads: allowed >= 1");
  }

  void set(size_t slot, nb::handle episode) {
    if (slot >= episodes.size()) throw nb::value_error("slot: allowed 0 to n - 1");
    NativeEpisode* ep = nb::cast<NativeEpisode*>(episode);
    for (size_t e = 0; e < episodes.size(); ++e)
      if (e != slot && episodes[e] == ep) throw nb::value_error("episode: allowed in one slot only");
    episodes[slot] = ep;
    keep[slot] = nb::borrow(episode);
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
    for (size_t e = 0; e < n; ++e)
      if (episodes[e]) checked_observation(static_cast<int>(n_obs), episodes[e]->s);
    check_shape(obs, "obs", {n, n_obs});
    check_shape(out, "out", {n, 7});
    if (mode < 0 || mode > 2) throw nb::value_error("mode: allowed 0 (residual), 1 (parameters) or 2 (set)");
    for (size_t e = 0; e < n; ++e)
      if (active.data()[e] && !episodes[e])
        throw nb::value_error(("active[" + std::to_string(e) + "]: slot without an episode; set it first").c_str());
    for (size_t e = 0; e < n; ++e)
      if (episodes[e] && (k.data()[e] < 0 || k.data()[e] > episodes[e]->n_total))
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
        const ffsr::DecisionResult d = ffsr::decide(*ep.robot, *ep.plant, ep.s, ep.d, *ep.e, steps[e], ep.n_total,
                                                    n_max, a + width * e, static_cast<int>(width),
                                                    static_cast<ffsr::ActionMode>(mode), true, ep.rows_from(steps[e]), o + n_obs * e,
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
        "stop_on_violation"_a = true, "record_only"_a = false, "plant"_a = nb::none(), "logs"_a = nb::none(),
        "timing"_a = nb::none(),
        "The closed loop on the kinematic plant from step k0: (x after, rows, status 0 ok / 1 rate / 2 collision / "
        "3 non-finite, logs of one row per step). plant: the robot the physics integrates, if not robot itself; "
        "logs: the ten log arrays to write the rows into (from their first row; new arrays without); timing: a "
        "commanded approach's state (5: command, s, ṡ, w, ẇ; float64), read and then written with the state after.");
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
      .def_rw("V_ref", &ffsr::DecisionSettings::V_ref)
      .def_rw("danger_rate_deg_s", &ffsr::DecisionSettings::danger_rate_deg_s)
      .def_rw("tolerance_m", &ffsr::DecisionSettings::tolerance_m)
      .def_rw("command_action", &ffsr::DecisionSettings::command_action,
              "Whether the action's last entry a in [-1, 1] commands the approach, u = a + 1 (docs/model.md §23).");
  nb::class_<NativeEpisode>(m, "Episode", "One environment episode on the native kernel.")
      .def(nb::init<const ffsr::Robot&, const ffsr::PlannerSettings&, const ffsr::DecisionSettings&, In, long,
                    const ffsr::Robot*, std::optional<nb::dict>>(),
           "robot"_a, "settings"_a, "decision"_a, "x"_a, "n_total"_a, "plant"_a = nb::none(), "logs"_a = nb::none(),
           nb::keep_alive<1, 2>(), nb::keep_alive<1, 7>(),
           "logs: a dict of the ten log arrays (float64, C order, n_total + 1 rows: x 19, v 18, dq 12, err 4, "
           "clear, self, mu 2, cdf 2, smin 2, tau 12) to write into; without, the episode keeps no log (its "
           "totals only).")
      .def("decide", &NativeEpisode::decide, "action"_a, "mode"_a, "stop"_a, "k"_a, "n_max"_a, "obs"_a,
           "One decision from step k: (rows, status, clipped, increment, cost, clearance, EE error); the next "
           "observation into obs (float32, 53, 59 or 76). Status 5: captured (a judge that stops at capture; the "
           "last row is the episode's final sample).")
      .def("observe", &NativeEpisode::observe, "k"_a, "obs"_a,
           "The observation at step k into obs (float32, 53, 59 or 76): (clearance [m], EE position error [m]).")
      .def("set_parameters", &NativeEpisode::set_parameters, "m"_a, "T_c"_a, "(m, T_c [s]) from the next step on.")
      .def("finish", &NativeEpisode::finish, "k"_a,
           "Record the final sample at step k (the rates there are not applied): into the log, and the totals.")
      .def_prop_rw(
          "totals", [](const NativeEpisode& ep) { return ep.e->totals; },
          [](NativeEpisode& ep, const ffsr::ScoreTotals& t) { ep.e->totals = t; },
          "The episode's score terms so far (a copy; set: a pickled episode's).")
      .def_prop_ro("recording", &NativeEpisode::recording, "Whether the episode writes a log of every step.")
      .def_prop_rw(
          "timing",
          [](const NativeEpisode& ep) {
            double values[ffsr::kTimingState];
            timing_values(ep.e->loop.p.timing, values);
            return copy_out(values, {ffsr::kTimingState});
          },
          [](NativeEpisode& ep, In values) {
            load_timing(data_of(values, "timing", {ffsr::kTimingState}), ep.e->loop.p.timing);
            ep.e->planned = false;
          },
          nb::rv_policy::move,
          "A commanded approach's state (5: command, s, ṡ, w, ẇ; a copy); set: a pickled episode's, or a new "
          "command.")
      .def(
          "judge_capture",
          [](NativeEpisode& ep, In bounds, double hold_s, double contact_m, bool stop) {
            ep.e->capture = ffsr::CaptureJudge();
            ep.e->capture.rule = capture_rule(ep.s, bounds, hold_s, contact_m);
            ep.e->capture.rule.stop = stop;
          },
          "bounds"_a, "hold_s"_a, "contact_m"_a = 0.0, "stop"_a = false,
          "Judge capture at every sample from now on (a commanded approach's episode; docs/model.md §23): bounds on "
          "position [m], attitude [rad], linear [m/s] and angular velocity [rad/s], held for hold_s [s]; contact_m: "
          "the distance at which the relative speed of first contact is read (0: none); stop: end the episode at "
          "its capture (a decision's status 5).")
      .def_prop_ro("capture", [](const NativeEpisode& ep) { return judge_dict(ep.e->capture); },
                   "What the capture judge says so far (capture_of's dict).")
      .def_prop_rw(
          "capture_state", [](const NativeEpisode& ep) { return judge_state(ep.e->capture); },
          [](NativeEpisode& ep, In state) { load_judge(ep.e->capture, state); }, nb::rv_policy::move,
          "The capture judge's state as floats (set: a pickled episode's).")
      .def("state", [](const NativeEpisode& ep) { return state_out(ep.e->loop); }, "The state x (40, a copy).")
      .def_prop_rw(
          "last_rates", [](const NativeEpisode& ep) { return copy_out(ep.e->last_rates, {12}); },
          [](NativeEpisode& ep, In rates) {
            std::memcpy(ep.e->last_rates, data_of(rates, "last_rates", {12}), sizeof ep.e->last_rates);
          },
          nb::rv_policy::move, "The joint rates applied last [rad/s] (12): what the next decision's variation starts from.")
      .def_prop_ro("m", [](const NativeEpisode& ep) { return ep.s.m; })
      .def_prop_ro("T_c", [](const NativeEpisode& ep) { return ep.s.T_c; });
  nb::class_<EpisodeBatch>(m, "EpisodeBatch", "Episodes advanced together, one decision each per call, on threads.")
      .def(nb::init<size_t, int>(), "n"_a, "threads"_a = 1)
      .def("set", &EpisodeBatch::set, "slot"_a, "episode"_a, "Put an episode into a slot (a copy's reset).")
      .def("decide", &EpisodeBatch::decide, "actions"_a, "active"_a, "k"_a, "mode"_a, "n_max"_a, "obs"_a, "out"_a,
           "One decision for every active episode from its step k (advanced in place); out (N, 7): rows, status, "
           "clipped, increment, cost, clearance, EE error; obs (N, 53 or 59) float32, written in place.");
}
