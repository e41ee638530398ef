#include <pybind11/numpy.h>

#include "common.hpp"
#include "params.hpp"
#include "safenav/navigation.hpp"

using namespace safenav;

namespace {

py::dict metrics_dict(const TrialMetrics& m) {
  py::dict d;
  d["path_ade"] = m.path_ade;
  d["goal_fde"] = m.goal_fde;
  d["path_error_percent"] = m.path_error_percent;
  d["awrs"] = m.awrs;
  d["awrs_true"] = m.awrs_true;
  d["truth_ade"] = m.truth_ade;
  d["truth_fde"] = m.truth_fde;
  d["max_deviation"] = m.max_deviation;
  return d;
}

}  // namespace

void pybind_navigation(py::module_& m) {
  m.attr("NAVIGATION_MAX_STEPS") = NavigationSettings::kMaxSteps;
  py::enum_<NavigationMethod>(m, "NavigationMethod")
      .value("CHULL", NavigationMethod::CHull)
      .value("CENTROID", NavigationMethod::Centroid);
  py::enum_<TrialOutcome>(m, "TrialOutcome")
      .value("ARRIVED", TrialOutcome::Arrived)
      .value("COLLISION", TrialOutcome::Collision)
      .value("LEFT_CORRIDOR", TrialOutcome::LeftCorridor)
      .value("STEP_LIMIT", TrialOutcome::StepLimit)
      .value("LOST_LOCALIZATION", TrialOutcome::LostLocalization)
      .value("NO_PATH", TrialOutcome::NoPath);
  m.def("outcome_name", [](TrialOutcome o) { return to_string(o); });

  def_params<SensorSettings>(py::class_<SensorSettings>(m, "SensorSettings"))
      .def(py::init<>())
      .def_readwrite("position", &SensorSettings::position)
      .def_readwrite("landmarks", &SensorSettings::landmarks)
      .def_readwrite("max_range", &SensorSettings::max_range)
      .def_readwrite("field_of_view", &SensorSettings::field_of_view)
      .def_readwrite("min_landmarks", &SensorSettings::min_landmarks)
      .def_readwrite("position_every", &SensorSettings::position_every)
      .def_readwrite("imu", &SensorSettings::imu)
      .def_readwrite("imu_speed_std", &SensorSettings::imu_speed_std)
      .def_readwrite("imu_heading_std", &SensorSettings::imu_heading_std)
      .def("validate", &SensorSettings::validate)
      .def("landmarks_in_view", &SensorSettings::landmarks_in_view, py::arg("state"));

  py::class_<NavigationProblem>(m, "NavigationProblem")
      .def(py::init<>())
      .def_readwrite("path", &NavigationProblem::path)
      .def_readwrite("zones", &NavigationProblem::zones)
      .def_readwrite("map", &NavigationProblem::map)
      .def_readwrite("bmm", &NavigationProblem::bmm)
      .def("validate", &NavigationProblem::validate);

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
      .def_readwrite("filter", &NavigationSettings::filter)
      .def_readwrite("record", &NavigationSettings::record)
      .def("validate", &NavigationSettings::validate);

  py::class_<TrialResult>(m, "TrialResult")
      .def_property_readonly("outcome", [](const TrialResult& r) { return r.outcome; })
      .def_property_readonly("outcome_name", [](const TrialResult& r) { return to_string(r.outcome); })
      .def_readonly("success", &TrialResult::success)
      .def_readonly("reason", &TrialResult::reason)
      .def_readonly("steps", &TrialResult::steps)
      .def_readonly("replans", &TrialResult::replans)
      .def_readonly("position_fixes", &TrialResult::position_fixes)
      .def_readonly("dropouts", &TrialResult::dropouts)
      .def_readonly("rejected", &TrialResult::rejected)
      .def_readonly("chull_default", &TrialResult::chull_default)
      .def_readonly("chull_corrective", &TrialResult::chull_corrective)
      .def_readonly("chull_step_back", &TrialResult::chull_step_back)
      .def_readonly("wall_time", &TrialResult::wall_time)
      .def_property_readonly("metrics", [](const TrialResult& r) { return metrics_dict(r.metrics); })
      .def_readonly("truth", &TrialResult::truth)
      .def_readonly("estimate", &TrialResult::estimate)
      .def_readonly("predicted", &TrialResult::predicted)
      .def_readonly("measured", &TrialResult::measured)
      .def_readonly("controls", &TrialResult::controls)
      .def_readonly("position_std", &TrialResult::position_std)
      .def_readonly("followed_path", &TrialResult::followed_path);

  py::class_<Navigator>(m, "Navigator",
                        "Runs SafeNav trials (SafeNav Algorithms 1 and 2; the extended paper's Algorithm 4) on one "
                        "problem.")
      .def(py::init<NavigationProblem, NavigationSettings, SensorSettings>(), py::arg("problem"),
           py::arg("settings"), py::arg("sensors"))
      .def_property_readonly("problem", &Navigator::problem)
      .def_property_readonly("settings", &Navigator::settings)
      .def_property_readonly("sensors", &Navigator::sensors)
      .def_property_readonly("segments", &Navigator::segments, py::return_value_policy::reference_internal)
      .def_property_readonly("max_steps", &Navigator::max_steps)
      .def(
          "run",
          [](const Navigator& nav, std::uint64_t seed, py::object position) {
            py::gil_scoped_release release;
            if (position.is_none()) return nav.run(seed);
            // position(truth (4,), step) -> None (no fix) or (z (2,), R (2, 2)).
            PositionCallback cb = [&position](const State& x, int step, Eigen::Vector2d& z, Eigen::Matrix2d& R) {
              py::gil_scoped_acquire acquire;
              py::object out = position(x, step);
              if (out.is_none()) return false;
              auto t = out.cast<py::tuple>();
              if (t.size() != 2)
                throw py::value_error("position callback must return None or (z, R), got a tuple of " +
                                      std::to_string(t.size()));
              z = t[0].cast<Eigen::Vector2d>();
              R = t[1].cast<Eigen::Matrix2d>();
              return true;
            };
            return nav.run(seed, cb);
          },
          py::arg("seed"), py::arg("position") = py::none(),
          "One trial.  `position`, when given, is called as position(truth, step) and returns None (no fix) or "
          "(z, R); it replaces the measurement-level source (e.g. the camera-in-the-loop pipeline).")
      .def(
          "run_many",
          [](const Navigator& nav, const std::vector<std::uint64_t>& seeds) {
            std::vector<TrialResult> rs;
            {
              py::gil_scoped_release release;
              rs = nav.run_many(seeds);
            }
            const auto n = static_cast<py::ssize_t>(rs.size());
            py::array_t<int> outcome(n), steps(n), replans(n), fixes(n), dropouts(n), rejected(n), cdef(n), ccor(n),
                cback(n);
            py::array_t<double> path_ade(n), goal_fde(n), perr(n), awrs(n), awrs_true(n), truth_ade(n), truth_fde(n),
                maxdev(n), wall(n);
            for (py::ssize_t i = 0; i < n; ++i) {
              const TrialResult& r = rs[static_cast<std::size_t>(i)];
              outcome.mutable_at(i) = static_cast<int>(r.outcome);
              steps.mutable_at(i) = r.steps;
              replans.mutable_at(i) = r.replans;
              fixes.mutable_at(i) = r.position_fixes;
              dropouts.mutable_at(i) = r.dropouts;
              rejected.mutable_at(i) = r.rejected;
              cdef.mutable_at(i) = r.chull_default;
              ccor.mutable_at(i) = r.chull_corrective;
              cback.mutable_at(i) = r.chull_step_back;
              path_ade.mutable_at(i) = r.metrics.path_ade;
              goal_fde.mutable_at(i) = r.metrics.goal_fde;
              perr.mutable_at(i) = r.metrics.path_error_percent;
              awrs.mutable_at(i) = r.metrics.awrs;
              awrs_true.mutable_at(i) = r.metrics.awrs_true;
              truth_ade.mutable_at(i) = r.metrics.truth_ade;
              truth_fde.mutable_at(i) = r.metrics.truth_fde;
              maxdev.mutable_at(i) = r.metrics.max_deviation;
              wall.mutable_at(i) = r.wall_time;
            }
            py::list reasons;
            for (const auto& r : rs) reasons.append(r.reason);
            py::dict d;
            d["outcome"] = outcome;
            d["reason"] = reasons;
            d["steps"] = steps;
            d["replans"] = replans;
            d["position_fixes"] = fixes;
            d["dropouts"] = dropouts;
            d["rejected"] = rejected;
            d["chull_default"] = cdef;
            d["chull_corrective"] = ccor;
            d["chull_step_back"] = cback;
            d["path_ade"] = path_ade;
            d["goal_fde"] = goal_fde;
            d["path_error_percent"] = perr;
            d["awrs"] = awrs;
            d["awrs_true"] = awrs_true;
            d["truth_ade"] = truth_ade;
            d["truth_fde"] = truth_fde;
            d["max_deviation"] = maxdev;
            d["time_s"] = wall;
            return d;
          },
          py::arg("seeds"),
          "Trials for each seed (measurement-level source), metrics only, as a dict of arrays.  Releases the GIL.");

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
