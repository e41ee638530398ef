// NavigationProblem, NavigationSettings (safenav/navigation_settings.hpp) and
// SensorSettings (safenav/navigation.hpp): names, validation and the parameter
// declarations of the navigation settings, and apply_faults.
#include "safenav/navigation_settings.hpp"
#include "safenav/navigation.hpp"

#include <algorithm>
#include <set>
#include <string>

#include "declare.hpp"
#include "errors.hpp"
#include "rng.hpp"
#include "safenav/metrics.hpp"
#include "safenav/seed.hpp"

namespace safenav {

template <>
const ParamSet<NavigationSettings>& param_set<NavigationSettings>();  // defined below
template <>
const ParamSet<SensorSettings>& param_set<SensorSettings>();  // defined below

using detail::bad;
using detail::require_finite_positive;

std::string to_string(NavigationMethod method) {
  return method == NavigationMethod::CHull ? "chull" : "centroid";
}

std::string to_string(TrialOutcome outcome) {
  switch (outcome) {
    case TrialOutcome::Arrived: return "arrived";
    case TrialOutcome::Collision: return "collision";
    case TrialOutcome::LeftCorridor: return "left_corridor";
    case TrialOutcome::StepLimit: return "step_limit";
    case TrialOutcome::LostLocalization: return "lost_localization";
    case TrialOutcome::NoPath: return "no_path";
    case TrialOutcome::Blocked: return "blocked";
  }
  return "unknown";
}

std::string to_string(FixModel model) { return model == FixModel::Profile ? "profile" : "ranges"; }

/// LandmarkFaults on given observations (the simulator's fault model, safenav/navigation.hpp).
FaultedObservations apply_faults(const LandmarkFaults& faults, const std::vector<int>& rows,
                                 const std::vector<double>& ranges, const Landmarks& landmarks,
                                 const Eigen::Vector2d& position, double confusion_range, std::uint64_t seed) {
  if (rows.size() != ranges.size())
    bad("apply_faults: rows and ranges differ in length: " + std::to_string(rows.size()) + " and " +
        std::to_string(ranges.size()));
  for (int r : rows)
    if (r < 0 || r >= landmarks.rows())
      bad("apply_faults: row " + std::to_string(r) + " is not a landmark of the map (" +
          std::to_string(landmarks.rows()) + " landmarks)");
  faults.validate();
  std::vector<LandmarkFaults::Observation> obs;
  obs.reserve(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) obs.push_back({rows[i], ranges[i], 0u});
  detail::Rng rng(seed);
  RandomSourceOf<detail::Rng> draws(rng);
  FaultedObservations out;
  faults.apply(obs, landmarks, position, confusion_range, draws, &out.dropped);
  for (const auto& o : obs) {
    out.rows.push_back(o.row);
    out.ranges.push_back(o.range);
    out.faults.push_back(o.faults);
  }
  return out;
}

SightingFaults apply_sighting_faults(const LandmarkFaults& faults, std::vector<LandmarkSighting>& sightings,
                                     const Landmarks& landmarks, const std::vector<int>& ids,
                                     const std::vector<LanBLocLandmark>& anchors, const Eigen::Vector2d& position,
                                     double confusion_range, std::uint64_t seed) {
  const auto row_of = [&](int id) -> int {
    if (ids.empty()) return id >= 0 && id < landmarks.rows() ? id : -1;
    const auto it = std::find(ids.begin(), ids.end(), id);
    return it == ids.end() ? -1 : static_cast<int>(it - ids.begin());
  };
  faults.validate();
  SightingFaults out;
  std::vector<LandmarkSighting> kept;
  kept.reserve(sightings.size());
  std::vector<LandmarkFaults::Observation> one(1);
  for (LandmarkSighting& s : sightings) {
    if (!s.ok) {
      kept.push_back(std::move(s));
      continue;
    }
    ++out.observations;
    const int row = row_of(s.landmark_id);
    if (row < 0) bad("apply_sighting_faults: landmark id " + std::to_string(s.landmark_id) + " is not in the map");
    one.assign(1, {row, s.range, 0u});
    detail::Rng rng(derive_seed(seed, static_cast<std::uint64_t>(s.landmark_id)));
    RandomSourceOf<detail::Rng> draws(rng);
    int dropped = 0;
    faults.apply(one, landmarks, position, confusion_range, draws, &dropped);
    if (dropped) {
      ++out.dropped;
      continue;
    }
    const LandmarkFaults::Observation& o = one.front();
    s.range = o.range;
    s.faults = o.faults;
    out.outliers += (o.faults & LandmarkFaults::kOutlier) != 0;
    if (o.faults & LandmarkFaults::kMisassociated) {
      ++out.misassociated;
      const int id = ids.empty() ? o.row : ids[static_cast<std::size_t>(o.row)];
      s.true_landmark_id = s.landmark_id;
      s.landmark_id = id;
      const auto a = std::find_if(anchors.begin(), anchors.end(), [&](const LanBLocLandmark& l) { return l.id == id; });
      s.anchor = a != anchors.end() ? a->position
                                    : Eigen::Vector3d(landmarks(o.row, 0), landmarks(o.row, 1), s.anchor.z());
    }
    kept.push_back(std::move(s));
  }
  sightings.swap(kept);
  return out;
}

void NavigationProblem::validate() const {
  check_points(path, "problem.path", 2);
  zones.validate();
  map.validate();
  bmm.validate();
}

void NavigationSettings::validate() const {
  if (max_steps < 0 || max_steps > kMaxSteps)
    bad("settings.max_steps = " + std::to_string(max_steps) + ": must be in [0, " + std::to_string(kMaxSteps) +
        "] (0 = automatic)");
  // The declared ranges, nested structs' included, named as the scenario names them (settings.guard_k, …).
  param_set<NavigationSettings>().check(*this, "settings.");
  if (filter.type == FilterType::InformationFilter)
    bad("settings.filter.type = InformationFilter: navigation supports the EKF and the particle filter");
  // The nested structs' own invariants beyond their ranges.
  planner.validate();
  segments.validate();
  filter.validate("settings.filter.");
  guard.validate();
}

// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<NavigationSettings>& param_set<NavigationSettings>() {
  using N = NavigationSettings;
  // The nested structs' parameters are declared beside them (SegmentOptions in
  // corridor.cpp, FilterOptions in filters/checks.cpp, GuardSettings in
  // guard.cpp) and included here under the scenario's names.
  static const ParamSet<N> s =
      Declare<N>{}
          .real("cruise_speed", SN_REF(N, cruise_speed), "m/s", closed(0.01, 100), "desired speed")
          .real("arrival_radius", SN_REF(N, arrival_radius), "m", above(0, 100), "arrived when the estimate is this close to the destination")
          .nested("segment_", param_set<SegmentOptions>(), SN_REF(N, segments), {{"sub_segments", "sub_segments"}})
          .real("lookahead", SN_REF(N, lookahead), "m", above(0, 1e5), "the corrective control aims this far ahead [SafeNav Alg. 1]")
          .real("step_back_speed", SN_REF(N, step_back_speed), "m/s", closed(0.01, 100), "speed of the step back [SafeNav Alg. 1]")
          .real("sensing_range", SN_REF(N, sensing_range), "m", above(0, 1e5), "obstacles this far ahead on the path are detected")
          .integer("obstacle_check_every", SN_REF(N, obstacle_check_every), closed(1, 1e6), "steps between obstacle checks")
          .real("replan_lookahead", SN_REF(N, replan_lookahead), "m", above(0, 1e5), "a detour rejoins the path this far ahead")
          .integer("max_replans", SN_REF(N, max_replans), closed(0, 1e6), "detours planned at most per trial")
          .integer64("replan_iterations", SN_REF(N, planner.max_iterations), closed(1, PlannerSettings::kMaxIterations), "RAw-RRT* iterations of a detour")
          .real("corridor_bias", SN_REF(N, planner.corridor_bias), "", closed(0, 1), "share of RAw-RRT* samples drawn inside the corridor")
          .real("corridor_margin", SN_REF(N, corridor_margin), "m", closed(0, 1e5), "left the corridor: deviation beyond half_width + this")
          .real("lost_position_std", SN_REF(N, lost_position_std), "m", above(0, 1e4), "lost localization above this position sigma")
          .real("collision_probability", SN_REF(N, collision_probability), "", above(0, 0.1), "acceptable probability of a collision per mission; the guard's k follows from it when guard_k = 0 (ours)")
          .real("input_timeout", SN_REF(N, input_timeout), "s", closed(0, 1e6), "stop when the latest motion input or measurement is older than this; 0 = off (ours)")
          .integer("max_steps", SN_REF(N, max_steps), closed(0, N::kMaxSteps), "step budget; 0 = 3 x path length / (speed x dt) + 200")
          .nested("filter_", param_set<FilterOptions>(), SN_REF(N, filter), {{"gate_probability", "gate_probability"}})
          .nested("guard_", param_set<GuardSettings>(), SN_REF(N, guard))
          .set;
  return s;
}

template class ParamSet<NavigationSettings>;

// ---------------------------------------------------------------------------
// SensorSettings' parameter declarations (safenav/navigation.hpp, safenav/params.hpp)

void SensorSettings::validate() const {
  position.validate();
  require_finite_positive(range_std, "sensors.range_std");
  faults.validate();
  if (faults.any() && fix_model != FixModel::Ranges)
    bad("sensors.faults: landmark faults need sensors.fix_model = ranges (fixes from single landmark ranges); "
        "the profile model has no landmark observations to corrupt");
  if (!landmarks.allFinite()) bad("sensors.landmarks: every landmark position must be finite");
  if (!landmark_ids.empty()) {
    if (static_cast<Eigen::Index>(landmark_ids.size()) != landmarks.rows())
      bad("sensors.landmark_ids: " + std::to_string(landmark_ids.size()) + " ids for " +
          std::to_string(landmarks.rows()) + " landmarks (one per row, or none for 0 … K−1)");
    std::set<int> seen;
    for (int id : landmark_ids)
      if (!seen.insert(id).second) bad("sensors.landmark_ids: id " + std::to_string(id) + " repeats");
  }
  require_finite_positive(max_range, "sensors.max_range");
  require_finite_positive(field_of_view, "sensors.field_of_view");
  if (min_landmarks < 0) bad("sensors.min_landmarks = " + std::to_string(min_landmarks) + ": must be >= 0");
  if (position_every < 1) bad("sensors.position_every = " + std::to_string(position_every) + ": must be >= 1");
  require_finite_positive(imu_speed_std, "sensors.imu_speed_std");
  require_finite_positive(imu_heading_std, "sensors.imu_heading_std");
  param_set<SensorSettings>().check(*this, "sensors.");
}

template <>
const ParamSet<SensorSettings>& param_set<SensorSettings>() {
  using S = SensorSettings;
  static const ParamSet<S> s =
      Declare<S>{}
          .real("max_range", SN_REF(S, max_range), "m", above(0, 1e4), "landmarks farther than this are not detected")
          .real("field_of_view", SN_REF(S, field_of_view), "rad", above(0, 2 * kPi), "full horizontal field of view, centred on the heading; 2 pi = all round")
          .integer("min_landmarks", SN_REF(S, min_landmarks), closed(1, 1000), "a position fix needs this many landmarks in view [SafeNav-ext §V-A3(ii)]: clusters of >= 3")
          .flag("occlusion", SN_REF(S, occlusion), "obstacles hide landmarks from the simulated camera (ours; off in the papers' loop)")
          .integer("position_every", SN_REF(S, position_every), closed(1, 1e6), "a position fix every n steps")
          .real("imu_speed_std", SN_REF(S, imu_speed_std), "m/s", closed(1e-6, 10), "sigma of the IMU's speed")
          .real("imu_heading_std", SN_REF(S, imu_heading_std), "rad", closed(1e-6, kPi), "sigma of the IMU's heading")
          .real("range_std", SN_REF(S, range_std), "m", closed(1e-6, 100), "sigma of one landmark range (fixes from ranges)")
          .real("dropout_probability", SN_REF(S, faults.dropout_probability), "", closed(0, 1), "a landmark observation is missed with this probability (ours)")
          .real("outlier_probability", SN_REF(S, faults.outlier_probability), "", closed(0, 1), "a landmark range is an outlier with this probability (ours)")
          .real("outlier_magnitude", SN_REF(S, faults.outlier_magnitude), "m", above(0, 1e4), "an outlier range is off by this much, either sign")
          .real("misassociation_probability", SN_REF(S, faults.misassociation_probability), "", closed(0, 1), "a landmark observation carries another landmark's id with this probability (ours)")
          .set;
  return s;
}

template class ParamSet<SensorSettings>;

}  // namespace safenav
