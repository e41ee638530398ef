// safenav/planning.hpp — RAw-RRT* [SafeNav eqs. 15–19, SafeNav-ext Alg. 3]
// (SafeNav-conf has no RAw-RRT* algorithm; [SafeNav-conf Alg. 3] is the navigation loop).
// Citations follow docs/paper_map.md; a bare "eq. 18" means [SafeNav eq. 18].
//
// Cost of a path p (eqs. 16 and 19, integrated along the motion):
//   C_total = α·C_length + β·C_risk,
//   C_length = Σ ‖p_{i+1} − p_i‖                        (eq. 15)
//   C_risk   = ∫ WRS(d(s)) ds  along the path, with d the deviation from the
//              central path (eq. 17) and WRS of eq. 18 (safenav::wrs).
// The integral is the trapezoid rule on sub-steps of at most `resolution`
// metres on every edge: it is how OMPL's StateCostIntegralObjective with
// motion-cost interpolation integrates a state cost, and path_cost()
// reports exactly that number.  β = 0 is plain RRT* (the baseline).
//
// Hazard term (ours): with hazard_weight β_h > 0 the cost gains
//   β_h·C_hazard,  C_hazard = ∫ risk(p) ds = Σ_k risk_k · (length inside hazard k),
// exact per motion (ObstacleChecker::hazard_integral: boundary crossings in
// closed form, no sampling).  Overlapping hazards add (see world.hpp), so
// C_hazard equals PathSafety::exposure.  β_h = 0 (the default) is the paper's
// cost, and the planner then builds exactly the paper's objective.
//
// The map and its collision checker are world.hpp's.  Built on OMPL's
// RRTstar; OMPL stays inside cpp/src/planning*.cpp: this header exposes only
// Eigen and std types.  docs/planning.md: the speed-ups (same plans bit for
// bit) and informed sampling.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "safenav/corridor.hpp"
#include "safenav/world.hpp"

namespace safenav {

/// What to plan: map, start, goal and the central (safe) path of the risk term.
struct PlanningProblem {
  PlanningMap map;
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d goal = Eigen::Vector2d::Zero();
  Points2 central_path;  ///< optional polyline (0 rows = no risk term)
  RiskZones zones;       ///< safe buffer of eq. 18 (half-width, weights 2/4/6/8)
  void validate() const;
};

/// Planner settings.  Defaults: α = β = 1 (eq. 16 leaves them free).
struct PlannerSettings {
  double alpha = 1.0;              ///< α, weight of the length term (eq. 16), ≥ 0
  double beta = 1.0;               ///< β, weight of the risk term (eq. 16), ≥ 0; 0 = plain RRT*
  double range = 0.0;              ///< longest tree edge [m]; 0 = OMPL's default (20 % of the field's diagonal)
  double goal_bias = 0.05;         ///< probability of sampling the goal, in [0, 1]
  std::int64_t max_iterations = 5000;  ///< RRT* iterations (the deterministic budget), > 0
  /// The most iterations of one plan (the declared range of max_iterations).
  static constexpr std::int64_t kMaxIterations = 1'000'000;
  double max_time = 0.0;           ///< wall-clock budget [s]; 0 = none (then only iterations bound the run)
  std::uint64_t seed = 0;          ///< same seed + same iteration budget → identical path
  double resolution = 0.1;         ///< cost-integration (and corridor-check) step along a motion [m], > 0
  double goal_tolerance = 1e-6;    ///< a tree node this close to the goal reaches it [m]
  bool smooth = false;             ///< shortcut the path with OMPL's PathSimplifier (collision-checked)
  bool stay_in_corridor = false;   ///< states must also lie within zones.half_width of the central path
  bool allow_approximate = false;  ///< return OMPL's approximate path (closest approach) instead of NoPath
  /// Probability of drawing a sample inside the safe corridor (uniform in arc
  /// length and in offset within ±half_width) instead of uniformly over the
  /// field; needs a central path.  0 = plain uniform sampling, as in the paper.
  /// With β > 0 the optimum hugs the central path, and biased samples find it
  /// far sooner (an extension of ours).
  double corridor_bias = 0.0;
  /// β_h, weight of the hazard term β_h·∫ risk ds [1/m · cost], ≥ 0; 0 = the paper's cost.
  double hazard_weight = 0.0;
  /// Informed sampling (ours, after Gammell et al. 2014; OMPL's RRTstar
  /// setInformedSampling): once a path of cost c exists, samples are drawn
  /// only where a path could be cheaper, the ellipse ‖x − start‖ + ‖x − goal‖
  /// ≤ c/α + goal_tolerance (α·length is an admissible bound on the cost:
  /// WRS and hazard risk are ≥ 0), mixed with the corridor samples as above.
  /// Needs α > 0.  false = the paper's sampling (every plan bit for bit).
  bool informed_sampling = false;
  void validate() const;
};

enum class PlanStatus {
  Exact,        ///< a path that reaches the goal
  Approximate,  ///< no path reached the goal; the path gets as close as the tree did (allow_approximate)
  NoPath,       ///< no path within the budget
};
std::string to_string(PlanStatus status);

/// Length, risk and total of a path under eq. 19 (see the header comment).
struct PathCost {
  double length = 0.0;  ///< C_length [m]
  double risk = 0.0;    ///< C_risk = ∫ WRS ds
  double hazard = 0.0;  ///< C_hazard = ∫ risk(p) ds over the hazards [m] (= PathSafety::exposure)
  double total = 0.0;   ///< α·length + β·risk (+ β_h·hazard when β_h > 0)
};

struct PlanResult {
  PlanStatus status = PlanStatus::NoPath;
  bool success = false;  ///< status == Exact
  Points2 path;          ///< N×2 waypoints, start first (0 rows when NoPath)
  PathCost cost;         ///< of `path` (after smoothing, if any)
  PathSafety safety;     ///< clearance and hazard exposure of `path` (world.hpp's path_safety)
  std::int64_t iterations = 0;            ///< RRT* iterations run
  double planning_time = 0.0;             ///< wall-clock time in OMPL's solve [s]
  std::int64_t first_solution_iteration = -1;  ///< iteration of the first exact solution (−1: none)
  double first_solution_time = -1.0;      ///< [s] since the start of solve (−1: none)
  /// Each improvement of the best solution: rows (iteration, time [s], cost).
  /// The cost is OMPL's objective value, which equals path_cost().total of
  /// that (unsmoothed) solution.
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> cost_history;
};

/// RAw-RRT* from problem.start to problem.goal [SafeNav-ext Alg. 3].
PlanResult plan(const PlanningProblem& problem, const PlannerSettings& settings = {});

/// Replanning for [SafeNav-ext Alg. 4 l. 9] (= [SafeNav-conf Alg. 3 l. 7]):
/// plan from `position` to the point `lookahead` metres (arc length) ahead of
/// position's projection on the central path; if that point is blocked, the
/// goal slides further along the path to the first free point (the path's end
/// at most).
PlanResult replan(const PlanningProblem& problem, const Eigen::Vector2d& position, double lookahead,
                  const PlannerSettings& settings = {});
/// Replanning to an explicit goal.
PlanResult replan_to(const PlanningProblem& problem, const Eigen::Vector2d& position, const Eigen::Vector2d& goal,
                     const PlannerSettings& settings = {});

/// The point `distance` metres of arc length ahead of the projection of
/// `position` on `path` (clamped to the path's end).
Eigen::Vector2d point_ahead(const Eigen::Ref<const Points2>& path, const Eigen::Vector2d& position, double distance);

/// Cost of a path under eq. 19 with the settings' α, β, β_h and resolution.
PathCost path_cost(const Eigen::Ref<const Points2>& path, const PlanningProblem& problem,
                   const PlannerSettings& settings = {});

/// The admissible lower bound that informed sampling uses (see
/// PlannerSettings::informed_sampling), at each point x: no path from
/// problem.start through x to the goal costs less than
///   α(‖x − start‖ + ‖x − goal‖ − goal_tolerance) + β(|W(d_x) − W(d_start)| + |W(d_x) − W(d_goal)|),
/// with d the deviation from the central path (eq. 17) and W(d) a lower bound
/// on ∫₀^d WRS(u) du (eq. 18; the deviation changes by at most 1 m per metre).
Eigen::VectorXd cost_lower_bound(const Eigen::Ref<const Points2>& points, const PlanningProblem& problem,
                                 const PlannerSettings& settings = {});

}  // namespace safenav
