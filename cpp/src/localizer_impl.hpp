// Private: the online Localizer's state (safenav/localizer.hpp), shared by
// localizer.cpp (the inputs), localizer_start.cpp (starting from the data)
// and localizer_history.cpp (late measurements applied at their own time).
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "errors.hpp"
#include "localizer_fit.hpp"
#include "safenav/filter.hpp"
#include "safenav/localizer.hpp"
#include "safenav/seed.hpp"

namespace safenav {

namespace localizer_detail {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// Timestamps this close are the same instant [s].
inline constexpr double kSameTime = 1e-9;
/// Starting from ranges: σ added to the fit's position [m] and heading [rad]
/// (the fit's own covariance ignores the odometry's drift within the window).
inline constexpr std::size_t kMaxBufferedRanges = 100000;
inline constexpr double kInitPositionFloor = 0.05, kInitHeadingFloor = 0.01;

using detail::bad;

inline std::string num(double v) { return detail::num(v, 12); }

inline void check_time(double t, const char* what) {
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


/// An input once the localizer has started, as it was given (odometry as
/// distance and heading change), kept max_delay seconds for late measurements.
struct LoggedInput {
  enum class Kind { Motion, Odometry, Observation, Fix, SpeedHeading };
  Kind kind = Kind::Motion;
  double t = 0.0;
  Eigen::Vector2d a = Eigen::Vector2d::Zero();  // (speed, Δθ), (distance, Δθ), fix z or (v, θ)
  Eigen::Matrix2d R = Eigen::Matrix2d::Zero();  // fix and speed_heading
  LandmarkObservation obs;                      // observation
  bool measurement() const { return kind != Kind::Motion && kind != Kind::Odometry; }
};

/// The position fixes the gate rejected (the resets, localizer.cpp): the
/// count in a row, and the newest rejected fixes, each with the displacement
/// and P_xy growth that the predictions added since it
/// (LocalizerSettings::reset_after_consistent).  Fixed storage: the tick
/// allocates nothing.
struct Rejections {
  static constexpr int kKeep = 8;
  struct Kept {
    Eigen::Vector2d z, moved;
    Eigen::Matrix2d R, grown;
  };
  int in_a_row = 0;  // fixes rejected in a row
  int passed = 0;    // fixes in a row that passed the gate since the newest kept one
  int n = 0;         // kept fixes, oldest first
  std::array<Kept, kKeep> kept;
  /// The position before the last reset (its estimate and P_xy, moved and grown by the
  /// predictions since), until a fix passes the gate: a rejected fix that agrees with it undoes
  /// the reset.
  bool has_undo = false;
  Kept undo;
  /// The newest fix through the gate (moved and grown by the predictions since): a rejected fix
  /// that contradicts it beyond what the motion since explains is discredited at once
  /// (LocalizerSettings::reset_discredit_tail).
  bool has_last = false;
  Kept last;

  bool watching() const { return n > 0 || has_undo || has_last; }
  /// A prediction moved the estimate's position by d and P_xy by dC.
  void predicted(const Eigen::Vector2d& d, const Eigen::Matrix2d& dC) {
    for (int i = 0; i < n; ++i) {
      kept[i].moved += d;
      kept[i].grown += dC;
    }
    for (Kept* k : {has_undo ? &undo : nullptr, has_last ? &last : nullptr})
      if (k) k->moved += d, k->grown += dC;
  }
  /// Whether (z, R) agrees with `k`: χ² of z − (k.z + its displacement since) on R + k.R + the
  /// P_xy growth since, within `gate`.
  static bool agree(const Kept& k, const Eigen::Vector2d& z, const Eigen::Matrix2d& R, double gate) {
    const Eigen::Vector2d e = z - k.z - k.moved;
    const Eigen::Matrix2d S = R + k.R + 0.5 * (k.grown + k.grown.transpose());
    const Eigen::LLT<Eigen::Matrix2d> llt(S);
    return llt.info() == Eigen::Success && e.dot(llt.solve(e)) <= gate;
  }
  /// Whether (z, R) agrees with kept fix i: χ² of z − (z_i + its predicted
  /// displacement since) on R + R_i + the P_xy growth since, within `gate`.
  bool agrees_with(int i, const Eigen::Vector2d& z, const Eigen::Matrix2d& R, double gate) const {
    return agree(kept[i], z, R, gate);
  }
  /// Whether (z, R) agrees with each of the newest `k` kept fixes (χ² bound `gate`).
  bool agrees(const Eigen::Vector2d& z, const Eigen::Matrix2d& R, int k, double gate) const {
    if (k > n) return false;
    for (int i = n - k; i < n; ++i)
      if (!agrees_with(i, z, R, gate)) return false;
    return true;
  }
  /// A fix that passed the gate, (z, R), discredits the kept rejected fixes
  /// that it disagrees with: they are dropped (oldest first order kept).
  void passed_fix(const Eigen::Vector2d& z, const Eigen::Matrix2d& R, double gate) {
    int m = 0;
    for (int i = 0; i < n; ++i)
      if (agrees_with(i, z, R, gate)) kept[m++] = kept[i];
    n = m;
  }
  void keep(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
    if (n == kKeep) {
      std::move(kept.begin() + 1, kept.end(), kept.begin());
      --n;
    }
    kept[n++] = Kept{z, Eigen::Vector2d::Zero(), R, Eigen::Matrix2d::Zero()};
    passed = 0;
  }
};

}  // namespace localizer_detail

using namespace localizer_detail;  // NOLINT: private header, included by the localizer's .cpp files only

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
  Rejections fix_rejections;  // the position fixes rejected by the gate
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
    if (smoother) smoother->cut();  // no smoothing across a restart
    fix_rejections = Rejections{};
    t_f = t;
    // A stream not heard from before the start counts from it (the watchdog's clock).
    if (std::isnan(t_heard_motion)) t_heard_motion = t;
    if (std::isnan(t_heard_measurement)) t_heard_measurement = t;
    why = "started at t = " + num(t);
    if (!(t_motion <= t)) t_motion = t;
    owed_distance = owed_heading = 0.0;
    ranges.clear();
    headings.clear();
    track.clear();
    anchor.reset();
  }

  /// Eq. 11 over dt; `motion`: a motion input's step (its end is a smoothed
  /// output time).  With a lag set, each prediction feeds the smoother
  /// (smoother.cpp); without one this is the filter's predict alone.
  void predict(const Control& u, double dt, bool motion = false) {
    // While rejected fixes are kept, their displacement since (reset_after_consistent).
    const bool watch = fix_rejections.watching();
    Eigen::Vector2d p0;
    Eigen::Matrix2d C0;
    if (watch) {
      p0 = filter->x().head<2>();
      C0 = filter->P().topLeftCorner<2, 2>();
    }
    if (smoother) smoother_filtered();
    filter->predict(u, dt);
    if (smoother) smoother_predicted(t_f + dt, u, dt, motion);
    if (watch) fix_rejections.predicted(filter->x().head<2>() - p0, filter->P().topLeftCorner<2, 2>() - C0);
  }
  std::unique_ptr<FixedLagSmoother> smoother;  // null unless Localizer::set_lag
  Eigen::MatrixXd smooth_F, smooth_Q;          // the augmented EKF's last transition (scratch)
  void smoother_filtered();
  void smoother_predicted(double t1, const Control& u, double dt, bool output);
  /// A measurement input the filter applied (the iterated smoother re-linearises it).
  void smoother_measured(const LoggedInput& in);
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
    const Rejections saved_rejections = fix_rejections;
    Filter::Transaction tx(*filter);
    try {
      const InputResult r = f();
      tx.commit("filter result");
      return r;
    } catch (const std::invalid_argument& e) {
      set_clock(saved);
      counts = saved_counts;
      fix_rejections = saved_rejections;
      bad(std::string(what) + " at t = " + num(t) + ": " + e.what());
    } catch (...) {
      set_clock(saved);
      counts = saved_counts;
      fix_rejections = saved_rejections;
      throw;
    }
  }

  /// The control that carries the filter dt seconds past its time for a
  /// measurement: the last motion input's rates (speed, heading change per
  /// second), or the estimated speed and no turn before any.
  Control rates_control(double dt) const {
    return std::isfinite(rate_speed) ? Control(rate_speed, rate_turn * dt) : Control(filter->x()[kV], 0.0);
  }

  /// Newest input times that were not late (Localizer::last_motion_time …) and
  /// the copy that Localizer::predict_to predicts on.
  double t_heard_motion = kNaN, t_heard_measurement = kNaN;
  std::unique_ptr<Filter> ahead;
  InputResult heard(double t, bool motion, const InputResult& r) {
    if (r.status == InputStatus::Late) return r;
    double& last = motion ? t_heard_motion : t_heard_measurement;
    if (!(t <= last)) last = t;
    return r;
  }

  /// Bring the filter to time t for a measurement; false when t is late.
  bool advance(double t) {
    if (t < t_f - kSameTime) return false;
    if (t > t_f + kSameTime) {
      const double dt = t - t_f;
      const Control u = rates_control(dt);
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

  // -- the inputs, once started (localizer.cpp) -------------------------------

  /// Applies an input now (the filter at its time, or Late); an applied
  /// measurement also goes to the smoother.
  InputResult apply(const LoggedInput& in) {
    const InputResult r = apply_input(in);
    if (smoother && in.measurement() && r.status == InputStatus::Applied) smoother_measured(in);
    return r;
  }
  InputResult apply_input(const LoggedInput& in);
  InputResult apply_motion(double t, const Control& u);
  InputResult apply_observation(double t, const LandmarkObservation& o);
  InputResult apply_fix(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R);

  // -- late measurements (localizer_history.cpp) ------------------------------

  /// The filter, clock and counts before a motion input (`input`: its
  /// sequence number in the input log).
  struct Checkpoint {
    Clock clock;
    LocalizerCounts counts;
    Rejections fix_rejections;
    std::unique_ptr<Filter> filter;
    std::uint64_t input = 0;
    std::size_t smoother_mark = 0;  // FixedLagSmoother::mark() at the checkpoint
    bool start = false;             // taken at a start from the data (keep_start)
  };
  std::vector<LoggedInput> inputs;      // every input from the oldest checkpoint's motion input on
  std::uint64_t first_input = 0;        // sequence number of inputs[0]
  std::vector<Checkpoint> checkpoints;  // oldest first, one before each motion input
  std::vector<std::unique_ptr<Filter>> spare_filters;  // recycled checkpoint storage
  std::vector<LoggedInput> redo;        // scratch of a late measurement's replay
  bool replaying = false;               // inside take_late: prune() waits

  /// An input once started: applied now and logged (settings.max_delay > 0),
  /// or, for a measurement older than the filter's time by at most
  /// max_delay, applied at its own time (take_late).
  InputResult take(const LoggedInput& in);
  InputResult take_now(const LoggedInput& in);
  InputResult take_late(const LoggedInput& in);
  Checkpoint capture();
  void restore(const Checkpoint& c);
  void recycle(Checkpoint& c);
  void prune();
  void clear_history();

  /// A start from the data as its fit saw it: the window of buffered
  /// observations, headings and motion integral, kept (with a checkpoint at
  /// the start) so that an observation older than the start, delivered late,
  /// joins the fit (take_before_start).
  struct StartWindow {
    bool kept = false;
    double t = kNaN;  // the start's time (its motion input)
    std::uint64_t input = 0;  // sequence number of the first input after the start
    std::vector<BufferedObs> ranges;
    std::vector<BufferedHeading> headings;
    std::vector<Eigen::Vector4d> track;
    std::string why;
  };
  StartWindow start_window;
  StartWindow start_window_now(double t) const;
  void keep_start(StartWindow w);
  InputResult take_before_start(const LoggedInput& in);

  // -- starting from the data (localizer_start.cpp) ---------------------------

  void position_known(double t, const Eigen::Vector2d& p, const Eigen::Matrix2d& cov);
  void push_pose(double t);
  bool rules_hold(const detail::StartWindow& w);
  void try_fit(double t_now);
  void accept_fit(double t_now, const detail::FitResult& fit);
};

}  // namespace safenav
