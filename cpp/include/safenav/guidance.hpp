// safenav/guidance.hpp — SafeNav as an online object that a vehicle's own
// loop ticks: SafeNav-CHull [SafeNav Alg. 1] or SafeNav-Centroid [SafeNav
// Alg. 2] along a safe path, with the obstacle check and RAw-RRT* detours of
// the safe path navigation loop [SafeNav-ext Alg. 4] (= [SafeNav-conf Alg. 3]),
// on the estimate of an online Localizer (LanBLoc-BMM, safenav/localizer.hpp).
//
// The vehicle feeds the localizer its timestamped inputs (motion input,
// landmark observations, position fixes, IMU) through localizer() or the
// forwarding calls here, and asks command(t) for the control of its next
// step.  The answer carries the control (desired speed, heading change), the
// status and what happened: a detour planned and spliced into the path, no
// path, lost localization, arrival.  The simulator (Navigator, navigation.hpp)
// drives this same object with a simulated vehicle and sensors: there is one
// navigation loop.
//
// Built once: the path's corridor, segment hulls and centroids, the obstacle
// checker and the localizer.  A command allocates nothing unless it plans a
// detour, or predicts past the localizer's time for the first time
// (Localizer::predict_to makes its copy of the filter once).  Only Eigen and std types appear here.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "safenav/corridor.hpp"
#include "safenav/filters.hpp"
#include "safenav/guard.hpp"
#include "safenav/localizer.hpp"
#include "safenav/motion.hpp"
#include "safenav/navigation_settings.hpp"
#include "safenav/planning.hpp"
#include "safenav/world.hpp"

namespace safenav {

/// [SafeNav Alg. 2]'s control: steer toward the nearest sub-segment centroid ahead
/// of the estimate (the destination when none is ahead) at cruise speed.
/// Δθ = atan2(Δy, Δx) − θ̂, wrapped (DESIGN.md: the paper's arctan(Δx/Δy)).
Control centroid_control(const PathSegments& segments, const State& estimate, double cruise_speed);

/// What [SafeNav Alg. 1] did with the default command.
enum class ChullAction {
  /// the default command's prediction lies in hull k or k+1: kept ([SafeNav-ext Alg. 1 l. 13], conf l. 10)
  Keep,
  Corrective,  ///< a corrective control back to the path ([SafeNav-ext Alg. 1 l. 17], conf l. 13)
  StepBack,    ///< the estimate is outside hulls k−1, k and k+1: step back
};

/// [SafeNav Alg. 1]'s decision.
struct ChullDecision {
  Control control{0, 0};
  int segment = 0;     ///< current segment k
  ChullAction action = ChullAction::Keep;
  Eigen::Vector2d predicted{0, 0};  ///< BMM prediction with the chosen control
};
/// [SafeNav Alg. 1] (SafeNav-CHull), our reading of it (DESIGN.md, decision 4):
///  * the estimate is outside hulls k−1, k and k+1 → step back: head for the
///    nearest path point at step_back_speed;
///  * otherwise the default command heads for the look-ahead point
///    `lookahead` metres ahead on the path (shortened, by halving, while the
///    chord to it crosses an obstacle of `obstacles`, when given); it is kept
///    if the BMM-predicted position lies in hull k or hull k+1
///    ([SafeNav-ext Alg. 1 l. 13] = [SafeNav-conf Alg. 1 l. 10]);
///  * else a corrective control heads back to the path, 1 m ahead of the
///    nearest path point ([SafeNav-ext Alg. 1 l. 17] = [SafeNav-conf Alg. 1 l. 13]).
ChullDecision chull_control(const PathSegments& segments, const Bmm& bmm, const State& estimate,
                            double cruise_speed, double lookahead, double step_back_speed,
                            const ObstacleChecker* obstacles = nullptr);

/// What guidance is doing.
enum class GuidanceStatus {
  Initializing,      ///< the localizer has no estimate yet (control = 0)
  Guiding,           ///< following the path
  Arrived,           ///< the estimate is within arrival_radius of the destination (control = 0)
  NoPath,            ///< the way ahead is blocked and no detour was found (control = 0)
  LostLocalization,  ///< the position σ exceeds lost_position_std (control = 0)
  /// The latest motion input or measurement is older than input_timeout
  /// (control 0: the BMM brakes).  Only a command reports it: status() has no time.
  StaleInput,
  /// The guard gave up: a hold it could not end, after its recoveries
  /// (GuardAction::Blocked; detail() says why).  Control 0 from then on.
  Blocked,
};
std::string to_string(GuidanceStatus status);

/// Events of one command request (bit flags).
enum GuidanceEvent : unsigned {
  kDetourPlanned = 1u << 0,     ///< RAw-RRT* planned a detour round an obstacle ahead
  kPathSpliced = 1u << 1,       ///< the detour was spliced into the path being followed
  kNoPath = 1u << 2,            ///< the way ahead is blocked and no detour was found
  kLostLocalization = 1u << 3,  ///< the position σ exceeds lost_position_std
  kArrived = 1u << 4,           ///< at the destination
  kGuardSlow = 1u << 5,         ///< the guard slowed down: the k-σ radius nears the clearance ahead
  kGuardSteer = 1u << 6,        ///< the guard steered away from the method's heading to keep clearance
  kGuardHold = 1u << 7,         ///< the guard stopped to hold for a fix, turning toward landmarks
  kStaleInput = 1u << 8,        ///< an input is older than input_timeout: stopped (the watchdog)
  kGuardRecover = 1u << 9,      ///< the guard recovers from a stuck hold: backs up along its track or spins
  kBlocked = 1u << 10,          ///< the guard gave up after its recoveries (GuidanceStatus::Blocked)
};

/// The answer to a command request.
struct Command {
  Control control{0.0, 0.0};  ///< (desired speed [m/s], heading change [rad]) for the next step
  GuidanceStatus status = GuidanceStatus::Initializing;
  unsigned events = 0;        ///< GuidanceEvent flags of this request
  int segment = 0;            ///< segment k of the path followed: CHull's current one, Centroid's target's
  /// √λ_max(P_xy) [m] of the estimate predicted to the command's time t
  /// (the localizer's own when t is not past its time).
  double position_std = std::numeric_limits<double>::quiet_NaN();
  /// t minus the older of the latest motion input's and the latest
  /// measurement's times [s] (what the watchdog compares with input_timeout).
  double input_age = std::numeric_limits<double>::quiet_NaN();
  ChullAction action = ChullAction::Keep;  ///< what SafeNav-CHull did (CHull only)
  /// The guard's clearance d of the way ahead [m]: exact where d < k·σ + buffer + slow_distance,
  /// a lower bound beyond (enough to know the control is kept); +inf when not computed.
  double clearance = std::numeric_limits<double>::infinity();
  double guard_margin = std::numeric_limits<double>::infinity();  ///< d − k·σ − buffer of the control sent [m]
  Eigen::Vector2d predicted = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());  ///< BMM prediction of the estimate under `control`
};

/// SafeNav guidance for one vehicle.  Not thread-safe.
class Guidance {
 public:
  /// `problem.path` is the safe path (its first vertex need not be the
  /// vehicle's position); `localizer` sets the filter (its bmm is replaced by
  /// problem.bmm); `landmarks`/`ids` are the landmark map for observations.
  /// `seed` fixes the particle filter (derive_seed(seed, 2)) and the detours
  /// (derive_seed(seed, 16 + n) for the n-th).
  Guidance(NavigationProblem problem, NavigationSettings settings, LocalizerSettings localizer = LocalizerSettings(),
           Landmarks landmarks = Landmarks(), std::vector<int> ids = {}, std::uint64_t seed = 0);
  /// Plans the safe path first: RAw-RRT* [SafeNav eq. 19] from planning.start
  /// to planning.goal with `planner` (throws std::runtime_error naming the
  /// planner's status when it finds none).  problem.path is ignored.
  static Guidance planned(const PlanningProblem& planning, const PlannerSettings& planner, NavigationProblem problem,
                          NavigationSettings settings, LocalizerSettings localizer = LocalizerSettings(),
                          Landmarks landmarks = Landmarks(), std::vector<int> ids = {}, std::uint64_t seed = 0);
  /// Another run on the same problem, settings and maps (sharing the path's
  /// segments and obstacle maps, which are built once): a fresh localizer
  /// (not initialized) and the safe path, with `seed`.  The simulator makes
  /// one per trial.
  Guidance fresh(std::uint64_t seed) const;
  ~Guidance();
  Guidance(Guidance&&) noexcept;
  Guidance& operator=(Guidance&&) noexcept;

  Localizer& localizer();
  const Localizer& localizer() const;
  // The localizer's inputs (see safenav/localizer.hpp).  The watchdog
  // (input_timeout) reads the localizer's own input times
  // (Localizer::last_motion_time, last_measurement_time), so inputs given to
  // localizer() directly count too; a stream never heard from counts from
  // the localizer's start.
  InputResult motion(double t, const Control& u) { return localizer().motion(t, u); }
  InputResult odometry(double t, double distance, double heading_change) {
    return localizer().odometry(t, distance, heading_change);
  }
  InputResult observe(double t, const LandmarkObservation& obs) { return localizer().observe(t, obs); }
  InputResult fix(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) { return localizer().fix(t, z, R); }
  InputResult speed_heading(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
    return localizer().speed_heading(t, z, R);
  }

  /// The control for the next step from the latest estimate.  In order:
  /// lost localization and arrival end guidance (control 0); the watchdog
  /// stops the vehicle while the latest motion input or measurement is older
  /// than input_timeout (StaleInput, control 0); past the localizer's time
  /// the estimate and its covariance are predicted to t (the EKF's eq. 11 at
  /// the last motion input's rates, on a copy: the localizer is unchanged);
  /// every obstacle_check_every-th request checks the way ahead for obstacles
  /// ([SafeNav-ext Alg. 4 ll. 7–9]) and splices a RAw-RRT* detour into the
  /// path when it is blocked; then CHull or Centroid chooses the control;
  /// then, when settings.guard.enabled, the guard may slow, steer or hold
  /// (GuardSettings; its events say which).
  /// `t` is the vehicle's time (the estimate is the localizer's latest).
  Command command(double t);
  /// The status from the latest estimate, without planning or a control.
  GuidanceStatus status() const;
  /// The nominal trajectory (ours; LQG-MP's nominal is the controlled one,
  /// van den Berg et al. 2011, §IV): the method's control [SafeNav Algs. 1–2]
  /// applied to the state itself, which moves by the BMM's noise-free
  /// transition f(x, u) [SafeNav eqs. 3–9], from the true start of a trial
  /// (the safe path's first vertex, at rest, heading along its first edge)
  /// until the state is within arrival_radius of the destination, or for
  /// `max_steps` steps.  No guard, no obstacle check, no detours: the path a
  /// vehicle that knew its state would drive.  Rows: the states at t = 0, Δt,
  /// 2Δt, …  The belief along it (propagate_belief_along, belief.hpp) sees
  /// with the heading the controller gives the vehicle after a turn.
  RowMatrixX4 nominal_trajectory(int max_steps) const;
  /// The true state a trial's vehicle starts in: the safe path's first
  /// vertex, at rest, heading along its first edge.
  State start_state() const;

  const NavigationProblem& problem() const;
  /// The settings, with guard.k resolved (k = 0 given: from collision_probability).
  const NavigationSettings& settings() const;
  /// The guard's k in use: the one given, or Φ⁻¹(1 − ε/N) for ε =
  /// collision_probability and N = guard_exposures() (guard_k_for_risk).
  double guard_k() const;
  /// N, the exposures of the safe path (path_exposures, guard.hpp): computed
  /// once, for the safe path; detours keep the k of the safe path.
  double guard_exposures() const;
  /// The safe path's segments, and those of the path now followed (detours spliced in).
  const PathSegments& safe_path() const;
  const PathSegments& path() const;
  int replans() const;
  /// Command requests that reached the control step (guiding).
  int commands() const;
  /// Why the last NoPath, LostLocalization, Blocked or Arrived happened.
  const std::string& detail() const;

 private:
  struct Impl;
  explicit Guidance(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace safenav
