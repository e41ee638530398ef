// The online Localizer: LanBLoc-BMM ticked with timestamped inputs
// (safenav/localizer.hpp).
#include "safenav/localizer.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <utility>

#include "errors.hpp"
#include "localizer_fit.hpp"
#include "safenav/filter.hpp"
#include "safenav/seed.hpp"
#include "safenav/params.hpp"

namespace safenav {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// Timestamps this close are the same instant [s].
constexpr double kSameTime = 1e-9;
/// Starting from ranges: σ added to the fit's position [m] and heading [rad]
/// (the fit's own covariance ignores the odometry's drift within the window).
constexpr std::size_t kMaxBufferedRanges = 100000;
constexpr double kInitPositionFloor = 0.05, kInitHeadingFloor = 0.01;

using detail::bad;

std::string num(double v) { return detail::num(v, 12); }

void check_time(double t, const char* what) {
  if (!std::isfinite(t)) bad(std::string(what) + ": time t = " + num(t) + " is not finite");
}

using detail::BufferedHeading;
using detail::BufferedObs;

/// A position known before the heading (trilateration or a fix), with the
/// motion-integrated pose at that time.
struct Anchor {
  double t;
  Eigen::Vector2d p;
  Eigen::Matrix2d cov;
  Eigen::Vector3d odo;  // (x, y, θ) of the motion integral in its own frame
};

}  // namespace

const char* to_string(InputStatus status) {
  switch (status) {
    case InputStatus::Applied: return "applied";
    case InputStatus::Rejected: return "rejected";
    case InputStatus::Late: return "late";
    case InputStatus::Buffered: return "buffered";
    case InputStatus::Ignored: return "ignored";
    case InputStatus::Reset: return "reset";
  }
  return "unknown";
}

double position_std(const StateCov& P) {
  // √ of the largest eigenvalue of the 2×2 position block.
  const double a = P(0, 0), b = P(0, 1), c = P(1, 1);
  const double m = 0.5 * (a + c), r = std::sqrt(0.25 * (a - c) * (a - c) + b * b);
  if (std::isfinite(m + r) || !P.topLeftCorner<2, 2>().allFinite()) return std::sqrt(std::max(0.0, m + r));
  // Entries beyond ~1e154 overflow the squares: the same eigenvalue of P/s, times s.
  const double s = std::max({std::abs(a), std::abs(b), std::abs(c)});
  const double as = a / s, bs = b / s, cs = c / s;
  const double ls = 0.5 * (as + cs) + std::sqrt(0.25 * (as - cs) * (as - cs) + bs * bs);
  return std::sqrt(s) * std::sqrt(std::max(0.0, ls));
}

struct Localizer::Impl {
  LocalizerSettings settings;
  Landmarks landmarks;
  std::vector<int> ids;
  std::unordered_map<int, int> row_of;
  Bmm bmm;
  std::unique_ptr<Filter> filter;  // the EKF or the PF, plain or augmented (safenav/filter.hpp); null until started

  double t_f = kNaN;       // filter time
  double t_motion = kNaN;  // time of the last motion input
  double rate_speed = kNaN, rate_turn = 0.0;  // last motion input: speed, heading change per second
  // Distance and heading change that measurements' predictions (at the last
  // rates) already added since the last motion input: the next one applies
  // only what its own Δd, Δθ still owe ("catch-up").
  double owed_distance = 0.0, owed_heading = 0.0;
  bool from_odometry = false;  // the motion input being applied is wheel odometry
  LocalizerCounts counts;
  int fix_rejections = 0;  // consecutive position fixes rejected by the gate
  State x_none = State::Constant(kNaN);  // the estimate until initialized
  StateCov P_none = StateCov::Constant(kNaN);

  // Initialization from data.
  std::vector<BufferedObs> ranges;  // observations within init_window of the newest motion input
  std::vector<BufferedHeading> headings;  // IMU headings within init_window
  bool fresh = false;  // an observation or heading with a bearing or heading arrived since the last fit
  std::string why = "waiting: no motion input yet";  // Localizer::reason()
  detail::StartWindow::Most most;  // the most distinct landmarks in any window so far
  std::vector<Eigen::Vector4d> track;  // (t, x, y, θ): the motion integral at each motion input
  std::optional<Anchor> anchor;
  Eigen::Vector3d odo = Eigen::Vector3d::Zero();  // motion integral (x, y, θ) in its own frame
  double imu_heading = kNaN, imu_heading_var = kNaN, imu_speed = kNaN, t_imu = kNaN;

  Impl(LocalizerSettings s, Landmarks lm, std::vector<int> id)
      : settings(std::move(s)), landmarks(std::move(lm)), ids(std::move(id)), bmm((settings.validate(), settings.bmm)) {
    if (!landmarks.allFinite()) bad("localizer landmarks: every landmark position must be finite");
    if (ids.empty()) {
      ids.resize(static_cast<std::size_t>(landmarks.rows()));
      for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int>(i);
    }
    if (static_cast<Eigen::Index>(ids.size()) != landmarks.rows())
      bad("localizer ids: " + std::to_string(ids.size()) + " ids for " + std::to_string(landmarks.rows()) +
          " landmarks");
    for (std::size_t i = 0; i < ids.size(); ++i)
      if (!row_of.emplace(ids[i], static_cast<int>(i)).second)
        bad("localizer ids: landmark id " + std::to_string(ids[i]) + " appears twice");
    ranges.reserve(256);
    track.reserve(256);
  }

  /// The first motion input ever covers one nominal step before its time.
  void start_clock(double t) {
    if (std::isfinite(t_motion)) return;
    t_motion = t - bmm.params().dt;
    if (!initialized()) push_pose(t_motion);
  }

  bool initialized() const { return filter != nullptr; }

  void start(double t, const State& x0, const StateCov& P0) { start(t, x0, P0, settings.filter.seed); }

  /// Starts the filter at (x0, P0); a particle filter draws with `seed`.  When
  /// the prior is refused the localizer stays as it was.
  void start(double t, const State& x0, const StateCov& P0, std::uint64_t seed) {
    filter = make_filter(settings.filter, settings.bmm, settings.augment, static_cast<int>(landmarks.rows()), x0, P0,
                         seed);
    fix_rejections = 0;
    t_f = t;
    why = "started at t = " + num(t);
    if (!(t_motion <= t)) t_motion = t;
    owed_distance = owed_heading = 0.0;
    ranges.clear();
    headings.clear();
    track.clear();
    anchor.reset();
  }

  void predict(const Control& u, double dt) { filter->predict(u, dt); }
  /// The motion input u over (t − interval, t] once initialized (Localizer::motion).
  InputResult move(double t, const Control& u, double interval);

  /// The filter's clock and the motion input's rates and debts.
  struct Clock {
    double t_f, t_motion, rate_speed, rate_turn, owed_distance, owed_heading;
  };
  Clock clock() const { return {t_f, t_motion, rate_speed, rate_turn, owed_distance, owed_heading}; }
  void set_clock(const Clock& c) {
    t_f = c.t_f;
    t_motion = c.t_motion;
    rate_speed = c.rate_speed;
    rate_turn = c.rate_turn;
    owed_distance = c.owed_distance;
    owed_heading = c.owed_heading;
  }

  /// Runs `f` (a prediction to t, then an update) as one step: when it
  /// throws, the localizer and its filter are left as they were, and the
  /// error names the input (`what` at t).
  template <class F>
  InputResult atomic(const char* what, double t, F&& f) {
    const Clock saved = clock();
    const LocalizerCounts saved_counts = counts;
    Filter::Transaction tx(*filter);
    try {
      const InputResult r = f();
      tx.commit("filter result");
      return r;
    } catch (const std::invalid_argument& e) {
      set_clock(saved);
      counts = saved_counts;
      bad(std::string(what) + " at t = " + num(t) + ": " + e.what());
    } catch (...) {
      set_clock(saved);
      counts = saved_counts;
      throw;
    }
  }

  /// Bring the filter to time t for a measurement; false when t is late.
  bool advance(double t) {
    if (t < t_f - kSameTime) return false;
    if (t > t_f + kSameTime) {
      const double dt = t - t_f;
      const Control u = std::isfinite(rate_speed) ? Control(rate_speed, rate_turn * dt) : Control(filter->x()[kV], 0.0);
      predict(u, dt);
      owed_distance += u[0] * dt;
      owed_heading += u[1];
      t_f = t;
    }
    return true;
  }

  InputResult counted(const UpdateResult& r) {
    InputResult out;
    out.nis = r.nis;
    out.dim = r.dim;
    out.log_det_s = r.log_det_s;
    out.status = r.accepted ? InputStatus::Applied : InputStatus::Rejected;
    ++(r.accepted ? counts.applied : counts.rejected);
    return out;
  }

  InputResult status(InputStatus s) {
    if (s == InputStatus::Late) ++counts.late;
    if (s == InputStatus::Buffered) ++counts.buffered;
    if (s == InputStatus::Ignored) ++counts.ignored;
    InputResult out;
    out.status = s;
    return out;
  }

  // -- initialization from data ---------------------------------------------

  /// A position known at time t (before initialization): start at once when
  /// a heading is known, else anchor it and wait for init_baseline of motion.
  void position_known(double t, const Eigen::Vector2d& p, const Eigen::Matrix2d& cov) {
    const double speed = std::isfinite(imu_speed) ? imu_speed : (std::isfinite(rate_speed) ? rate_speed : 0.0);
    const double v_var = settings.init_speed_std * settings.init_speed_std;
    if (std::isfinite(imu_heading) && std::abs(t - t_imu) <= settings.init_window) {
      StateCov P0 = StateCov::Zero();
      P0.topLeftCorner<2, 2>() = cov;
      P0(2, 2) = v_var;
      P0(3, 3) = imu_heading_var;
      start(t, State(p.x(), p.y(), std::max(bmm.params().min_speed(), speed), imu_heading), P0);
      return;
    }
    if (!anchor) {
      anchor = Anchor{t, p, cov, odo};
      return;
    }
    const Eigen::Vector2d dodo = odo.head<2>() - anchor->odo.head<2>();
    const Eigen::Vector2d dp = p - anchor->p;
    const double moved = dodo.norm();
    if (moved < settings.init_baseline) return;
    const double pos_var = 0.5 * (cov.trace() + anchor->cov.trace());
    // The two positions must agree with the motion between them, else start over from this one.
    if (std::abs(dp.norm() - moved) > 3.0 * std::sqrt(2.0 * pos_var) + 0.2 * moved) {
      anchor = Anchor{t, p, cov, odo};
      return;
    }
    // Rotation from the motion integral's frame to the world: φ = ∠Δp − ∠Δodo.
    const double phi = std::atan2(dp.y(), dp.x()) - std::atan2(dodo.y(), dodo.x());
    StateCov P0 = StateCov::Zero();
    P0.topLeftCorner<2, 2>() = cov;
    P0(2, 2) = v_var;
    P0(3, 3) = std::min(2.0 * pos_var / (moved * moved), kPi * kPi);
    start(t, State(p.x(), p.y(), std::max(bmm.params().min_speed(), speed), wrap_angle(phi + odo[2])), P0);
  }

  /// The motion integral's pose at a motion input at time t (the first one starts it at 0).
  void push_pose(double t) {
    track.push_back(Eigen::Vector4d(t, odo[0], odo[1], odo[2]));
  }

  /// The start rules (detail::start_rules); sets `why` to what the window holds.
  bool rules_hold(const detail::StartWindow& w) {
    return detail::start_rules(w, settings.init_window, settings.init_min_path, settings.init_min_beacons, most, why);
  }

  /// Starting from data: fit the rigid transform (X, Y, φ) from the motion
  /// integral's frame to the world to the observations and headings of the
  /// last init_window seconds (detail::fit_transform) once a start rule holds
  /// (rules_hold); with bearings or headings only when one arrived since the
  /// last fit.  Starts the filter at the newest motion input when the fit is
  /// good enough (accept_fit).
  void try_fit(double t_now) {
    const double t0 = t_now - settings.init_window;
    track.erase(track.begin(), std::find_if(track.begin(), track.end(), [&](const Eigen::Vector4d& q) { return q[0] >= t0; }));
    if (track.size() < 2) return;
    const double t_first = track.front()[0];
    ranges.erase(std::remove_if(ranges.begin(), ranges.end(), [&](const BufferedObs& r) { return r.t < t_first; }),
                 ranges.end());
    // A heading from before the first motion input is taken at the integral's start.
    headings.erase(std::remove_if(headings.begin(), headings.end(), [&](const BufferedHeading& h) { return h.t < t0; }),
                   headings.end());
    const detail::StartWindow w = detail::start_window(track, ranges, headings, t_now);
    const std::string waiting = why.rfind("waiting", 0) == 0 ? why : std::string();
    if (!rules_hold(w)) return;
    if (w.angles && !fresh) {  // nothing new since the last fit: keep its verdict
      if (!waiting.empty()) why = waiting;
      return;
    }
    fresh = false;
    std::vector<detail::FitObs> obs;
    for (const BufferedObs& r : ranges) {
      if (r.t > t_now) continue;
      const Eigen::Vector3d q = detail::odo_at(track, r.t);
      obs.push_back(detail::FitObs{q.x(), q.y(), q.z(), landmarks(r.row, 0), landmarks(r.row, 1), r.range,
                                   r.range_std, r.bearing, r.bearing_std});
    }
    std::vector<detail::FitHeading> hs;
    for (const BufferedHeading& h : headings)
      if (h.t <= t_now) hs.push_back(detail::FitHeading{detail::odo_at(track, h.t)[2], h.theta, h.std});
    const double k0 = settings.augment.range_scale ? settings.augment.scale_prior : 0.0;
    detail::FitResult fit;
    if (!detail::fit_transform(obs, hs, k0, fit)) {
      why += "; last fit at t = " + num(t_now) +
             (fit.ambiguous ? ": ambiguous (another pose explains the data as well)"
                            : ": degenerate geometry (the data do not fix X, Y and the heading)");
      return;
    }
    accept_fit(t_now, fit);
  }

  /// Starts the filter from a fit when its residual RMS, position σ and (with
  /// bearings or headings) heading σ pass; else records why not.
  void accept_fit(double t_now, const detail::FitResult& fit) {
    const Eigen::Vector3d& th = fit.th;
    // The pose at t_now and the covariance of (x, y, θ) through the transform.
    const double c = std::cos(th[2]), s = std::sin(th[2]);
    const Eigen::Vector4d& q = track.back();
    const double px = th[0] + c * q[1] - s * q[2], py = th[1] + s * q[1] + c * q[2];
    Eigen::Matrix3d Jt = Eigen::Matrix3d::Identity();
    Jt(0, 2) = -s * q[1] - c * q[2];
    Jt(1, 2) = c * q[1] - s * q[2];
    const Eigen::Matrix3d Cp = Jt * fit.C * Jt.transpose();
    const double pos_std = std::sqrt(std::max(Cp(0, 0), Cp(1, 1)));
    const double heading_std = std::sqrt(std::max(0.0, Cp(2, 2)));
    // A range-only fit: its range RMS in metres; with bearings or headings the normalised RMS (in σ).
    const bool angles = fit.angle_rows > 0;
    const double rms = angles ? fit.normalised_rms : fit.range_rms;
    std::ostringstream os;
    const bool kept = fit.rows >= settings.init_min_inlier_share * fit.all_rows;
    os << std::setprecision(3) << fit.rows << " of " << fit.all_rows << " residuals kept, residual RMS " << rms << (angles ? " σ" : " m") << ", position σ " << pos_std
       << " m, heading σ " << heading_std << " rad";
    if (!(kept && rms <= settings.init_max_rms && pos_std <= settings.init_max_pos_std &&
          (!angles || heading_std <= settings.init_max_heading_std))) {
      std::ostringstream lim;
      lim << std::setprecision(3) << " (limits " << settings.init_min_inlier_share << " kept, " << settings.init_max_rms << ", " << settings.init_max_pos_std
          << " m" << (angles ? ", " + num(settings.init_max_heading_std) + " rad" : std::string()) << ")";
      why += "; last fit at t = " + num(t_now) + ": " + os.str() + lim.str();
      return;
    }
    StateCov P0 = StateCov::Zero();
    const int map[3] = {kX, kY, kTheta};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) P0(map[i], map[j]) = settings.init_cov_inflation * Cp(i, j);
    P0(kX, kX) += kInitPositionFloor * kInitPositionFloor;
    P0(kY, kY) += kInitPositionFloor * kInitPositionFloor;
    P0(kTheta, kTheta) += kInitHeadingFloor * kInitHeadingFloor;
    P0(kV, kV) = settings.init_speed_std * settings.init_speed_std;
    const double speed = std::isfinite(rate_speed) ? std::max(bmm.params().min_speed(), rate_speed) : 0.0;
    start(t_now, State(px, py, speed, wrap_angle(th[2] + q[3])), 0.5 * (P0 + P0.transpose()));
    why += " from the data (" + os.str() + ")";
  }
};

Localizer::Localizer(LocalizerSettings settings, Landmarks landmarks, std::vector<int> ids)
    : impl_(std::make_unique<Impl>(std::move(settings), std::move(landmarks), std::move(ids))) {}
Localizer::~Localizer() = default;
Localizer::Localizer(Localizer&&) noexcept = default;
Localizer& Localizer::operator=(Localizer&&) noexcept = default;

void Localizer::initialize(double t, const State& x0, const StateCov& P0) {
  check_time(t, "initialize");
  impl_->start(t, x0, P0);
}

bool Localizer::initialized() const { return impl_->initialized(); }
double Localizer::time() const { return impl_->t_f; }

InputResult Localizer::motion(double t, const Control& u) {
  check_time(t, "motion");
  if (!u.allFinite())
    bad("motion at t = " + num(t) + ": (speed, heading change) = (" + num(u[0]) + ", " + num(u[1]) +
        ") is not finite");
  Impl& I = *impl_;
  I.start_clock(t);
  if (t < I.t_motion - kSameTime) return I.status(InputStatus::Late);
  const double interval = t - I.t_motion;
  if (!I.initialized()) {
    if (interval > kSameTime) {  // the motion integral for the heading (BMM step without noise)
      I.odo[2] = wrap_angle(I.odo[2] + u[1]);
      I.odo[0] += u[0] * interval * std::cos(I.odo[2]);
      I.odo[1] += u[0] * interval * std::sin(I.odo[2]);
      I.rate_speed = u[0];
      I.rate_turn = u[1] / interval;
    }
    I.t_motion = t;
    if (interval > kSameTime) {
      I.push_pose(t);
      I.try_fit(t);
    }
    if (I.initialized()) return InputResult{};  // the fit started the filter at this input
    return I.status(InputStatus::Buffered);
  }
  if (interval <= kSameTime) return I.status(InputStatus::Late);  // no interval to move over
  return I.atomic("motion", t, [&] { return I.move(t, u, interval); });
}

InputResult Localizer::Impl::move(double t, const Control& u, double interval) {
  Impl& I = *this;
  const double dt = t - I.t_f;
  const double owed_d = I.owed_distance, owed_h = I.owed_heading;
  I.rate_speed = u[0];
  I.rate_turn = u[1] / interval;
  I.t_motion = t;
  I.owed_distance = I.owed_heading = 0.0;
  if (dt <= kSameTime) return InputResult{};  // a measurement at t already took the filter there
  const Control step = (owed_d == 0.0 && owed_h == 0.0)
                           ? u  // the whole interval (dt = interval)
                           // Catch-up: a measurement inside the interval was predicted to at the last
                           // rates; apply what this input's distance and heading change still owe.
                           : Control((u[0] * interval - owed_d) / dt, u[1] - owed_h);
  I.predict(step, dt);
  const AugmentedEkf* aekf = I.filter->augmented_ekf();
  if (I.from_odometry && aekf) {
    // Odometry measured its distance and heading change: what the BMM's limits
    // (eq. 3's speed in [v_min, v_max] and a·Δt, eq. 4's clip) kept this step from
    // applying is owed by the next one.  A catch-up step that follows a
    // measurement just before the input can ask for any speed, even a
    // negative one.  (Augmented path only: the plain EKF stays as it was.)
    const Bmm b = I.bmm.is_nominal_step(dt) ? I.bmm : I.bmm.with_step(dt);
    I.owed_distance = aekf->x()[kV] * dt - step[0] * dt;
    I.owed_heading = b.clipped_heading_change(step[1]) - step[1];
  }
  I.t_f = t;
  ++I.counts.motion;
  return InputResult{};
}

InputResult Localizer::odometry(double t, double distance, double heading_change) {
  check_time(t, "odometry");
  if (!std::isfinite(distance) || !std::isfinite(heading_change))
    bad("odometry at t = " + num(t) + ": (distance, heading change) = (" + num(distance) + ", " +
        num(heading_change) + ") is not finite");
  Impl& I = *impl_;
  I.start_clock(t);
  const double interval = t - I.t_motion;
  if (interval <= kSameTime) return I.status(InputStatus::Late);
  struct Flag {
    bool& f;
    explicit Flag(bool& b) : f(b) { f = true; }
    ~Flag() { f = false; }
  } flag(I.from_odometry);
  return motion(t, Control(distance / interval, heading_change));
}

InputResult Localizer::observe(double t, const LandmarkObservation& o) {
  check_time(t, "observation");
  Impl& I = *impl_;
  const auto it = I.row_of.find(o.id);
  if (it == I.row_of.end()) bad("observation at t = " + num(t) + ": unknown landmark id " + std::to_string(o.id));
  const bool has_r = !std::isnan(o.range), has_b = !std::isnan(o.bearing);
  if (!has_r && !has_b) bad("observation of landmark " + std::to_string(o.id) + " at t = " + num(t) +
                            ": neither a range nor a bearing");
  if (has_r && !(std::isfinite(o.range) && o.range >= 0.0))
    bad("observation of landmark " + std::to_string(o.id) + ": range = " + num(o.range) + " must be finite and >= 0");
  if (has_b && !std::isfinite(o.bearing))
    bad("observation of landmark " + std::to_string(o.id) + ": bearing = " + num(o.bearing) + " is not finite");
  if (has_r && !(std::isfinite(o.range_std) && o.range_std > 0.0))
    bad("observation of landmark " + std::to_string(o.id) + ": range_std = " + num(o.range_std) + " must be > 0");
  if (has_b && !(std::isfinite(o.bearing_std) && o.bearing_std > 0.0))
    bad("observation of landmark " + std::to_string(o.id) + ": bearing_std = " + num(o.bearing_std) + " must be > 0");
  const int row = it->second;
  if (!I.initialized()) {
    if (I.ranges.size() >= kMaxBufferedRanges) I.ranges.erase(I.ranges.begin());
    // Fitted after the next motion input (range and bearing as measured, NaN where not).
    I.ranges.push_back(BufferedObs{t, row, has_r ? o.range : kNaN, o.range_std, has_b ? o.bearing : kNaN,
                                   o.bearing_std});
    I.fresh = I.fresh || has_b;
    return I.status(InputStatus::Buffered);
  }
  LandmarkMeasurement m;
  m.row = row;
  m.landmark = I.landmarks.row(row).transpose();
  m.range = o.range;
  m.bearing = o.bearing;
  m.range_std = o.range_std;
  m.bearing_std = o.bearing_std;
  return I.atomic("observation", t, [&] {
    if (!I.advance(t)) return I.status(InputStatus::Late);
    const State& x = I.filter->x();
    const LandmarkGeometry g = landmark_geometry(x[kX], x[kY], m.landmark.x(), m.landmark.y());
    if (!(g.r > 1e-9)) return I.status(InputStatus::Ignored);  // at the landmark: h is undefined
    return I.counted(I.filter->update(m));
  });
}

InputResult Localizer::fix(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_time(t, "fix");
  Impl& I = *impl_;
  if (!z.allFinite()) bad("fix at t = " + num(t) + ": z = (" + num(z[0]) + ", " + num(z[1]) + ") is not finite");
  if (!I.initialized()) {
    check_covariance(R, "fix R");
    I.position_known(t, z, R);
    return I.status(InputStatus::Buffered);
  }
  InputResult r = I.atomic("fix", t, [&] {
    if (!I.advance(t)) return I.status(InputStatus::Late);
    return I.counted(I.filter->update_position(z, R));
  });
  if (r.status == InputStatus::Late) return r;
  if (r.status != InputStatus::Rejected) {
    I.fix_rejections = 0;
    return r;
  }
  const int n = I.settings.reset_after_rejections;
  if (n > 0 && ++I.fix_rejections > n) {
    check_covariance(R, "fix R");
    State x = I.filter->x();
    x.head<2>() = z;
    StateCov P = I.filter->P();
    P.topRows<2>().setZero();
    P.leftCols<2>().setZero();
    P.topLeftCorner<2, 2>() = R;
    // The restart keeps what the motion input still owes (start() clears it)
    // and gives a particle filter fresh draws.
    const double owed_d = I.owed_distance, owed_h = I.owed_heading;
    ++I.counts.resets;
    I.start(I.t_f, x, P, derive_seed(I.settings.filter.seed, static_cast<std::uint64_t>(I.counts.resets)));
    I.owed_distance = owed_d;
    I.owed_heading = owed_h;
    r.status = InputStatus::Reset;
  }
  return r;
}

InputResult Localizer::speed_heading(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_time(t, "speed_heading");
  Impl& I = *impl_;
  if (!z.allFinite()) bad("speed_heading at t = " + num(t) + ": z = (" + num(z[0]) + ", " + num(z[1]) + ") is not finite");
  if (!I.initialized()) {
    check_covariance(R, "speed_heading R");
    I.imu_speed = z[0];
    I.imu_heading = wrap_angle(z[1]);
    I.imu_heading_var = R(1, 1);
    I.t_imu = t;
    if (I.headings.size() >= kMaxBufferedRanges) I.headings.erase(I.headings.begin());
    I.headings.push_back(BufferedHeading{t, I.imu_heading, std::sqrt(R(1, 1))});
    I.fresh = true;
    return I.status(InputStatus::Buffered);
  }
  return I.atomic("speed_heading", t, [&] {
    if (!I.advance(t)) return I.status(InputStatus::Late);
    return I.counted(I.filter->update_speed_heading(z, R));
  });
}

const State& Localizer::x() const { return impl_->filter ? impl_->filter->x() : impl_->x_none; }
const StateCov& Localizer::P() const { return impl_->filter ? impl_->filter->P() : impl_->P_none; }
double Localizer::position_std() const { return safenav::position_std(P()); }
const LocalizerCounts& Localizer::counts() const { return impl_->counts; }
std::string Localizer::reason() const {
  const Impl& I = *impl_;
  if (!I.initialized() && !std::isfinite(I.t_motion))
    return "waiting: no motion input yet (" + std::to_string(I.ranges.size()) + " observation(s), " +
           std::to_string(I.headings.size()) + " heading(s) buffered)";
  return I.why;
}
const LocalizerSettings& Localizer::settings() const { return impl_->settings; }
const Bmm& Localizer::model() const { return impl_->bmm; }
int Localizer::landmark_index(int id) const {
  const auto it = impl_->row_of.find(id);
  return it == impl_->row_of.end() ? -1 : it->second;
}
const Landmarks& Localizer::landmarks() const { return impl_->landmarks; }
const AugmentedEkf* Localizer::augmented_filter() const {
  return impl_->filter ? impl_->filter->augmented_ekf() : nullptr;
}
Eigen::VectorXd Localizer::augmented_state() const {
  return impl_->filter ? impl_->filter->augmented_state() : Eigen::VectorXd();
}

}  // namespace safenav
