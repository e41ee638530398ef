// The online Localizer: starting from the data (safenav/localizer.hpp,
// "Initialization"; the fit is localizer_fit.cpp).
#include <iomanip>
#include <sstream>

#include "localizer_impl.hpp"

namespace safenav {

/// A position known at time t (before initialization): start at once when
/// a heading is known, else anchor it and wait for init_baseline of motion.
void Localizer::Impl::position_known(double t, const Eigen::Vector2d& p, const Eigen::Matrix2d& cov) {
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
void Localizer::Impl::push_pose(double t) {
  track.push_back(Eigen::Vector4d(t, odo[0], odo[1], odo[2]));
}

/// The start rules (detail::start_rules); sets `why` to what the window holds.
bool Localizer::Impl::rules_hold(const detail::StartWindow& w) {
  return detail::start_rules(w, settings.init_window, settings.init_min_path, settings.init_min_beacons, most, why);
}

/// Starting from data: fit the rigid transform (X, Y, φ) from the motion
/// integral's frame to the world to the observations and headings of the
/// last init_window seconds (detail::fit_transform) once a start rule holds
/// (rules_hold); with bearings or headings only when one arrived since the
/// last fit.  Starts the filter at the newest motion input when the fit is
/// good enough (accept_fit).
void Localizer::Impl::try_fit(double t_now) {
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
void Localizer::Impl::accept_fit(double t_now, const detail::FitResult& fit) {
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
  StartWindow window = start_window_now(t_now);  // start() empties the buffers
  start(t_now, State(px, py, speed, wrap_angle(th[2] + q[3])), 0.5 * (P0 + P0.transpose()));
  why += " from the data (" + os.str() + ")";
  keep_start(std::move(window));  // late observations from before the start (localizer_history.cpp)
}

}  // namespace safenav
