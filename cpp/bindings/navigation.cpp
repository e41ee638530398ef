#include <pybind11/numpy.h>

#include <map>

#include "common.hpp"
#include "params.hpp"
#include "safenav/navigation.hpp"

using namespace safenav;

// bindings/guidance.cpp: guidance.hpp's method, problem and settings.
void pybind_guidance_settings(py::module_& m);

namespace {

// The per-trial numbers, named once: metrics (TrialMetrics) and counts (TrialResult).
struct MetricField {
  const char* name;
  double TrialMetrics::*member;
};
constexpr MetricField kMetrics[] = {
    {"path_ade", &TrialMetrics::path_ade},         {"goal_fde", &TrialMetrics::goal_fde},
    {"path_error_percent", &TrialMetrics::path_error_percent},
    {"awrs", &TrialMetrics::awrs},                 {"awrs_true", &TrialMetrics::awrs_true},
    {"truth_ade", &TrialMetrics::truth_ade},       {"truth_fde", &TrialMetrics::truth_fde},
    {"max_deviation", &TrialMetrics::max_deviation}, {"min_clearance", &TrialMetrics::min_clearance},
    {"hazard_time", &TrialMetrics::hazard_time},   {"hazard_length", &TrialMetrics::hazard_length},
    {"exposure", &TrialMetrics::exposure},         {"nees", &TrialMetrics::nees},
    {"outside_3sigma", &TrialMetrics::outside_3sigma},
};
struct CountField {
  const char* name;
  int TrialResult::*member;
};
constexpr CountField kCounts[] = {
    {"steps", &TrialResult::steps},
    {"replans", &TrialResult::replans},
    {"position_fixes", &TrialResult::position_fixes},
    {"dropouts", &TrialResult::dropouts},
    {"rejected", &TrialResult::rejected},
    {"resets", &TrialResult::resets},
    {"start_disputed", &TrialResult::start_disputed},
    {"chull_default", &TrialResult::chull_default},
    {"chull_corrective", &TrialResult::chull_corrective},
    {"chull_step_back", &TrialResult::chull_step_back},
    {"observations", &TrialResult::observations},
    {"dropped", &TrialResult::dropped},
    {"outliers", &TrialResult::outliers},
    {"misassociated", &TrialResult::misassociated},
    {"ranges_rejected", &TrialResult::ranges_rejected},
    {"faults_through", &TrialResult::faults_through},
    {"guard_slow", &TrialResult::guard_slow},
    {"guard_steer", &TrialResult::guard_steer},
    {"guard_hold", &TrialResult::guard_hold},
    {"guard_recover", &TrialResult::guard_recover},
    {"stale_input", &TrialResult::stale_input},
};

py::dict metrics_dict(const TrialMetrics& m) {
  py::dict d;
  for (const auto& f : kMetrics) d[f.name] = m.*f.member;
  return d;
}

}  // namespace

namespace {

/// LandmarkFaults.
void bind_faults(py::module_& m) {
  py::class_<LandmarkFaults>(m, "LandmarkFaults",
                             "Landmark-level faults (ours): dropout, misassociation, outliers, in that order.")
      .def(py::init([](double dropout, double outlier, double magnitude, double misassociation) {
             LandmarkFaults f{dropout, outlier, magnitude, misassociation};
             f.validate();
             return f;
           }),
           py::arg("dropout_probability") = 0.0, py::arg("outlier_probability") = 0.0,
           py::arg("outlier_magnitude") = 5.0, py::arg("misassociation_probability") = 0.0)
      .def_readwrite("dropout_probability", &LandmarkFaults::dropout_probability)
      .def_readwrite("outlier_probability", &LandmarkFaults::outlier_probability)
      .def_readwrite("outlier_magnitude", &LandmarkFaults::outlier_magnitude)
      .def_readwrite("misassociation_probability", &LandmarkFaults::misassociation_probability)
      .def("any", &LandmarkFaults::any)
      .def("validate", &LandmarkFaults::validate)
      .def(
          "apply",
          [](const LandmarkFaults& f, const std::vector<int>& rows, const std::vector<double>& ranges,
             const Landmarks& landmarks, const Eigen::Vector2d& position, double confusion_range, std::uint64_t seed) {
            const FaultedObservations o = apply_faults(f, rows, ranges, landmarks, position, confusion_range, seed);
            return py::make_tuple(o.rows, o.ranges, std::vector<int>(o.faults.begin(), o.faults.end()), o.dropped);
          },
          py::arg("rows"), py::arg("ranges"), py::arg("landmarks"), py::arg("position"), py::arg("confusion_range"),
          py::arg("seed"),
          "Apply the faults to observations (landmark rows, ranges) of a vehicle at `position`, drawing from the "
          "core's generator seeded with `seed`.  Returns (rows, ranges, fault flags, number dropped); flags: "
          "1 dropped (never returned), 2 misassociated, 4 outlier.");
  m.def(
      "apply_sighting_faults",
      [](const LandmarkFaults& f, std::vector<LandmarkSighting> sightings, const Landmarks& landmarks,
         const std::vector<int>& ids, const std::map<int, Eigen::Vector3d>& anchors, const Eigen::Vector2d& position,
         double confusion_range, std::uint64_t seed) {
        std::vector<LanBLocLandmark> a;
        for (const auto& [id, p] : anchors) a.push_back({id, p});
        const SightingFaults c = apply_sighting_faults(f, sightings, landmarks, ids, a, position, confusion_range, seed);
        py::dict counts;
        counts["observations"] = c.observations;
        counts["dropped"] = c.dropped;
        counts["outliers"] = c.outliers;
        counts["misassociated"] = c.misassociated;
        return py::make_tuple(sightings, counts);
      },
      py::arg("faults"), py::arg("sightings"), py::arg("landmarks"), py::arg("ids"), py::arg("anchors"),
      py::arg("position"), py::arg("confusion_range"), py::arg("seed"),
      "The landmark faults on a camera frame's sightings (the camera loop's): each ranged sighting through "
      "LandmarkFaults.apply alone with the draws of derive_seed(seed, its id); returns (the sightings kept, "
      "counts).  landmarks: the map's (K, 2) rows, ids one per row ([]: the rows), anchors {id: (x, y, z)}.");
}

/// SensorSettings.
void bind_sensors(py::module_& m) {
  def_params<SensorSettings>(py::class_<SensorSettings>(m, "SensorSettings"))
      .def(py::init<>())
      .def_readwrite("position", &SensorSettings::position)
      .def_readwrite("fix_model", &SensorSettings::fix_model)
      .def_readwrite("range_std", &SensorSettings::range_std)
      .def_readwrite("faults", &SensorSettings::faults)
      .def_readwrite("landmarks", &SensorSettings::landmarks)
      .def_readwrite("landmark_ids", &SensorSettings::landmark_ids,
                     "The landmarks' ids (the world's), one per row of landmarks; empty: 0 … K−1.")
      .def_readwrite("max_range", &SensorSettings::max_range)
      .def_readwrite("field_of_view", &SensorSettings::field_of_view)
      .def_readwrite("min_landmarks", &SensorSettings::min_landmarks)
      .def_readwrite("occlusion", &SensorSettings::occlusion,
                     "Obstacles hide landmarks from the simulated camera (ObstacleChecker.line_of_sight).")
      .def_readwrite("position_every", &SensorSettings::position_every)
      .def_readwrite("imu", &SensorSettings::imu)
      .def_readwrite("imu_speed_std", &SensorSettings::imu_speed_std)
      .def_readwrite("imu_heading_std", &SensorSettings::imu_heading_std)
      .def("validate", &SensorSettings::validate)
      .def("landmarks_in_view", &SensorSettings::landmarks_in_view, py::arg("state"), py::arg("obstacles") = nullptr,
           "Landmarks within max_range and the field of view of a vehicle at state (x, y, v, theta); with "
           "`occlusion` on and `obstacles` (an ObstacleChecker of the true obstacles, no clearance) given, "
           "less those an obstacle hides.");
}

/// TrialResult.
void bind_trial_result(py::module_& m) {
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
      .def_readonly("resets", &TrialResult::resets)
      .def_readonly("start_disputed", &TrialResult::start_disputed)
      .def_readonly("observations", &TrialResult::observations)
      .def_readonly("dropped", &TrialResult::dropped)
      .def_readonly("outliers", &TrialResult::outliers)
      .def_readonly("misassociated", &TrialResult::misassociated)
      .def_readonly("ranges_rejected", &TrialResult::ranges_rejected)
      .def_readonly("faults_through", &TrialResult::faults_through)
      .def_readonly("guard_slow", &TrialResult::guard_slow)
      .def_readonly("guard_steer", &TrialResult::guard_steer)
      .def_readonly("guard_hold", &TrialResult::guard_hold)
      .def_readonly("guard_recover", &TrialResult::guard_recover)
      .def_readonly("stale_input", &TrialResult::stale_input)
      .def_readonly("wall_time", &TrialResult::wall_time)
      .def_property_readonly("metrics", [](const TrialResult& r) { return metrics_dict(r.metrics); })
      .def_readonly("truth", &TrialResult::truth)
      .def_readonly("estimate", &TrialResult::estimate)
      .def_readonly("predicted", &TrialResult::predicted)
      .def_readonly("measured", &TrialResult::measured)
      .def_readonly("controls", &TrialResult::controls)
      .def_readonly("position_std", &TrialResult::position_std)
      .def_readonly("followed_path", &TrialResult::followed_path);
}

/// Navigator.
void bind_navigator(py::module_& m) {
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
      .def("nominal_trajectory", &Navigator::nominal_trajectory,
           "The states (rows x, y, v, theta at t = 0, dt, 2 dt, ...) of the vehicle driven by the method without "
           "noise, from a trial's true start to arrival (Guidance.nominal_trajectory; no guard, no detours).")
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
            py::array_t<int> outcome(n);
            py::array_t<double> wall(n);
            py::list reasons;
            for (py::ssize_t i = 0; i < n; ++i) {
              const TrialResult& r = rs[static_cast<std::size_t>(i)];
              outcome.mutable_at(i) = static_cast<int>(r.outcome);
              wall.mutable_at(i) = r.wall_time;
              reasons.append(r.reason);
            }
            py::dict d;
            d["outcome"] = outcome;
            d["reason"] = reasons;
            for (const auto& f : kCounts) {
              py::array_t<int> a(n);
              for (py::ssize_t i = 0; i < n; ++i) a.mutable_at(i) = rs[static_cast<std::size_t>(i)].*f.member;
              d[f.name] = a;
            }
            for (const auto& f : kMetrics) {
              py::array_t<double> a(n);
              for (py::ssize_t i = 0; i < n; ++i) a.mutable_at(i) = rs[static_cast<std::size_t>(i)].metrics.*f.member;
              d[f.name] = a;
            }
            d["time_s"] = wall;
            return d;
          },
          py::arg("seeds"),
          "Trials for each seed (measurement-level source), metrics only, as a dict of arrays.  Releases the GIL.");
}

}  // namespace

void pybind_navigation(py::module_& m) {
  pybind_guidance_settings(m);  // first: the Navigator takes them
  py::enum_<TrialOutcome>(m, "TrialOutcome")
      .value("ARRIVED", TrialOutcome::Arrived)
      .value("COLLISION", TrialOutcome::Collision)
      .value("LEFT_CORRIDOR", TrialOutcome::LeftCorridor)
      .value("STEP_LIMIT", TrialOutcome::StepLimit)
      .value("LOST_LOCALIZATION", TrialOutcome::LostLocalization)
      .value("NO_PATH", TrialOutcome::NoPath)
      .value("BLOCKED", TrialOutcome::Blocked);
  m.def("outcome_name", [](TrialOutcome o) { return to_string(o); });

  py::enum_<FixModel>(m, "FixModel", "Where the simulator's position fixes come from.")
      .value("PROFILE", FixModel::Profile, "the measurement-level error profile (the paper's)")
      .value("RANGES", FixModel::Ranges, "single landmark ranges, landmark faults, LanBLoc trilateration");

  bind_faults(m);
  bind_sensors(m);
  bind_trial_result(m);
  bind_navigator(m);
}
