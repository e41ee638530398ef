// Private to the planner (cpp/src/planning*.cpp): the central path of the
// risk term, the RAw-RRT* objective [SafeNav eqs. 15–19] and the path cost.
// OMPL types appear here, so this header never leaves cpp/src.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <ompl/base/OptimizationObjective.h>
#include <ompl/base/SpaceInformation.h>
#include <ompl/base/objectives/StateCostIntegralObjective.h>
#include <ompl/base/samplers/InformedStateSampler.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>

#include "safenav/corridor.hpp"
#include "safenav/planning.hpp"
#include "safenav/world.hpp"

namespace safenav::planning_detail {

namespace ob = ompl::base;
using Vec2 = Eigen::Vector2d;

inline const double* xy(const ob::State* s) { return s->as<ob::RealVectorStateSpace::StateType>()->values; }

/// Sub-step count of an edge: OMPL's validSegmentCount() for a space whose
/// longest valid segment is `step`.
unsigned int segment_count(double distance, double step);

/// The central path of the risk term: a Corridor (deviation, eq. 17; WRS,
/// eq. 18), or, when the path has a single distinct point, that point.
///
/// deviation() is Corridor::project(p).distance bit for bit: the same
/// per-edge arithmetic with the edge vectors computed once, and without the
/// side test (CGAL orientation), arc length and per-call overflow scan that
/// project() also does.  Coordinates at or beyond 2^500 (where project()
/// rescales) and non-finite points go to project() itself.
class CentralPath {
 public:
  CentralPath(const Points2& path, const RiskZones& zones);
  bool empty() const { return empty_; }
  double deviation(const Vec2& p) const;
  /// WRS of eq. 18 at p (safenav::wrs of the deviation); 0 without a path.
  double risk(const Vec2& p) const { return empty_ ? 0.0 : wrs(deviation(p), zones_); }
  double arc_length(const Vec2& p) const { return corridor_ ? corridor_->project(p).arc_length : 0.0; }
  Vec2 point_at(double s) const { return corridor_ ? corridor_->point_at(s) : point_; }
  Vec2 tangent_at(double s) const { return corridor_ ? corridor_->tangent_at(s) : Vec2(1.0, 0.0); }
  double length() const { return corridor_ ? corridor_->length() : 0.0; }
  const RiskZones& zones() const { return zones_; }

 private:
  struct Edge {
    Vec2 a, ab;   ///< first vertex, and the edge vector (second − first)
    double ab2;   ///< ‖ab‖²
  };
  RiskZones zones_;
  bool empty_ = true;
  bool scaled_ = false;  ///< the path reaches 2^500: project() rescales every query
  Vec2 point_{0, 0};
  std::optional<Corridor> corridor_;
  std::vector<Edge> edges_;
};

/// The planner's state sampler, with its own seed: uniform over the field,
/// or — with probability `corridor_bias` — uniform in arc length and offset
/// within the corridor around the central path (ours; 0 = the paper's
/// uniform sampling).
class SeededSampler : public ob::RealVectorStateSampler {
 public:
  SeededSampler(const ob::StateSpace* space, std::uint_fast32_t seed, const CentralPath* central = nullptr,
                double corridor_bias = 0.0, double half_width = 0.0);
  void sampleUniform(ob::State* state) override;
  /// Informed sampling (Gammell et al. 2014, in the plane): a state of the
  /// same mixture restricted to the ellipse {x : ‖x − f1‖ + ‖x − f2‖ ≤ D}
  /// (drawn directly in the ellipse when that is smaller than the field, by
  /// rejection otherwise) and accepted by `accept`.  D = ∞: sampleUniform().
  /// False after `attempts` rejected draws, or when the ellipse is empty.
  template <class Accept>
  bool sample_within(ob::State* state, const Vec2& f1, const Vec2& f2, double D, unsigned int attempts,
                     const Accept& accept) {
    if (!std::isfinite(D)) {
      sampleUniform(state);
      return true;
    }
    for (unsigned int i = 0; i < attempts; ++i) {
      Vec2 p;
      if (propose(state, f1, f2, D, p) && accept(p)) return true;
    }
    return false;
  }

 private:
  bool corridor_sample(Vec2& p);  ///< draws the bias coin; false: no corridor sample this time
  Vec2 ellipse_sample(const Vec2& f1, const Vec2& f2, double D);
  /// One draw of the mixture inside the field and the ellipse, written to `state` and `p`.
  bool propose(ob::State* state, const Vec2& f1, const Vec2& f2, double D, Vec2& p);
  const CentralPath* central_;
  double bias_, half_width_;
};

/// W(d) = ∫₀^d WRS(u) du from below (eq. 18's WRS, safenav::wrs): the left
/// Riemann sum on cells aligned with the zone borders, where WRS only grows
/// within a cell; beyond d_max WRS is constant.  Since the deviation from the
/// central path changes by at most one metre per metre travelled, any path
/// between deviations d0 and d1 collects at least |W(d1) − W(d0)| of ∫WRS ds.
class WrsPrimitive {
 public:
  explicit WrsPrimitive(const RiskZones& zones);
  double operator()(double d) const;

 private:
  double h_ = 1.0, dmax_ = 0.0, tail_ = 0.0;
  std::vector<double> table_, left_;  ///< W at each cell's left end, WRS there
};

/// The informed set's test: a state x can lie on a path cheaper than c only if
///   h(x) = α(‖x − start‖ + ‖x − goal‖ − tol) + β(|W(d_x) − W(d_start)| + |W(d_x) − W(d_goal)|) ≤ c,
/// a lower bound on the cost of every path from start through x to the goal
/// region (length ≥ the two straight lines, minus the goal region's radius
/// tol; WrsPrimitive for the risk; the hazard term is ≥ 0).
class CostBound {
 public:
  CostBound(double alpha, double beta, const CentralPath* risk, const Vec2& start, const Vec2& goal,
            double goal_tolerance);
  double operator()(const Vec2& x) const;
  double alpha() const { return alpha_; }
  double tolerance() const { return tolerance_; }
  const Vec2& start() const { return start_; }
  const Vec2& goal() const { return goal_; }

 private:
  double alpha_, beta_, tolerance_;
  const CentralPath* risk_;
  WrsPrimitive primitive_;
  Vec2 start_, goal_;
  double w_start_ = 0.0, w_goal_ = 0.0;
};

/// OMPL's informed-sampler interface for RawObjective: proposals come from
/// the ellipse that CostBound's length part allows, D = c/α + tol, and a
/// proposal is kept when h(x) ≤ c.
class EllipseInformedSampler : public ob::InformedSampler {
 public:
  EllipseInformedSampler(const ob::ProblemDefinitionPtr& pdef, unsigned int attempts, const CostBound& bound);
  bool sampleUniform(ob::State* state, const ob::Cost& max_cost) override;
  bool sampleUniform(ob::State* state, const ob::Cost& min_cost, const ob::Cost& max_cost) override;
  bool hasInformedMeasure() const override { return true; }
  double getInformedMeasure(const ob::Cost& current_cost) const override;

 private:
  double diameter(const ob::Cost& cost) const;
  std::shared_ptr<SeededSampler> sampler_;
  CostBound bound_;
};

/// β-term of eq. 19: ∫ WRS ds along every motion, the trapezoid rule on
/// OMPL's valid-segment sub-steps (StateCostIntegralObjective with motion-cost
/// interpolation).  motionCost() repeats the base class's arithmetic step for
/// step, on two stack points instead of two heap-allocated states.
class WrsObjective : public ob::StateCostIntegralObjective {
 public:
  WrsObjective(const ob::SpaceInformationPtr& si, const CentralPath& risk);
  ob::Cost stateCost(const ob::State* s) const override;
  ob::Cost motionCost(const ob::State* s1, const ob::State* s2) const override;

 private:
  const CentralPath& risk_;
};

/// α·length + β·∫WRS (+ β_h·∫risk over the hazards): OMPL's sum of weighted
/// objectives, with the admissible heuristics that OMPL's informed sampling,
/// pruning and new-state rejection need.  Every term is ≥ 0 and the length
/// term is α·‖s1 − s2‖ exactly, so α·‖s1 − s2‖ never exceeds a motion's cost
/// and α·(distance to the goal region) never exceeds the cost to go.
class RawObjective : public ob::MultiOptimizationObjective {
 public:
  RawObjective(const ob::SpaceInformationPtr& si, double alpha);
  ob::Cost motionCostHeuristic(const ob::State* s1, const ob::State* s2) const override;
  /// Informed sampling (PlannerSettings::informed_sampling): the ellipse sampler above.
  void set_informed_set(const CostBound& bound) { bound_.emplace(bound); }
  ob::InformedSamplerPtr allocInformedStateSampler(const ob::ProblemDefinitionPtr& pdef,
                                                   unsigned int attempts) const override;
  double alpha() const { return alpha_; }

 private:
  double alpha_;
  std::optional<CostBound> bound_;
};

/// The planner's objective for these settings (eqs. 16, 19, plus the hazard
/// term when β_h > 0); its cost threshold is −∞ (never "good enough").
ob::OptimizationObjectivePtr make_objective(const ob::SpaceInformationPtr& si, const PlanningProblem& problem,
                                            const PlannerSettings& settings, const ObstacleChecker& obstacles,
                                            const CentralPath& risk, bool has_risk);

/// path_cost() with the central path already built.
PathCost cost_of(const Eigen::Ref<const Points2>& path, const CentralPath& risk, const ObstacleChecker& hazards,
                 const PlanningProblem& problem, const PlannerSettings& settings);

}  // namespace safenav::planning_detail
