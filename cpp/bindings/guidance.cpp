// Bindings of the online API: Localizer (safenav/localizer.hpp) and Guidance
// (safenav/guidance.hpp).  Per-tick calls take scalars, so that a Python loop
// pays for one call, not for numpy conversions.
#include <cmath>
#include <limits>

#include "common.hpp"
#include "params.hpp"
#include "safenav/guard.hpp"
#include "safenav/guidance.hpp"
#include "safenav/localizer.hpp"

using namespace safenav;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

LandmarkObservation observation(int id, double range, double bearing, double range_std, double bearing_std) {
  LandmarkObservation o;
  o.id = id;
  o.range = range;
  o.bearing = bearing;
  o.range_std = range_std;
  o.bearing_std = bearing_std;
  return o;
}

Eigen::Matrix2d diag2(double a, double b) { return Eigen::Vector2d(a * a, b * b).asDiagonal(); }

/// The input calls shared by Localizer and Guidance (T forwards them).
template <class T, class Class>
void def_inputs(Class& c) {
  c.def(
       "motion", [](T& s, double t, double speed, double heading_change) {
         return s.motion(t, Control(speed, heading_change));
       },
       py::arg("t"), py::arg("speed"), py::arg("heading_change"),
       "Motion input over (t_prev, t]: desired speed [m/s] and heading change [rad] (a BMM step of t - t_prev).")
      .def("odometry", &T::odometry, py::arg("t"), py::arg("distance"), py::arg("heading_change"),
           "Wheel odometry over (t_prev, t]: distance [m] and heading change [rad].")
      .def(
          "observe",
          [](T& s, double t, int id, double range, double bearing, double range_std, double bearing_std) {
            return s.observe(t, observation(id, range, bearing, range_std, bearing_std));
          },
          py::arg("t"), py::arg("id"), py::arg("range") = kNaN, py::arg("bearing") = kNaN, py::arg("range_std") = 1.0,
          py::arg("bearing_std") = 0.05,
          "A landmark observation: range [m] and/or bearing [rad, relative to the heading] (NaN = not measured), "
          "gated on its own.")
      .def(
          "fix",
          [](T& s, double t, double x, double y, const Eigen::Matrix2d& R) {
            return s.fix(t, Eigen::Vector2d(x, y), R);
          },
          py::arg("t"), py::arg("x"), py::arg("y"), py::arg("R"), "A LanBLoc position fix with its covariance R (2x2).")
      .def(
          "speed_heading",
          [](T& s, double t, double speed, double heading, double speed_std, double heading_std) {
            return s.speed_heading(t, Eigen::Vector2d(speed, heading), diag2(speed_std, heading_std));
          },
          py::arg("t"), py::arg("speed"), py::arg("heading"), py::arg("speed_std"), py::arg("heading_std"),
          "An IMU measurement of speed [m/s] and heading [rad] with their sigmas.");
}

}  // namespace

namespace {

/// GuardSettings (guard.hpp).
void bind_guard_settings(py::module_& m) {
  def_params<GuardSettings>(py::class_<GuardSettings>(m, "GuardSettings",
                            "The uncertainty-aware guard (ours): keeps k sigma of position clear of obstacles and "
                            "forbidden hazards by slowing, steering or holding for a fix."))
      .def(py::init<>())
      .def_readwrite("enabled", &GuardSettings::enabled)
      .def_readwrite("k", &GuardSettings::k)
      .def_readwrite("buffer", &GuardSettings::buffer)
      .def_readwrite("look_first", &GuardSettings::look_first)
      .def_readwrite("look_timeout", &GuardSettings::look_timeout)
      .def_readwrite("slow_distance", &GuardSettings::slow_distance)
      .def_readwrite("min_speed_fraction", &GuardSettings::min_speed_fraction)
      .def_readwrite("horizon", &GuardSettings::horizon)
      .def_readwrite("hold_timeout", &GuardSettings::hold_timeout)
      .def_readwrite("max_recoveries", &GuardSettings::max_recoveries)
      .def_readwrite("recovery_speed", &GuardSettings::recovery_speed)
      .def_readwrite("look_range", &GuardSettings::look_range)
      .def_readwrite("look_min_landmarks", &GuardSettings::look_min_landmarks)
      .def_readwrite("field_of_view", &GuardSettings::field_of_view)
      .def_readwrite("occlusion", &GuardSettings::occlusion,
                     "The look ignores landmarks that obstacles hide from the estimate (look_with_camera).")
      .def("look_with_camera", &GuardSettings::look_with_camera, py::arg("field_of_view"), py::arg("max_range"),
           py::arg("min_landmarks"), py::arg("occlusion"),
           "The guard looks with the vehicle's camera: full horizontal field of view [rad] (at most 2 pi), "
           "detection range [m], landmarks a fix needs (at least 1), whether obstacles hide landmarks.")
      .def("validate", &GuardSettings::validate);
}

/// NavigationSettings.
void bind_navigation_settings(py::module_& m) {
  def_params<NavigationSettings>(py::class_<NavigationSettings>(m, "NavigationSettings"))
      .def(py::init<>())
      .def_readwrite("method", &NavigationSettings::method)
      .def_readwrite("cruise_speed", &NavigationSettings::cruise_speed)
      .def_readwrite("arrival_radius", &NavigationSettings::arrival_radius)
      .def_readwrite("max_steps", &NavigationSettings::max_steps)
      .def_readwrite("segments", &NavigationSettings::segments)
      .def_readwrite("lookahead", &NavigationSettings::lookahead)
      .def_readwrite("step_back_speed", &NavigationSettings::step_back_speed)
      .def_readwrite("replan", &NavigationSettings::replan)
      .def_readwrite("sensing_range", &NavigationSettings::sensing_range)
      .def_readwrite("obstacle_check_every", &NavigationSettings::obstacle_check_every)
      .def_readwrite("replan_lookahead", &NavigationSettings::replan_lookahead)
      .def_readwrite("max_replans", &NavigationSettings::max_replans)
      .def_readwrite("planner", &NavigationSettings::planner)
      .def_readwrite("corridor_margin", &NavigationSettings::corridor_margin)
      .def_readwrite("lost_position_std", &NavigationSettings::lost_position_std)
      .def_readwrite("collision_probability", &NavigationSettings::collision_probability,
                     "Acceptable probability of a collision per mission; the guard's k follows from it when guard.k = 0.")
      .def_readwrite("input_timeout", &NavigationSettings::input_timeout,
                     "A command stops the vehicle while the latest motion input or measurement is older than this [s]; "
                     "0 = off.")
      .def_readwrite("filter", &NavigationSettings::filter)
      .def_readwrite("guard", &NavigationSettings::guard)
      .def_readwrite("record", &NavigationSettings::record)
      .def("validate", &NavigationSettings::validate);
}

/// The methods' controls: SafeNav-CHull [SafeNav Alg. 1] and SafeNav-Centroid [SafeNav Alg. 2].
void bind_method_controls(py::module_& m) {
  m.def("centroid_control", &centroid_control, py::arg("segments"), py::arg("estimate"), py::arg("cruise_speed"));
  py::enum_<ChullAction>(m, "ChullAction", "What SafeNav Algorithm 1 (SafeNav-CHull) did with the default command.")
      .value("KEEP", ChullAction::Keep,
             "the default command's prediction lies in hull k or k+1: kept (extended paper's line 13; conference "
             "line 10)")
      .value("CORRECTIVE", ChullAction::Corrective,
             "a corrective control back to the path (extended paper's line 17; conference line 13)")
      .value("STEP_BACK", ChullAction::StepBack, "outside hulls k-1, k and k+1: step back toward the path");
  py::class_<ChullDecision>(m, "ChullDecision")
      .def_readonly("control", &ChullDecision::control)
      .def_readonly("segment", &ChullDecision::segment)
      .def_readonly("action", &ChullDecision::action)
      .def_readonly("predicted", &ChullDecision::predicted);
  m.def("chull_control", &chull_control, py::arg("segments"), py::arg("bmm"), py::arg("estimate"),
        py::arg("cruise_speed"), py::arg("lookahead"), py::arg("step_back_speed"),
        py::arg("obstacles") = static_cast<const ObstacleChecker*>(nullptr));
}

}  // namespace

void pybind_guidance_settings(py::module_& m) {
  m.attr("NAVIGATION_MAX_STEPS") = NavigationSettings::kMaxSteps;
  py::enum_<NavigationMethod>(m, "NavigationMethod")
      .value("CHULL", NavigationMethod::CHull)
      .value("CENTROID", NavigationMethod::Centroid);
  py::class_<NavigationProblem>(m, "NavigationProblem")
      .def(py::init<>())
      .def_readwrite("path", &NavigationProblem::path)
      .def_readwrite("zones", &NavigationProblem::zones)
      .def_readwrite("map", &NavigationProblem::map)
      .def_readwrite("bmm", &NavigationProblem::bmm)
      .def("validate", &NavigationProblem::validate);

  bind_guard_settings(m);
  m.def("guard_k_for_risk", &guard_k_for_risk, py::arg("collision_probability"), py::arg("exposures"),
        "The guard's k for a mission's collision-risk budget eps over N exposures: k = Phi^-1(1 - eps/N) "
        "(a union bound of N one-sided Gaussian tails; docs/safety.md).");
  m.def("path_exposures", &path_exposures, py::arg("path"), py::arg("obstacles"), py::arg("reach"),
        py::arg("exposure_length"), py::arg("step"),
        "N: the arc length of the path (a Corridor) within `reach` of an obstacle of `obstacles`, measured in "
        "steps of `step` metres, per `exposure_length` metres, rounded up, at least 1 (docs/safety.md).");
  bind_navigation_settings(m);
  bind_method_controls(m);
}

namespace {

/// Localizer (localizer.hpp).
void bind_localizer(py::module_& m) {
  py::class_<Localizer> loc(m, "Localizer",
                            "LanBLoc-BMM online (SafeNav eqs. 10-14 over the BMM of eqs. 3-9), ticked with "
                            "timestamped inputs.");
  loc.def(py::init<LocalizerSettings, Landmarks, std::vector<int>>(), py::arg("settings"),
          py::arg("landmarks") = Landmarks(), py::arg("ids") = std::vector<int>())
      .def("initialize", &Localizer::initialize, py::arg("t"), py::arg("x0"), py::arg("P0"))
      .def_property_readonly("initialized", &Localizer::initialized)
      .def_property_readonly("time", &Localizer::time)
      .def_property_readonly("x", &Localizer::x)
      .def_property_readonly("P", &Localizer::P)
      .def_property_readonly("position_std", &Localizer::position_std)
      .def(
          "predict_to",
          [](const Localizer& l, double t) -> py::object {
            State x;
            StateCov P;
            if (!l.predict_to(t, x, P)) return py::none();
            return py::make_tuple(x, P);
          },
          py::arg("t"),
          "(x, P) predicted to t > time as a measurement at t would be, on a copy of the filter; None before "
          "the start or when t <= time")
      .def(
          "set_lag",
          [](Localizer& l, double lag, const std::string& smoother, int iterations) {
            l.set_lag(lag, smoother_kind(smoother), iterations);
          },
          py::arg("lag"), py::arg("smoother") = "rts", py::arg("iterations") = 1,
          "fixed-lag smoothing beside the causal estimate (safenav/smoother.hpp); lag [s] >= 0, EKF only; "
          "smoother 'rts' (a Rauch-Tung-Striebel pass over the filter's linearisation) or 'iterated' (the "
          "window re-linearised: `iterations` Gauss-Newton passes per output, in [1, 100])")
      .def_property_readonly(
          "smoother", [](const Localizer& l) { return std::string(to_string(l.smoother())); },
          "the fixed-lag smoother's kind: 'rts' or 'iterated' ('rts' when off)")
      .def_property_readonly("lag", &Localizer::lag, "the smoother's lag [s], NaN when off")
      .def(
          "take_smoothed",
          [](Localizer& l) {
            const std::vector<SmoothedEstimate> s = l.take_smoothed();
            const auto n = static_cast<Eigen::Index>(s.size());
            Eigen::VectorXd t(n);
            Eigen::MatrixXd x(n, 4), P(n, 16);
            for (Eigen::Index i = 0; i < n; ++i) {
              const SmoothedEstimate& e = s[static_cast<std::size_t>(i)];
              t[i] = e.t;
              x.row(i) = e.x.transpose();
              for (int r = 0; r < 4; ++r) P.block<1, 4>(i, 4 * r) = e.P.row(r);
            }
            return py::make_tuple(t, x, P);
          },
          "(t (n,), x (n, 4), P (n, 16) row-major): the smoothed estimates final since the last call")
      .def("finish_smoothing", &Localizer::finish_smoothing,
           "end of data: smooth every estimate not yet final with all the data")
      .def_property_readonly("last_motion_time", &Localizer::last_motion_time,
                             "time of the newest motion input that was not late (NaN: none)")
      .def_property_readonly("last_measurement_time", &Localizer::last_measurement_time,
                             "time of the newest measurement that was not late (NaN: none)")
      .def_property_readonly(
          "augmented",
          [](const Localizer& l) -> py::object {
            Eigen::VectorXd a = l.augmented_state();
            if (a.size() == 0) return py::none();
            return py::cast(a);
          },
          "The full augmented state (x, y, v, theta, [k], [beta], [b_j]), or None without augmented states.")
      .def_property_readonly("counts", &Localizer::counts)
      .def("reason", &Localizer::reason,
           "Why it has not started ('waiting: ...': what the recent data hold, what a start needs, the last "
           "fit's verdict), or how it started ('started at t = ...').")
      .def_property_readonly("settings", &Localizer::settings)
      .def_property_readonly("landmarks", &Localizer::landmarks)
      .def("landmark_index", &Localizer::landmark_index, py::arg("id"));
  def_inputs<Localizer>(loc);
}

/// Guidance, its status, events and commands.
void bind_guidance(py::module_& m) {
  py::enum_<GuidanceStatus>(m, "GuidanceStatus")
      .value("INITIALIZING", GuidanceStatus::Initializing)
      .value("GUIDING", GuidanceStatus::Guiding)
      .value("ARRIVED", GuidanceStatus::Arrived)
      .value("NO_PATH", GuidanceStatus::NoPath)
      .value("LOST_LOCALIZATION", GuidanceStatus::LostLocalization)
      .value("STALE_INPUT", GuidanceStatus::StaleInput)
      .value("BLOCKED", GuidanceStatus::Blocked);
  m.attr("EVENT_DETOUR_PLANNED") = static_cast<unsigned>(kDetourPlanned);
  m.attr("EVENT_PATH_SPLICED") = static_cast<unsigned>(kPathSpliced);
  m.attr("EVENT_NO_PATH") = static_cast<unsigned>(kNoPath);
  m.attr("EVENT_LOST_LOCALIZATION") = static_cast<unsigned>(kLostLocalization);
  m.attr("EVENT_ARRIVED") = static_cast<unsigned>(kArrived);
  m.attr("EVENT_GUARD_SLOW") = static_cast<unsigned>(kGuardSlow);
  m.attr("EVENT_GUARD_STEER") = static_cast<unsigned>(kGuardSteer);
  m.attr("EVENT_GUARD_HOLD") = static_cast<unsigned>(kGuardHold);
  m.attr("EVENT_STALE_INPUT") = static_cast<unsigned>(kStaleInput);
  m.attr("EVENT_GUARD_RECOVER") = static_cast<unsigned>(kGuardRecover);
  m.attr("EVENT_BLOCKED") = static_cast<unsigned>(kBlocked);

  py::class_<Command>(m, "Command")
      .def_property_readonly("speed", [](const Command& c) { return c.control[0]; })
      .def_property_readonly("heading_change", [](const Command& c) { return c.control[1]; })
      .def_readonly("control", &Command::control)
      .def_readonly("status", &Command::status)
      .def_readonly("events", &Command::events)
      .def_readonly("segment", &Command::segment)
      .def_readonly("position_std", &Command::position_std)
      .def_readonly("action", &Command::action)
      .def_readonly("predicted", &Command::predicted)
      .def_readonly("clearance", &Command::clearance)
      .def_readonly("guard_margin", &Command::guard_margin)
      .def_readonly("input_age", &Command::input_age,
                    "t minus the older of the latest motion input's and measurement's times [s] (the watchdog's).")
      .def("__repr__", [](const Command& c) {
        return "Command(speed=" + std::to_string(c.control[0]) + ", heading_change=" + std::to_string(c.control[1]) +
               ", status=" + to_string(c.status) + ", events=" + std::to_string(c.events) +
               ", segment=" + std::to_string(c.segment) + ")";
      });

  py::class_<Guidance> g(m, "Guidance",
                         "SafeNav guidance ticked by a vehicle's loop: SafeNav-CHull or -Centroid (SafeNav Algorithms "
                         "1-2) with obstacle checks and RAw-RRT* detours (extended paper's Algorithm 4).");
  g.def(py::init<NavigationProblem, NavigationSettings, LocalizerSettings, Landmarks, std::vector<int>, std::uint64_t>(),
        py::arg("problem"), py::arg("settings"), py::arg("localizer") = LocalizerSettings(),
        py::arg("landmarks") = Landmarks(), py::arg("ids") = std::vector<int>(), py::arg("seed") = 0)
      .def_static("planned", &Guidance::planned, py::arg("planning"), py::arg("planner"), py::arg("problem"),
                  py::arg("settings"), py::arg("localizer") = LocalizerSettings(), py::arg("landmarks") = Landmarks(),
                  py::arg("ids") = std::vector<int>(), py::arg("seed") = 0)
      .def("fresh", &Guidance::fresh, py::arg("seed"))
      .def_property_readonly("localizer", py::overload_cast<>(&Guidance::localizer),
                             py::return_value_policy::reference_internal)
      .def("command", &Guidance::command, py::arg("t"))
      .def_property_readonly("status", &Guidance::status)
      .def("nominal_trajectory", &Guidance::nominal_trajectory, py::arg("max_steps"),
           "The states (rows x, y, v, theta) of the vehicle driven by the method without noise, from the safe "
           "path's start to arrival or max_steps (no guard, no detours).")
      .def_property_readonly("safe_path", &Guidance::safe_path, py::return_value_policy::reference_internal)
      .def_property_readonly(
          "path", [](const Guidance& g) { return Points2(g.path().corridor().path()); },
          "The path now followed, with detours spliced in (a copy).")
      .def_property_readonly("replans", &Guidance::replans)
      .def_property_readonly("commands", &Guidance::commands)
      .def_property_readonly("detail", &Guidance::detail)
      .def_property_readonly("problem", &Guidance::problem)
      .def_property_readonly("settings", &Guidance::settings)
      .def_property_readonly("guard_k", &Guidance::guard_k,
                             "The guard's k in use: the one given, or the risk budget's (guard_k_for_risk).")
      .def_property_readonly("guard_exposures", &Guidance::guard_exposures,
                             "N, the exposures of the safe path (path_exposures) behind the risk budget's k.");
  def_inputs<Guidance>(g);
}

}  // namespace

void pybind_guidance(py::module_& m) {
  py::enum_<InputStatus>(m, "InputStatus", "What became of one input to the online localizer.")
      .value("APPLIED", InputStatus::Applied)
      .value("REJECTED", InputStatus::Rejected)
      .value("LATE", InputStatus::Late)
      .value("BUFFERED", InputStatus::Buffered)
      .value("IGNORED", InputStatus::Ignored)
      .value("RESET", InputStatus::Reset);

  py::class_<InputResult>(m, "InputResult")
      .def_readonly("status", &InputResult::status)
      .def_readonly("nis", &InputResult::nis)
      .def_readonly("log_det_s", &InputResult::log_det_s)
      .def_readonly("dim", &InputResult::dim)
      .def_property_readonly("applied", &InputResult::applied)
      .def("__repr__", [](const InputResult& r) {
        return std::string("InputResult(") + to_string(r.status) + ", nis=" + std::to_string(r.nis) +
               ", dim=" + std::to_string(r.dim) + ")";
      });

  def_params<LocalizerSettings>(py::class_<LocalizerSettings>(m, "LocalizerSettings"))
      .def(py::init<>())
      .def_readwrite("bmm", &LocalizerSettings::bmm)
      .def_readwrite("filter", &LocalizerSettings::filter)
      .def_readwrite("init_window", &LocalizerSettings::init_window)
      .def_readwrite("init_baseline", &LocalizerSettings::init_baseline)
      .def_readwrite("init_speed_std", &LocalizerSettings::init_speed_std)
      .def_readwrite("reset_after_rejections", &LocalizerSettings::reset_after_rejections)
      .def_readwrite("reset_after_consistent", &LocalizerSettings::reset_after_consistent)
      .def_readwrite("reset_discredit_tail", &LocalizerSettings::reset_discredit_tail)
      .def_readwrite("max_delay", &LocalizerSettings::max_delay)
      .def_readwrite("augment", &LocalizerSettings::augment,
                     "AugmentedStates: with any on (and the EKF) the localizer runs the AugmentedEkf.")
      .def("validate", &LocalizerSettings::validate);

  py::class_<LocalizerCounts>(m, "LocalizerCounts")
      .def_readonly("motion", &LocalizerCounts::motion)
      .def_readonly("applied", &LocalizerCounts::applied)
      .def_readonly("rejected", &LocalizerCounts::rejected)
      .def_readonly("resets", &LocalizerCounts::resets)
      .def_readonly("late", &LocalizerCounts::late)
      .def_readonly("buffered", &LocalizerCounts::buffered)
      .def_readonly("ignored", &LocalizerCounts::ignored);

  bind_localizer(m);
  bind_guidance(m);
}
