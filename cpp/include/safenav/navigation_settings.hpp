// safenav/navigation_settings.hpp — what SafeNav navigates (NavigationProblem:
// the safe path and its world) and how (NavigationSettings: the method
// [SafeNav Alg. 1] or [SafeNav Alg. 2], segments, detours of [SafeNav-ext
// Alg. 4], failure thresholds, the filter's gate and the guard).  The online
// object that uses them is Guidance (safenav/guidance.hpp, which includes
// this header); the simulator's Navigator (safenav/navigation.hpp) runs it.
//
// Only Eigen and std types appear here.
#pragma once

#include <string>

#include "safenav/corridor.hpp"
#include "safenav/filters.hpp"
#include "safenav/guard.hpp"
#include "safenav/motion.hpp"
#include "safenav/planning.hpp"
#include "safenav/world.hpp"

namespace safenav {

enum class NavigationMethod {
  CHull,     ///< SafeNav-CHull, Algorithm 1
  Centroid,  ///< SafeNav-Centroid, Algorithm 2
};
std::string to_string(NavigationMethod method);

/// The navigation problem: the safe path to follow and the world it runs in
/// (the vehicle's map: obstacles for the detours; the simulator's truth).
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
  /// ε, the acceptable probability of a collision over the whole mission
  /// (ours).  The guard's k follows from it and the path when guard.k = 0
  /// (guard_k_for_risk, guard.hpp; docs/safety.md).  In (0, 0.1].
  double collision_probability = 1e-4;
  /// The stale-input watchdog (ours; as Nav2's collision monitor's
  /// source_timeout): a command at t stops the vehicle (control 0, the BMM
  /// brakes) when the latest motion input or the latest measurement is older
  /// than this [s].  0: off (scenario files refuse inf in every field).
  double input_timeout = 1.0;
  /// EKF or PF (seed ignored: derived from the trial seed).  The χ² gate is
  /// on (0.99): the papers' loop has none (gate_probability = 0).
  FilterOptions filter = [] {
    FilterOptions f;
    f.gate_probability = 0.99;
    return f;
  }();
  /// The uncertainty-aware guard (guard.hpp; on; enabled = false: the papers'
  /// loop).  Its k = 0 (default): from collision_probability and the path.
  GuardSettings guard;
  bool record = true;              ///< keep the trajectories in the result
  void validate() const;
};

}  // namespace safenav
