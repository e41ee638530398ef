// The RAw-RRT* cost [SafeNav eqs. 15–19]: the central path's deviation and
// WRS, the OMPL objective, and path_cost().  See planning.hpp and
// planning_internal.hpp.
//
// Speed without changing a bit: OMPL's StateCostIntegralObjective clones and
// allocates two states per motion, and Corridor::project() also computes the
// side (a CGAL orientation), the arc length and an overflow scan of the whole
// path for every sub-step.  The versions here do only what the cost needs,
// in the same floating-point operations in the same order, so every motion
// cost (and so every tree and path) is the one the plain OMPL objective
// gives.  tests/test_planning_speed.py checks this against Corridor's WRS.
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <ompl/base/Goal.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>

#include "planning_internal.hpp"
#include "planning_nn.hpp"

namespace safenav::planning_detail {

unsigned int segment_count(double distance, double step) {
  return static_cast<unsigned int>(std::ceil(distance / step));
}

namespace {

// Corridor::project() rescales coordinates whose magnitude reaches 2^500
// (overflow_scale: frexp exponent > 500); below that it works unscaled.
constexpr double kUnscaled = 0x1p500;
bool unscaled(double v) { return std::abs(v) < kUnscaled; }  // false for NaN

// β_h-term (ours): ∫ risk ds over the hazards, exact per motion.
class HazardObjective : public ob::OptimizationObjective {
 public:
  HazardObjective(const ob::SpaceInformationPtr& si, const ObstacleChecker& map)
      : ob::OptimizationObjective(si), map_(map) {
    description_ = "hazard risk integrated along the path (exact)";
  }
  ob::Cost stateCost(const ob::State*) const override { return identityCost(); }
  ob::Cost motionCost(const ob::State* s1, const ob::State* s2) const override {
    const double *a = xy(s1), *b = xy(s2);
    return ob::Cost(map_.hazard_integral(Vec2(a[0], a[1]), Vec2(b[0], b[1])));
  }

 private:
  const ObstacleChecker& map_;
};

}  // namespace

// ---------------------------------------------------------------- central path
CentralPath::CentralPath(const Points2& path, const RiskZones& zones) : zones_(zones) {
  if (path.rows() == 0) return;
  empty_ = false;
  point_ = Vec2(path(0, 0), path(0, 1));
  for (Eigen::Index i = 1; i < path.rows(); ++i)
    if (path.row(i) != path.row(0)) {
      corridor_.emplace(path, zones);
      break;
    }
  if (!corridor_) return;
  const Points2& p = corridor_->path();  // consecutive duplicates dropped, as project() sees it
  scaled_ = !(p.cwiseAbs().maxCoeff() < kUnscaled);
  for (Eigen::Index k = 0; k + 1 < p.rows(); ++k) {
    const Vec2 a = p.row(k).transpose(), ab = p.row(k + 1).transpose() - a;
    edges_.push_back({a, ab, ab.squaredNorm()});
  }
}

double CentralPath::deviation(const Vec2& p) const {
  if (!corridor_) return (p - point_).norm();
  if (scaled_ || !unscaled(p.x()) || !unscaled(p.y())) return corridor_->project(p).distance;
  // Corridor::project's loop at scale 1: clamp the foot's parameter to the
  // edge, keep the first edge with the smallest squared distance.
  double best_d2 = std::numeric_limits<double>::infinity();
  for (const Edge& e : edges_) {
    const double t = std::clamp((p - e.a).dot(e.ab) / e.ab2, 0.0, 1.0);
    const Vec2 foot = e.a + t * e.ab;
    const double d2 = (p - foot).squaredNorm();
    if (d2 < best_d2) best_d2 = d2;
  }
  const double d = std::sqrt(best_d2);
  return std::isfinite(d) ? d : corridor_->project(p).distance;  // project() names the overflow
}

// ---------------------------------------------------------------- objectives
WrsObjective::WrsObjective(const ob::SpaceInformationPtr& si, const CentralPath& risk)
    : ob::StateCostIntegralObjective(si, true), risk_(risk) {
  description_ = "weighted risk score (SafeNav eq. 18) integrated along the path";
}

ob::Cost WrsObjective::stateCost(const ob::State* s) const {
  const double* v = xy(s);
  return ob::Cost(risk_.risk(Vec2(v[0], v[1])));
}

ob::Cost WrsObjective::motionCost(const ob::State* s1, const ob::State* s2) const {
  // StateCostIntegralObjective::motionCost (OMPL 1.5) with RealVectorStateSpace's
  // interpolate() and distance() written out: nd sub-steps, trapezoid rule
  // 0.5·dist·(c1 + c2) on each, summed from s1 to s2.
  const double* a = xy(s1);
  const double* b = xy(s2);
  const int nd = static_cast<int>(si_->getStateSpace()->validSegmentCount(s1, s2));
  double total = 0.0;
  double p[2] = {a[0], a[1]};
  double prev = risk_.risk(Vec2(p[0], p[1]));
  for (int j = 1; j < nd; ++j) {
    const double t = static_cast<double>(j) / static_cast<double>(nd);
    const double q[2] = {a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t};
    const double next = risk_.risk(Vec2(q[0], q[1]));
    total = total + 0.5 * ompl_distance_2d(p, q) * (prev + next);
    p[0] = q[0];
    p[1] = q[1];
    prev = next;
  }
  total = total + 0.5 * ompl_distance_2d(p, b) * (prev + risk_.risk(Vec2(b[0], b[1])));
  return ob::Cost(total);
}

RawObjective::RawObjective(const ob::SpaceInformationPtr& si, double alpha)
    : ob::MultiOptimizationObjective(si), alpha_(alpha) {
  description_ = "RAw-RRT* cost alpha*length + beta*integral(WRS) (SafeNav eq. 19)";
  // α·(distance to the goal region), ≤ α·length of any path that reaches it.
  setCostToGoHeuristic([alpha](const ob::State* s, const ob::Goal* goal) {
    return ob::Cost(alpha * ob::goalRegionCostToGo(s, goal).value());
  });
}

ob::Cost RawObjective::motionCostHeuristic(const ob::State* s1, const ob::State* s2) const {
  return ob::Cost(alpha_ * si_->distance(s1, s2));
}

ob::InformedSamplerPtr RawObjective::allocInformedStateSampler(const ob::ProblemDefinitionPtr& pdef,
                                                               unsigned int attempts) const {
  return bound_ ? std::make_shared<EllipseInformedSampler>(pdef, attempts, *bound_)
                : ob::OptimizationObjective::allocInformedStateSampler(pdef, attempts);
}

ob::OptimizationObjectivePtr make_objective(const ob::SpaceInformationPtr& si, const PlanningProblem& problem,
                                            const PlannerSettings& settings, const ObstacleChecker& obstacles,
                                            const CentralPath& risk, bool has_risk) {
  const bool wrs_term = settings.beta != 0.0 && has_risk;
  const bool hazard_term = settings.hazard_weight > 0.0 && !problem.map.hazards.empty();
  ob::OptimizationObjectivePtr objective;
  if (!wrs_term && !hazard_term && settings.alpha == 1.0 && !settings.informed_sampling) {
    objective = std::make_shared<ob::PathLengthOptimizationObjective>(si);  // plain RRT*
  } else {
    // Components in the order OMPL's operators built them: α·length (absent
    // when α = 0 and the WRS term is there), β·∫WRS, β_h·∫risk.
    auto sum = std::make_shared<RawObjective>(si, settings.alpha);
    if (!(wrs_term && settings.alpha == 0.0))
      sum->addObjective(std::make_shared<ob::PathLengthOptimizationObjective>(si), settings.alpha);
    if (wrs_term) sum->addObjective(std::make_shared<WrsObjective>(si, risk), settings.beta);
    if (hazard_term) sum->addObjective(std::make_shared<HazardObjective>(si, obstacles), settings.hazard_weight);
    sum->lock();
    sum->set_informed_set(CostBound(settings.alpha, wrs_term ? settings.beta : 0.0, wrs_term ? &risk : nullptr,
                                    problem.start, problem.goal, settings.goal_tolerance));
    objective = sum;
  }
  // Never "good enough": optimise until the budget is spent.
  objective->setCostThreshold(ob::Cost(-std::numeric_limits<double>::infinity()));
  return objective;
}

// ---------------------------------------------------------------- path cost
PathCost cost_of(const Eigen::Ref<const Points2>& path, const CentralPath& risk, const ObstacleChecker& hazards,
                 const PlanningProblem& problem, const PlannerSettings& settings) {
  // The same step as OMPL's longest valid segment (extent · fraction).
  const double extent = (problem.map.upper - problem.map.lower).norm();
  const double step = extent * (settings.resolution / extent);
  PathCost c;
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i) {
    const Vec2 a(path(i, 0), path(i, 1)), b(path(i + 1, 0), path(i + 1, 1));
    const double len = (b - a).norm();
    c.length += len;
    c.hazard += hazards.hazard_integral(a, b);
    if (risk.empty()) continue;
    const unsigned int n = std::max(1u, segment_count(len, step));
    Vec2 prev = a;
    double r_prev = risk.risk(a);
    for (unsigned int j = 1; j <= n; ++j) {
      const Vec2 q = j == n ? b : Vec2(a + (static_cast<double>(j) / n) * (b - a));
      const double r = risk.risk(q);
      c.risk += 0.5 * (r_prev + r) * (q - prev).norm();
      prev = q;
      r_prev = r;
    }
  }
  c.total = settings.alpha * c.length + settings.beta * c.risk;
  if (settings.hazard_weight > 0.0) c.total += settings.hazard_weight * c.hazard;
  return c;
}

}  // namespace safenav::planning_detail
