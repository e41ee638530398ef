// The belief step (safenav/belief.hpp): legs cut into steps, the landmarks
// expected in view, and the covariance recursion of LQG-MP with the EKF's own
// predict [SafeNav eq. 11] and Joseph-form update [SafeNav eqs. 12–14].
#include "belief_model.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "errors.hpp"
#include "filters/kalman_update.hpp"
#include "safenav/filters.hpp"
#include "safenav/localizer.hpp"
#include "safenav/trilateration.hpp"

namespace safenav::belief {

using detail::bad;
using detail::num;

namespace {
/// The maximum-likelihood update of P by an M-row measurement with
/// Jacobian H and noise R: the residual is 0, so only the covariance moves
/// (the filters' own update, kalman_update.hpp, gate off).
template <int M>
void ml_update(StateCov& P, const Eigen::Matrix<double, M, 4>& H, const Eigen::Matrix<double, M, M>& R,
               MeasurementKind kind) {
  const State x = State::Zero();
  const Eigen::Matrix<double, M, 1> y = Eigen::Matrix<double, M, 1>::Zero();
  Eigen::Matrix<double, 4, M> PHt, unused;
  StateCov P1;
  State x1;
  kalman_update<M>("belief", kind, x, P, y, H, R, [](double, int) { return false; },
                   KalmanWork{PHt, unused, unused, unused, P1, x1});
  P = P1;
}

/// The Jacobian of a measurement model that does not depend on the state
/// (position, speed and heading), from the model itself.
Eigen::Matrix<double, 2, 4> constant_jacobian(const MeasurementModel& model) {
  return model.jacobian(State::Zero());
}

/// The Jacobian row of the range to a landmark (eq. 10, MeasurementModel's
/// range): one row for update()'s ranges and fix_information().
Eigen::Matrix<double, 1, 4> range_row(const LandmarkGeometry& g) {
  LandmarkJacobian J;
  predict_range(g, 0.0, 0.0, &J);
  Eigen::Matrix<double, 1, 4> H;
  H << J.x, J.y, 0.0, J.theta;
  return H;
}

/// P(Bin(k, q) ≥ r): the probability that at least r of k independent
/// observations, each kept with probability q, are kept.
double binomial_tail(int k, double q, int r) {
  if (r <= 0) return 1.0;
  if (r > k) return 0.0;
  double sum = 0.0, c = 1.0;  // c = C(k, j)
  for (int j = 0; j <= k; ++j) {
    if (j >= r) sum += c * std::pow(q, j) * std::pow(1.0 - q, k - j);
    c = c * (k - j) / (j + 1);
  }
  return std::min(1.0, sum);
}

/// The camera the belief sees with (BeliefSettings::sight_fov_margin,
/// sight_range_fraction): the vehicle's, narrowed; an all-round one stays so.
SensorSettings sight(SensorSettings s, const BeliefSettings& settings) {
  settings.validate();
  s.validate();
  if (s.field_of_view < 2.0 * kPi)
    s.field_of_view = std::max(10.0 * kPi / 180.0, s.field_of_view - settings.sight_fov_margin);
  s.max_range *= settings.sight_range_fraction;
  return s;
}
}  // namespace

Model::Model(const BmmParams& bmm, const SensorSettings& sensors, const PlanningMap& map,
             const BeliefSettings& settings)
    : bmm_(bmm), sensors_(sight(sensors, settings)), single_(sensors_), checker_(map), settings_(settings) {
  map.validate();
  step_ = settings.step > 0.0 ? settings.step : bmm.dt;
  single_.landmarks = Landmarks::Zero(1, 2);
  H_fix_ = constant_jacobian(MeasurementModel::position(Eigen::Matrix2d::Identity()));
  H_imu_ = constant_jacobian(MeasurementModel::speed_heading(Eigen::Matrix2d::Identity()));
  R_fix_ = sensors.position.reported_cov();
  R_imu_ = Eigen::Vector2d(sensors.imu_speed_std * sensors.imu_speed_std,
                           sensors.imu_heading_std * sensors.imu_heading_std)
               .asDiagonal();
}

void Model::observe(Step& s) const {
  State at = s.x;
  at.head<2>() = s.end;
  at[kTheta] += s.view_dtheta;
  s.in_view = sensors_.landmarks_in_view(at, &checker_);
  const bool ranges = sensors_.fix_model == FixModel::Ranges;
  s.fix = !ranges && (!sensors_.position.needs_landmarks || s.in_view >= sensors_.min_landmarks);
  s.seen.clear();
  s.ranges = false;
  s.unambiguous = -1.0;
  const bool range_fix = ranges && s.in_view >= std::max(3, sensors_.min_landmarks);
  if (s.in_view == 0 || !(range_fix || settings_.bearing_std > 0.0)) return;
  // The rows in view, each asked of the one visibility rule in turn.
  s.ranges = range_fix;
  SensorSettings& one = single_;
  for (Eigen::Index i = 0; i < sensors_.landmarks.rows(); ++i) {
    one.landmarks.row(0) = sensors_.landmarks.row(i);
    if (one.landmarks_in_view(at, &checker_) == 1) s.seen.push_back(static_cast<int>(i));
  }
}

double Model::unambiguous_share(const Eigen::Vector2d& p, const std::vector<int>& seen) const {
  const auto n = static_cast<Eigen::Index>(seen.size());
  Anchors anchors(n, 2);
  Eigen::VectorXd ranges(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    anchors.row(i) = sensors_.landmarks.row(seen[static_cast<std::size_t>(i)]);
    ranges[i] = (anchors.row(i).transpose() - p).norm();
  }
  const LocalizationOptions opt;  // the simulator's (Trial::range_fix)
  const LocalizationResult r = trilaterate(anchors, ranges, Eigen::VectorXd::Constant(n, sensors_.range_std), opt);
  const double gap = r.ambiguity_gap;
  if (!r.ok() && !(gap <= opt.ambiguity_margin)) return 0.0;  // refused for its geometry, not as ambiguous
  if (!std::isfinite(gap)) return 1.0;
  if (!(gap > 0.0)) return 0.0;
  // Noise ε (whitened) moves the gap to Δ + 2 aᵀε, a the mirror's residuals (‖a‖² = Δ): N(Δ, 4Δ).
  const double sd = 2.0 * std::sqrt(gap), M = opt.ambiguity_margin;
  return normal_sf((M - gap) / sd) + normal_sf((M + gap) / sd);
}

Step Model::offset(const Step& s, double lateral, double dtheta) const {
  Step m = s;
  m.end += lateral * Eigen::Vector2d(-std::sin(s.x[kTheta]), std::cos(s.x[kTheta]));
  m.view_dtheta = s.view_dtheta + dtheta;
  observe(m);
  return m;
}

Step Model::seen_from(const Step& motion, const Step& view, const Eigen::Vector2d& shift, double dtheta) const {
  Step m = motion;
  m.end = view.end + shift;
  m.view_dtheta = wrap_angle(view.x[kTheta] + view.view_dtheta - motion.x[kTheta]) + dtheta;
  observe(m);
  return m;
}

void Model::leg(const Eigen::Vector2d& a, const Eigen::Vector2d& b, std::vector<Step>& out) const {
  const double L = (b - a).norm();
  if (!(L > 0.0)) return;
  const double per_step = settings_.speed * step_;
  const long n = std::max(1L, static_cast<long>(std::ceil(L / per_step - 1e-9)));
  if (n > 10'000'000) bad("belief leg of " + num(L) + " m: more than 1e7 steps of " + num(per_step) + " m");
  const double heading = std::atan2(b.y() - a.y(), b.x() - a.x());
  for (long j = 0; j < n; ++j) {
    Step s;
    const Eigen::Vector2d p = a + (b - a) * (static_cast<double>(j) / static_cast<double>(n));
    s.x << p.x(), p.y(), settings_.speed, heading;
    s.u = Control(settings_.speed, 0.0);
    s.end = a + (b - a) * (static_cast<double>(j + 1) / static_cast<double>(n));
    s.length = L / static_cast<double>(n);
    s.dt = s.length / settings_.speed;
    observe(s);
    s.clearance = clearance_at(s.end);
    out.push_back(std::move(s));
  }
}

void Model::trajectory(const Eigen::Ref<const RowMatrixX4>& states, std::vector<Step>& out) const {
  const double dt = bmm_.params().dt;
  const Eigen::Index every = std::max<Eigen::Index>(1, std::llround(step_ / dt));
  const Eigen::Index last = states.rows() - 1;
  for (Eigen::Index i = 0; i < last;) {
    const Eigen::Index j = std::min(last, i + every);
    Step s;
    s.x = states.row(i).transpose();
    const double turn = wrap_angle(states(j, kTheta) - states(i, kTheta));
    s.u = Control(states(j, kV), turn);
    s.end = states.row(j).head<2>().transpose();
    s.view_dtheta = turn;  // the camera looks along the end's heading
    s.dt = static_cast<double>(j - i) * dt;
    s.length = (s.end - s.x.head<2>()).norm();
    observe(s);
    s.clearance = clearance_at(s.end);
    out.push_back(std::move(s));
    i = j;
  }
}

Model::FixOdds Model::fix_odds(const Step& s, double n) const {
  FixOdds o;
  const double a = n / sensors_.position_every;  // fix attempts in the step
  // 1 − (1 − q)^a: at least one of a attempts succeeds, each with probability q.
  const auto any = [a](double q) { return q < 1.0 ? -std::expm1(a * std::log1p(-q)) : 1.0; };
  if (s.fix) {  // FixModel::Profile: a fix is lost with the profile's dropout_probability
    const double q = 1.0 - sensors_.position.dropout_probability;
    o.p = any(q);
    o.count = o.p > 0.0 ? a * q / o.p : 0.0;
  } else if (s.ranges) {
    // FixModel::Ranges (navigation_sensors.cpp, Trial::range_fix): a range
    // survives the dropout fault and is sound (neither an outlier nor
    // misassociated) with probability q.  A fix needs m = max(3,
    // min_landmarks) sound ranges: with exactly three, one faulty range fails
    // the fix's χ² test; with more, the outlier test drops it and the sound
    // ones remain.  So a fix forms with P(Bin(in view, q) ≥ m), and a sound
    // range is in it when at least m − 1 of the others are sound too:
    // q·P(Bin(in view − 1, q) ≥ m − 1) per attempt.
    const LandmarkFaults& f = sensors_.faults;
    const double q = (1.0 - f.dropout_probability) * (1.0 - f.outlier_probability) *
                     (1.0 - f.misassociation_probability);
    const int m = std::max(3, sensors_.min_landmarks);
    const int k = static_cast<int>(s.seen.size());
    if (s.unambiguous < 0.0) s.unambiguous = unambiguous_share(s.end, s.seen);
    o.p = any(binomial_tail(k, q, m) * s.unambiguous);
    o.count = o.p > 0.0 ? a * q * binomial_tail(k - 1, q, m - 1) * s.unambiguous / o.p : 0.0;
  }
  return o;
}

namespace {

/// The expected error covariance of a start whose fix the loop disputes (Trial::dispute_start_fix,
/// the gate on): a right fix z (error a ~ N(0, R)) and the rough start s (error b ~ N(0, σ₀²I))
/// give d = z − s ~ N(0, S), S = R + σ₀²I, disputed where q = dᵀS⁻¹d > c (c = χ²₂ at the gate's
/// probability).  The loop then starts from (z + s)/2, error e = (a + b)/2.  Given d, a + b is
/// Gaussian with mean A S⁻¹ d and covariance S − A S⁻¹ A (A = R − σ₀²I); in two dimensions
/// E[ddᵀ | q > c] = (1 + c/2) S; so E[eeᵀ | q > c] = ¼ (S + (c/2) A S⁻¹ A).
Eigen::Matrix2d disputed_start_error(const Eigen::Matrix2d& R, double s0, double c) {
  const Eigen::Matrix2d S = R + s0 * s0 * Eigen::Matrix2d::Identity();
  const Eigen::Matrix2d A = R - s0 * s0 * Eigen::Matrix2d::Identity();
  const Eigen::Matrix2d E = 0.25 * (S + 0.5 * c * A * S.ldlt().solve(A));
  return 0.5 * (E + E.transpose());
}

}  // namespace

StateCov Model::start_covariance(const Eigen::Vector2d& start, double heading) const {
  Step s;
  s.x << start.x(), start.y(), 0.0, heading;
  s.end = start;
  observe(s);
  const FixOdds odds = fix_odds(s, sensors_.position_every);  // one attempt
  const StateCov none = sensors_.start_covariance(nullptr);
  if (!(s.fix || s.ranges) || !(odds.p > 0.0)) return none;
  Eigen::Matrix2d R = R_fix_;
  if (s.ranges) {
    // The simulator's trilateration (Trial::range_fix) of the noise-free
    // ranges, each σ_r/√c: its covariance (Jᵀ W J)⁻¹, W = c/σ_r², and its
    // refusals (too few, degenerate or ambiguous geometry: no fix).
    const Eigen::Index n = static_cast<Eigen::Index>(s.seen.size());
    Anchors anchors(n, 2);
    Eigen::VectorXd ranges(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      anchors.row(i) = sensors_.landmarks.row(s.seen[static_cast<std::size_t>(i)]);
      ranges[i] = (anchors.row(i).transpose() - start).norm();
    }
    const LocalizationResult lr = trilaterate(
        anchors, ranges, Eigen::VectorXd::Constant(n, sensors_.range_std / std::sqrt(odds.count)), LocalizationOptions{});
    if (!lr.ok()) return none;
    R = lr.covariance;
  }
  const double g = settings_.gate_probability;
  if (g > 0.0) {
    // The loop disputes a right fix at 1 − g (its check against the rough start): the expected
    // error of its start.  The fixes it keeps are taken at R (their selection by small d is left out).
    const Eigen::Matrix2d E = disputed_start_error(R, sensors_.unfixed_start_std(), chi2_quantile(g, 2));
    R = g * R + (1.0 - g) * E;
  }
  const StateCov fix = sensors_.start_covariance(&R);
  if (odds.p == 1.0) return fix;
  return odds.p * fix + (1.0 - odds.p) * none;
}

void Model::update(const Step& s, double n, double fix_count, bool with_fix, StateCov& P) const {
  if (with_fix && s.fix && fix_count > 0.0) ml_update<2>(P, H_fix_, R_fix_ / fix_count, MeasurementKind::Position);
  if (!s.seen.empty()) {
    State at = s.x;
    at.head<2>() = s.end;
    for (int row : s.seen) {
      const LandmarkGeometry g = landmark_geometry(at[kX], at[kY], sensors_.landmarks(row, 0), sensors_.landmarks(row, 1));
      if (!g.defined()) continue;
      if (with_fix && s.ranges && fix_count > 0.0) {  // FixModel::Ranges: a range to each landmark in view (eq. 10)
        const Eigen::Matrix<double, 1, 1> R(sensors_.range_std * sensors_.range_std / fix_count);
        ml_update<1>(P, range_row(g), R, MeasurementKind::Range);
      }
      if (settings_.bearing_std > 0.0) {  // a bearing to each landmark in view [Placement §III-A]
        LandmarkJacobian J;
        predict_bearing(g, at[kTheta], &J);
        Eigen::Matrix<double, 1, 4> H;
        H << J.x, J.y, 0.0, J.theta;
        const Eigen::Matrix<double, 1, 1> R(settings_.bearing_std * settings_.bearing_std / n);
        ml_update<1>(P, H, R, MeasurementKind::Bearing);
      }
    }
  }
  if (sensors_.imu) ml_update<2>(P, H_imu_, R_imu_ / n, MeasurementKind::SpeedHeading);
}

StateCov Model::process_noise(const Step& s) const { return bmm_.with_step(s.dt).process_cov(s.x, s.u); }

void Model::step(const Step& s, StateCov& P, StepOutcome* out, bool gate) const {
  // Eq. 11 about the nominal: P⁻ = F P Fᵀ + G Σ_ε Gᵀ (the BMM over the step's dt).
  const Bmm bmm = bmm_.with_step(s.dt);
  Eigen::Matrix4d F, G;
  bmm.linearize(s.x, s.u, &F, &G);
  P = F * P * F.transpose() + G * bmm.noise_cov() * G.transpose();
  P = 0.5 * (P + P.transpose());
  if (out) {
    out->Pm = P;
    out->F = F;
    out->p_fix = 1.0;
  }
  // How many filter steps this belief step stands for: each measurement's
  // information is that many times one's (R divided by the count).
  const double n = s.dt / bmm_.params().dt;
  const FixOdds odds = fix_odds(s, n);
  // The mixture's strata branch on the gate (belief_gate.hpp) where a fix may
  // arrive and the filter's prediction is far less certain than the fix.
  bool gated = false;
  Eigen::Matrix2d R;
  if (gate && out && settings_.gate_probability > 0.0 && odds.p > 0.0 && (s.fix || s.ranges)) {
    R = fix_information(s, odds.count).inverse();
    gated = R.allFinite() && R.determinant() > 0.0 && P.topLeftCorner<2, 2>().trace() > kGatePersists * R.trace();
    out->gating = gated ? StepOutcome::Gating::Branches : StepOutcome::Gating::Passes;
  }
  if (!(odds.p > 0.0 && odds.p < 1.0) && !gated) {  // the updates are certain
    update(s, n, odds.count, odds.p > 0.0, P);
    return;
  }
  const StateCov Pm = P;
  StateCov P_fix = Pm, P_none = Pm;
  update(s, n, odds.count, true, P_fix);
  update(s, n, odds.count, false, P_none);
  if (odds.p < 1.0) {
    P = odds.p * P_fix + (1.0 - odds.p) * P_none;
    P = 0.5 * (P + P.transpose());
  } else {
    P = P_fix;
  }
  if (out) {
    const Eigen::LDLT<StateCov> ldlt(Pm);
    out->p_fix = odds.p;
    out->T_fix = ldlt.solve(P_fix.transpose()).transpose();
    out->T_none = ldlt.solve(P_none.transpose()).transpose();
    if (gated) {
      out->P_fix = P_fix;
      out->P_none = P_none;
      out->R = R;
    }
  }
}

Eigen::Matrix2d Model::fix_information(const Step& s, double count) const {
  if (s.fix) return (R_fix_ / count).inverse();
  Eigen::Matrix2d Y = Eigen::Matrix2d::Zero();
  for (int row : s.seen) {  // the ranges of update(), as one position fix
    const LandmarkGeometry g = landmark_geometry(s.end.x(), s.end.y(), sensors_.landmarks(row, 0), sensors_.landmarks(row, 1));
    if (!g.defined()) continue;
    const Eigen::Vector2d d = range_row(g).head<2>().transpose();
    Y += d * d.transpose() * (count / (sensors_.range_std * sensors_.range_std));
  }
  return Y;
}

void Model::direction(Step& s) const {
  if (!std::isnan(s.toward.x())) return;
  s.toward.setZero();
  if (!std::isfinite(s.clearance) || s.clearance <= 0.0) return;
  // The keep-out distance is 1-Lipschitz: its gradient, where defined, is
  // the unit vector away from the nearest point.  Equidistant walls (a
  // corridor's middle) give a short difference vector: undefined there.
  const double h = 1e-4 * std::max(1.0, s.clearance);
  const Eigen::Vector2d ex(h, 0.0), ey(0.0, h);
  const Eigen::Vector2d grad((clearance_at(s.end + ex) - clearance_at(s.end - ex)) / (2 * h),
                             (clearance_at(s.end + ey) - clearance_at(s.end - ey)) / (2 * h));
  const double g = grad.norm();
  if (g > 0.5) s.toward = -grad / g;
}

double Model::sigma_toward(Step& s, const StateCov& P) const {
  direction(s);
  if (s.toward.squaredNorm() == 0.0) return position_std(P);
  const Eigen::Vector2d& a = s.toward;
  return std::sqrt(std::max(0.0, a.dot(P.topLeftCorner<2, 2>() * a)));
}

}  // namespace safenav::belief
