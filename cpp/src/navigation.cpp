// SafeNav navigation: [SafeNav Algs. 1–2] (CHull, Centroid) and [SafeNav-ext Alg. 4]
// (= [SafeNav-conf Alg. 3]), the safe path navigation loop with RAw-RRT*
// replanning.  See safenav/navigation.hpp.
#include "safenav/navigation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "rng.hpp"
#include "errors.hpp"

namespace safenav {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using detail::bad;

std::string num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

void require_finite_positive(double v, const char* name) {
  if (!std::isfinite(v) || v <= 0.0) bad(std::string(name) + " = " + num(v) + ": must be finite and > 0");
}

void require_finite_nonneg(double v, const char* name) {
  if (!std::isfinite(v) || v < 0.0) bad(std::string(name) + " = " + num(v) + ": must be finite and >= 0");
}

double heading_to(const State& x, const Eigen::Vector2d& target) {
  const Eigen::Vector2d d = target - x.head<2>();
  if (d.squaredNorm() < 1e-18) return 0.0;
  return wrap_angle(std::atan2(d.y(), d.x()) - x[kTheta]);
}

double position_std(const StateCov& P) {
  // √ of the largest eigenvalue of the 2×2 position block.
  const double a = P(0, 0), b = P(0, 1), c = P(1, 1);
  const double m = 0.5 * (a + c), r = std::sqrt(0.25 * (a - c) * (a - c) + b * b);
  return std::sqrt(std::max(0.0, m + r));
}

/// The filter in the loop: an EKF or a particle filter behind one interface.
class LoopFilter {
 public:
  LoopFilter(const BmmParams& bmm, const FilterOptions& o, const State& x0, const StateCov& P0, std::uint64_t seed) {
    if (o.type == FilterType::Ekf) {
      ekf_.emplace(bmm, x0, P0);
      if (o.gate_probability > 0.0) ekf_->set_gate(o.gate_probability);
    } else if (o.type == FilterType::ParticleFilter) {
      pf_.emplace(bmm, x0, P0, o.n_particles, seed, o.resample_threshold);
    } else {
      bad("settings.filter.type = InformationFilter: navigation supports the EKF and the particle filter");
    }
  }
  void predict(const Control& u) {
    if (ekf_) ekf_->predict(u);
    else pf_->predict(u);
  }
  UpdateResult update(const MeasurementModel& m, const Eigen::Ref<const Eigen::VectorXd>& z) {
    return ekf_ ? ekf_->update(m, z) : pf_->update(m, z);
  }
  void estimate(State& x, StateCov& P) const {
    if (ekf_) {
      x = ekf_->x();
      P = ekf_->P();
    } else {
      x = pf_->mean();
      P = pf_->covariance(x);
    }
  }

 private:
  std::optional<Ekf> ekf_;
  std::optional<ParticleFilter> pf_;
};

/// The path being followed (the safe path, or it with detours spliced in).
struct ActivePath {
  std::shared_ptr<const PathSegments> segments;
  const Corridor& corridor() const { return segments->corridor(); }
};

}  // namespace

// ---------------------------------------------------------------------------
// names and validation

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
  }
  return "unknown";
}

void SensorSettings::validate() const {
  position.validate();
  if (!landmarks.allFinite()) bad("sensors.landmarks: every landmark position must be finite");
  require_finite_positive(max_range, "sensors.max_range");
  require_finite_positive(field_of_view, "sensors.field_of_view");
  if (min_landmarks < 0) bad("sensors.min_landmarks = " + std::to_string(min_landmarks) + ": must be >= 0");
  if (position_every < 1) bad("sensors.position_every = " + std::to_string(position_every) + ": must be >= 1");
  require_finite_positive(imu_speed_std, "sensors.imu_speed_std");
  require_finite_positive(imu_heading_std, "sensors.imu_heading_std");
  param_set<SensorSettings>().check(*this, "sensors.");
}

int SensorSettings::landmarks_in_view(const State& x) const {
  const double r2 = max_range * max_range;
  const bool all_round = field_of_view >= 2.0 * kPi;
  const double half = 0.5 * field_of_view;
  const double c = std::cos(x[kTheta]), s = std::sin(x[kTheta]);
  const double cos_half = std::cos(half);
  int n = 0;
  for (Eigen::Index i = 0; i < landmarks.rows(); ++i) {
    const double dx = landmarks(i, 0) - x[kX], dy = landmarks(i, 1) - x[kY];
    const double d2 = dx * dx + dy * dy;
    if (d2 > r2) continue;
    if (!all_round) {
      // inside the FOV: angle to the heading ≤ half  ⇔  cos(angle) ≥ cos(half)
      const double along = c * dx + s * dy;
      if (d2 > 0.0 && along < cos_half * std::sqrt(d2)) continue;
    }
    ++n;
  }
  return n;
}

void NavigationProblem::validate() const {
  check_points(path, "problem.path", 2);
  zones.validate();
  map.validate();
  bmm.validate();
}

void NavigationSettings::validate() const {
  require_finite_positive(cruise_speed, "settings.cruise_speed");
  require_finite_positive(arrival_radius, "settings.arrival_radius");
  if (max_steps < 0 || max_steps > kMaxSteps)
    bad("settings.max_steps = " + std::to_string(max_steps) + ": must be in [0, " + std::to_string(kMaxSteps) +
        "] (0 = automatic)");
  segments.validate();
  require_finite_positive(lookahead, "settings.lookahead");
  require_finite_positive(step_back_speed, "settings.step_back_speed");
  require_finite_positive(sensing_range, "settings.sensing_range");
  if (obstacle_check_every < 1)
    bad("settings.obstacle_check_every = " + std::to_string(obstacle_check_every) + ": must be >= 1");
  require_finite_positive(replan_lookahead, "settings.replan_lookahead");
  if (max_replans < 0) bad("settings.max_replans = " + std::to_string(max_replans) + ": must be >= 0");
  planner.validate();
  require_finite_nonneg(corridor_margin, "settings.corridor_margin");
  require_finite_positive(lost_position_std, "settings.lost_position_std");
  if (filter.type == FilterType::ParticleFilter && filter.n_particles < 1)
    bad("settings.filter.n_particles = " + std::to_string(filter.n_particles) + ": must be >= 1");
  if (!(filter.resample_threshold >= 0.0 && filter.resample_threshold <= 1.0))
    bad("settings.filter.resample_threshold = " + num(filter.resample_threshold) + ": must be in [0, 1]");
  if (!(filter.gate_probability >= 0.0 && filter.gate_probability < 1.0))
    bad("settings.filter.gate_probability = " + num(filter.gate_probability) + ": must be in [0, 1)");
  if (filter.type == FilterType::InformationFilter)
    bad("settings.filter.type = InformationFilter: navigation supports the EKF and the particle filter");
  param_set<NavigationSettings>().check(*this, "settings.");
}

// ---------------------------------------------------------------------------
// [SafeNav Algs. 1–2]

Control centroid_control(const PathSegments& segments, const State& estimate, double cruise_speed) {
  check_finite_state(estimate, "estimate");
  require_finite_positive(cruise_speed, "cruise_speed");
  const Eigen::Vector2d p = estimate.head<2>();
  const CentroidTarget t = segments.nearest_centroid_ahead(p);
  const Eigen::Vector2d target = t.ahead ? t.point : Eigen::Vector2d(segments.corridor().path().bottomRows<1>().transpose());
  return Control(cruise_speed, heading_to(estimate, target));
}

ChullDecision chull_control(const PathSegments& segments, const Bmm& bmm, const State& estimate, double cruise_speed,
                            double lookahead, double step_back_speed, const ObstacleChecker* obstacles) {
  check_finite_state(estimate, "estimate");
  require_finite_positive(cruise_speed, "cruise_speed");
  require_finite_positive(lookahead, "lookahead");
  require_finite_positive(step_back_speed, "step_back_speed");
  const Corridor& corridor = segments.corridor();
  const Eigen::Vector2d p = estimate.head<2>();
  const PathProjection proj = corridor.project(p);
  ChullDecision d;
  d.segment = segments.segment_at(proj.arc_length);
  const int k = d.segment;
  // Outside every adjacent hull (k−1, k, k+1): step back toward the path.
  const bool inside_adjacent = segments.in_current_or_next(k, p) || (k > 0 && segments.hull_contains(k - 1, p));
  if (!inside_adjacent) {
    const Eigen::Vector2d foot = (proj.foot - p).squaredNorm() > 1e-18
                                     ? proj.foot
                                     : Eigen::Vector2d(proj.foot + corridor.tangent_at(proj.arc_length));
    d.control = Control(step_back_speed, heading_to(estimate, foot));
    d.action = ChullAction::StepBack;
    d.predicted = bmm.predict(estimate, d.control).head<2>();
    return d;
  }
  // Default command: toward the look-ahead point on the safe path; the look-
  // ahead shrinks (halving, down to 1/8) while the chord to it hits an obstacle.
  double la = lookahead;
  Eigen::Vector2d aim = corridor.point_at(proj.arc_length + la);
  if (obstacles) {
    while (la > lookahead / 8.0 && !obstacles->segment_free(p, aim)) {
      la *= 0.5;
      aim = corridor.point_at(proj.arc_length + la);
    }
  }
  Control u(cruise_speed, heading_to(estimate, aim));
  State pred = bmm.predict(estimate, u);
  if (segments.in_current_or_next(k, pred.head<2>())) {  // [SafeNav-ext Alg. 1 l. 13] (conf l. 10)
    d.control = u;
    d.action = ChullAction::Keep;
    d.predicted = pred.head<2>();
    return d;
  }
  // Corrective control ([SafeNav-ext Alg. 1 l. 17], conf l. 13): back toward the path, 1 m ahead of the foot.
  u = Control(cruise_speed, heading_to(estimate, corridor.point_at(proj.arc_length + 1.0)));
  d.control = u;
  d.action = ChullAction::Corrective;
  d.predicted = bmm.predict(estimate, u).head<2>();
  return d;
}

// ---------------------------------------------------------------------------
// Navigator

struct Navigator::Impl {
  NavigationProblem problem;
  NavigationSettings settings;
  SensorSettings sensors;
  std::shared_ptr<const PathSegments> segments;  // of the safe path
  ObstacleChecker obstacles;                     // the true obstacles with the planning clearance
  ObstacleChecker collisions;                    // the true obstacles, no clearance
  MeasurementModel position_model;
  MeasurementModel imu_model;
  Bmm bmm;
  int max_steps = 0;

  static PlanningMap no_clearance(PlanningMap m) {
    m.clearance = 0.0;
    return m;
  }

  Impl(NavigationProblem p, NavigationSettings s, SensorSettings se)
      : problem(std::move(p)),
        settings(std::move(s)),
        sensors(std::move(se)),
        obstacles((problem.validate(), problem.map)),
        collisions(no_clearance(problem.map)),
        position_model(MeasurementModel::position(Eigen::Matrix2d::Identity())),
        imu_model(MeasurementModel::speed_heading(Eigen::Matrix2d::Identity())),
        bmm(problem.bmm) {
    settings.validate();
    sensors.validate();
    segments = std::make_shared<const PathSegments>(Corridor(problem.path, problem.zones), settings.segments);
    position_model = MeasurementModel::position(sensors.position.reported_cov());
    Eigen::Matrix2d Ri = Eigen::Vector2d(sensors.imu_speed_std * sensors.imu_speed_std,
                                         sensors.imu_heading_std * sensors.imu_heading_std).asDiagonal();
    imu_model = MeasurementModel::speed_heading(Ri);
    const double L = segments->corridor().length();
    const double automatic =
        std::ceil(3.0 * L / (settings.cruise_speed * problem.bmm.dt * problem.bmm.terrain_factor())) + 200.0;
    if (settings.max_steps == 0 && !(automatic <= NavigationSettings::kMaxSteps))
      bad("automatic max_steps = 3·L/(cruise_speed·dt·terrain factor) + 200 = " + num(automatic) + " exceeds " +
          std::to_string(NavigationSettings::kMaxSteps) + " (path length L = " + num(L) + " m, cruise_speed = " +
          num(settings.cruise_speed) + " m/s, dt = " + num(problem.bmm.dt) + " s, terrain factor = " +
          num(problem.bmm.terrain_factor()) + "): raise the speed or dt, or set settings.max_steps");
    max_steps = settings.max_steps > 0 ? settings.max_steps : static_cast<int>(automatic);
  }

  /// [SafeNav-ext Alg. 4 l. 8] (= conf Alg. 3 l. 6): whether the way ahead of a vehicle at p (arc length
  /// s on the path) hits an obstacle — the chord from p to the path
  /// (look-ahead point) and the path up to sensing_range of arc beyond s.
  bool blocked_ahead(const Corridor& c, const Eigen::Vector2d& p, double s) const {
    const double s1 = std::min(c.length(), s + settings.sensing_range);
    Eigen::Vector2d a = p;
    const Eigen::VectorXd& vs = c.vertex_arc_lengths();
    Eigen::Index i = 0;
    while (i < vs.size() && vs[i] <= s) ++i;
    for (; i < vs.size() && vs[i] < s1; ++i) {
      const Eigen::Vector2d b = c.path().row(i).transpose();
      if (!collisions.segment_free(a, b)) return true;
      a = b;
    }
    return !collisions.segment_free(a, c.point_at(s1));
  }

  /// Splice a RAw-RRT* detour from p into the active path.  Returns the new
  /// segments, or null when no path was found.
  std::shared_ptr<const PathSegments> detour(const ActivePath& active, const Eigen::Vector2d& p,
                                             std::uint64_t seed, std::string* why) const {
    // Plan locally: in a window around the vehicle and the rejoin point (the
    // whole field when the window would not fit), keeping the planning
    // clearance where the vehicle's own position allows it.
    const Corridor& ac = active.corridor();
    const double s_here = ac.project(p).arc_length;
    const Eigen::Vector2d rejoin = ac.point_at(s_here + settings.replan_lookahead);
    const double margin = settings.replan_lookahead;
    PlanningProblem pp;
    pp.map = problem.map;
    pp.map.lower = pp.map.lower.cwiseMax(p.cwiseMin(rejoin) - Eigen::Vector2d::Constant(margin));
    pp.map.upper = pp.map.upper.cwiseMin(p.cwiseMax(rejoin) + Eigen::Vector2d::Constant(margin));
    pp.central_path = ac.path();
    pp.zones = problem.zones;
    while (pp.map.clearance > 0.05 && !ObstacleChecker(pp.map).point_free(p)) pp.map.clearance *= 0.5;
    if (!ObstacleChecker(pp.map).point_free(p)) pp.map.clearance = 0.0;
    PlannerSettings ps = settings.planner;
    ps.seed = seed;
    PlanResult r;
    try {
      // The goal slides along the path past blocked points, possibly out of the window.
      r = replan(pp, p, settings.replan_lookahead, ps);
    } catch (const std::invalid_argument&) {
      r = PlanResult{};
    }
    if (!r.success) {
      pp.map.lower = problem.map.lower;
      pp.map.upper = problem.map.upper;
      try {
        r = replan(pp, p, settings.replan_lookahead, ps);
      } catch (const std::invalid_argument& e) {  // e.g. the estimate lies inside an obstacle
        *why = e.what();
        return nullptr;
      }
    }
    if (!r.success || r.path.rows() < 2) {
      *why = "RAw-RRT* found no path (" + to_string(r.status) + ", " + std::to_string(r.iterations) + " iterations)";
      return nullptr;
    }
    const Corridor& c = active.corridor();
    const Eigen::Vector2d goal = r.path.bottomRows<1>().transpose();
    const double s_goal = c.project(goal).arc_length;
    const Eigen::VectorXd& vs = c.vertex_arc_lengths();
    std::vector<Eigen::Vector2d> pts;
    for (Eigen::Index i = 0; i < r.path.rows(); ++i) pts.emplace_back(r.path.row(i).transpose());
    for (Eigen::Index i = 0; i < vs.size(); ++i)
      if (vs[i] > s_goal + 1e-9) pts.emplace_back(c.path().row(i).transpose());
    Points2 np(static_cast<Eigen::Index>(pts.size()), 2);
    for (std::size_t i = 0; i < pts.size(); ++i) np.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
    return std::make_shared<const PathSegments>(Corridor(np, problem.zones), settings.segments);
  }
};

Navigator::Navigator(NavigationProblem problem, NavigationSettings settings, SensorSettings sensors)
    : impl_(std::make_unique<Impl>(std::move(problem), std::move(settings), std::move(sensors))) {}
Navigator::~Navigator() = default;
Navigator::Navigator(Navigator&&) noexcept = default;
Navigator& Navigator::operator=(Navigator&&) noexcept = default;

const NavigationProblem& Navigator::problem() const { return impl_->problem; }
const NavigationSettings& Navigator::settings() const { return impl_->settings; }
const SensorSettings& Navigator::sensors() const { return impl_->sensors; }
const PathSegments& Navigator::segments() const { return *impl_->segments; }
int Navigator::max_steps() const { return impl_->max_steps; }

TrialResult Navigator::run(std::uint64_t seed, const PositionCallback& position) const {
  return run_trial(seed, position, impl_->settings.record);
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
  const NavigationSettings& st = im.settings;
  const SensorSettings& se = im.sensors;
  const BmmParams& bp = im.problem.bmm;
  const Bmm& bmm = im.bmm;
  detail::Rng motion_rng(derive_seed(seed, 0));
  detail::Rng sensor_rng(derive_seed(seed, 1));

  ActivePath active{im.segments};
  const Corridor& safe = im.segments->corridor();
  const Eigen::Vector2d destination = safe.path().bottomRows<1>().transpose();

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
  auto fix = [&](const State& x, int step, Eigen::Vector2d& z, Eigen::Matrix2d& R) -> bool {
    if (position_cb) {
      if (!position_cb(x, step, z, R)) return false;
      if (!z.allFinite() || !R.allFinite())
        throw std::runtime_error("position callback returned a non-finite fix at step " + std::to_string(step));
      return true;
    }
    if (src.needs_landmarks && se.landmarks_in_view(x) < se.min_landmarks) return false;
    if (!source_noise.sample(x.head<2>(), sensor_draws, z)) return false;
    R = src.reported_cov();
    return true;
  };

  // Initial estimate: a LanBLoc fix (if one is available) and the IMU.
  State x0 = truth;
  StateCov P0 = StateCov::Zero();
  {
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
  }
  LoopFilter filter(bp, st.filter, x0, P0, derive_seed(seed, 2));

  TrialResult res;
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
  Eigen::Vector2d prev_est = x0.head<2>();
  double est_length = 0.0, loc_sum = 0.0, wrs_est = 0.0, wrs_true = 0.0, max_dev = 0.0;
  std::vector<Eigen::Vector2d> est_points;
  est_points.reserve(static_cast<std::size_t>(N) + 1);

  State xe = x0;
  StateCov Pe = P0;
  auto record = [&](int row, const Eigen::Vector2d& pred, const Eigen::Vector2d* meas) {
    const double dev = safe.project(truth.head<2>()).distance;
    max_dev = std::max(max_dev, dev);
    wrs_true += wrs(dev, im.problem.zones);
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
    res.position_std[row] = position_std(Pe);
  };
  {
    Eigen::Vector2d z0 = x0.head<2>();
    record(0, x0.head<2>(), &z0);
  }

  const Eigen::Vector4d sigma(bp.position_noise, bp.position_noise, bp.speed_noise, bp.heading_noise);
  TrialOutcome outcome = TrialOutcome::StepLimit;
  std::string reason = "no arrival within " + std::to_string(N) + " steps";
  int step = 0;
  while (step < N) {
    // 1–2. Obstacles ahead [SafeNav-ext Alg. 4 ll. 7–9].
    if (st.replan && step % st.obstacle_check_every == 0) {
      const double s = active.corridor().project(xe.head<2>()).arc_length;
      if (im.blocked_ahead(active.corridor(), xe.head<2>(), s)) {
        if (res.replans >= st.max_replans) {
          outcome = TrialOutcome::NoPath;
          reason = "path blocked after " + std::to_string(res.replans) + " replans (max_replans)";
          break;
        }
        std::string why;
        auto next = im.detour(active, xe.head<2>(), derive_seed(seed, 16 + res.replans), &why);
        ++res.replans;
        if (!next) {
          outcome = TrialOutcome::NoPath;
          reason = "path blocked at s = " + num(s) + " m and no detour: " + why;
          break;
        }
        active.segments = std::move(next);
      }
    }
    // 1. Control from the estimate.
    Control u;
    Eigen::Vector2d pred;
    if (st.method == NavigationMethod::Centroid) {
      u = centroid_control(*active.segments, xe, st.cruise_speed);
      pred = bmm.predict(xe, u).head<2>();
    } else {
      const ChullDecision d = chull_control(*active.segments, bmm, xe, st.cruise_speed, st.lookahead,
                                            st.step_back_speed, &im.obstacles);
      u = d.control;
      pred = d.predicted;
      switch (d.action) {
        case ChullAction::Keep: ++res.chull_default; break;
        case ChullAction::Corrective: ++res.chull_corrective; break;
        case ChullAction::StepBack: ++res.chull_step_back; break;
      }
    }
    ++step;
    if (rec) res.controls.row(step - 1) = u.transpose();
    // 3. Move the true vehicle.
    const Eigen::Vector2d before = truth.head<2>();
    Eigen::Vector4d eps;
    for (int i = 0; i < 4; ++i) eps[i] = sigma[i] * motion_rng.normal();
    truth = bmm.transition(truth, u, eps);
    // 4. Measure and update.
    filter.predict(u);
    Eigen::Vector2d z;
    Eigen::Matrix2d R;
    bool have_fix = false;
    if (step % se.position_every == 0) {
      have_fix = fix(truth, step, z, R);
      if (have_fix) {
        const UpdateResult ur = position_cb ? filter.update(MeasurementModel::position(R), z)
                                            : filter.update(im.position_model, z);
        if (ur.accepted) ++res.position_fixes;
        else ++res.rejected;
      } else {
        ++res.dropouts;
      }
    }
    if (se.imu) {
      const Eigen::Vector2d zi(std::max(0.0, truth[kV] + se.imu_speed_std * sensor_rng.normal()),
                               wrap_angle(truth[kTheta] + se.imu_heading_std * sensor_rng.normal()));
      if (!filter.update(im.imu_model, zi).accepted) ++res.rejected;
    }
    filter.estimate(xe, Pe);
    // 5. Record.
    record(step, pred, have_fix ? &z : nullptr);
    // Ends.
    if (!im.collisions.segment_free(before, truth.head<2>())) {
      outcome = TrialOutcome::Collision;
      reason = "collision at (" + num(truth[kX]) + ", " + num(truth[kY]) + ") at step " + std::to_string(step);
      break;
    }
    const double dev = active.corridor().project(truth.head<2>()).distance;
    if (dev > im.problem.zones.half_width + st.corridor_margin) {
      outcome = TrialOutcome::LeftCorridor;
      reason = "left the corridor at step " + std::to_string(step) + ": deviation " + num(dev) + " m > " +
               num(im.problem.zones.half_width + st.corridor_margin) + " m";
      break;
    }
    const double pstd = position_std(Pe);
    if (!(pstd <= st.lost_position_std)) {
      outcome = TrialOutcome::LostLocalization;
      reason = "position std " + num(pstd) + " m > " + num(st.lost_position_std) + " m at step " + std::to_string(step);
      break;
    }
    if ((xe.head<2>() - destination).norm() <= st.arrival_radius) {
      outcome = TrialOutcome::Arrived;
      reason = "arrived in " + std::to_string(step) + " steps";
      break;
    }
  }

  res.outcome = outcome;
  res.success = outcome == TrialOutcome::Arrived;
  res.reason = reason;
  res.steps = step;
  const Eigen::Index rows = step + 1;
  if (rec) {
    res.truth.conservativeResize(rows, 4);
    res.estimate.conservativeResize(rows, 4);
    res.predicted.conservativeResize(rows, 2);
    res.measured.conservativeResize(rows, 2);
    res.controls.conservativeResize(step, 2);
    res.position_std.conservativeResize(rows);
    res.followed_path = active.corridor().path();
  }
  // Metrics [SafeNav-ext eqs. 20–23] against the safe path (and the truth).
  Points2 est(rows, 2);
  for (Eigen::Index i = 0; i < rows; ++i) est.row(i) = est_points[static_cast<std::size_t>(i)].transpose();
  TrialMetrics& m = res.metrics;
  m.path_ade = safe.distance(est).mean();
  m.goal_fde = (est.bottomRows<1>().transpose() - destination).norm();
  m.path_error_percent = std::abs(est_length - safe.length()) / safe.length() * 100.0;
  m.awrs = wrs_est / double(rows);
  m.awrs_true = wrs_true / double(rows);
  m.truth_ade = loc_sum / double(rows);
  m.truth_fde = (xe.head<2>() - truth.head<2>()).norm();
  m.max_deviation = max_dev;
  res.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace safenav
