// The online Localizer: LanBLoc-BMM ticked with timestamped inputs
// (safenav/localizer.hpp).  Its state is localizer_impl.hpp.
#include "localizer_impl.hpp"

#include <stdexcept>

namespace safenav {

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

Localizer::Localizer(LocalizerSettings settings, Landmarks landmarks, std::vector<int> ids)
    : impl_(std::make_unique<Impl>(std::move(settings), std::move(landmarks), std::move(ids))) {}
Localizer::~Localizer() = default;
Localizer::Localizer(Localizer&&) noexcept = default;
Localizer& Localizer::operator=(Localizer&&) noexcept = default;

void Localizer::initialize(double t, const State& x0, const StateCov& P0) {
  check_time(t, "initialize");
  impl_->start(t, x0, P0);
  impl_->clear_history();
}

bool Localizer::initialized() const { return impl_->initialized(); }
double Localizer::time() const { return impl_->t_f; }

InputResult Localizer::motion_input(double t, const Control& u) {
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
  LoggedInput in;
  in.kind = LoggedInput::Kind::Motion;
  in.t = t;
  in.a = u;
  return I.take(in);
}

InputResult Localizer::Impl::apply_motion(double t, const Control& u) {
  if (t < t_motion - kSameTime) return status(InputStatus::Late);
  const double interval = t - t_motion;
  if (interval <= kSameTime) return status(InputStatus::Late);  // no interval to move over
  return atomic("motion", t, [&] { return move(t, u, interval); });
}

InputResult Localizer::Impl::apply_input(const LoggedInput& in) {
  switch (in.kind) {
    case LoggedInput::Kind::Motion:
      return apply_motion(in.t, in.a);
    case LoggedInput::Kind::Odometry: {
      const double interval = in.t - t_motion;
      if (interval <= kSameTime) return status(InputStatus::Late);
      struct Flag {
        bool& f;
        explicit Flag(bool& b) : f(b) { f = true; }
        ~Flag() { f = false; }
      } flag(from_odometry);
      return apply_motion(in.t, Control(in.a[0] / interval, in.a[1]));
    }
    case LoggedInput::Kind::Observation:
      return apply_observation(in.t, in.obs);
    case LoggedInput::Kind::Fix:
      return apply_fix(in.t, in.a, in.R);
    case LoggedInput::Kind::SpeedHeading:
      return atomic("speed_heading", in.t, [&] {
        if (!advance(in.t)) return status(InputStatus::Late);
        return counted(filter->update_speed_heading(in.a, in.R));
      });
  }
  throw std::logic_error("Localizer: an input of unknown kind");
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
  I.predict(step, dt, true);
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

InputResult Localizer::odometry_input(double t, double distance, double heading_change) {
  check_time(t, "odometry");
  if (!std::isfinite(distance) || !std::isfinite(heading_change))
    bad("odometry at t = " + num(t) + ": (distance, heading change) = (" + num(distance) + ", " +
        num(heading_change) + ") is not finite");
  Impl& I = *impl_;
  I.start_clock(t);
  const double interval = t - I.t_motion;
  if (interval <= kSameTime) return I.status(InputStatus::Late);
  if (!I.initialized()) return motion_input(t, Control(distance / interval, heading_change));
  LoggedInput in;
  in.kind = LoggedInput::Kind::Odometry;
  in.t = t;
  in.a = Eigen::Vector2d(distance, heading_change);
  return I.take(in);
}

InputResult Localizer::observe_input(double t, const LandmarkObservation& o) {
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
  LoggedInput in;
  in.kind = LoggedInput::Kind::Observation;
  in.t = t;
  in.obs = o;
  return I.take(in);
}

InputResult Localizer::Impl::apply_observation(double t, const LandmarkObservation& o) {
  const int row = row_of.at(o.id);
  LandmarkMeasurement m;
  m.row = row;
  m.landmark = landmarks.row(row).transpose();
  m.range = o.range;
  m.bearing = o.bearing;
  m.range_std = o.range_std;
  m.bearing_std = o.bearing_std;
  return atomic("observation", t, [&] {
    if (!advance(t)) return status(InputStatus::Late);
    const State& x = filter->x();
    const LandmarkGeometry g = landmark_geometry(x[kX], x[kY], m.landmark.x(), m.landmark.y());
    if (!(g.r > 1e-9)) return status(InputStatus::Ignored);  // at the landmark: h is undefined
    return counted(filter->update(m));
  });
}

InputResult Localizer::fix_input(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  check_time(t, "fix");
  Impl& I = *impl_;
  if (!z.allFinite()) bad("fix at t = " + num(t) + ": z = (" + num(z[0]) + ", " + num(z[1]) + ") is not finite");
  if (!I.initialized()) {
    check_covariance(R, "fix R");
    I.position_known(t, z, R);
    return I.status(InputStatus::Buffered);
  }
  LoggedInput in;
  in.kind = LoggedInput::Kind::Fix;
  in.t = t;
  in.a = z;
  in.R = R;
  return I.take(in);
}

InputResult Localizer::Impl::apply_fix(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  Impl& I = *this;
  InputResult r = I.atomic("fix", t, [&] {
    if (!I.advance(t)) return I.status(InputStatus::Late);
    return I.counted(I.filter->update_position(z, R));
  });
  if (r.status == InputStatus::Late) return r;
  Rejections& rej = I.fix_rejections;
  const int k = I.settings.reset_after_consistent;
  const double p_gate = I.settings.filter.gate_probability;
  const double gate = p_gate > 0.0 ? chi2_quantile(p_gate, 2) : 0.0;
  if (r.status != InputStatus::Rejected) {
    rej.in_a_row = 0;
    rej.has_undo = false;  // the position the last reset gave is confirmed
    // The newest pass, for the discredit below (kept only where it is on: it is tracked at every prediction).
    rej.has_last = I.settings.reset_discredit_tail > 0.0;
    rej.last = Rejections::Kept{z, Eigen::Vector2d::Zero(), R, Eigen::Matrix2d::Zero()};
    if (++rej.passed >= std::max(k, 1)) rej.n = 0;  // the filter agrees with the fixes again
    // A fix through the gate that contradicts a kept rejected one discredits it: rejected fixes
    // that agree with each other but not with the fixes the filter takes (a repeated wrong
    // landmark) must not reset the position.  A lost filter's occasional pass, a good fix
    // through a grown σ, agrees with the rejected good ones and keeps them.
    else if (k > 0 && rej.n > 0) rej.passed_fix(z, R, gate);
    return r;
  }
  const int n = I.settings.reset_after_rejections;
  // A rejected fix that agrees with the position before the last reset undoes it: the fixes that
  // reset it agreed with each other but were wrong (one landmark's outlier repeated over a few
  // frames, where three ranges cannot show it), and the fixes since agree with what the filter
  // held before.  Until a fix passes the gate, one such fix is evidence enough.
  const bool undo = rej.has_undo && Rejections::agree(rej.undo, z, R, gate);
  const bool in_a_row = n > 0 && ++rej.in_a_row > n;
  // A rejected fix that contradicts the newest fix through the gate beyond what the predicted
  // motion since explains is not evidence that the filter is lost: a filter that took a fix
  // moments ago and now meets fixes metres away meets faulty fixes (one landmark's outlier
  // repeated, where three ranges fit a point metres off as well as the truth).  It counts
  // toward no agreement: three of them reset good filters 8–12 m off before a blind stretch.
  const double tail = I.settings.reset_discredit_tail;
  const bool credible = !rej.has_last || Rejections::agree(rej.last, z, R, chi2_quantile(1.0 - tail, 2));
  const bool consistent = credible && k > 0 && rej.agrees(z, R, k - 1, gate);
  if (credible) rej.keep(z, R);
  if (undo || in_a_row || consistent) {
    check_covariance(R, "fix R");
    const Rejections::Kept before{I.filter->x().head<2>(), Eigen::Vector2d::Zero(),
                                  I.filter->P().topLeftCorner<2, 2>(), Eigen::Matrix2d::Zero()};
    State x = I.filter->x();
    x.head<2>() = undo ? Eigen::Vector2d(rej.undo.z + rej.undo.moved) : z;
    StateCov P = I.filter->P();
    P.topRows<2>().setZero();
    P.leftCols<2>().setZero();
    P.topLeftCorner<2, 2>() = undo ? Eigen::Matrix2d(rej.undo.R + 0.5 * (rej.undo.grown + rej.undo.grown.transpose()))
                                   : R;
    // The restart keeps what the motion input still owes (start() clears it)
    // and gives a particle filter fresh draws.
    const double owed_d = I.owed_distance, owed_h = I.owed_heading;
    ++I.counts.resets;
    I.start(I.t_f, x, P, derive_seed(I.settings.filter.seed, static_cast<std::uint64_t>(I.counts.resets)));
    I.owed_distance = owed_d;
    I.owed_heading = owed_h;
    I.fix_rejections.has_undo = !undo;  // an undone reset is not undone again
    I.fix_rejections.undo = before;
    r.status = InputStatus::Reset;
  }
  return r;
}

InputResult Localizer::speed_heading_input(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
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
  LoggedInput in;
  in.kind = LoggedInput::Kind::SpeedHeading;
  in.t = t;
  in.a = z;
  in.R = R;
  return I.take(in);
}

// The public inputs: each noted for the watchdog's input times (not when late).

InputResult Localizer::motion(double t, const Control& u) { return impl_->heard(t, true, motion_input(t, u)); }
InputResult Localizer::odometry(double t, double distance, double heading_change) {
  return impl_->heard(t, true, odometry_input(t, distance, heading_change));
}
InputResult Localizer::observe(double t, const LandmarkObservation& obs) {
  return impl_->heard(t, false, observe_input(t, obs));
}
InputResult Localizer::fix(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  return impl_->heard(t, false, fix_input(t, z, R));
}
InputResult Localizer::speed_heading(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  return impl_->heard(t, false, speed_heading_input(t, z, R));
}

bool Localizer::predict_to(double t, State& x, StateCov& P) const {
  Impl& I = *impl_;
  if (!I.initialized() || !(t > I.t_f + kSameTime)) return false;
  if (!I.ahead) I.ahead = I.filter->clone();
  else I.ahead->assign(*I.filter);
  const double dt = t - I.t_f;
  I.ahead->predict(I.rates_control(dt), dt);
  x = I.ahead->x();
  P = I.ahead->P();
  return true;
}
double Localizer::last_motion_time() const { return impl_->t_heard_motion; }
double Localizer::last_measurement_time() const { return impl_->t_heard_measurement; }

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
