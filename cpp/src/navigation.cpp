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
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "rng.hpp"
#include "declare.hpp"
#include "errors.hpp"
#include "navigation_trial.hpp"
#include "safenav/trilateration.hpp"

namespace safenav {

template <>
const ParamSet<SensorSettings>& param_set<SensorSettings>();  // navigation_settings.cpp

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using detail::bad;
using detail::num;

}  // namespace

namespace navigation_detail {

/// The start fix against the start point known roughly (ours: with the gate on).  Three ranges,
/// one of them faulty, can fit the start's reflection across the other two landmarks' line: a fix
/// 7 m off that passes its own χ² test (one range more than the unknowns).  The rough start
/// s ~ N(truth, σ₀²I) (σ₀ = unfixed_start_std(), drawn from a stream of its own so that the
/// sensor's draws stay as they were) and the fix fail the gate together where
/// dᵀ(R + σ₀²I)⁻¹d > χ²₂ (d = z − s, the filter's gate probability).  Which of the two is wrong
/// cannot be told then: the prior is their midpoint (z + s)/2 with a covariance that holds either
/// one, R + σ₀²I + ddᵀ/4 (the equal-weight mixture's moments, (R + σ₀²I)/2 + ddᵀ/4, are narrower
/// than the rough start's own σ₀ across d, and the next fix failed the gate there), so that the
/// next fix, near either, passes the gate.
void Trial::dispute_start_fix(Eigen::Vector2d& z, Eigen::Matrix2d& R) {
  detail::Rng rng(start_seed_);
  const double s0 = se_.unfixed_start_std();
  Eigen::Vector2d rough = truth_.head<2>();
  rough.x() += s0 * rng.normal();
  rough.y() += s0 * rng.normal();
  const Eigen::Vector2d d = z - rough;
  const Eigen::Matrix2d S = R + s0 * s0 * Eigen::Matrix2d::Identity();
  if (!(d.dot(S.ldlt().solve(d)) > fit_threshold(2))) return;
  ++res_.start_disputed;
  z = 0.5 * (z + rough);
  R = S + 0.25 * d * d.transpose();
}

/// The initial estimate (the localizer's prior): a LanBLoc fix, if one is available (checked
/// against the rough start: dispute_start_fix), and the IMU.
void Trial::initialize() {
  State x0 = truth_;
  Eigen::Vector2d z;
  Eigen::Matrix2d R;
  const bool fixed = frames_ ? first_frame(z, R) : fix(truth_, 0, z, R);
  if (fixed) {
    if (gate_ > 0.0) dispute_start_fix(z, R);
    x0.head<2>() = z;
  } else {
    // No fix at the start: the start point is known only roughly.
    x0.head<2>() += se_.unfixed_start_std() * Eigen::Vector2d(sensor_rng_.normal(), sensor_rng_.normal());
  }
  x0[kV] = std::max(0.0, truth_[kV] + se_.imu_speed_std * sensor_rng_.normal());
  x0[kTheta] = wrap_angle(truth_[kTheta] + se_.imu_heading_std * sensor_rng_.normal());
  guidance_.localizer().initialize(0.0, x0, se_.start_covariance(fixed ? &R : nullptr));
}

void Trial::start_recording() {
  res_.truth.resize(N_ + 1, 4);
  res_.estimate.resize(N_ + 1, 4);
  res_.predicted.resize(N_ + 1, 2);
  res_.measured.resize(N_ + 1, 2);
  res_.controls.resize(N_, 2);
  res_.position_std.resize(N_ + 1);
}

void Trial::record(int row, const Eigen::Vector2d& predicted, const Eigen::Vector2d* measured) {
  const Localizer& loc = guidance_.localizer();
  const State& xe = loc.x();
  score_.add(xe, loc.P(), truth_);
  const double dev = safe_.project(truth_.head<2>()).distance;
  score_.add_risk(dev, wrs(dev, zones_), safe_.wrs(Eigen::Vector2d(xe.head<2>())));
  if (!rec_) return;
  res_.truth.row(row) = truth_.transpose();
  res_.estimate.row(row) = xe.transpose();
  res_.predicted.row(row) = predicted.transpose();
  if (measured) res_.measured.row(row) = measured->transpose();
  else res_.measured.row(row).setConstant(kNaN);
  res_.position_std[row] = loc.position_std();
}

/// Safety along the true step a–b: clearance (cached lower bound, as the guard's) and hazards.
void Trial::track_safety(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  if (clear_d_ - std::max((a - clear_p_).norm(), (b - clear_p_).norm()) < score_.min_clearance()) {
    score_.add_clearance(collisions_.keep_out_distance(a, b));
    clear_p_ = b;
    clear_d_ = collisions_.keep_out_distance(b, b);
  }
  const ObstacleChecker::HazardStep h = collisions_.hazard_step(a, b);
  score_.add_hazard(h.length, h.exposure, h.inside, bp_.dt);
}

/// 1–2. The vehicle asks guidance for its control: obstacles ahead and
/// detours [SafeNav-ext Alg. 4 ll. 7–9], then CHull or Centroid.  False when
/// the trial ends with no path.
bool Trial::command(int step, Command& cmd) {
  cmd = guidance_.command(step * bp_.dt);
  res_.guard_slow += (cmd.events & kGuardSlow) != 0;
  res_.guard_steer += (cmd.events & kGuardSteer) != 0;
  res_.guard_hold += (cmd.events & kGuardHold) != 0;
  res_.guard_recover += (cmd.events & kGuardRecover) != 0;
  res_.stale_input += (cmd.events & kStaleInput) != 0;
  if (cmd.status == GuidanceStatus::NoPath || cmd.status == GuidanceStatus::Blocked) {
    outcome_ = cmd.status == GuidanceStatus::NoPath ? TrialOutcome::NoPath : TrialOutcome::Blocked;
    reason_ = guidance_.detail();
    if (cmd.status == GuidanceStatus::Blocked) reason_ += " (step " + std::to_string(step) + ")";
    return false;
  }
  if (st_.method == NavigationMethod::CHull) {
    switch (cmd.action) {
      case ChullAction::Keep: ++res_.chull_default; break;
      case ChullAction::Corrective: ++res_.chull_corrective; break;
      case ChullAction::StepBack: ++res_.chull_step_back; break;
    }
  }
  return true;
}

/// 4. The vehicle's inputs after its motion: a LanBLoc fix, the IMU.  True
/// when a fix was measured (into z).
bool Trial::measure(int step, double t, Eigen::Vector2d& z) {
  Eigen::Matrix2d R;
  bool have_fix = false;
  if (step % se_.position_every == 0 && frames_) {
    have_fix = frame(step, t, z);
  } else if (step % se_.position_every == 0) {
    have_fix = fix(truth_, step, z, R);
    if (have_fix) {
      if (guidance_.fix(t, z, R).applied()) {
        ++res_.position_fixes;
        res_.faults_through += fix_faults_;
      } else {
        ++res_.rejected;
      }
    } else {
      ++res_.dropouts;
    }
  }
  if (se_.imu) {
    const Eigen::Vector2d zi(std::max(0.0, truth_[kV] + se_.imu_speed_std * sensor_rng_.normal()),
                             wrap_angle(truth_[kTheta] + se_.imu_heading_std * sensor_rng_.normal()));
    if (!guidance_.speed_heading(t, zi, imu_R_).applied()) ++res_.rejected;
  }
  return have_fix;
}

/// The ends after a step: the truth's (collision, corridor), then guidance's (lost, arrived).
bool Trial::ended(int step, const Eigen::Vector2d& before) {
  if (!collisions_.segment_free(before, truth_.head<2>())) {
    outcome_ = TrialOutcome::Collision;
    reason_ = "collision at (" + num(truth_[kX]) + ", " + num(truth_[kY]) + ") at step " + std::to_string(step);
    return true;
  }
  const double dev = guidance_.path().corridor().project(truth_.head<2>()).distance;
  if (dev > zones_.half_width + st_.corridor_margin) {
    outcome_ = TrialOutcome::LeftCorridor;
    reason_ = "left the corridor at step " + std::to_string(step) + ": deviation " + num(dev) + " m > " +
              num(zones_.half_width + st_.corridor_margin) + " m";
    return true;
  }
  const GuidanceStatus gs = guidance_.status();
  if (gs == GuidanceStatus::LostLocalization) {
    outcome_ = TrialOutcome::LostLocalization;
    reason_ = "position std " + num(guidance_.localizer().position_std()) + " m > " + num(st_.lost_position_std) +
              " m at step " + std::to_string(step);
    return true;
  }
  if (gs == GuidanceStatus::Arrived) {
    outcome_ = TrialOutcome::Arrived;
    reason_ = "arrived in " + std::to_string(step) + " steps";
    return true;
  }
  return false;
}

TrialResult Trial::run() {
  initialize();
  if (rec_) start_recording();
  clear_p_ = truth_.head<2>();
  clear_d_ = collisions_.keep_out_distance(clear_p_, clear_p_);
  score_.add_clearance(clear_d_);
  {
    const Eigen::Vector2d z0 = guidance_.localizer().x().head<2>();
    record(0, z0, &z0);
  }
  const Eigen::Vector4d sigma(bp_.position_noise, bp_.position_noise, bp_.speed_noise, bp_.heading_noise);
  reason_ = "no arrival within " + std::to_string(N_) + " steps";
  int step = 0;
  Command cmd;
  while (step < N_) {
    if (!command(step, cmd)) break;
    const Control& u = cmd.control;
    ++step;
    const double t1 = step * bp_.dt;
    if (rec_) res_.controls.row(step - 1) = u.transpose();
    // 3. Move the true vehicle.
    const Eigen::Vector2d before = truth_.head<2>();
    Eigen::Vector4d eps;
    for (int i = 0; i < 4; ++i) eps[i] = sigma[i] * motion_rng_.normal();
    truth_ = bmm_.transition(truth_, u, eps);
    // 4. The vehicle's inputs: its commanded motion, a LanBLoc fix, the IMU.
    guidance_.motion(t1, u);
    Eigen::Vector2d z;
    const bool have_fix = measure(step, t1, z);
    // 5. Record.
    record(step, cmd.predicted, have_fix ? &z : nullptr);
    track_safety(before, truth_.head<2>());
    if (ended(step, before)) break;
  }
  finish(step);
  res_.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  return std::move(res_);
}

void Trial::finish(int step) {
  TrialResult& res = res_;
  res.outcome = outcome_;
  res.success = outcome_ == TrialOutcome::Arrived;
  res.reason = reason_;
  res.steps = step;
  res.replans = guidance_.replans();
  res.resets = guidance_.localizer().counts().resets;
  const Eigen::Index rows = step + 1;
  if (rec_) {
    res.truth.conservativeResize(rows, 4);
    res.estimate.conservativeResize(rows, 4);
    res.predicted.conservativeResize(rows, 2);
    res.measured.conservativeResize(rows, 2);
    res.controls.conservativeResize(step, 2);
    res.position_std.conservativeResize(rows);
    res.followed_path = guidance_.path().corridor().path();
  }
  // Metrics [SafeNav-ext eqs. 20–23] against the safe path (and the truth).
  const Eigen::Vector2d destination = safe_.path().bottomRows<1>().transpose();
  const Points2 est = score_.estimates();
  TrialMetrics& m = res.metrics;
  m.path_ade = safe_.distance(est).mean();
  m.goal_fde = (est.bottomRows<1>().transpose() - destination).norm();
  m.path_error_percent = std::abs(score_.length() - safe_.length()) / safe_.length() * 100.0;
  score_.fill(m);
}

}  // namespace navigation_detail

using navigation_detail::Trial;

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
    // No history for late measurements: each step's inputs come at the time of its motion input
    // (Trial::run: motion(t), then the fix or frame and the IMU at t), so none is ever older than
    // the filter and Localizer::take applies each one as it would with a history; the history
    // would only copy the filter before every motion input.
    ls.max_delay = 0.0;
    return ls;
  }
  static PlanningMap no_clearance(PlanningMap m) {
    m.clearance = 0.0;
    return m;
  }

  // The guard looks with the simulated camera.
  static NavigationSettings with_camera(NavigationSettings s, const SensorSettings& se) {
    se.validate();  // first, so that a bad sensor is named as such
    s.guard.look_with_camera(se.field_of_view, se.max_range, se.min_landmarks, se.occlusion);
    return s;
  }

  Impl(NavigationProblem p, NavigationSettings s, SensorSettings se)
      : guidance(p, with_camera(s, se), loop_filter(s), se.landmarks, se.landmark_ids),
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
RowMatrixX4 Navigator::nominal_trajectory() const { return impl_->guidance.nominal_trajectory(impl_->max_steps); }

TrialResult Navigator::run(std::uint64_t seed, const PositionCallback& position) const {
  return run_trial(seed, position, impl_->guidance.settings().record);
}

std::vector<TrialResult> Navigator::run_many(const std::vector<std::uint64_t>& seeds) const {
  std::vector<TrialResult> out;
  out.reserve(seeds.size());
  for (std::uint64_t s : seeds) out.push_back(run_trial(s, nullptr, false));
  return out;
}

TrialResult Navigator::run_frames(std::uint64_t seed, std::shared_ptr<const LanBLocFrontEnd> front_end,
                                  const FrameCallback& frames) const {
  if (!front_end) bad("run_frames: front_end is null");
  if (!frames) bad("run_frames: frames is empty");
  return run_trial(seed, nullptr, impl_->guidance.settings().record, &frames, std::move(front_end));
}

TrialResult Navigator::run_trial(std::uint64_t seed, const PositionCallback& position_cb, bool rec,
                                 const FrameCallback* frames, std::shared_ptr<const LanBLocFrontEnd> front_end) const {
  const Impl& im = *impl_;
  Trial trial(im.guidance, im.sensors, im.collisions, im.imu_R, im.max_steps, seed, position_cb, rec, frames,
              std::move(front_end));
  return trial.run();
}


}  // namespace safenav
