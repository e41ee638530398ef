// SafeNav navigation: [SafeNav Algs. 1–2] (CHull, Centroid) and [SafeNav-ext Alg. 4]
// (= [SafeNav-conf Alg. 3]), the safe path navigation loop with RAw-RRT*
// replanning.  See safenav/navigation.hpp.
#include "safenav/navigation.hpp"

#include <algorithm>
#include <chrono>
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "rng.hpp"
#include "errors.hpp"
#include "safenav/localization.hpp"

namespace safenav {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using detail::bad;
using detail::num;
using detail::require_finite_nonneg;
using detail::require_finite_positive;

}  // namespace

// ---------------------------------------------------------------------------
// names and validation

std::string to_string(TrialOutcome outcome) {
  switch (outcome) {
    case TrialOutcome::Arrived: return "arrived";
    case TrialOutcome::Collision: return "collision";
    case TrialOutcome::LeftCorridor: return "left_corridor";
    case TrialOutcome::StepLimit: return "step_limit";
    case TrialOutcome::LostLocalization: return "lost_localization";
    case TrialOutcome::NoPath: return "no_path";
  }
  return "unknown";
}

std::string to_string(FixModel model) { return model == FixModel::Profile ? "profile" : "ranges"; }

void SensorSettings::validate() const {
  position.validate();
  require_finite_positive(range_std, "sensors.range_std");
  faults.validate();
  if (faults.any() && fix_model != FixModel::Ranges)
    bad("sensors.faults: landmark faults need sensors.fix_model = ranges (fixes from single landmark ranges); "
        "the profile model has no landmark observations to corrupt");
  if (!landmarks.allFinite()) bad("sensors.landmarks: every landmark position must be finite");
  require_finite_positive(max_range, "sensors.max_range");
  require_finite_positive(field_of_view, "sensors.field_of_view");
  if (min_landmarks < 0) bad("sensors.min_landmarks = " + std::to_string(min_landmarks) + ": must be >= 0");
  if (position_every < 1) bad("sensors.position_every = " + std::to_string(position_every) + ": must be >= 1");
  require_finite_positive(imu_speed_std, "sensors.imu_speed_std");
  require_finite_positive(imu_heading_std, "sensors.imu_heading_std");
  param_set<SensorSettings>().check(*this, "sensors.");
}

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

// ---------------------------------------------------------------------------
// Navigator

struct Navigator::Impl {
  Guidance guidance;             // the prototype: each trial runs guidance.fresh(seed)
  SensorSettings sensors;
  ObstacleChecker collisions;    // the true obstacles, no clearance
  Eigen::Matrix2d imu_R;
  int max_steps = 0;

  static LocalizerSettings loop_filter(const NavigationSettings& s) {
    LocalizerSettings ls;
    ls.filter = s.filter;  // the loop's gate is the settings' (0 = off, the paper's loop)
    return ls;
  }
  static PlanningMap no_clearance(PlanningMap m) {
    m.clearance = 0.0;
    return m;
  }

  // The guard looks with the simulated camera.
  static NavigationSettings with_camera(NavigationSettings s, const SensorSettings& se) {
    se.validate();  // first, so that a bad sensor is named as such
    s.guard.field_of_view = std::min(se.field_of_view, 2.0 * kPi);
    s.guard.look_range = se.max_range;
    s.guard.look_min_landmarks = std::max(1, se.min_landmarks);
    s.guard.occlusion = se.occlusion;
    return s;
  }

  Impl(NavigationProblem p, NavigationSettings s, SensorSettings se)
      : guidance(p, with_camera(s, se), loop_filter(s), se.landmarks),
        sensors((se.validate(), std::move(se))),
        collisions(no_clearance(p.map)) {
    imu_R = Eigen::Vector2d(sensors.imu_speed_std * sensors.imu_speed_std,
                            sensors.imu_heading_std * sensors.imu_heading_std).asDiagonal();
    const NavigationSettings& st = guidance.settings();
    const BmmParams& bmm = guidance.problem().bmm;
    const double L = guidance.safe_path().corridor().length();
    const double automatic = std::ceil(3.0 * L / (st.cruise_speed * bmm.dt * bmm.terrain_factor())) + 200.0;
    if (st.max_steps == 0 && !(automatic <= NavigationSettings::kMaxSteps))
      bad("automatic max_steps = 3·L/(cruise_speed·dt·terrain factor) + 200 = " + num(automatic) + " exceeds " +
          std::to_string(NavigationSettings::kMaxSteps) + " (path length L = " + num(L) + " m, cruise_speed = " +
          num(st.cruise_speed) + " m/s, dt = " + num(bmm.dt) + " s, terrain factor = " +
          num(bmm.terrain_factor()) + "): raise the speed or dt, or set settings.max_steps");
    max_steps = st.max_steps > 0 ? st.max_steps : static_cast<int>(automatic);
  }
};

Navigator::Navigator(NavigationProblem problem, NavigationSettings settings, SensorSettings sensors)
    : impl_(std::make_unique<Impl>(std::move(problem), std::move(settings), std::move(sensors))) {}
Navigator::~Navigator() = default;
Navigator::Navigator(Navigator&&) noexcept = default;
Navigator& Navigator::operator=(Navigator&&) noexcept = default;

const NavigationProblem& Navigator::problem() const { return impl_->guidance.problem(); }
const NavigationSettings& Navigator::settings() const { return impl_->guidance.settings(); }
const SensorSettings& Navigator::sensors() const { return impl_->sensors; }
const PathSegments& Navigator::segments() const { return impl_->guidance.safe_path(); }
int Navigator::max_steps() const { return impl_->max_steps; }

TrialResult Navigator::run(std::uint64_t seed, const PositionCallback& position) const {
  return run_trial(seed, position, impl_->guidance.settings().record);
}

std::vector<TrialResult> Navigator::run_many(const std::vector<std::uint64_t>& seeds) const {
  std::vector<TrialResult> out;
  out.reserve(seeds.size());
  for (std::uint64_t s : seeds) out.push_back(run_trial(s, nullptr, false));
  return out;
}

TrialResult Navigator::run_trial(std::uint64_t seed, const PositionCallback& position_cb, bool rec) const {
  const auto t0 = std::chrono::steady_clock::now();
  const Impl& im = *impl_;
  const SensorSettings& se = im.sensors;
  const BmmParams& bp = im.guidance.problem().bmm;
  const NavigationSettings& st = im.guidance.settings();
  const Bmm bmm(bp);
  detail::Rng motion_rng(derive_seed(seed, 0));
  detail::Rng sensor_rng(derive_seed(seed, 1));

  // The vehicle's guidance: the same object a vehicle program ticks (guidance.hpp).
  Guidance guidance = im.guidance.fresh(seed);
  const Corridor& safe = guidance.safe_path().corridor();

  // True start: first path vertex, at rest, heading along the first edge.
  State truth;
  {
    const Eigen::Vector2d t = safe.tangent_at(0.0);
    truth << safe.path()(0, 0), safe.path()(0, 1), 0.0, std::atan2(t.y(), t.x());
  }

  // Position source: the callback, or the measurement-level profile.
  const PositionNoise& src = se.position;
  RandomSourceOf<detail::Rng> sensor_draws(sensor_rng);
  PositionNoise::Trial source_noise(src, sensor_draws);
  const Eigen::Matrix2d source_R = src.reported_cov();
  TrialResult res;
  // FixModel::Ranges: landmark ranges, faults, LanBLoc trilateration.
  std::vector<LandmarkFaults::Observation> obs;
  obs.reserve(static_cast<std::size_t>(se.landmarks.rows()));
  LocalizationOptions trilateration;
  trilateration.seed = derive_seed(seed, 3);
  const double gate = st.filter.gate_probability;
  std::vector<double> fit_thresholds;
  auto fit_threshold = [&](int dof) {
    while (static_cast<int>(fit_thresholds.size()) < dof)
      fit_thresholds.push_back(chi2_quantile(gate, static_cast<int>(fit_thresholds.size()) + 1));
    return fit_thresholds[static_cast<std::size_t>(dof - 1)];
  };
  int fix_faults = 0;  // faulty ranges inside the last fix
  auto range_fix = [&](const State& x, Eigen::Vector2d& z, Eigen::Matrix2d& R) -> bool {
    obs.clear();
    se.for_each_in_view(x, &im.collisions, [&](Eigen::Index i, double d) {
      obs.push_back({static_cast<int>(i), std::max(0.0, d + se.range_std * sensor_rng.normal()), 0u});
    });
    res.observations += static_cast<int>(obs.size());
    se.faults.apply(obs, se.landmarks, x.head<2>(), se.max_range, sensor_draws, &res.dropped);
    for (const auto& o : obs) {
      res.outliers += (o.faults & LandmarkFaults::kOutlier) != 0;
      res.misassociated += (o.faults & LandmarkFaults::kMisassociated) != 0;
    }
    if (static_cast<int>(obs.size()) < std::max(3, se.min_landmarks)) return false;
    const Eigen::Index n = static_cast<Eigen::Index>(obs.size());
    Anchors anchors(n, 2);
    Eigen::VectorXd ranges(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      anchors.row(i) = se.landmarks.row(obs[static_cast<std::size_t>(i)].row);
      ranges[i] = obs[static_cast<std::size_t>(i)].range;
    }
    const LocalizationResult lr = trilaterate(anchors, ranges, Eigen::VectorXd::Constant(n, se.range_std), trilateration);
    if (!lr.ok()) return false;
    // The fix's own χ² test at the gate's probability (ours): with one range
    // more than the two unknowns the fit's residual reveals a bad range even
    // where the outlier test (>= 4 ranges) cannot name it.
    const int used = static_cast<int>(lr.inliers.count());
    if (gate > 0.0 && used > 2 && lr.chi2 > fit_threshold(used - 2)) {
      res.ranges_rejected += static_cast<int>(n);  // the whole fix: its inliers fail, the outliers were out already
      return false;
    }
    fix_faults = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!lr.inliers[i]) ++res.ranges_rejected;
      else if (obs[static_cast<std::size_t>(i)].faults) ++fix_faults;
    }
    z = lr.position;
    R = lr.covariance;
    return true;
  };
  auto fix = [&](const State& x, int step, Eigen::Vector2d& z, Eigen::Matrix2d& R) -> bool {
    fix_faults = 0;
    if (position_cb) {
      if (!position_cb(x, step, z, R)) return false;
      if (!z.allFinite() || !R.allFinite())
        throw std::runtime_error("position callback returned a non-finite fix at step " + std::to_string(step));
      return true;
    }
    if (se.fix_model == FixModel::Ranges) return range_fix(x, z, R);
    if (src.needs_landmarks && se.landmarks_in_view(x, &im.collisions) < se.min_landmarks) return false;
    if (!source_noise.sample(x.head<2>(), sensor_draws, z)) return false;
    R = source_R;
    return true;
  };

  // Initial estimate (the localizer's prior): a LanBLoc fix, if one is available, and the IMU.
  {
    State x0 = truth;
    StateCov P0 = StateCov::Zero();
    Eigen::Vector2d z;
    Eigen::Matrix2d R;
    if (fix(truth, 0, z, R)) {
      x0.head<2>() = z;
      P0.topLeftCorner<2, 2>() = R;
    } else {
      // No fix at the start: the start point is known only roughly.
      const double s0 = std::max(1.0, src.std.maxCoeff());
      x0.head<2>() += s0 * Eigen::Vector2d(sensor_rng.normal(), sensor_rng.normal());
      P0.topLeftCorner<2, 2>() = s0 * s0 * Eigen::Matrix2d::Identity();
    }
    x0[kV] = std::max(0.0, truth[kV] + se.imu_speed_std * sensor_rng.normal());
    x0[kTheta] = wrap_angle(truth[kTheta] + se.imu_heading_std * sensor_rng.normal());
    P0(2, 2) = se.imu_speed_std * se.imu_speed_std;
    P0(3, 3) = se.imu_heading_std * se.imu_heading_std;
    guidance.localizer().initialize(0.0, x0, P0);
  }
  const Localizer& loc = guidance.localizer();

  const int N = im.max_steps;
  if (rec) {
    res.truth.resize(N + 1, 4);
    res.estimate.resize(N + 1, 4);
    res.predicted.resize(N + 1, 2);
    res.measured.resize(N + 1, 2);
    res.controls.resize(N, 2);
    res.position_std.resize(N + 1);
  }
  // Metrics accumulate on the fly, so they need no recording.
  Eigen::Vector2d prev_est = loc.x().head<2>();
  double est_length = 0.0, loc_sum = 0.0, wrs_est = 0.0, wrs_true = 0.0, max_dev = 0.0;
  std::vector<Eigen::Vector2d> est_points;
  est_points.reserve(static_cast<std::size_t>(N) + 1);

  // Safety along the true track: clearance (cached lower bound, as the guard's), hazards, consistency.
  double min_clear = std::numeric_limits<double>::infinity(), nees_sum = 0.0;
  int outside = 0, nees_n = 0;
  Eigen::Vector2d clear_p = truth.head<2>();
  double clear_d = im.collisions.keep_out_distance(clear_p, clear_p);
  min_clear = clear_d;
  auto track_safety = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    if (clear_d - std::max((a - clear_p).norm(), (b - clear_p).norm()) < min_clear) {
      min_clear = std::min(min_clear, im.collisions.keep_out_distance(a, b));
      clear_p = b;
      clear_d = im.collisions.keep_out_distance(b, b);
    }
    const ObstacleChecker::HazardStep h = im.collisions.hazard_step(a, b);
    res.metrics.hazard_length += h.length;
    res.metrics.exposure += h.exposure;
    if (h.inside) res.metrics.hazard_time += bp.dt;
  };
  auto consistency = [&] {
    State e = truth - loc.x();
    e[kTheta] = wrap_angle(e[kTheta]);
    // A P that is not positive definite (a particle cloud collapsed onto a few
    // particles) has no NEES: left out of the mean, and counted outside 3σ below.
    const Eigen::LLT<Eigen::Matrix4d> llt(loc.P());
    const double n4 = llt.info() == Eigen::Success ? e.dot(llt.solve(e)) : kNaN;
    if (std::isfinite(n4)) {
      nees_sum += n4;
      ++nees_n;
    }
    const Eigen::Vector2d ep = e.head<2>();
    const Eigen::Matrix2d Pxy = loc.P().topLeftCorner<2, 2>();
    const double det = Pxy.determinant();
    const double d2 = det > 0.0 ? (Pxy(1, 1) * ep.x() * ep.x() - 2.0 * Pxy(0, 1) * ep.x() * ep.y() + Pxy(0, 0) * ep.y() * ep.y()) / det
                                : std::numeric_limits<double>::infinity();
    if (!(d2 <= 9.0)) ++outside;
  };

  const RiskZones& zones = guidance.problem().zones;
  auto record = [&](int row, const Eigen::Vector2d& pred, const Eigen::Vector2d* meas) {
    const State& xe = loc.x();
    consistency();
    const double dev = safe.project(truth.head<2>()).distance;
    max_dev = std::max(max_dev, dev);
    wrs_true += wrs(dev, zones);
    wrs_est += safe.wrs(Eigen::Vector2d(xe.head<2>()));
    loc_sum += (xe.head<2>() - truth.head<2>()).norm();
    if (row > 0) est_length += (xe.head<2>() - prev_est).norm();
    prev_est = xe.head<2>();
    est_points.push_back(xe.head<2>());
    if (!rec) return;
    res.truth.row(row) = truth.transpose();
    res.estimate.row(row) = xe.transpose();
    res.predicted.row(row) = pred.transpose();
    if (meas) res.measured.row(row) = meas->transpose();
    else res.measured.row(row).setConstant(kNaN);
    res.position_std[row] = loc.position_std();
  };
  {
    const Eigen::Vector2d z0 = loc.x().head<2>();
    record(0, z0, &z0);
  }

  const Eigen::Vector4d sigma(bp.position_noise, bp.position_noise, bp.speed_noise, bp.heading_noise);
  TrialOutcome outcome = TrialOutcome::StepLimit;
  std::string reason = "no arrival within " + std::to_string(N) + " steps";
  int step = 0;
  while (step < N) {
    // 1–2. The vehicle asks guidance for its control: obstacles ahead and
    // detours [SafeNav-ext Alg. 4 ll. 7–9], then CHull or Centroid.
    const double t = step * bp.dt;
    const Command cmd = guidance.command(t);
    res.guard_slow += (cmd.events & kGuardSlow) != 0;
    res.guard_steer += (cmd.events & kGuardSteer) != 0;
    res.guard_hold += (cmd.events & kGuardHold) != 0;
    if (cmd.status == GuidanceStatus::NoPath) {
      outcome = TrialOutcome::NoPath;
      reason = guidance.detail();
      break;
    }
    if (st.method == NavigationMethod::CHull) {
      switch (cmd.action) {
        case ChullAction::Keep: ++res.chull_default; break;
        case ChullAction::Corrective: ++res.chull_corrective; break;
        case ChullAction::StepBack: ++res.chull_step_back; break;
      }
    }
    const Control& u = cmd.control;
    ++step;
    const double t1 = step * bp.dt;
    if (rec) res.controls.row(step - 1) = u.transpose();
    // 3. Move the true vehicle.
    const Eigen::Vector2d before = truth.head<2>();
    Eigen::Vector4d eps;
    for (int i = 0; i < 4; ++i) eps[i] = sigma[i] * motion_rng.normal();
    truth = bmm.transition(truth, u, eps);
    // 4. The vehicle's inputs: its commanded motion, a LanBLoc fix, the IMU.
    guidance.motion(t1, u);
    Eigen::Vector2d z;
    Eigen::Matrix2d R;
    bool have_fix = false;
    if (step % se.position_every == 0) {
      have_fix = fix(truth, step, z, R);
      if (have_fix) {
        if (guidance.fix(t1, z, R).applied()) {
          ++res.position_fixes;
          res.faults_through += fix_faults;
        } else {
          ++res.rejected;
        }
      } else {
        ++res.dropouts;
      }
    }
    if (se.imu) {
      const Eigen::Vector2d zi(std::max(0.0, truth[kV] + se.imu_speed_std * sensor_rng.normal()),
                               wrap_angle(truth[kTheta] + se.imu_heading_std * sensor_rng.normal()));
      if (!guidance.speed_heading(t1, zi, im.imu_R).applied()) ++res.rejected;
    }
    // 5. Record.
    record(step, cmd.predicted, have_fix ? &z : nullptr);
    track_safety(before, truth.head<2>());
    // Ends: the truth's (collision, corridor), then guidance's (lost, arrived).
    if (!im.collisions.segment_free(before, truth.head<2>())) {
      outcome = TrialOutcome::Collision;
      reason = "collision at (" + num(truth[kX]) + ", " + num(truth[kY]) + ") at step " + std::to_string(step);
      break;
    }
    const double dev = guidance.path().corridor().project(truth.head<2>()).distance;
    if (dev > zones.half_width + st.corridor_margin) {
      outcome = TrialOutcome::LeftCorridor;
      reason = "left the corridor at step " + std::to_string(step) + ": deviation " + num(dev) + " m > " +
               num(zones.half_width + st.corridor_margin) + " m";
      break;
    }
    const GuidanceStatus gs = guidance.status();
    if (gs == GuidanceStatus::LostLocalization) {
      outcome = TrialOutcome::LostLocalization;
      reason = "position std " + num(loc.position_std()) + " m > " + num(st.lost_position_std) + " m at step " +
               std::to_string(step);
      break;
    }
    if (gs == GuidanceStatus::Arrived) {
      outcome = TrialOutcome::Arrived;
      reason = "arrived in " + std::to_string(step) + " steps";
      break;
    }
  }

  res.outcome = outcome;
  res.success = outcome == TrialOutcome::Arrived;
  res.reason = reason;
  res.steps = step;
  res.replans = guidance.replans();
  res.resets = loc.counts().resets;
  const Eigen::Index rows = step + 1;
  if (rec) {
    res.truth.conservativeResize(rows, 4);
    res.estimate.conservativeResize(rows, 4);
    res.predicted.conservativeResize(rows, 2);
    res.measured.conservativeResize(rows, 2);
    res.controls.conservativeResize(step, 2);
    res.position_std.conservativeResize(rows);
    res.followed_path = guidance.path().corridor().path();
  }
  // Metrics [SafeNav-ext eqs. 20–23] against the safe path (and the truth).
  const Eigen::Vector2d destination = safe.path().bottomRows<1>().transpose();
  Points2 est(rows, 2);
  for (Eigen::Index i = 0; i < rows; ++i) est.row(i) = est_points[static_cast<std::size_t>(i)].transpose();
  TrialMetrics& m = res.metrics;
  m.path_ade = safe.distance(est).mean();
  m.goal_fde = (est.bottomRows<1>().transpose() - destination).norm();
  m.path_error_percent = std::abs(est_length - safe.length()) / safe.length() * 100.0;
  m.awrs = wrs_est / double(rows);
  m.awrs_true = wrs_true / double(rows);
  m.truth_ade = loc_sum / double(rows);
  m.truth_fde = (loc.x().head<2>() - truth.head<2>()).norm();
  m.max_deviation = max_dev;
  m.min_clearance = min_clear;
  m.nees = nees_n > 0 ? nees_sum / double(nees_n) : kNaN;
  m.outside_3sigma = double(outside) / double(rows);
  res.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace safenav
