// The online Localizer: LanBLoc-BMM ticked with timestamped inputs
// (safenav/localizer.hpp).
#include "safenav/localizer.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <utility>

#include "errors.hpp"
#include "safenav/rng.hpp"
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

/// A range kept for initialization from data.
struct BufferedRange {
  double t;
  int row;  // landmark row
  double range, std;
};

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
  return std::sqrt(std::max(0.0, m + r));
}

void LocalizerSettings::validate() const {
  bmm.validate();
  if (filter.type == FilterType::InformationFilter)
    bad("localizer.filter.type = InformationFilter: the localizer runs the EKF or the particle filter");
  if (filter.type == FilterType::ParticleFilter && filter.n_particles < 1)
    bad("localizer.filter.n_particles = " + std::to_string(filter.n_particles) + ": must be >= 1");
  if (!(filter.resample_threshold >= 0.0 && filter.resample_threshold <= 1.0))
    bad("localizer.filter.resample_threshold = " + num(filter.resample_threshold) + ": must be in [0, 1]");
  if (!(filter.gate_probability >= 0.0 && filter.gate_probability < 1.0))
    bad("localizer.filter.gate_probability = " + num(filter.gate_probability) + ": must be in [0, 1) (0 = off)");
  param_set<LocalizerSettings>().check(*this, "localizer.");
  augment.validate();
}

struct Localizer::Impl {
  LocalizerSettings settings;
  Landmarks landmarks;
  std::vector<int> ids;
  std::unordered_map<int, int> row_of;
  Bmm bmm;
  std::optional<Ekf> ekf;
  std::optional<AugmentedEkf> aekf;  // instead of ekf when settings.augment is on
  std::optional<AugmentedParticleFilter> apf;  // instead of pf when settings.augment is on
  std::optional<ParticleFilter> pf;
  // Particle-filter models reused while their covariance stays the same.
  std::optional<MeasurementModel> pf_fix, pf_imu;
  Eigen::Matrix2d pf_fix_R, pf_imu_R;

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
  mutable State x_cache = State::Constant(kNaN);  // NaN until initialized
  mutable StateCov P_cache = StateCov::Constant(kNaN);
  mutable bool dirty = true;

  // Initialization from data.
  std::vector<BufferedRange> ranges;  // ranges within init_window of the newest motion input
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

  bool initialized() const { return ekf.has_value() || aekf.has_value() || pf.has_value() || apf.has_value(); }

  void start(double t, const State& x0, const StateCov& P0) { start(t, x0, P0, settings.filter.seed); }

  /// Starts the filter at (x0, P0); a particle filter draws with `seed`.
  void start(double t, const State& x0, const StateCov& P0, std::uint64_t seed) {
    const FilterOptions& o = settings.filter;
    fix_rejections = 0;
    ekf.reset();
    aekf.reset();
    pf.reset();
    apf.reset();
    if (o.type == FilterType::Ekf && settings.augment.any()) {
      aekf.emplace(settings.bmm, settings.augment, static_cast<int>(landmarks.rows()), x0, P0);
      if (o.gate_probability > 0.0) aekf->set_gate(o.gate_probability);
    } else if (o.type == FilterType::Ekf) {
      ekf.emplace(settings.bmm, x0, P0);
      if (o.gate_probability > 0.0) ekf->set_gate(o.gate_probability);
    } else if (settings.augment.any()) {
      apf.emplace(settings.bmm, settings.augment, static_cast<int>(landmarks.rows()), x0, P0, o.n_particles, seed,
                  o.resample_threshold);
      if (o.gate_probability > 0.0) apf->set_gate(o.gate_probability);
    } else {
      pf.emplace(settings.bmm, x0, P0, o.n_particles, seed, o.resample_threshold);
      if (o.gate_probability > 0.0) pf->set_gate(o.gate_probability);
    }
    t_f = t;
    if (!(t_motion <= t)) t_motion = t;
    // Until the first input the estimate is the prior itself (not, say, the particles' sample mean).
    x_cache = ekf ? ekf->x() : aekf ? aekf->x() : x0;
    x_cache[kTheta] = wrap_angle(x_cache[kTheta]);
    P_cache = ekf ? ekf->P() : aekf ? aekf->P() : P0;
    dirty = false;
    owed_distance = owed_heading = 0.0;
    ranges.clear();
    track.clear();
    anchor.reset();
  }

  void refresh() const {
    if (!dirty) return;
    if (ekf) {
      x_cache = ekf->x();
      P_cache = ekf->P();
    } else if (aekf) {
      x_cache = aekf->x();
      P_cache = aekf->P();
    } else if (pf) {
      x_cache = pf->mean();
      P_cache = pf->covariance(x_cache);
    } else if (apf) {
      x_cache = apf->mean();
      P_cache = apf->covariance();
    }
    dirty = false;
  }

  void predict(const Control& u, double dt) {
    if (ekf) ekf->predict(u, dt);
    else if (aekf) aekf->predict(u, dt);
    else if (apf) apf->predict(u, dt);
    else pf->predict(u, dt);
    dirty = true;
  }

  /// Bring the filter to time t for a measurement; false when t is late.
  bool advance(double t) {
    if (t < t_f - kSameTime) return false;
    if (t > t_f + kSameTime) {
      const double dt = t - t_f;
      refresh();
      const Control u = std::isfinite(rate_speed) ? Control(rate_speed, rate_turn * dt) : Control(x_cache[kV], 0.0);
      predict(u, dt);
      owed_distance += u[0] * dt;
      owed_heading += u[1];
      t_f = t;
    }
    return true;
  }

  InputResult counted(const UpdateResult& r) {
    dirty = true;
    InputResult out;
    out.nis = r.nis;
    out.dim = r.dim;
    out.status = r.accepted ? InputStatus::Applied : InputStatus::Rejected;
    ++(r.accepted ? counts.applied : counts.rejected);
    return out;
  }

  InputResult status(InputStatus s) {
    if (s == InputStatus::Late) ++counts.late;
    if (s == InputStatus::Buffered) ++counts.buffered;
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
      start(t, State(p.x(), p.y(), std::max(0.0, speed), imu_heading), P0);
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
    start(t, State(p.x(), p.y(), std::max(0.0, speed), wrap_angle(phi + odo[2])), P0);
  }

  /// The motion integral's pose at a motion input at time t (the first one starts it at 0).
  void push_pose(double t) {
    track.push_back(Eigen::Vector4d(t, odo[0], odo[1], odo[2]));
  }

  /// Starting from ranges: fit the rigid transform (X, Y, φ) from the motion
  /// integral's frame to the world to the ranges of the last init_window
  /// seconds (ours, after ref.py's _init_from_data): minimise
  /// Σ (r − (1+k₀)‖T(q(t_r)) − a‖)²/σ_r², q(t_r) the motion integral's
  /// position interpolated to the range's time; Gauss–Newton from 16 headings
  /// × 5 positions, residuals > 3σ dropped, refitted.  Starts the filter at
  /// the newest motion input when the fit is good enough.
  void try_fit(double t_now) {
    const double t0 = t_now - settings.init_window;
    track.erase(track.begin(), std::find_if(track.begin(), track.end(), [&](const Eigen::Vector4d& q) { return q[0] >= t0; }));
    if (track.size() < 2) return;
    const double t_first = track.front()[0];
    ranges.erase(std::remove_if(ranges.begin(), ranges.end(), [&](const BufferedRange& r) { return r.t < t_first; }),
                 ranges.end());
    double path = 0.0;
    for (std::size_t i = 1; i < track.size(); ++i)
      path += std::hypot(track[i][1] - track[i - 1][1], track[i][2] - track[i - 1][2]);
    if (path < settings.init_min_path) return;
    struct Obs {
      double qx, qy, ax, ay, z, s;
    };
    std::vector<Obs> obs;
    std::vector<int> rows;
    for (const BufferedRange& r : ranges) {
      if (r.t > t_now) continue;  // not interpolable yet
      auto hi = std::lower_bound(track.begin(), track.end(), r.t, [](const Eigen::Vector4d& q, double t) { return q[0] < t; });
      Eigen::Vector2d q;
      if (hi == track.end()) q = track.back().segment<2>(1);
      else if (hi == track.begin() || (*hi)[0] == r.t) q = hi->segment<2>(1);
      else {
        const Eigen::Vector4d& lo = *(hi - 1);
        const double w = (r.t - lo[0]) / ((*hi)[0] - lo[0]);
        q = lo.segment<2>(1) + w * (hi->segment<2>(1) - lo.segment<2>(1));
      }
      obs.push_back(Obs{q.x(), q.y(), landmarks(r.row, 0), landmarks(r.row, 1), r.range, r.std});
      if (std::find(rows.begin(), rows.end(), r.row) == rows.end()) rows.push_back(r.row);
    }
    if (static_cast<int>(rows.size()) < settings.init_min_beacons) return;
    const double k0 = settings.augment.range_scale ? settings.augment.scale_prior : 0.0;
    const auto n = static_cast<Eigen::Index>(obs.size());
    Eigen::VectorXd e(n);
    Eigen::MatrixXd J(n, 3);
    std::vector<char> mask(obs.size(), 1);
    // Normalised residuals e = (z − h)/σ and J = ∂e/∂(X, Y, φ) over the masked rows.
    auto residuals = [&](const Eigen::Vector3d& th) {
      const double c = std::cos(th[2]), s = std::sin(th[2]);
      Eigen::Index m = 0;
      for (std::size_t i = 0; i < obs.size(); ++i) {
        if (!mask[i]) continue;
        const Obs& o = obs[i];
        const double dx = th[0] + c * o.qx - s * o.qy - o.ax, dy = th[1] + s * o.qx + c * o.qy - o.ay;
        const double rho = std::max(std::hypot(dx, dy), 1e-6), ux = dx / rho, uy = dy / rho;
        e[m] = (o.z - (1.0 + k0) * rho) / o.s;
        J(m, 0) = -(1.0 + k0) * ux / o.s;
        J(m, 1) = -(1.0 + k0) * uy / o.s;
        J(m, 2) = -(1.0 + k0) * (ux * (-s * o.qx - c * o.qy) + uy * (c * o.qx - s * o.qy)) / o.s;
        ++m;
      }
      return m;
    };
    auto gauss_newton = [&](Eigen::Vector3d th, int iters) {
      for (int it = 0; it < iters; ++it) {
        const Eigen::Index m = residuals(th);
        const Eigen::Vector3d step = J.topRows(m).completeOrthogonalDecomposition().solve(-e.head(m));
        th += step;
        if (step.cwiseAbs().maxCoeff() < 1e-6) break;
      }
      return th;
    };
    double ax = 0.0, ay = 0.0;
    for (const Obs& o : obs) ax += o.ax, ay += o.ay;
    ax /= static_cast<double>(n);
    ay /= static_cast<double>(n);
    const double seeds[5][2] = {{ax, ay}, {ax + 30, ay}, {ax - 30, ay}, {ax, ay + 30}, {ax, ay - 30}};
    double best_cost = std::numeric_limits<double>::infinity();
    Eigen::Vector3d best = Eigen::Vector3d::Zero();
    for (int h = 0; h < 16; ++h) {
      const double phi0 = -kPi + 2.0 * kPi * h / 16.0;
      for (const auto& sd : seeds) {
        const Eigen::Vector3d th = gauss_newton(Eigen::Vector3d(sd[0], sd[1], phi0), 15);
        const Eigen::Index m = residuals(th);
        const double cost = e.head(m).squaredNorm();
        if (cost < best_cost) best_cost = cost, best = th;
      }
    }
    if (!std::isfinite(best_cost)) return;
    // Drop residuals over 3σ and refit once.
    residuals(best);
    int inliers = 0;
    for (Eigen::Index i = 0; i < n; ++i) inliers += (mask[i] = std::abs(e[i]) < 3.0);
    if (inliers < 3) return;
    const Eigen::Vector3d th = gauss_newton(best, 20);
    const Eigen::Index m = residuals(th);
    double ss = 0.0;
    for (Eigen::Index i = 0, r = 0; i < n; ++i)
      if (mask[i]) ss += (e[r] * obs[i].s) * (e[r] * obs[i].s), ++r;
    const double rms = std::sqrt(ss / static_cast<double>(m));
    const Eigen::Matrix3d JtJ = J.topRows(m).transpose() * J.topRows(m);
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(JtJ);
    if (!lu.isInvertible()) return;
    const Eigen::Matrix3d C = lu.inverse();
    // The pose at t_now and the covariance of (x, y, θ) through the transform.
    const double c = std::cos(th[2]), s = std::sin(th[2]);
    const Eigen::Vector4d& q = track.back();
    const double px = th[0] + c * q[1] - s * q[2], py = th[1] + s * q[1] + c * q[2];
    Eigen::Matrix3d Jt = Eigen::Matrix3d::Identity();
    Jt(0, 2) = -s * q[1] - c * q[2];
    Jt(1, 2) = c * q[1] - s * q[2];
    const Eigen::Matrix3d Cp = Jt * C * Jt.transpose();
    const double pos_std = std::sqrt(std::max(Cp(0, 0), Cp(1, 1)));
    if (!(rms <= settings.init_max_rms && pos_std <= settings.init_max_pos_std)) return;
    StateCov P0 = StateCov::Zero();
    const int map[3] = {kX, kY, kTheta};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) P0(map[i], map[j]) = settings.init_cov_inflation * Cp(i, j);
    P0(kX, kX) += kInitPositionFloor * kInitPositionFloor;
    P0(kY, kY) += kInitPositionFloor * kInitPositionFloor;
    P0(kTheta, kTheta) += kInitHeadingFloor * kInitHeadingFloor;
    P0(kV, kV) = settings.init_speed_std * settings.init_speed_std;
    const double speed = std::isfinite(rate_speed) ? std::max(0.0, rate_speed) : 0.0;
    start(t_now, State(px, py, speed, wrap_angle(th[2] + q[3])), 0.5 * (P0 + P0.transpose()));
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
  if (I.from_odometry && I.aekf) {
    // Odometry measured its distance and heading change: what the BMM's limits
    // (eq. 3's speed in [0, v_max] and a·Δt, eq. 4's clip) kept this step from
    // applying is owed by the next one.  A catch-up step that follows a
    // measurement just before the input can ask for any speed, even a
    // negative one.  (Augmented path only: the plain EKF stays as it was.)
    const Bmm b = I.bmm.is_nominal_step(dt) ? I.bmm : I.bmm.with_step(dt);
    I.owed_distance = I.aekf->x()[kV] * dt - step[0] * dt;
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
    if (!has_r) return I.status(InputStatus::Ignored);
    if (I.ranges.size() >= kMaxBufferedRanges) I.ranges.erase(I.ranges.begin());
    I.ranges.push_back(BufferedRange{t, row, o.range, o.range_std});  // fitted after the next motion input
    return I.status(InputStatus::Buffered);
  }
  if (!I.advance(t)) return I.status(InputStatus::Late);
  I.refresh();
  const State& x = I.x_cache;
  const LandmarkGeometry g = landmark_geometry(x[kX], x[kY], I.landmarks(row, 0), I.landmarks(row, 1));
  if (!(g.r > 1e-9)) return I.status(InputStatus::Ignored);  // at the landmark: h is undefined
  // The augmented EKF and PF share their update interface.
  auto augmented = [&](auto& f) {
    const Eigen::Vector2d a = I.landmarks.row(row).transpose();
    if (has_r && has_b) {
      const Eigen::Matrix2d R = Eigen::Vector2d(o.range_std * o.range_std, o.bearing_std * o.bearing_std).asDiagonal();
      return I.counted(f.update_range_bearing(row, a, Eigen::Vector2d(o.range, o.bearing), R));
    }
    if (has_r) return I.counted(f.update_range(row, a, o.range, o.range_std * o.range_std));
    return I.counted(f.update_bearing(row, a, o.bearing, o.bearing_std * o.bearing_std));
  };
  if (I.aekf) return augmented(*I.aekf);
  if (I.apf) return augmented(*I.apf);
  if (I.ekf) {
    // The landmark model (safenav/measurement.hpp) with k = b = 0.
    LandmarkJacobian Jr, Jb;
    const double hr = has_r ? predict_range(g, 0.0, 0.0, &Jr) : 0.0;
    const double hb = has_b ? predict_bearing(g, x[kTheta], &Jb) : 0.0;
    if (has_r && has_b) {
      const Eigen::Vector2d y(o.range - hr, wrap_angle(o.bearing - hb));
      Eigen::Matrix<double, 2, 4> H;
      H << Jr.x, Jr.y, 0.0, Jr.theta, Jb.x, Jb.y, 0.0, Jb.theta;
      const Eigen::Matrix2d R = Eigen::Vector2d(o.range_std * o.range_std, o.bearing_std * o.bearing_std).asDiagonal();
      return I.counted(I.ekf->update_linearized(y, H, R, MeasurementKind::RangeBearing));
    }
    const LandmarkJacobian& J = has_r ? Jr : Jb;
    Eigen::Matrix<double, 1, 1> y, R;
    Eigen::Matrix<double, 1, 4> H;
    H << J.x, J.y, 0.0, J.theta;
    y(0) = has_r ? o.range - hr : wrap_angle(o.bearing - hb);
    R(0) = has_r ? o.range_std * o.range_std : o.bearing_std * o.bearing_std;
    return I.counted(I.ekf->update_linearized(y, H, R, has_r ? MeasurementKind::Range : MeasurementKind::Bearing));
  }
  const Landmarks lm = I.landmarks.row(row);
  if (has_r && has_b)
    return I.counted(I.pf->update(MeasurementModel::range_bearing(lm, o.range_std, o.bearing_std),
                                  Eigen::Vector2d(o.range, o.bearing)));
  if (has_r)
    return I.counted(I.pf->update(MeasurementModel::range(lm, o.range_std), Eigen::Matrix<double, 1, 1>(o.range)));
  return I.counted(I.pf->update(MeasurementModel::bearing(lm, o.bearing_std), Eigen::Matrix<double, 1, 1>(o.bearing)));
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
  if (!I.advance(t)) return I.status(InputStatus::Late);
  InputResult r;
  if (I.ekf) r = I.counted(I.ekf->update_position(z, R));
  else if (I.aekf) r = I.counted(I.aekf->update_position(z, R));
  else if (I.apf) r = I.counted(I.apf->update_position(z, R));
  else {
    if (!I.pf_fix || I.pf_fix_R != R) {
      I.pf_fix.emplace(MeasurementModel::position(R));
      I.pf_fix_R = R;
    }
    r = I.counted(I.pf->update(*I.pf_fix, z));
  }
  if (r.status != InputStatus::Rejected) {
    I.fix_rejections = 0;
    return r;
  }
  const int n = I.settings.reset_after_rejections;
  if (n > 0 && ++I.fix_rejections > n) {
    check_covariance(R, "fix R");
    I.refresh();
    State x = I.x_cache;
    x.head<2>() = z;
    StateCov P = I.P_cache;
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
    return I.status(InputStatus::Buffered);
  }
  if (!I.advance(t)) return I.status(InputStatus::Late);
  if (I.ekf) {
    // h(x) = (v, θ), H = [0 0 1 0; 0 0 0 1]: the arithmetic of update(MeasurementModel::speed_heading(R), z).
    const State& x = I.ekf->x();
    const Eigen::Vector2d y(z[0] - x[kV], wrap_angle(z[1] - x[kTheta]));
    Eigen::Matrix<double, 2, 4> H;
    H << 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0;
    return I.counted(I.ekf->update_linearized(y, H, R, MeasurementKind::SpeedHeading));
  }
  if (I.aekf) return I.counted(I.aekf->update_speed_heading(z, R));
  if (I.apf) return I.counted(I.apf->update_speed_heading(z, R));
  if (!I.pf_imu || I.pf_imu_R != R) {
    I.pf_imu.emplace(MeasurementModel::speed_heading(R));
    I.pf_imu_R = R;
  }
  return I.counted(I.pf->update(*I.pf_imu, z));
}

const State& Localizer::x() const {
  impl_->refresh();
  return impl_->x_cache;
}
const StateCov& Localizer::P() const {
  impl_->refresh();
  return impl_->P_cache;
}
double Localizer::position_std() const { return safenav::position_std(P()); }
const LocalizerCounts& Localizer::counts() const { return impl_->counts; }
const LocalizerSettings& Localizer::settings() const { return impl_->settings; }
const Bmm& Localizer::model() const { return impl_->bmm; }
int Localizer::landmark_index(int id) const {
  const auto it = impl_->row_of.find(id);
  return it == impl_->row_of.end() ? -1 : it->second;
}
const Landmarks& Localizer::landmarks() const { return impl_->landmarks; }
const AugmentedEkf* Localizer::augmented_filter() const { return impl_->aekf ? &*impl_->aekf : nullptr; }
Eigen::VectorXd Localizer::augmented_state() const {
  if (impl_->aekf) return impl_->aekf->augmented();
  if (impl_->apf) return impl_->apf->augmented();
  return Eigen::VectorXd();
}

}  // namespace safenav
