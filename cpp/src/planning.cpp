// RAw-RRT* on OMPL [SafeNav eqs. 15–19, SafeNav-ext Alg. 3].  See planning.hpp.
//
// Determinism: OMPL 1.5's global RNG::setSeed() only works before the first
// RNG of the process exists, so it cannot give every call the same stream.
// Instead every random source the planner touches gets a local seed derived
// from settings.seed: the state sampler (through the space's sampler
// allocator), RRTstar's own goal-bias RNG and the PathSimplifier's RNG.  The
// budget counts RRT* iterations, not seconds, so the same seed and budget give
// the same path on any machine.
#include "safenav/planning.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>

#include <ompl/base/MotionValidator.h>
#include <ompl/base/OptimizationObjective.h>
#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/SpaceInformation.h>
#include <ompl/base/StateValidityChecker.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/base/objectives/StateCostIntegralObjective.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/geometric/PathGeometric.h>
#include <ompl/geometric/PathSimplifier.h>
#include <ompl/geometric/planners/rrt/RRTstar.h>
#include <ompl/util/Console.h>
#include <ompl/util/RandomNumbers.h>

#include "safenav/corridor.hpp"
#include "declare.hpp"
#include "planning_internal.hpp"
#include "planning_nn.hpp"
#include "safenav/seed.hpp"
#include "errors.hpp"

namespace safenav {

template <>
const ParamSet<PlannerSettings>& param_set<PlannerSettings>();  // defined below
namespace {

namespace ob = ompl::base;
namespace og = ompl::geometric;
using Vec2 = Eigen::Vector2d;

using detail::bad;
using detail::fmt;
using planning_detail::CentralPath;
using planning_detail::cost_of;
using planning_detail::make_objective;
using planning_detail::SeededSampler;
using planning_detail::segment_count;
using planning_detail::xy;

// ---------------------------------------------------------------- OMPL glue
class Checker : public ob::StateValidityChecker {
 public:
  Checker(const ob::SpaceInformationPtr& si, const ObstacleChecker& obstacles, const CentralPath* corridor,
          double half_width)
      : ob::StateValidityChecker(si), obstacles_(obstacles), corridor_(corridor), half_width_(half_width) {}
  bool isValid(const ob::State* s) const override {
    const double* v = xy(s);
    const Vec2 p(v[0], v[1]);
    if (!obstacles_.point_free(p)) return false;
    return !corridor_ || corridor_->deviation(p) <= half_width_;
  }

 private:
  const ObstacleChecker& obstacles_;
  const CentralPath* corridor_;
  double half_width_;
};

// Exact segment/obstacle tests (no sampling gaps); the optional corridor
// constraint is checked every `step` metres.
class MotionChecker : public ob::MotionValidator {
 public:
  MotionChecker(const ob::SpaceInformationPtr& si, const ObstacleChecker& obstacles, const CentralPath* corridor,
                double half_width, double step)
      : ob::MotionValidator(si), obstacles_(obstacles), corridor_(corridor), half_width_(half_width), step_(step) {}

  bool checkMotion(const ob::State* s1, const ob::State* s2) const override {
    const double *a = xy(s1), *b = xy(s2);
    const bool ok = free(Vec2(a[0], a[1]), Vec2(b[0], b[1]));
    ok ? ++valid_ : ++invalid_;
    return ok;
  }

  bool checkMotion(const ob::State* s1, const ob::State* s2,
                   std::pair<ob::State*, double>& last_valid) const override {
    if (checkMotion(s1, s2)) return true;
    // Walk forward in `step` sub-steps to report the last valid state.
    const double *a = xy(s1), *b = xy(s2);
    const Vec2 pa(a[0], a[1]), pb(b[0], b[1]);
    const unsigned int n = std::max(1u, segment_count((pb - pa).norm(), step_));
    double t_ok = 0.0;
    for (unsigned int j = 1; j <= n; ++j) {
      const double t = static_cast<double>(j) / n;
      if (!free(pa, pa + t * (pb - pa))) break;
      t_ok = t;
    }
    if (last_valid.first) si_->getStateSpace()->interpolate(s1, s2, t_ok, last_valid.first);
    last_valid.second = t_ok;
    return false;
  }

 private:
  bool free(const Vec2& a, const Vec2& b) const {
    if (!obstacles_.segment_free(a, b)) return false;
    if (!corridor_) return true;
    const unsigned int n = std::max(1u, segment_count((b - a).norm(), step_));
    for (unsigned int j = 0; j <= n; ++j) {
      const Vec2 p = a + (static_cast<double>(j) / n) * (b - a);
      if (corridor_->deviation(p) > half_width_) return false;
    }
    return true;
  }
  const ObstacleChecker& obstacles_;
  const CentralPath* corridor_;
  double half_width_, step_;
};

// RRTstar with its own seed and, in place of GNAT, the exact grid
// neighbour structure of planning_nn.hpp (same neighbours, same plans).
class SeededRRTstar : public og::RRTstar {
 public:
  SeededRRTstar(const ob::SpaceInformationPtr& si, std::uint_fast32_t seed) : og::RRTstar(si) {
    rng_.setLocalSeed(seed);
    const auto& b = si->getStateSpace()->as<ob::RealVectorStateSpace>()->getBounds();
    nn_ = std::make_shared<planning_detail::GridNearestNeighbors<Motion*>>(b.low[0], b.low[1], b.high[0],
                                                                             b.high[1]);
  }
};

class SeededSimplifier : public og::PathSimplifier {
 public:
  SeededSimplifier(const ob::SpaceInformationPtr& si, const ob::OptimizationObjectivePtr& obj,
                   std::uint_fast32_t seed)
      : og::PathSimplifier(si, ob::GoalPtr(), obj) {
    rng_.setLocalSeed(seed);
  }
};

// OMPL's generators take 32-bit seeds: the low half of the core's derive_seed.
std::uint_fast32_t derive_seed32(std::uint64_t seed, std::uint64_t stream) {
  return static_cast<std::uint_fast32_t>(derive_seed(seed, stream) & 0xFFFFFFFFULL);
}

Points2 to_points(const og::PathGeometric& path) {
  Points2 out(static_cast<Eigen::Index>(path.getStateCount()), 2);
  for (std::size_t i = 0; i < path.getStateCount(); ++i) {
    const double* v = xy(path.getState(i));
    out(static_cast<Eigen::Index>(i), 0) = v[0];
    out(static_cast<Eigen::Index>(i), 1) = v[1];
  }
  return out;
}

void check_point(const PlanningProblem& problem, const PlannerSettings& settings, const ObstacleChecker& obstacles,
                 const CentralPath& central, const Vec2& p, const std::string& name) {
  if (!p.allFinite()) bad(name + " " + fmt(p) + " is not finite");
  if (!problem.map.in_field(p))
    bad(name + " " + fmt(p) + " is outside the field " + fmt(problem.map.lower) + "–" + fmt(problem.map.upper));
  if (!obstacles.point_free(p)) {
    const auto& hz = problem.map.hazards;
    const bool forbidden = std::any_of(hz.begin(), hz.end(),
                                       [&](const HazardZone& h) { return h.risk >= problem.map.forbidden_risk; });
    bad(name + " " + fmt(p) + " is inside an obstacle" +
        (forbidden ? " or a forbidden hazard (risk >= forbidden_risk = " + std::to_string(problem.map.forbidden_risk) + ")"
                   : std::string()) +
        " (or within its clearance)");
  }
  if (settings.stay_in_corridor) {
    const double d = central.deviation(p);
    if (d > problem.zones.half_width)
      bad(name + " " + fmt(p) + " is " + std::to_string(d) + " m from the central path, outside the corridor (half_width " +
          std::to_string(problem.zones.half_width) + ")");
  }
}

}  // namespace

// ---------------------------------------------------------------- validation
void PlanningProblem::validate() const {
  map.validate();
  if (central_path.rows() > 0) {
    if (!central_path.allFinite()) bad("central_path has a non-finite point");
    zones.validate();
  }
}

void PlannerSettings::validate() const {
  auto finite_nonneg = [](double v, const char* name) {
    if (!std::isfinite(v) || v < 0.0) bad(std::string(name) + " must be finite and >= 0, got " + std::to_string(v));
  };
  finite_nonneg(alpha, "alpha");
  finite_nonneg(beta, "beta");
  if (alpha == 0.0 && beta == 0.0) bad("alpha and beta are both 0: the cost would be 0 for every path");
  finite_nonneg(range, "range");
  if (!(goal_bias >= 0.0 && goal_bias <= 1.0)) bad("goal_bias must be in [0, 1], got " + std::to_string(goal_bias));
  if (max_iterations <= 0) bad("max_iterations must be > 0, got " + std::to_string(max_iterations));
  finite_nonneg(max_time, "max_time");
  if (!std::isfinite(resolution) || resolution <= 0.0) bad("resolution must be > 0, got " + std::to_string(resolution));
  finite_nonneg(goal_tolerance, "goal_tolerance");
  if (!(corridor_bias >= 0.0 && corridor_bias <= 1.0))
    bad("corridor_bias must be in [0, 1], got " + std::to_string(corridor_bias));
  finite_nonneg(hazard_weight, "hazard_weight");
  if (informed_sampling && alpha == 0.0) bad("informed_sampling needs alpha > 0 (alpha * length bounds the cost), got alpha = 0");
  param_set<PlannerSettings>().check(*this);
}

std::string to_string(PlanStatus status) {
  switch (status) {
    case PlanStatus::Exact: return "exact";
    case PlanStatus::Approximate: return "approximate";
    case PlanStatus::NoPath: return "no_path";
  }
  return "unknown";
}

// ---------------------------------------------------------------- path queries
Vec2 point_ahead(const Eigen::Ref<const Points2>& path, const Vec2& position, double distance) {
  if (path.rows() == 0) bad("point_ahead needs a non-empty path");
  if (!path.allFinite()) bad("path has a non-finite point");
  if (!position.allFinite()) bad("position " + fmt(position) + " is not finite");
  if (!std::isfinite(distance)) bad("distance " + std::to_string(distance) + " is not finite");
  const CentralPath central(path, RiskZones{});
  return central.point_at(central.arc_length(position) + distance);
}

PathCost path_cost(const Eigen::Ref<const Points2>& path, const PlanningProblem& problem,
                   const PlannerSettings& settings) {
  settings.validate();
  if (!path.allFinite()) bad("path has a non-finite point");
  return cost_of(path, CentralPath(problem.central_path, problem.zones), ObstacleChecker(problem.map), problem,
                 settings);
}

Eigen::VectorXd cost_lower_bound(const Eigen::Ref<const Points2>& points, const PlanningProblem& problem,
                                 const PlannerSettings& settings) {
  problem.validate();
  settings.validate();
  if (!points.allFinite()) bad("points has a non-finite point");
  const CentralPath risk(problem.central_path, problem.zones);
  const bool wrs_term = settings.beta != 0.0 && problem.central_path.rows() > 0;
  const planning_detail::CostBound bound(settings.alpha, wrs_term ? settings.beta : 0.0, wrs_term ? &risk : nullptr,
                                         problem.start, problem.goal, settings.goal_tolerance);
  Eigen::VectorXd out(points.rows());
  for (Eigen::Index i = 0; i < points.rows(); ++i) out[i] = bound(Vec2(points(i, 0), points(i, 1)));
  return out;
}

// ---------------------------------------------------------------- planning
namespace {

/// The state space (the map's box, the seeded corridor-biased sampler) and
/// the space information with the validity and motion checkers.
ob::SpaceInformationPtr make_space_information(const PlanningProblem& problem, const PlannerSettings& settings,
                                               const ObstacleChecker& obstacles, const CentralPath& risk,
                                               const CentralPath* corridor) {
  const PlanningMap& map = problem.map;
  auto space = std::make_shared<ob::RealVectorStateSpace>(2);
  ob::RealVectorBounds bounds(2);
  bounds.setLow(0, map.lower.x());
  bounds.setLow(1, map.lower.y());
  bounds.setHigh(0, map.upper.x());
  bounds.setHigh(1, map.upper.y());
  space->setBounds(bounds);
  const std::uint_fast32_t sampler_seed = derive_seed32(settings.seed, 0);
  const CentralPath* central = settings.corridor_bias > 0.0 ? &risk : nullptr;
  const double bias = settings.corridor_bias, half_width = problem.zones.half_width;
  space->setStateSamplerAllocator([sampler_seed, central, bias, half_width](const ob::StateSpace* s) {
    return std::make_shared<SeededSampler>(s, sampler_seed, central, bias, half_width);
  });
  space->setLongestValidSegmentFraction(settings.resolution / space->getMaximumExtent());

  auto si = std::make_shared<ob::SpaceInformation>(space);
  si->setStateValidityChecker(std::make_shared<Checker>(si, obstacles, corridor, problem.zones.half_width));
  si->setMotionValidator(
      std::make_shared<MotionChecker>(si, obstacles, corridor, problem.zones.half_width, settings.resolution));
  si->setup();
  return si;
}

/// Runs the seeded RRT* on `pdef` until the iteration or time budget is
/// spent; fills the result's timing, iteration count and cost history.
ob::PlannerStatus solve(const ob::SpaceInformationPtr& si, const ob::ProblemDefinitionPtr& pdef,
                        const PlannerSettings& settings, PlanResult& result) {
  auto planner = std::make_shared<SeededRRTstar>(si, derive_seed32(settings.seed, 1));
  if (settings.range > 0.0) planner->setRange(settings.range);
  planner->setGoalBias(settings.goal_bias);
  // Radius neighbourhoods (r ≤ range) instead of k-nearest: no long edges, each
  // costing a full WRS integral, while the tree is sparse.
  planner->setKNearest(false);
  if (settings.informed_sampling) planner->setInformedSampling(true);
  planner->setProblemDefinition(pdef);
  planner->setup();

  std::vector<std::array<double, 3>> history;
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&t0] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const SeededRRTstar* raw = planner.get();
  pdef->setIntermediateSolutionCallback(
      [&history, &elapsed, raw](const ob::Planner*, const std::vector<const ob::State*>&, const ob::Cost cost) {
        history.push_back({static_cast<double>(raw->numIterations()), elapsed(), cost.value()});
      });
  const auto max_it = static_cast<std::uint64_t>(settings.max_iterations);
  const double max_time = settings.max_time;
  ob::PlannerTerminationCondition ptc([raw, max_it, max_time, &elapsed] {
    return raw->numIterations() >= max_it || (max_time > 0.0 && elapsed() >= max_time);
  });
  const ob::PlannerStatus status = planner->solve(ptc);
  result.planning_time = elapsed();
  result.iterations = static_cast<std::int64_t>(planner->numIterations());

  result.cost_history.resize(static_cast<Eigen::Index>(history.size()), 3);
  for (std::size_t i = 0; i < history.size(); ++i)
    for (int k = 0; k < 3; ++k) result.cost_history(static_cast<Eigen::Index>(i), k) = history[i][k];
  if (!history.empty()) {
    result.first_solution_iteration = static_cast<std::int64_t>(history.front()[0]);
    result.first_solution_time = history.front()[1];
  }
  return status;
}

/// Cost-aware shortcuts (the objective judges every shortcut), then a dense
/// re-check: the smoothed path replaces `points` only if it is free, inside
/// the corridor when there is one, and no dearer.
void smooth(const ob::SpaceInformationPtr& si, const ob::OptimizationObjectivePtr& objective,
            const og::PathGeometric& solution, const PlanningProblem& problem, const PlannerSettings& settings,
            const ObstacleChecker& obstacles, const CentralPath& risk, const CentralPath* corridor, bool has_risk,
            Points2& points) {
  SeededSimplifier simplifier(si, objective, derive_seed32(settings.seed, 2));
  og::PathGeometric smoothed(solution);
  simplifier.shortcutPath(smoothed);
  if (settings.beta == 0.0 || !has_risk) simplifier.reduceVertices(smoothed);
  const Points2 candidate = to_points(smoothed);
  bool ok = path_is_free(problem.map, candidate);
  if (ok && corridor) {
    for (Eigen::Index i = 0; ok && i + 1 < candidate.rows(); ++i) {
      const Vec2 a(candidate(i, 0), candidate(i, 1)), b(candidate(i + 1, 0), candidate(i + 1, 1));
      const unsigned int n = std::max(1u, segment_count((b - a).norm(), settings.resolution));
      for (unsigned int j = 0; ok && j <= n; ++j) {
        const Vec2 q = a + (static_cast<double>(j) / n) * (b - a);
        ok = risk.deviation(q) <= problem.zones.half_width;
      }
    }
  }
  if (ok && cost_of(candidate, risk, obstacles, problem, settings).total <=
                cost_of(points, risk, obstacles, problem, settings).total)
    points = candidate;
}

}  // namespace

PlanResult plan(const PlanningProblem& problem, const PlannerSettings& settings) {
  problem.validate();
  settings.validate();
  const bool has_risk = problem.central_path.rows() > 0;
  if (settings.stay_in_corridor && !has_risk) bad("stay_in_corridor needs a central_path");
  if (settings.alpha == 0.0 && !has_risk) bad("alpha = 0 needs a central_path for the risk term");
  const ObstacleChecker obstacles(problem.map);
  const CentralPath risk(problem.central_path, problem.zones);
  const CentralPath* corridor = settings.stay_in_corridor ? &risk : nullptr;
  check_point(problem, settings, obstacles, risk, problem.start, "start");
  check_point(problem, settings, obstacles, risk, problem.goal, "goal");

  ompl::msg::setLogLevel(ompl::msg::LOG_ERROR);
  const ob::SpaceInformationPtr si = make_space_information(problem, settings, obstacles, risk, corridor);
  const ob::OptimizationObjectivePtr objective = make_objective(si, problem, settings, obstacles, risk, has_risk);

  auto pdef = std::make_shared<ob::ProblemDefinition>(si);
  ob::ScopedState<ob::RealVectorStateSpace> start(si->getStateSpace()), goal(si->getStateSpace());
  start[0] = problem.start.x();
  start[1] = problem.start.y();
  goal[0] = problem.goal.x();
  goal[1] = problem.goal.y();
  pdef->setStartAndGoalStates(start, goal, settings.goal_tolerance);
  pdef->setOptimizationObjective(objective);

  PlanResult result;
  const ob::PlannerStatus status = solve(si, pdef, settings, result);
  const bool exact = status == ob::PlannerStatus::EXACT_SOLUTION && pdef->hasExactSolution();
  const bool approximate = !exact && pdef->hasSolution() && settings.allow_approximate;
  if (!exact && !approximate) {
    result.status = PlanStatus::NoPath;
    result.path.resize(0, 2);
    result.cost = PathCost{};
    return result;
  }
  auto path = std::static_pointer_cast<og::PathGeometric>(pdef->getSolutionPath());
  const og::PathGeometric solution(*path);
  Points2 points = to_points(solution);
  if (settings.smooth && solution.getStateCount() > 2)
    smooth(si, objective, solution, problem, settings, obstacles, risk, corridor, has_risk, points);
  result.status = exact ? PlanStatus::Exact : PlanStatus::Approximate;
  result.success = exact;
  result.path = points;
  result.cost = cost_of(points, risk, obstacles, problem, settings);
  result.safety = path_safety(points, problem.map);
  return result;
}

PlanResult replan_to(const PlanningProblem& problem, const Vec2& position, const Vec2& goal,
                     const PlannerSettings& settings) {
  PlanningProblem p = problem;
  p.start = position;
  p.goal = goal;
  return plan(p, settings);
}

PlanResult replan(const PlanningProblem& problem, const Vec2& position, double lookahead,
                  const PlannerSettings& settings) {
  if (problem.central_path.rows() == 0) bad("replan needs a central_path to look ahead on");
  if (!std::isfinite(lookahead) || lookahead <= 0.0) bad("lookahead must be > 0, got " + std::to_string(lookahead));
  problem.validate();
  settings.validate();
  if (!position.allFinite()) bad("position " + fmt(position) + " is not finite");
  const CentralPath path(problem.central_path, problem.zones);
  const double total = path.length();
  double s = path.arc_length(position) + lookahead;
  Vec2 goal = path.point_at(s);
  // Slide the goal past whatever blocks it ([SafeNav-ext Alg. 4]: a point ahead on the safe path).
  while (!point_is_free(problem.map, goal) && s < total) {
    s += settings.resolution;
    goal = path.point_at(s);
  }
  if (!point_is_free(problem.map, goal))
    bad("no free point on the central path ahead of " + fmt(position) + " (the path's end " + fmt(goal) +
        " is blocked)");
  return replan_to(problem, position, goal, settings);
}


// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<PlannerSettings>& param_set<PlannerSettings>() {
  static const ParamSet<PlannerSettings> s =
      Declare<PlannerSettings>{}
          .real("alpha", SN_REF(PlannerSettings, alpha), "", above(0, 1e6), "alpha, weight of the length term [SafeNav eq. 19]")
          .real("beta", SN_REF(PlannerSettings, beta), "", closed(0, 1e6), "beta, weight of the risk term [SafeNav eq. 19]; 0 = plain RRT*")
          .real("range", SN_REF(PlannerSettings, range), "m", closed(0, 1e6), "longest tree edge; 0 = OMPL's default (20 % of the field's diagonal)")
          .real("goal_bias", SN_REF(PlannerSettings, goal_bias), "", closed(0, 1), "probability of sampling the goal")
          .integer64("max_iterations", SN_REF(PlannerSettings, max_iterations), closed(1, PlannerSettings::kMaxIterations), "RRT* iterations (the deterministic budget)")
          .real("max_time", SN_REF(PlannerSettings, max_time), "s", closed(0, 1e6), "wall-clock budget; 0 = none")
          .real("resolution", SN_REF(PlannerSettings, resolution), "m", above(0, 1e3), "cost-integration and corridor-check step along a motion")
          .real("goal_tolerance", SN_REF(PlannerSettings, goal_tolerance), "m", closed(0, 1e3), "a tree node this close to the goal reaches it")
          .real("corridor_bias", SN_REF(PlannerSettings, corridor_bias), "", closed(0, 1), "share of samples drawn inside the corridor (0 = uniform, as the paper)")
          .real("hazard_weight", SN_REF(PlannerSettings, hazard_weight), "1/m", closed(0, 1e6), "beta_h, weight of the hazard term beta_h * integral of risk ds; 0 = the paper's cost")
          .set;
  return s;
}

template class ParamSet<PlannerSettings>;

}  // namespace safenav
