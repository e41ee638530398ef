// safenav/belief.hpp — belief-aware planning: the localization covariance a
// path will have, its collision probability, and a planner that keeps the
// k·σ ellipse clear (ours; the SafeNav papers plan blind to localization).
//
// Belief along a path (LQG-MP, van den Berg, Abbeel & Goldberg 2011, §IV–V):
// the vehicle runs the path at a constant speed; the a-priori covariance is
// stepped with the filter's own models, each step
//   predict  P⁻ = F P Fᵀ + G Σ_ε Gᵀ        [SafeNav eq. 11] (Bmm::linearize, Bmm::noise_cov)
//   update   P  = (I−KH) P⁻ (I−KH)ᵀ + K R Kᵀ [SafeNav eqs. 12–14] (the filters' Joseph-form update)
// with every measurement the sensors are expected to make at the step's end
// (the maximum-likelihood observation assumption: the residual is taken as
// 0, so the covariances do not depend on the unknown measurements).  What is
// measured follows SensorSettings, as the simulator does: a LanBLoc fix
// (FixModel::Profile, H = [I₂ 0], R = PositionNoise::reported_cov()) when
// at least min_landmarks are in view, or one range per landmark in view
// (FixModel::Ranges, predict_range's Jacobian, σ = range_std) when at least
// max(3, min_landmarks) are; optionally a bearing per landmark
// (predict_bearing's Jacobian, σ = bearing_std); the IMU's speed and heading
// each step.  "In view" is SensorSettings::landmarks_in_view (range, field of
// view, occlusion by ObstacleChecker::line_of_sight), the simulator's rule.
// A belief step longer than the BMM's Δt covers n = step/Δt filter steps:
// Bmm::with_step(step) scales the process noise, and each measurement's R is
// divided by the number of times it would have been made in the step
// (n/position_every fix attempts, n IMU readings), which keeps the
// information rate.  With step = Δt and position_every = 1 the recursion is
// the EKF's, step for step.  A fix that may not arrive (dropouts, faulty
// ranges) makes two branches, with it and without it, and P is their mean
// weighted by the fix's probability (Sinopoli et al. 2004's expected
// covariance for intermittent observations; docs/belief_planning.md).
//
// Collision probability (Patil, van den Berg & Alterovitz, ICRA 2012): the
// estimation error e_k evolves as e_{k+1} = A_k e_k + w_k with
// A_k = (I − K H) F = P_{k+1} (P⁻_{k+1})⁻¹ F_k and Cov w_k = P_{k+1} − A_k P_k A_kᵀ.
// At each stage k the vehicle collides when its error toward the nearest
// keep-out area exceeds the clearance there less the vehicle's radius:
// aₖᵀ e_k > b_k, a_k the unit direction of the nearest obstacle,
// b_k = d_k − vehicle_radius.  p_k is that probability given no collision
// before (the distribution of e_k truncated at each earlier stage and
// re-approximated by a Gaussian), and P(collision) = 1 − Π (1 − p_k).  The
// union bound Σ P(aₖᵀ e_k > b_k) is reported beside it.
//
// Belief planner (RRBT, Bry & Roy 2011, on a fixed roadmap): see
// plan_belief() and docs/belief_planning.md.
//
// Only Eigen and std types appear here.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "safenav/motion.hpp"
#include "safenav/navigation.hpp"
#include "safenav/world.hpp"

namespace safenav {

/// How the belief is stepped along a path.
struct BeliefSettings {
  double speed = 2.0;        ///< speed along the path [m/s] (NavigationSettings::cruise_speed), > 0
  double step = 0.0;         ///< belief step [s]; 0 = the BMM's Δt (then exact EKF steps)
  double bearing_std = 0.0;  ///< σ of a bearing to each landmark in view [rad]; 0 = no bearings (the simulator measures none)
  /// The belief counts a landmark as seen inside the vehicle's camera less
  /// `sight_fov_margin` of field of view (at least 10° left) and within
  /// `sight_range_fraction` of its range.  The defaults, 0 and 1, are the
  /// vehicle's own camera: the expected belief, the σ profile the vehicle
  /// will get (measured within ±25 % of the Monte Carlo RMS error,
  /// docs/belief_planning.md, "Calibration").  The planner's chance constraint
  /// and the certificate see with a narrower camera, a robustness margin for
  /// heading and cross-track deviations: BeliefPlannerSettings::belief
  /// (25°, 0.9), which safenav.certify's placement_camera also places for.
  double sight_fov_margin = 0.0;     ///< [rad]
  double sight_range_fraction = 1.0;  ///< of SensorSettings::max_range, in (0, 1]
  /// The expected belief over the vehicle's deviation from the nominal path
  /// (ours): the vehicle drives its estimate along the path, so at a given
  /// arc position its true position is off the path, and its heading off the
  /// leg's, by minus its own error, and a landmark comes into view (or leaves
  /// it) a little earlier or later than from the nominal pose.  With this on,
  /// the error is stratified on its lateral and heading parts, at cells of
  /// the deviation cut where the view changes (deviation_split) or at the
  /// n×n Gauss–Hermite nodes (deviation_nodes; with 3, weights 1/36, 4/36,
  /// 16/36): each stratum sees from
  /// the nominal pose moved by minus its mean error, takes the filter's
  /// updates of what it sees, and carries its actual error's second moment,
  /// so the strata that see late keep their larger error until they see;
  /// each stage reports the mixture's second moment (docs/belief_planning.md,
  /// "The model" and "Calibration").  Off, a transition is a step at the
  /// nominal pose, and the first fix after a blind stretch lowers σ before
  /// half the vehicles get it.  On by default (the expected belief); the
  /// planner's and the certificate's robust camera turn it off: it is
  /// narrowed for the deviations already.
  bool deviation_mixture = true;
  /// Gauss–Hermite nodes per axis of the deviation mixture (3, 5 or 7: 9, 25
  /// or 49 strata, n³ with deviation_along); more nodes reach further into
  /// the deviation's tails.
  int deviation_nodes = 3;
  /// Stratify the deviation along the path too (n³ strata).  A vehicle's
  /// true progress along the path keeps to the nominal's (its speed follows
  /// the command); it is its estimate that runs ahead or behind by the
  /// error's along-track part, and the controller turns where the estimate
  /// is.  So such a stratum sees from the nominal pose that far along the
  /// path, moved by minus its whole error: at a turn it turns early or late.
  /// Where each stratum's vehicles are is reported (BeliefProfile::strata_positions
  /// and strata_position_cov), so a calibration against driven vehicles can
  /// bin them at their own arcs.
  /// Off by default: along a path's legs the turns are instant, and a
  /// stratum ahead would see round a corner that no controller drives; the
  /// expected belief along a method's nominal run turns it on
  /// (safenav.certify.NOMINAL_DEVIATION).
  bool deviation_along = false;
  /// Stratify at cells of the deviation instead of at points, and cut a
  /// cell where its vehicles would see otherwise than its mean (ours, on by
  /// default; off, the Gauss–Hermite nodes;
  /// docs/belief_planning.md, "Strata cut where the view changes").  The
  /// n nodes' weights become the masses of n intervals per axis (for 3:
  /// z < −0.967, |z| ≤ 0.967, z > 0.967), each stratum at its cell's mean
  /// and with its variance.  Each step, a cell whose ends (an unbounded end
  /// at z = ±4.26) see other landmarks than its mean is cut where the view
  /// changes, and the part beyond takes its exact share of the deviation:
  /// a vehicle 2.6 σ beside the path that misses a short window of
  /// landmarks then keeps its error in the belief, as it does in the
  /// Monte Carlo.  A stratum that sees no fix and whose cell no cut divides
  /// is cut along its viewed heading (its error's heading and the step's
  /// heading noise, which each step draws anew) where that shows it a fix
  /// (docs/belief_planning.md, "A fresh heading at each step").  A second
  /// pass in the same step cuts the parts again where a fix still comes or
  /// goes within a cell ("Two cuts at a first fix").  At most the
  /// rule's strata and deviation_free_strata more (twice the rule's where
  /// that is more); no part under 10⁻⁴ of the vehicles, or 10⁻⁶ where the
  /// part takes a fix and the rest of its stratum does not, or the reverse.
  bool deviation_split = true;
  /// With deviation_split: the strata the mixture may hold beyond its rule's
  /// (it holds at least twice the rule's).  1 000 is room for every stratum
  /// on the missions measured (3 000 moves their σ profiles by at most 5 %);
  /// the profile costs 2–4 times what it did with 55 (docs/belief_planning.md,
  /// "Room for every stratum").  Where it is full, it joins the
  /// closest adjacent pair that sees alike, moment for moment, to make room
  /// for the step's cuts and the gate's branches, but never two whose filter
  /// covariances differ by more than half (docs/belief_planning.md, "Room
  /// made only among alike strata").
  int deviation_free_strata = 1000;
  /// The filter's χ² gate on position fixes (NavigationSettings::filter's
  /// gate_probability; 0 = none, the papers' loop).  With the deviation
  /// mixture, a stratum whose filter trusts its prediction far less than
  /// the fix (tr P⁻_xy above 10 tr R) splits where a fix may arrive: the
  /// vehicles still waiting for one, those whose fix passes, and those whose
  /// innovation fails the gate (by quarter of directions) go on as strata of
  /// their own, each with its own filter covariance; the turned-away ones
  /// keep their error, and have their later fixes turned away too, until
  /// the localizer resets the position from the third (LocalizerSettings'
  /// defaults, as the loop's).  A vehicle that starts 3σ off gets its first
  /// fix turned away and stays off, as in the Monte Carlo
  /// (docs/belief_planning.md, "A fix the gate turns away").  Off by
  /// default; safenav.certify.mission_inputs passes the scenario's.
  double gate_probability = 0.0;
  Inflation inflation;       ///< vehicle radius (collision) and margin (kept beyond it by the planner)
  void validate() const;     ///< throws std::invalid_argument naming the bad value
};

/// The belief along a path: one row per stage, row 0 the start.
struct BeliefProfile {
  Points2 positions;              ///< nominal positions [m]
  Eigen::VectorXd headings;       ///< heading of the leg each stage lies on [rad]
  Eigen::VectorXd time;           ///< [s] since the start
  RowMatrixX16 covariance;        ///< the a-posteriori P (4×4, row-major) at each stage
  RowMatrixX4 cov_xy;             ///< its position block (P_xx, P_xy, P_yx, P_yy) [m²]
  Eigen::VectorXd sigma;          ///< √λ_max of the position block [m]
  Eigen::VectorXi landmarks;      ///< landmarks in view at each stage
  RowMatrixX16 transition;        ///< A_k: e_{k+1} = A_k e_k + w_k (row k; the last row is 0)
  Eigen::VectorXd clearance;      ///< distance to the nearest keep-out area (obstacle, forbidden hazard) [m]; +inf with none
  Points2 direction;              ///< unit vector toward it (the σ-largest axis where the direction is undefined)
  Eigen::VectorXd sigma_toward;   ///< √(aᵀ P_xy a) in that direction [m]
  Eigen::VectorXd stage_probability;  ///< p_k: collision at stage k given none before
  Eigen::VectorXd marginal_probability;  ///< P(aₖᵀ e_k > b_k), unconditioned
  double collision_probability = 0.0;  ///< 1 − Π (1 − p_k)
  double union_bound = 0.0;            ///< min(1, Σ marginal_probability)
  double length = 0.0;                 ///< path length [m]
  double vehicle_radius = 0.0;         ///< the radius the probabilities were computed for [m]
  /// The deviation mixture's strata (BeliefSettings::deviation_mixture; empty
  /// without it), per stage (row): each stratum's weight (N×S; the rows sum
  /// to 1, a slot no stratum holds at that stage weighs 0: with
  /// deviation_split the strata come and go), where its vehicles are (they
  /// see from the nominal position moved by minus their error, with
  /// deviation_along the nominal's where their estimate is): the mean
  /// (N×2S: x₀, y₀, x₁, y₁, …) and covariance (N×3S: xx₀, xy₀, yy₀, …) of
  /// that position over the stratum's error, by the unscented transform of
  /// the error's position part (centre 1/3, ±√3 along each axis 1/6 each),
  /// and the trace of its error's second moment in position, P_i + N_i
  /// (N×S) [m²].  Stage 0 puts every stratum at the start with P0.
  Eigen::MatrixXd strata_weight;
  Eigen::MatrixXd strata_positions;
  Eigen::MatrixXd strata_position_cov;
  Eigen::MatrixXd strata_msq;
};

/// The prior the navigation loop starts from (its Trial::initialize, in
/// navigation.cpp) for a vehicle at `start` heading `heading` [rad], in
/// expectation over its first fix: with the fix (at least min_landmarks in
/// view, or a source that needs none; for FixModel::Ranges at least
/// max(3, min_landmarks) ranges that survive the dropout fault and are
/// sound), the fix's covariance (the source's reported one, or the
/// trilateration's from the ranges in view); without it, a start known to
/// σ = max(1 m, the source's largest σ) in x and y; their mean weighted by
/// the fix's probability (1 without dropouts and faults).  With the loop's
/// gate (`gate_probability` > 0, ours) the fix's part holds the starts whose
/// fix the loop disputes against the rough start (1 − gate_probability of
/// the right fixes: navigation.cpp, Trial::dispute_start_fix).  The IMU's
/// speed and heading variances.
StateCov start_covariance(const SensorSettings& sensors, const PlanningMap& map, const Eigen::Vector2d& start,
                          double heading, double gate_probability = 0.0);

/// The belief and collision probability along `path` (N×2, N ≥ 2, start
/// first) from the start covariance P0, in `map` (obstacles, forbidden
/// hazards; the map's clearance plays no part here).  Throws
/// std::invalid_argument naming a bad input.
BeliefProfile propagate_belief(const Eigen::Ref<const Points2>& path, const BmmParams& bmm,
                               const SensorSettings& sensors, const PlanningMap& map, const StateCov& P0,
                               const BeliefSettings& settings = {});

/// The belief and collision probability along a trajectory of states (N×4,
/// N ≥ 2, rows x, y, v, θ at the BMM's Δt, start first), typically the
/// method's nominal trajectory (Guidance::nominal_trajectory): LQG-MP's
/// nominal is the controlled trajectory, not the geometric path.  The
/// recursion is propagate_belief's; each step is linearized at the
/// trajectory's state with the control that reaches the next one, and sees
/// from the next one's pose, so the camera turns as the controller turns the
/// vehicle (it cuts corners and settles on a new leg over a few metres)
/// instead of with each leg at once.  BeliefSettings::speed plays no part.
BeliefProfile propagate_belief_along(const Eigen::Ref<const RowMatrixX4>& states, const BmmParams& bmm,
                                     const SensorSettings& sensors, const PlanningMap& map, const StateCov& P0,
                                     const BeliefSettings& settings = {});

/// The collision probability of `profile` by Monte Carlo of the same linear
/// error model (e_0 ~ N(0, P_0), e_{k+1} = A_k e_k + w_k) and the same
/// half-planes aₖᵀe_k > clearance_k − vehicle_radius: the reference that
/// Patil et al.'s estimate approximates.  `samples` ≥ 1 trajectories from the
/// core's generator seeded with `seed`.
double collision_monte_carlo(const BeliefProfile& profile, int samples, std::uint64_t seed = 0);

// ---------------------------------------------------------------------------
// The belief planner

/// Belief-aware planner settings.
struct BeliefPlannerSettings {
  /// Belief steps of 0.25 s (coarser than the filter's; see the header
  /// comment), seen with the robust camera: the field of view less 25° and
  /// 90 % of the detection range (BeliefSettings::sight_fov_margin,
  /// sight_range_fraction).  The controllers follow the path only within the
  /// corridor and turn ahead of corners, so a path must not rely on a
  /// landmark at the edge of the view; the certificate checks paths with the
  /// same camera (safenav.certify).
  BeliefSettings belief = [] {
    BeliefSettings b;
    b.step = 0.25;
    b.sight_fov_margin = 25.0 * kPi / 180.0;
    b.sight_range_fraction = 0.9;
    b.deviation_mixture = false;
    return b;
  }();
  double k_sigma = 3.0;        ///< k: clearance ≥ k·σ + vehicle_radius + margin at every stage, ≥ 0
  double alpha = 1.0;          ///< α, weight of the length [1/m], ≥ 0 (as RAw-RRT*'s, eq. 16)
  double sigma_weight = 0.0;   ///< w_σ: cost += w_σ·∫ σ ds [1/m²], ≥ 0
  int samples = 600;           ///< roadmap vertices drawn (besides start, goal and guide points), ≥ 0
  int neighbours = 10;         ///< each vertex is joined to this many nearest ones, ≥ 1
  double max_edge = 30.0;      ///< longest roadmap edge [m], > 0
  double guide_spacing = 5.0;  ///< guide paths are cut into pieces of at most this [m], > 0
  std::uint64_t seed = 0;      ///< roadmap samples
  int max_beliefs = 24;        ///< non-dominated beliefs kept per vertex, ≥ 1
  double dominance_tolerance = 1e-3;  ///< relative ε of the partial order (Bry & Roy's ε), ≥ 0
  std::int64_t max_expansions = 200000;  ///< belief expansions before giving up, ≥ 1
  double max_time = 0.0;  ///< wall-clock budget of the roadmap and the search [s]; 0 = none (max_expansions alone)
  /// The most a path may turn [rad], in (0, π], at a vertex and in all
  /// within any stretch of turn_window metres (ours).  The belief turns the
  /// camera with each leg at once, while the controllers aim lookahead metres
  /// ahead on the path (NavigationSettings::lookahead) and cut what turns
  /// within it.  A path that doubles back (on to a vertex, then a short leg
  /// back) or glances aside (two sharp turns a few metres apart) to see
  /// landmarks behind or beside it is credited with fixes the vehicle never
  /// gets, and the corridor controllers cannot follow it.  90° keeps every turn one that the
  /// vehicle makes while still looking ahead.  π and a turn_window of 0 are
  /// the unconstrained search.
  double max_turn = kPi / 2.0;
  double turn_window = 5.0;  ///< [m], ≥ 0: the controllers' lookahead
  /// Shorten the found path greedily: from each vertex, the farthest later
  /// vertex joined by a free segment along which (and after which) the chance
  /// constraint still holds.
  bool shortcut = true;
  void validate() const;
};

/// What to plan: the map (obstacles grown by belief.inflation's clearance for
/// the roadmap's edges), start, goal, the motion model, the sensors, the
/// start covariance, and optional guide paths (their vertices join the
/// roadmap with their edges, e.g. a RAw-RRT* path).
struct BeliefProblem {
  PlanningMap map;
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d goal = Eigen::Vector2d::Zero();
  BmmParams bmm;
  SensorSettings sensors;
  StateCov start_cov = StateCov::Identity() * 1e-4;
  std::vector<Points2> guide_paths;
  void validate() const;
};

enum class BeliefPlanStatus {
  Exact,       ///< a path that meets the chance constraint
  Infeasible,  ///< the roadmap joins start and goal, but no path meets the chance constraint
  NoPath,      ///< the roadmap does not join start and goal (or one of them is not free)
  Budget,      ///< max_expansions or max_time ran out
};
std::string to_string(BeliefPlanStatus status);

struct BeliefPlanResult {
  BeliefPlanStatus status = BeliefPlanStatus::NoPath;
  bool success = false;      ///< status == Exact
  std::string detail;        ///< why, in words
  Points2 path;              ///< N×2, start first (0 rows unless Exact)
  double cost = 0.0;         ///< α·length + w_σ·∫σ ds of `path` (after shortcuts)
  BeliefProfile profile;     ///< of `path` (collision probability included)
  int vertices = 0;          ///< roadmap vertices
  int edges = 0;             ///< roadmap edges (undirected)
  std::int64_t expansions = 0;  ///< beliefs expanded
  std::int64_t beliefs = 0;     ///< beliefs created (kept at some time)
  std::int64_t capped = 0;      ///< beliefs dropped because a vertex held max_beliefs
  double planning_time = 0.0;   ///< [s]
};

/// RRBT-style search (Bry & Roy 2011) on a probabilistic roadmap: each
/// vertex keeps the beliefs (cost, covariance) that no other belief there
/// dominates (c ≤ c' and P ⪯ P'); edges propagate the covariance as
/// propagate_belief does; a belief whose stage breaks the chance constraint
/// clearance − vehicle_radius − margin ≥ k·σ (σ toward the nearest obstacle,
/// CC-RRT*'s per-constraint tightening) is dropped.  Best-first on cost +
/// α·‖v − goal‖.
BeliefPlanResult plan_belief(const BeliefProblem& problem, const BeliefPlannerSettings& settings = {});

}  // namespace safenav
