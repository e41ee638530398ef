// safenav/guard.hpp — the uncertainty-aware guard (ours; the papers have
// none): it keeps the estimate's k-σ position disc, plus a buffer, off the
// obstacles and forbidden hazards by slowing, looking at landmarks, steering
// or holding for a fix.  Guidance (guidance.hpp) asks it about each control
// that SafeNav-CHull [SafeNav Alg. 1] or SafeNav-Centroid [SafeNav Alg. 2]
// chooses.
//
// Only Eigen and std types appear here.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "safenav/corridor.hpp"
#include "safenav/motion.hpp"
#include "safenav/types.hpp"
#include "safenav/world.hpp"

namespace safenav {

/// The uncertainty-aware guard (ours; the papers have none).  Each command
/// it compares the estimate's k-σ position radius ρ = k·√λ_max(P_xy) with the
/// clearance d of the way ahead to the nearest obstacle or forbidden hazard
/// (not grown: the true vehicle's collision test).  The way ahead of a
/// control is the BMM arc of that control held for `horizon` seconds, then
/// braking to a stop (a dynamic-window rollout).  With margin
/// m = d − ρ − buffer for the method's control:
///   * m ≥ slow_distance: the method's control is kept;
///   * 0 ≤ m < slow_distance, with fixes arriving (σ did not grow since the
///     previous request): it slows down, to a speed fraction m/slow_distance
///     (at least min_speed_fraction), so more fixes arrive per metre; without
///     fixes it keeps the control (σ grows per step, not per metre: slowing
///     would only lose time);
///   * m < 0, but the method's turn at half or at the slowest speed has a
///     clear way ahead (m ≥ 0: a shorter way ahead, the obstacle is ahead,
///     not beside): it slows to the fastest of those (a graded speed law; no
///     look, no turn away from the path);
///   * m < 0, the way ahead clear of the obstacles themselves (the conflict
///     is the uncertainty), look_min_landmarks mapped landmarks within
///     look_range that could be brought into view but are not in it, and σ
///     at least twice the least σ of this run (a fix can still shrink it): it
///     stops and turns toward them ("look first": a fix shrinks ρ); the look
///     lasts until σ halves, σ stops shrinking with the landmarks in view, or
///     look_timeout passes, and the next look waits until the margin has
///     been met again;
///   * m < 0 otherwise: it steers — among arcs of a fan of turn rates within the BMM's
///     limit at the commanded, half and slowest speeds, the fastest speed with
///     a clear arc (m ≥ 0) that keeps the k-σ disc in the corridor, with the
///     turn closest to the method's; if none is clear, the slowest arc that
///     ends farthest from the obstacles (if farther than the vehicle is now);
///   * otherwise it stops and holds for a fix, turning toward the bearing that
///     puts the most mapped landmarks within look_range inside field_of_view;
///   * a hold that has not halved σ within hold_timeout cannot end by waiting
///     (blind: no landmark can be seen from here, and σ only grows; or σ is
///     as small as fixes make it and the gap is still too narrow).  Then it
///     recovers, as Nav2's recoveries do: it backs up along the track it
///     drove since the estimate last had a fix-quality σ, at
///     recovery_speed, each control's way ahead kept clear as above; with no
///     such track it spins once in place, looking all round.  After
///     max_recoveries recoveries, the next stuck hold gives up: Blocked,
///     with the reason (Guidance ends with GuidanceStatus::Blocked).
/// With `occlusion`, a landmark hidden by an obstacle from the estimated
/// position counts for none of these looks.
/// Off, the loop is the papers'.
struct GuardSettings {
  bool enabled = true;
  /// k of the k-σ radius (the scenario's navigation.guard_k).  0 (default):
  /// Guidance sets it from the mission's collision_probability ε and the
  /// exposures N of its path, k = Φ⁻¹(1 − ε/N) (guard_k_for_risk); a k > 0
  /// set explicitly wins.
  double k = 0.0;
  double buffer = 0.25;              ///< kept beyond the k-σ radius (the vehicle's next step, the truth's process noise) [m]
  bool look_first = true;            ///< before steering round an uncertain way ahead, turn to look at landmarks
  double look_timeout = 6.0;         ///< the longest look [s]
  double slow_distance = 1.0;        ///< margin below which it slows down [m]
  double min_speed_fraction = 0.25;  ///< slowest fraction of the commanded speed while slowing
  double horizon = 1.0;              ///< the way ahead: a control held this long, then braking [s]
  double hold_timeout = 3.0;         ///< a hold that has not halved σ in this long is stuck: recover [s]
  int max_recoveries = 2;            ///< recoveries (back-ups, spins) per run before a stuck hold gives up
  double recovery_speed = 0.5;       ///< speed of a back-up along the track driven [m/s]
  // What the guard looks with: set all four with look_with_camera.
  double look_range = 30.0;          ///< landmarks within this can be looked at while holding [m]
  int look_min_landmarks = 3;        ///< a fix needs this many landmarks in view
  double field_of_view = 85.0 * kPi / 180.0;  ///< the camera's full horizontal FOV [rad]
  /// Obstacles hide landmarks (SensorSettings::occlusion): the look counts and
  /// turns toward only the landmarks in line of sight of the estimated position
  /// (ObstacleChecker::line_of_sight on the problem's map, no clearance).
  bool occlusion = true;
  /// The guard looks with the vehicle's camera: its full horizontal field of
  /// view [rad] (at most 2π), its detection range [m], the landmarks a fix
  /// needs (at least 1) and whether obstacles hide landmarks.  The one place
  /// that maps a camera onto the guard's look (the simulator's
  /// SensorSettings, a scenario's camera and detection).
  void look_with_camera(double camera_field_of_view, double max_range, int min_landmarks, bool camera_occlusion);
  void validate() const;
};

/// The guard's k for a collision-risk budget ε spread over N exposures:
/// k = Φ⁻¹(1 − ε/N) = Q⁻¹(ε/N), Q(k) = 1 − Φ(k) the Gaussian tail.  One
/// exposure: the nearest obstacle lies beyond a line at least k·√λ_max(P_xy)
/// from the estimate, so the truth, Gaussian about it, crosses that line with
/// probability Q(d/√(nᵀPn)) ≤ Q(k) (nᵀPn ≤ λ_max); a union bound over the N
/// exposures keeps the mission's probability ≤ N·Q(k) = ε (docs/safety.md).
/// Throws std::invalid_argument unless 0 < ε < 1 (named collision_probability)
/// and N ≥ 1 (finite).  Negative for ε/N > 0.5.
double guard_k_for_risk(double collision_probability, double exposures);

/// The exposures N of a mission along `path` (docs/safety.md, "The guard's
/// k"): the arc length of the path where an obstacle or forbidden hazard of
/// `obstacles` lies within `reach` of it (the vehicle's largest deviation
/// from the path plus the guard's buffer), measured in steps of `step`
/// metres (the distance of one control step), divided by `exposure_length`
/// (the distance over which the estimate's error is taken to decorrelate:
/// the guard's horizon at cruise speed), rounded up, at least 1.
/// Throws std::invalid_argument unless 0 < step ≤ exposure_length and
/// reach ≥ 0 (all finite).
double path_exposures(const Corridor& path, const ObstacleChecker& obstacles, double reach, double exposure_length,
                      double step);

/// What the guard did with a control.
enum class GuardAction {
  Keep,   ///< the method's control is kept
  Slow,   ///< slowed down: the k-σ radius nears the clearance ahead
  Steer,  ///< steered away from the method's heading to keep clearance
  Hold,   ///< stopped to hold for a fix, turning toward landmarks
  /// Recovering from a stuck hold: backing up along the track driven to
  /// where the estimate last had a fix-quality σ, or spinning in place.
  Recover,
  /// A stuck hold after max_recoveries recoveries: the guard gives up
  /// (control 0; GuardDecision::reason says why).
  Blocked,
};

/// The guard's answer for one control.
struct GuardDecision {
  Control control{0.0, 0.0};  ///< the control to send
  GuardAction action = GuardAction::Keep;
  /// The clearance d of the way ahead of `control` [m]: exact where
  /// d < k·σ + buffer + slow_distance, a lower bound beyond.
  double clearance = std::numeric_limits<double>::infinity();
  double margin = std::numeric_limits<double>::infinity();  ///< d − k·σ − buffer [m]
  std::string reason;  ///< why, when Blocked
};

/// The guard of one vehicle (GuardSettings).  It keeps the state of its looks
/// and a cached clearance between requests; not thread-safe.  The objects it
/// is built from must outlive it.
class Guard {
 public:
  /// `obstacles`: the true obstacles and forbidden hazards, no clearance;
  /// `landmarks`: the map (K×2); `corridor_limit`: the largest deviation
  /// from the path allowed (half-width + corridor margin) [m].  Throws
  /// std::invalid_argument when settings.k is not > 0 (0 is resolved by
  /// Guidance: guard_k_for_risk).
  Guard(const GuardSettings& settings, const Bmm& bmm, const ObstacleChecker& obstacles, const Points2& landmarks,
        double corridor_limit);

  /// The guard's decision about `proposed`, the method's control for a
  /// vehicle estimated at `x` with position σ `position_std` at time `t` [s],
  /// following `path`.
  GuardDecision decide(double t, const State& x, double position_std, const Control& proposed, const Corridor& path);

 private:
  /// The way ahead of a control u: held for horizon seconds, then braking.
  struct WayAhead {
    double clearance = std::numeric_limits<double>::infinity();      ///< least, along the arc [m]
    double end_clearance = std::numeric_limits<double>::infinity();  ///< at the stop point [m]
    double deviation = 0.0;  ///< largest distance of the arc from the path followed [m]
  };
  double clearance(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double keep);
  WayAhead way_ahead(const State& x, const Control& u, double keep, const Corridor* path = nullptr);
  std::vector<double> bearings_in_range(const Eigen::Vector2d& p) const;
  int landmarks_seen(const std::vector<double>& bearings, double heading) const;
  double look_turn(const State& x, const std::vector<double>& bearings, int* seen) const;
  bool steer(const State& x, const Control& u0, double rho, double keep, const Corridor& path, GuardDecision& out);
  bool slow_to_clear(const State& x, const Control& u0, double keep, GuardDecision& out);
  void track(const State& x, double position_std);
  GuardDecision hold(double t, const State& x, double position_std, double keep, double look, int could_see);
  bool recover(double t, const State& x, double position_std, double keep, GuardDecision& out);

  const GuardSettings& settings_;
  const Bmm& bmm_;
  const ObstacleChecker& obstacles_;
  const Points2& landmarks_;
  double corridor_limit_;
  // The cached clearance: keep-out distance cache_d_ from cache_p_ (−inf: none
  // yet).  A segment within r of cache_p_ is at least cache_d_ − r away, so the
  // exact query runs only near obstacles.
  Eigen::Vector2d cache_p_ = Eigen::Vector2d::Zero();
  double cache_d_ = -std::numeric_limits<double>::infinity();
  // Look first: 0 idle, > 0 the steps spent looking, −1 looked (until the margin is met).
  int looking_ = 0;
  double look_sigma_ = 0.0;  // σ when the look began
  double look_start_ = 0.0;  // and its time [s]
  double look_prev_ = 0.0;   // σ at the previous step of the look
  // The run's history (the vehicle's own estimate only): the least σ seen,
  // σ at the previous request, and the track driven since σ was last of
  // fix quality (≤ 2 × the least), one point per metre, oldest first.
  double sigma_min_ = std::numeric_limits<double>::infinity();
  double sigma_prev_ = std::numeric_limits<double>::infinity();
  bool fixing_ = false;  // σ did not grow since the previous request: fixes arrive
  static constexpr std::size_t kTrackPoints = 512;  // a recovery backs up at most this many metres
  std::vector<Eigen::Vector2d> track_;
  // The hold in progress: its start time (−inf: none) and σ then.
  double hold_start_ = -std::numeric_limits<double>::infinity();
  double hold_sigma_ = 0.0;
  // The recovery in progress: 0 none, 1 backing up, 2 spinning; its start
  // time and σ; and the recoveries so far.
  int recovering_ = 0;
  double recover_start_ = 0.0;
  double recover_sigma_ = 0.0;
  int recoveries_ = 0;
};

}  // namespace safenav
