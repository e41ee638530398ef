// safenav/navigation.hpp — SafeNav safe-path navigation: SafeNav-CHull
// [SafeNav Alg. 1], SafeNav-Centroid [SafeNav Alg. 2] and the safe path
// navigation loop with RAw-RRT* replanning [SafeNav-ext Alg. 4] (= [SafeNav-conf
// Alg. 3]), with LanBLoc-BMM (EKF or PF) in the loop.  Citations follow
// docs/paper_map.md: algorithm line numbers differ between the versions.
//
// One trial: a true vehicle (the BMM with process noise and terrain) follows a
// safe path from its first to its last vertex.  Each step the navigator
//   1. chooses a control from the filter's estimate with the selected method;
//   2. checks the path ahead for obstacles and replans with RAw-RRT* when it
//      is blocked (the detour is spliced into the path it follows);
//   3. moves the true vehicle;
//   4. measures — a LanBLoc position fix when enough landmarks are in the
//      camera's view (measurement-level noise profile, or a user callback
//      such as the camera-in-the-loop pipeline), plus IMU speed and heading —
//      and updates the filter;
//   5. records the true, predicted, measured and estimated trajectories.
// It ends at the destination or with an explicit failure (TrialOutcome).
//
// Only Eigen and std types appear here.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "safenav/corridor.hpp"
#include "safenav/filters.hpp"
#include "safenav/measurement.hpp"
#include "safenav/metrics.hpp"
#include "safenav/motion.hpp"
#include "safenav/params.hpp"
#include "safenav/planning.hpp"
#include "safenav/world.hpp"

namespace safenav {

enum class NavigationMethod {
  CHull,     ///< SafeNav-CHull, Algorithm 1
  Centroid,  ///< SafeNav-Centroid, Algorithm 2
};
std::string to_string(NavigationMethod method);

/// How a trial ended.
enum class TrialOutcome {
  Arrived,           ///< the estimate reached the destination (within arrival_radius)
  Collision,         ///< the true vehicle's step crossed an obstacle
  LeftCorridor,      ///< the true vehicle left the safe buffer of the path it follows
  StepLimit,         ///< max_steps ran out
  LostLocalization,  ///< the position standard deviation exceeded lost_position_std
  NoPath,            ///< the path ahead was blocked and RAw-RRT* found no way round
};
std::string to_string(TrialOutcome outcome);

/// A position fix from a user callback (e.g. the camera-in-the-loop LanBLoc
/// pipeline): given the true state and the step, fill z and its covariance R
/// and return true, or return false when localization failed (a dropout).
using PositionCallback = std::function<bool(const State& truth, int step, Eigen::Vector2d& z, Eigen::Matrix2d& R)>;

/// What the vehicle senses.
struct SensorSettings {
  PositionNoise position;              ///< the measurement-level source (LanBLoc by default)
  Landmarks landmarks;                 ///< K×2 landmark positions (map)
  double max_range = 30.0;             ///< landmark detection range [m]
  double field_of_view = 85.0 * kPi / 180.0;  ///< full horizontal FOV [rad], centred on the heading; ≥ 2π = all round
  int min_landmarks = 3;               ///< trilateration needs ≥ 3 ([SafeNav-ext §V-A3(ii)]: clusters of ≥ 3)
  int position_every = 1;              ///< a fix every n steps
  bool imu = true;                     ///< IMU speed and heading every step
  double imu_speed_std = 0.05;         ///< [m/s]
  double imu_heading_std = 0.02;       ///< [rad]
  void validate() const;
  /// Landmarks within range and inside the field of view of a vehicle at (x, y, θ).
  int landmarks_in_view(const State& x) const;
};

/// The navigation problem: the safe path to follow and the true world.
struct NavigationProblem {
  Points2 path;           ///< the safe path, start first, ≥ 2 distinct vertices
  RiskZones zones;        ///< the safe buffer (half-width and zone weights, eq. 18)
  PlanningMap map;        ///< the true field and obstacles (collision checks, detection, replanning)
  BmmParams bmm;          ///< true vehicle and filter model
  void validate() const;
};

struct NavigationSettings {
  NavigationMethod method = NavigationMethod::Centroid;
  double cruise_speed = 2.0;       ///< desired speed [m/s]
  double arrival_radius = 1.0;     ///< arrived when the estimate is this close to the destination [m]
  int max_steps = 0;               ///< 0 = 3·L/(cruise_speed·Δt) + 200; at most kMaxSteps either way
  /// The largest step budget, given or derived: 1e7 steps at Δt = 0.05 s is 139 h.
  static constexpr int kMaxSteps = 10'000'000;
  SegmentOptions segments;         ///< segments, hulls and sub-segment centroids (Algorithms 1–2)
  double lookahead = 5.0;          ///< Algorithm 1's corrective control aims this far ahead on the path [m]
  double step_back_speed = 0.5;    ///< Algorithm 1's step back: speed toward the path [m/s]
  // Obstacles ahead [SafeNav-ext Alg. 4 ll. 7–9] (= [SafeNav-conf Alg. 3 ll. 5–7]).
  bool replan = true;
  double sensing_range = 10.0;     ///< obstacles within this arc length ahead on the path are detected [m]
  int obstacle_check_every = 5;    ///< steps between obstacle checks
  double replan_lookahead = 20.0;  ///< the detour rejoins the path this far ahead (slid past the obstacle) [m]
  int max_replans = 10;
  /// RAw-RRT* settings for detours (seed derived per trial and replan):
  /// 3000 iterations, half the samples inside the corridor, smoothed.
  PlannerSettings planner = [] {
    PlannerSettings p;
    p.max_iterations = 3000;
    p.corridor_bias = 0.5;
    p.smooth = true;
    return p;
  }();
  // Failure thresholds.
  double corridor_margin = 0.0;    ///< left the corridor: deviation > half_width + margin
  double lost_position_std = 10.0; ///< lost localization: √λ_max(P_xy) above this [m]
  FilterOptions filter;            ///< EKF or PF (seed ignored: derived from the trial seed)
  bool record = true;              ///< keep the trajectories in the result
  void validate() const;
};

/// Per-trial metrics [SafeNav-ext eqs. 20–23], each named by what it compares
/// against (as evo's results name their reference): `path_*` and `goal_*` take
/// the safe path as ground truth (see Navigator::run), `truth_*` the true
/// vehicle.
struct TrialMetrics {
  double path_ade = 0.0;        ///< ext eq. 21: mean distance of the estimate to the safe path (our reading)
  double goal_fde = 0.0;        ///< ext eq. 22: final estimate vs the destination
  double path_error_percent = 0.0;  ///< ext eq. 23: |L_est − L_path| / L_path · 100
  double awrs = 0.0;            ///< ext eq. 20: mean WRS of the estimated trajectory (eq. 18, about the safe path)
  double awrs_true = 0.0;       ///< mean WRS of the true trajectory
  double truth_ade = 0.0;       ///< mean ‖estimate − truth‖
  double truth_fde = 0.0;       ///< final ‖estimate − truth‖
  double max_deviation = 0.0;   ///< largest deviation of the true vehicle from the safe path [m]
};

struct TrialResult {
  TrialOutcome outcome = TrialOutcome::StepLimit;
  bool success = false;          ///< outcome == Arrived
  std::string reason;            ///< human-readable detail of the outcome
  int steps = 0;
  int replans = 0;
  int position_fixes = 0;        ///< accepted position updates
  int dropouts = 0;              ///< fix steps without a fix (no landmarks in view, failed callback, random loss)
  int rejected = 0;              ///< updates rejected by the NIS gate
  int chull_default = 0;         ///< Algorithm 1: steps that kept the default command
  int chull_corrective = 0;      ///< Algorithm 1: corrective controls
  int chull_step_back = 0;       ///< Algorithm 1: step-back controls
  double wall_time = 0.0;        ///< [s]
  TrialMetrics metrics;
  // Trajectories (rows 0 … steps), when NavigationSettings::record.
  RowMatrixX4 truth;             ///< true states
  RowMatrixX4 estimate;          ///< filter estimates
  RowMatrixX2 predicted;         ///< BMM prediction from the previous estimate with the chosen control (row 0 = start)
  RowMatrixX2 measured;          ///< position fixes (NaN when none)
  RowMatrixX2 controls;          ///< steps×2 (v_desired, Δθ)
  Eigen::VectorXd position_std;  ///< √λ_max(P_xy) per row
  Points2 followed_path;         ///< the path finally followed (with detours)
};

/// Runs trials of one navigation problem.  Construction builds the corridor,
/// segment hulls and centroids once; run() is const and thread-safe.
class Navigator {
 public:
  Navigator(NavigationProblem problem, NavigationSettings settings, SensorSettings sensors);
  ~Navigator();
  Navigator(Navigator&&) noexcept;
  Navigator& operator=(Navigator&&) noexcept;

  const NavigationProblem& problem() const;
  const NavigationSettings& settings() const;
  const SensorSettings& sensors() const;
  const PathSegments& segments() const;
  int max_steps() const;

  /// One trial with its own seed (process noise, measurement noise, PF,
  /// planner).  A position callback, when given, replaces the
  /// measurement-level position source.
  TrialResult run(std::uint64_t seed, const PositionCallback& position = nullptr) const;

  /// Trials for each seed with the measurement-level source, metrics only
  /// (no trajectories), in order.  Results equal run(seed) one by one.
  std::vector<TrialResult> run_many(const std::vector<std::uint64_t>& seeds) const;

 private:
  TrialResult run_trial(std::uint64_t seed, const PositionCallback& position, bool record) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

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

}  // namespace safenav
