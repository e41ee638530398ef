// The simulator's sensors in a trial (navigation_trial.hpp): the landmarks in
// view, position fixes from the measurement-level profile or from landmark
// ranges with faults and LanBLoc's trilateration, and camera frames through
// the vehicle's own front end, with the landmark faults on their sightings.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "errors.hpp"
#include "navigation_trial.hpp"
#include "safenav/trilateration.hpp"

namespace safenav {

using detail::bad;
using detail::num;

int SensorSettings::landmarks_in_view(const State& x, const ObstacleChecker* obstacles) const {
  if (!x.allFinite())
    bad("landmarks_in_view: state (" + num(x[0]) + ", " + num(x[1]) + ", " + num(x[2]) + ", " + num(x[3]) +
        ") is not finite");
  int n = 0;
  for_each_in_view(x, obstacles, [&](Eigen::Index, double) { ++n; });
  return n;
}

template <class F>
void SensorSettings::for_each_in_view(const State& x, const ObstacleChecker* obstacles, F&& f) const {
  const bool hidden_possible = occlusion && obstacles != nullptr && obstacles->obstacle_count() > 0;
  const double r2 = max_range * max_range;
  const bool all_round = field_of_view >= 2.0 * kPi;
  const double half = 0.5 * field_of_view;
  const double c = std::cos(x[kTheta]), s = std::sin(x[kTheta]);
  const double cos_half = std::cos(half);
  for (Eigen::Index i = 0; i < landmarks.rows(); ++i) {
    const double dx = landmarks(i, 0) - x[kX], dy = landmarks(i, 1) - x[kY];
    const double d2 = dx * dx + dy * dy;
    if (d2 > r2) continue;
    if (!all_round) {
      // inside the FOV: angle to the heading ≤ half  ⇔  cos(angle) ≥ cos(half)
      const double along = c * dx + s * dy;
      if (d2 > 0.0 && along < cos_half * std::sqrt(d2)) continue;
    }
    if (hidden_possible && !obstacles->line_of_sight(x.head<2>(), Eigen::Vector2d(landmarks(i, 0), landmarks(i, 1))))
      continue;  // occluded by an obstacle
    f(i, std::sqrt(d2));
  }
}

namespace navigation_detail {

bool Trial::range_fix(const State& x, Eigen::Vector2d& z, Eigen::Matrix2d& R) {
  TrialResult& res = res_;
  obs_.clear();
  se_.for_each_in_view(x, &collisions_, [&](Eigen::Index i, double d) {
    obs_.push_back({static_cast<int>(i), std::max(0.0, d + se_.range_std * sensor_rng_.normal()), 0u});
  });
  res.observations += static_cast<int>(obs_.size());
  se_.faults.apply(obs_, se_.landmarks, x.head<2>(), se_.max_range, sensor_draws_, &res.dropped);
  for (const auto& o : obs_) {
    res.outliers += (o.faults & LandmarkFaults::kOutlier) != 0;
    res.misassociated += (o.faults & LandmarkFaults::kMisassociated) != 0;
  }
  res.ranges_rejected += drop_repeated_landmarks(obs_, [](const auto& o) { return o.row; });
  if (static_cast<int>(obs_.size()) < std::max(3, se_.min_landmarks)) return false;
  const Eigen::Index n = static_cast<Eigen::Index>(obs_.size());
  Anchors anchors(n, 2);
  Eigen::VectorXd ranges(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    anchors.row(i) = se_.landmarks.row(obs_[static_cast<std::size_t>(i)].row);
    ranges[i] = obs_[static_cast<std::size_t>(i)].range;
  }
  const LocalizationResult lr = trilaterate(anchors, ranges, Eigen::VectorXd::Constant(n, se_.range_std), trilateration_);
  if (!lr.ok()) return false;
  // The fix's own χ² test at the gate's probability (ours): with one range
  // more than the two unknowns the fit's residual reveals a bad range even
  // where the outlier test (>= 4 ranges) cannot name it.
  const int used = static_cast<int>(lr.inliers.count());
  if (gate_ > 0.0 && used > 2 && lr.chi2 > fit_threshold(used - 2)) {
    res.ranges_rejected += static_cast<int>(n);  // the whole fix: its inliers fail, the outliers were out already
    return false;
  }
  fix_faults_ = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!lr.inliers[i]) ++res.ranges_rejected;
    else if (obs_[static_cast<std::size_t>(i)].faults) ++fix_faults_;
  }
  z = lr.position;
  R = lr.covariance;
  return true;
}

bool Trial::fix(const State& x, int step, Eigen::Vector2d& z, Eigen::Matrix2d& R) {
  fix_faults_ = 0;
  if (position_cb_) {
    if (!position_cb_(x, step, z, R)) return false;
    if (!z.allFinite() || !R.allFinite())
      throw std::runtime_error("position callback returned a non-finite fix at step " + std::to_string(step));
    return true;
  }
  if (se_.fix_model == FixModel::Ranges) return range_fix(x, z, R);
  if (se_.position.needs_landmarks && se_.landmarks_in_view(x, &collisions_) < se_.min_landmarks) return false;
  if (!source_noise_.sample(x.head<2>(), sensor_draws_, z)) return false;
  R = source_R_;
  return true;
}

/// The front end's landmarks are the map's: each id is a localizer id (sensors.landmark_ids) at the
/// same position, so that a sighting updates the landmark it names.
void Trial::check_front_end_ids(const LanBLocFrontEnd& fe) const {
  const Localizer& loc = guidance_.localizer();
  for (const LanBLocLandmark& lm : fe.landmarks()) {
    const int row = loc.landmark_index(lm.id);
    const Eigen::Vector2d p = lm.position.head<2>();
    if (row < 0)
      bad("front end landmark id " + std::to_string(lm.id) + " at (" + num(p.x()) + ", " + num(p.y()) +
          ") is not in the map's ids (sensors.landmark_ids)");
    const Eigen::Vector2d q = loc.landmarks().row(row).transpose();
    if (!((q - p).norm() <= 1e-9 * std::max(1.0, q.norm())))
      bad("front end landmark id " + std::to_string(lm.id) + " is at (" + num(p.x()) + ", " + num(p.y()) +
          "), the map's landmark " + std::to_string(lm.id) + " at (" + num(q.x()) + ", " + num(q.y()) + ")");
  }
}

/// The camera loop's first frame: no estimate yet, so the front end searches the whole frame.
bool Trial::first_frame(Eigen::Vector2d& z, Eigen::Matrix2d& R) {
  const LanBLocFrontEnd& fe = *guidance_.localizer().front_end();
  const SearchPlan plan = fe.plan(std::nullopt);
  const std::shared_ptr<const StereoPixels> pixels = (*frames_)(truth_, 0, plan);
  if (!pixels) return false;
  const LanBLocFix f = fe.localize(*pixels, plan, frame_faults(0));
  if (!f.ok()) return false;
  z = f.position;
  R = f.covariance;
  return true;
}

/// A camera frame at a fix step: drawn where the localizer's front end will search (its plan from
/// the filter's prediction), then localized and applied by the localizer (observe_frame, gated).
bool Trial::frame(int step, double t, Eigen::Vector2d& z) {
  Localizer& loc = guidance_.localizer();
  const SearchPlan plan = loc.frame_plan(t);
  const std::shared_ptr<const StereoPixels> pixels = (*frames_)(truth_, step, plan);
  if (!pixels) {
    ++res_.dropouts;
    return false;
  }
  // Without a fix (fewer whole markers than a fix needs) each ranged landmark's range and bearing
  // still updates the filter through its gate (FixOrLandmarks: Localizer::observe, eq. 10's models);
  // the front end and the localizer name landmarks by the same ids (check_front_end_ids).
  const FrameResult r = loc.observe_frame(t, *pixels, plan, FrameUpdate::FixOrLandmarks, frame_faults(step));
  if (!r.fix.ok()) {
    ++res_.dropouts;
    for (std::size_t i = 0; i < r.fix.observations.size(); ++i) {
      if (!r.fix.observations[i].ok) continue;
      if (!r.landmarks[i].applied()) ++res_.rejected;
      else if (r.fix.observations[i].faults) ++res_.faults_through;
    }
    return false;
  }
  z = r.fix.position;
  // the trilateration's outliers, and the faulty ranges among its inliers (in the ranged sightings' order)
  const LocalizationResult& lr = r.fix.localization;
  const bool applied = r.update.applied();
  Eigen::Index j = 0;
  for (const LandmarkSighting& o : r.fix.observations) {
    if (!o.ok || j >= lr.inliers.size()) continue;
    if (!lr.inliers[j++]) ++res_.ranges_rejected;
    else if (applied && o.faults) ++res_.faults_through;
  }
  if (applied) ++res_.position_fixes;
  else ++res_.rejected;
  return true;
}

/// The simulator's landmark faults on a camera frame's ranged sightings, before trilateration
/// (apply_sighting_faults, as range_fix applies them to the measurement level's ranges), with the
/// vehicle at its true position and each frame's draws from derive_seed(trial stream 4, step); the
/// ranged sightings are counted here, before the faults drop any.
SightingEdit Trial::frame_faults(int step) {
  const bool faults = se_.faults.any();
  const std::uint64_t seed = derive_seed(frame_fault_seed_, static_cast<std::uint64_t>(step));
  return [this, faults, seed](std::vector<LandmarkSighting>& sightings) {
    if (!faults) {
      for (const LandmarkSighting& o : sightings) res_.observations += o.ok;
      return;
    }
    const SightingFaults f =
        apply_sighting_faults(se_.faults, sightings, se_.landmarks, se_.landmark_ids,
                              guidance_.localizer().front_end()->landmarks(), truth_.head<2>(), se_.max_range, seed);
    res_.observations += f.observations;
    res_.dropped += f.dropped;
    res_.outliers += f.outliers;
    res_.misassociated += f.misassociated;
  };
}

}  // namespace navigation_detail
}  // namespace safenav
