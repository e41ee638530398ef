// The uncertainty-aware guard (ours): safenav/guard.hpp.
#include "safenav/guard.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <boost/math/distributions/normal.hpp>

#include "declare.hpp"
#include "errors.hpp"

namespace safenav {

template <>
const ParamSet<GuardSettings>& param_set<GuardSettings>();  // defined below

void GuardSettings::look_with_camera(double camera_field_of_view, double max_range, int min_landmarks,
                                     bool camera_occlusion) {
  field_of_view = std::min(camera_field_of_view, 2.0 * kPi);
  look_range = max_range;
  look_min_landmarks = std::max(1, min_landmarks);
  occlusion = camera_occlusion;
}

void GuardSettings::validate() const { param_set<GuardSettings>().check(*this, "settings.guard."); }

Guard::Guard(const GuardSettings& settings, const Bmm& bmm, const ObstacleChecker& obstacles,
             const Points2& landmarks, double corridor_limit)
    : settings_(settings), bmm_(bmm), obstacles_(obstacles), landmarks_(landmarks), corridor_limit_(corridor_limit) {
  track_.reserve(kTrackPoints);  // the online tick allocates nothing
  if (!(settings.k > 0.0))
    detail::bad("Guard: settings.guard.k = " + detail::num(settings.k) +
                ": must be > 0 (k = 0 is resolved from collision_probability by Guidance: guard_k_for_risk)");
}

// ---------------------------------------------------------------------------
// The risk budget (docs/safety.md, "The guard's k")

double guard_k_for_risk(double collision_probability, double exposures) {
  const double eps = collision_probability;
  if (!(eps > 0.0 && eps < 1.0))
    detail::bad("collision_probability = " + detail::num(eps) + ": must be in (0, 1)");
  if (!(exposures >= 1.0) || !std::isfinite(exposures))
    detail::bad("exposures = " + detail::num(exposures) + ": must be finite and >= 1");
  // k = Q⁻¹(ε/N) = Φ⁻¹(1 − ε/N), from the complement: exact for tiny ε/N.
  return boost::math::quantile(boost::math::complement(boost::math::normal_distribution<double>(), eps / exposures));
}

double path_exposures(const Corridor& path, const ObstacleChecker& obstacles, double reach, double exposure_length,
                      double step) {
  if (!(step > 0.0) || !std::isfinite(step)) detail::bad("step = " + detail::num(step) + ": must be finite and > 0");
  if (!(exposure_length >= step) || !std::isfinite(exposure_length))
    detail::bad("exposure_length = " + detail::num(exposure_length) + ": must be finite and >= step = " +
                detail::num(step));
  if (!(reach >= 0.0) || !std::isfinite(reach)) detail::bad("reach = " + detail::num(reach) + ": must be finite and >= 0");
  // Walk the path in steps; a point at keep-out distance d > reach lets the
  // walk skip d − reach metres of arc (every point within them is still
  // farther than reach), so open ground costs few queries.
  const double length = path.length();
  double near = 0.0;  // the steps within reach of an obstacle
  for (double s = 0.0; s <= length;) {
    const Eigen::Vector2d p = path.point_at(s);
    const double d = obstacles.keep_out_distance(p, p);
    if (d <= reach) {
      near += 1.0;
      s += step;
    } else {
      s += std::max(step, std::floor((d - reach) / step) * step);
    }
  }
  return std::max(1.0, std::ceil(near * step / exposure_length - 1e-9));
}

/// Clearance of the segment a–b (a = the estimate) to obstacles and
/// forbidden hazards: exact when it could matter (bound − keep < slow_distance,
/// keep = k·σ + buffer), else the lower bound.
double Guard::clearance(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double keep) {
  // The bound suffices when even it leaves the margin d − keep at slow_distance or more:
  // the guard then keeps the control, as it would with the exact distance.
  const double slow = settings_.slow_distance;
  auto bound = [&] { return cache_d_ - std::max((a - cache_p_).norm(), (b - cache_p_).norm()); };
  if (bound() - keep >= slow) return bound();
  if ((a - cache_p_).norm() > 0.0 || !std::isfinite(cache_d_)) {
    cache_p_ = a;
    cache_d_ = obstacles_.keep_out_distance(a, a);
    if (bound() - keep >= slow) return bound();
  }
  return obstacles_.keep_out_distance(a, b);
}

/// The way ahead under u: u held for horizon seconds (a constant-turn arc of
/// the BMM, as in the dynamic window approach), then braking to a stop.  With
/// `path`, also the arc's largest deviation from it and the clearance at the stop.
Guard::WayAhead Guard::way_ahead(const State& x, const Control& u, double keep, const Corridor* path) {
  const BmmParams& p = bmm_.params();
  const int steps = std::max(1, static_cast<int>(std::ceil(settings_.horizon / p.dt)));
  constexpr int kEvery = 4;  // clearance checked over chords of this many steps
  State xi = x;
  Eigen::Vector2d a = x.head<2>();
  WayAhead w;
  for (int i = 1; i <= steps; ++i) {
    xi = bmm_.predict(xi, u);
    if (i % kEvery == 0 || i == steps) {
      const Eigen::Vector2d b = xi.head<2>();
      w.clearance = std::min(w.clearance, clearance(a, b, keep));
      if (path) w.deviation = std::max(w.deviation, path->project(b).distance);
      a = b;
    }
  }
  const double v = xi[kV];
  const Eigen::Vector2d stop =
      xi.head<2>() + v * v / (2.0 * p.deceleration) * Eigen::Vector2d(std::cos(xi[kTheta]), std::sin(xi[kTheta]));
  w.clearance = std::min(w.clearance, clearance(a, stop, keep));
  if (path) {
    w.deviation = std::max(w.deviation, path->project(stop).distance);
    w.end_clearance = obstacles_.keep_out_distance(stop, stop);
  }
  return w;
}

/// Bearings from p of the landmarks within look_range (not at p itself)
/// that p can see: with occlusion, those no obstacle hides
/// (ObstacleChecker::line_of_sight, no clearance).
std::vector<double> Guard::bearings_in_range(const Eigen::Vector2d& p) const {
  std::vector<double> out;
  for (Eigen::Index j = 0; j < landmarks_.rows(); ++j) {
    const Eigen::Vector2d lj = landmarks_.row(j).transpose();
    const Eigen::Vector2d dj = lj - p;
    if (dj.norm() > settings_.look_range || dj.squaredNorm() < 1e-18) continue;
    if (settings_.occlusion && !obstacles_.line_of_sight(p, lj)) continue;
    out.push_back(std::atan2(dj.y(), dj.x()));
  }
  return out;
}

/// How many of `bearings` lie inside the field of view centred on `heading`.
int Guard::landmarks_seen(const std::vector<double>& bearings, double heading) const {
  const double half = 0.5 * settings_.field_of_view;
  int n = 0;
  for (double b : bearings) n += std::abs(wrap_angle(b - heading)) <= half;
  return n;
}

/// The heading change toward the landmark bearing that puts the most
/// landmarks of `bearings` inside the field of view (0 when there is none;
/// ties: the smaller turn); `seen` gets that count.
double Guard::look_turn(const State& x, const std::vector<double>& bearings, int* seen) const {
  int best = 0;
  double best_turn = 0.0;
  for (double bi : bearings) {
    const int n = landmarks_seen(bearings, bi);
    const double turn = wrap_angle(bi - x[kTheta]);
    if (n > best || (n == best && std::abs(turn) < std::abs(best_turn))) {
      best = n;
      best_turn = turn;
    }
  }
  if (seen) *seen = best;
  return best_turn;
}

/// Steer: arcs of a fan of turn rates within the BMM's limit, at a few
/// speeds; the fastest speed with a clear arc, then the turn closest to the
/// method's.  An arc may not take the k-σ disc out of the corridor (or, when
/// it already is, any farther out).  Failing that, the escape: the slow arc
/// that ends farthest from the obstacles, if it ends farther than the vehicle
/// is now and touches nothing.  False when neither exists.
bool Guard::steer(const State& x, const Control& u0, double rho, double keep, const Corridor& path,
                  GuardDecision& out) {
  const BmmParams& p = bmm_.params();
  const double lim = p.max_heading_rate * p.dt;
  const double want = bmm_.clipped_heading_change(u0[1]);
  const double out_now = path.project(x.head<2>()).distance;
  const double dev_limit = std::max(corridor_limit_ - rho, out_now);
  constexpr int kTurns = 9;
  const double speeds[3] = {u0[0], 0.5 * u0[0], settings_.min_speed_fraction * u0[0]};
  const double here = obstacles_.keep_out_distance(x.head<2>(), x.head<2>());
  Control best = u0, escape = u0;
  double best_cost = std::numeric_limits<double>::infinity(), best_d = 0.0;
  double escape_end = here + 1e-3, escape_d = 0.0;
  bool found = false, can_escape = false;
  for (double v : speeds) {
    for (int j = 0; j <= kTurns; ++j) {
      const double dth = j == kTurns ? want : -lim + 2.0 * lim * j / (kTurns - 1);
      const Control u(v, dth);
      const WayAhead w = way_ahead(x, u, keep, &path);
      if (w.deviation > dev_limit) continue;
      if (w.clearance - keep >= 0.0) {
        const double cost = std::abs(dth - want);
        if (cost < best_cost) {
          best_cost = cost;
          best = u;
          best_d = w.clearance;
          found = true;
        }
      } else if (v == speeds[2] && w.clearance > 0.0 && w.end_clearance > escape_end) {
        escape = u;
        escape_end = w.end_clearance;
        escape_d = w.clearance;
        can_escape = true;
      }
    }
    if (found) break;
  }
  if (!found && !can_escape) return false;
  out.control = found ? best : escape;
  out.action = GuardAction::Steer;
  out.clearance = found ? best_d : escape_d;
  out.margin = out.clearance - keep;
  return true;
}

/// The graded speed law: when the method's control conflicts (m < 0), the
/// fastest of half and the slowest speed, on the method's own turn, whose
/// way ahead is clear (m ≥ 0).  A slower control's way ahead is shorter, so
/// an obstacle ahead (a bend of the path round it) drops out of it; one
/// beside the path does not, and this fails.  The control kept is clear, so
/// the one-exposure bound of the risk budget holds for it as for any other.
bool Guard::slow_to_clear(const State& x, const Control& u0, double keep, GuardDecision& out) {
  for (double f : {0.5, settings_.min_speed_fraction}) {
    if (f >= 1.0 || !(u0[0] > 0.0)) continue;
    const Control u(f * u0[0], u0[1]);
    const double d = way_ahead(x, u, keep).clearance;
    if (d - keep >= 0.0) {
      out.control = u;
      out.action = GuardAction::Slow;
      out.clearance = d;
      out.margin = d - keep;
      return true;
    }
  }
  return false;
}

/// The run's history from the estimate alone: the least σ of a fix, and the
/// track driven since σ was last of fix quality (≤ 2 × that σ), one point
/// per metre, the last kTrackPoints of them.  The BMM's process noise
/// grows σ every step, so a σ that did not grow since the previous request
/// was shrunk by a measurement.
void Guard::track(const State& x, double position_std) {
  const double sd = position_std;
  fixing_ = std::isfinite(sigma_prev_) && sd <= sigma_prev_;
  if (fixing_) sigma_min_ = std::min(sigma_min_, sd);
  sigma_prev_ = sd;
  if (recovering_ == 1) return;  // backing up consumes the track
  const Eigen::Vector2d p = x.head<2>();
  if (!std::isfinite(sigma_min_) || sd <= 2.0 * sigma_min_) {
    track_.assign(1, p);
  } else if (track_.empty() || (p - track_.back()).norm() >= 1.0) {
    if (track_.size() == kTrackPoints) track_.erase(track_.begin());  // the last kTrackPoints metres
    track_.push_back(p);
  }
}

/// A recovery step (Nav2's recoveries): back up along the track, or spin in
/// place.  False when it is over — σ has halved since it began (a fix), the
/// track is used up, the spin has turned once round, or the step's own way
/// ahead is neither clear nor as safe as holding — and the guard decides afresh.
bool Guard::recover(double t, const State& x, double position_std, double keep, GuardDecision& out) {
  const BmmParams& p = bmm_.params();
  if (position_std <= 0.5 * recover_sigma_) recovering_ = 0;
  Control u(0.0, 0.0);
  if (recovering_ == 1) {
    while (!track_.empty() && (track_.back() - x.head<2>()).norm() < 1.0) track_.pop_back();
    if (track_.empty()) {
      recovering_ = 0;
      return false;
    }
    const double turn = wrap_angle(std::atan2(track_.back().y() - x[kY], track_.back().x() - x[kX]) - x[kTheta]);
    // Turn in place first when the track lies behind, then drive along it.
    u = Control(std::abs(turn) > 0.5 * kPi ? 0.0 : settings_.recovery_speed, turn);
  } else if (recovering_ == 2) {
    if (t - recover_start_ > 2.0 * kPi / p.max_heading_rate) recovering_ = 0;
    u = Control(0.0, p.max_heading_rate * p.dt);
  }
  if (recovering_ == 0) return false;
  // Clear (m ≥ 0), or, like the hold it replaces (outside the risk bound
  // too), touching nothing and no nearer the obstacles than holding here:
  // a spin in place always is, a back-up along the way in usually.
  const double d = way_ahead(x, u, keep).clearance;
  const bool as_hold = d > settings_.buffer && d >= way_ahead(x, Control(0.0, 0.0), keep).clearance - 1e-9;
  if (d - keep < 0.0 && !as_hold) {
    recovering_ = 0;
    return false;
  }
  out.control = u;
  out.action = GuardAction::Recover;
  out.clearance = d;
  out.margin = d - keep;
  return true;
}

/// Hold for a fix, turning toward `look`.  A hold that has not halved σ
/// within hold_timeout is stuck: a recovery, or after max_recoveries, Blocked.
GuardDecision Guard::hold(double t, const State& x, double position_std, double keep, double look, int could_see) {
  const GuardSettings& g = settings_;
  if (!std::isfinite(hold_start_) || position_std <= 0.5 * hold_sigma_) {  // a new hold, or progress: restart
    hold_start_ = t;
    hold_sigma_ = position_std;
  }
  GuardDecision out;
  if (t - hold_start_ > g.hold_timeout) {
    hold_start_ = -std::numeric_limits<double>::infinity();
    if (recoveries_ < g.max_recoveries) {
      ++recoveries_;
      recovering_ = track_.size() > 1 ? 1 : 2;
      recover_start_ = t;
      recover_sigma_ = position_std;
      if (recover(t, x, position_std, keep, out)) return out;
    } else {
      const double d = way_ahead(x, Control(0.0, 0.0), keep).clearance;
      out.control = Control(0.0, 0.0);
      out.action = GuardAction::Blocked;
      out.clearance = d;
      out.margin = d - keep;
      out.reason = "blocked at (" + detail::num(x[kX]) + ", " + detail::num(x[kY]) + "): held " +
                   detail::num(g.hold_timeout) + " s without sigma halving (sigma = " + detail::num(position_std) +
                   " m, k*sigma + buffer = " + detail::num(keep) + " m), " +
                   (could_see >= g.look_min_landmarks ? "sigma is as small as fixes make it here"
                                                      : "no landmark can be seen from here") +
                   "; " + std::to_string(recoveries_) + " recoveries did not help";
      return out;
    }
  }
  out.control = Control(0.0, look);
  out.action = GuardAction::Hold;
  out.clearance = way_ahead(x, out.control, keep).clearance;
  out.margin = out.clearance - keep;
  return out;
}

GuardDecision Guard::decide(double t, const State& x, double position_std, const Control& proposed,
                            const Corridor& path) {
  const GuardSettings& g = settings_;
  const double rho = g.k * position_std;
  const double keep = rho + g.buffer;  // the clearance the way ahead must keep
  const Control u0 = proposed;
  track(x, position_std);
  GuardDecision out;
  if (recovering_ && recover(t, x, position_std, keep, out)) return out;
  auto set = [&](const Control& u, GuardAction action, double d) {
    out.control = u;
    out.action = action;
    out.clearance = d;
    out.margin = d - keep;
    return out;
  };
  const double d0 = way_ahead(x, u0, keep).clearance;
  set(u0, GuardAction::Keep, d0);
  // Any answer but the hold below ends a hold in progress; the hold keeps its clock.
  const double held_since = hold_start_;
  hold_start_ = -std::numeric_limits<double>::infinity();
  if (out.margin >= 0.0 && looking_ < 0) looking_ = 0;  // clear again: a later conflict may look again
  if (out.margin >= g.slow_distance && looking_ == 0) return out;
  // Slow down, so that more fixes arrive per metre; without fixes (σ grew
  // since the last request: dead reckoning) slowing buys nothing — σ grows
  // per step, not per metre — and the clear way ahead (m ≥ 0) is the whole
  // promise, so the method's control is kept.
  if (out.margin >= 0.0 && looking_ == 0) {
    if (!fixing_) return out;
    const double f = std::max(g.min_speed_fraction, g.slow_distance > 0 ? out.margin / g.slow_distance : 1.0);
    if (f < 1.0) {
      const Control u(f * u0[0], u0[1]);
      set(u, GuardAction::Slow, way_ahead(x, u, keep).clearance);
    }
    return out;
  }
  if (looking_ == 0 && slow_to_clear(x, u0, keep, out)) return out;
  int could_see = 0;
  const std::vector<double> bearings = bearings_in_range(x.head<2>());
  const double look = look_turn(x, bearings, &could_see);
  // Look first: the way ahead is clear of the obstacles themselves (d0 > buffer), so the
  // conflict is the uncertainty; landmarks that would give a fix are in range
  // but out of view; σ is at least twice a fix's (or no fix yet): stop and
  // turn toward them, until they are in view and a fix has halved σ or σ
  // stops shrinking, or for at most look_timeout.
  const bool in_view = landmarks_seen(bearings, x[kTheta]) >= g.look_min_landmarks;
  const bool can_shrink = !std::isfinite(sigma_min_) || position_std >= 2.0 * sigma_min_;
  if (g.look_first && looking_ == 0 && d0 > g.buffer && could_see >= g.look_min_landmarks && !in_view &&
      can_shrink) {
    looking_ = 1;
    look_sigma_ = position_std;
    look_start_ = t;
    look_prev_ = position_std;
  }
  if (looking_ > 0) {
    // A look runs to its end even if the margin clears meanwhile: stopped, the
    // way ahead looks shorter, and ending there would start and stop the vehicle in turn.
    const bool converged = in_view && looking_ > 2 && position_std > 0.95 * look_prev_;
    const bool done = position_std <= 0.5 * look_sigma_ || converged || t - look_start_ > g.look_timeout;
    look_prev_ = position_std;
    if (!done) {
      ++looking_;
      const Control u(0.0, in_view ? 0.0 : look);
      return set(u, GuardAction::Hold, way_ahead(x, u, keep).clearance);
    }
    looking_ = -1;  // looked: no second look until the margin is met again
  }
  if (steer(x, u0, rho, keep, path, out)) return out;
  // Hold for a fix: stop, turning toward where landmarks can be seen.
  hold_start_ = held_since;
  return hold(t, x, position_std, keep, look, could_see);
}

// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<GuardSettings>& param_set<GuardSettings>() {
  using G = GuardSettings;
  // NavigationSettings nests these as guard_<name> (the scenario's navigation.guard_k, …).
  static const ParamSet<G> s =
      Declare<G>{}
          .real("k", SN_REF(G, k), "", closed(0, 100), "the guard keeps k x position sigma clear of obstacles and forbidden hazards (ours); 0 = from collision_probability and the path")
          .real("buffer", SN_REF(G, buffer), "m", closed(0, 1e4), "the guard keeps this much beyond k sigma")
          .real("slow_distance", SN_REF(G, slow_distance), "m", closed(0, 1e4), "the guard slows down when its margin falls below this")
          .real("horizon", SN_REF(G, horizon), "s", above(0, 1e3), "the guard looks at the control held this long, then braking")
          .real("min_speed_fraction", SN_REF(G, min_speed_fraction), "", above(0, 1), "slowest fraction of the commanded speed while the guard slows")
          .real("hold_timeout", SN_REF(G, hold_timeout), "s", above(0, 1e4), "a hold that has not halved sigma in this long is stuck: the guard recovers")
          .integer("max_recoveries", SN_REF(G, max_recoveries), closed(0, 1000), "recoveries (back up along the track, spin) per run before a stuck hold gives up: blocked")
          .real("recovery_speed", SN_REF(G, recovery_speed), "m/s", above(0, 100), "speed of the guard's back-up along the track driven")
          .flag("enabled", SN_REF(G, enabled), "the guard is on (off: the papers' loop)")
          .flag("look_first", SN_REF(G, look_first), "before steering round an uncertain way ahead, turn to look at landmarks")
          .real("look_timeout", SN_REF(G, look_timeout), "s", closed(0, 1e4), "the longest look")
          .real("look_range", SN_REF(G, look_range), "m", closed(0, 1e4), "landmarks within this can be looked at (the camera's detection range, look_with_camera)")
          .integer("look_min_landmarks", SN_REF(G, look_min_landmarks), closed(1, 1000), "a fix needs this many landmarks in view (the camera's, look_with_camera)")
          .real("field_of_view", SN_REF(G, field_of_view), "rad", above(0, 2 * kPi), "the camera's full horizontal field of view (look_with_camera)")
          .flag("occlusion", SN_REF(G, occlusion), "obstacles hide landmarks from the look (the camera's, look_with_camera)")
          .set;
  return s;
}

template class ParamSet<GuardSettings>;

}  // namespace safenav
