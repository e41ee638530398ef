// RAw-RRT* on OMPL (SafeNav eqs. 15–19, Algorithm 3).  See planning.hpp.
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

namespace safenav {
namespace {

namespace ob = ompl::base;
namespace og = ompl::geometric;
using Vec2 = Eigen::Vector2d;

[[noreturn]] void bad(const std::string& what) { throw std::invalid_argument(what); }

std::string fmt(const Vec2& p) {
  std::ostringstream s;
  s << "(" << p.x() << ", " << p.y() << ")";
  return s.str();
}

// ---------------------------------------------------------------- geometry
double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

double point_segment_distance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

bool segments_intersect(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const double d1 = cross(b - a, c - a), d2 = cross(b - a, d - a);
  const double d3 = cross(d - c, a - c), d4 = cross(d - c, b - c);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  // Collinear or touching cases are caught by the endpoint distances below.
  return false;
}

double segment_segment_distance(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  if (segments_intersect(a, b, c, d)) return 0.0;
  return std::min({point_segment_distance(a, c, d), point_segment_distance(b, c, d),
                   point_segment_distance(c, a, b), point_segment_distance(d, a, b)});
}

// Crossing-number test; boundary points count as inside via the distance test
// of the callers.
bool point_in_polygon(const Vec2& p, const Points2& poly) {
  bool inside = false;
  const Eigen::Index n = poly.rows();
  for (Eigen::Index i = 0, j = n - 1; i < n; j = i++) {
    const double xi = poly(i, 0), yi = poly(i, 1), xj = poly(j, 0), yj = poly(j, 1);
    if ((yi > p.y()) != (yj > p.y()) && p.x() < (xj - xi) * (p.y() - yi) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

Vec2 vertex(const Points2& poly, Eigen::Index i) { return Vec2(poly(i, 0), poly(i, 1)); }

// Polygon with a repeated closing vertex removed.
Points2 open_polygon(const Points2& poly) {
  if (poly.rows() > 1 && poly.row(0) == poly.row(poly.rows() - 1)) return poly.topRows(poly.rows() - 1);
  return poly;
}

bool in_bounds(const PlanningMap& map, const Vec2& p) {
  return p.x() >= map.lower.x() && p.x() <= map.upper.x() && p.y() >= map.lower.y() && p.y() <= map.upper.y();
}

// Path length along `path` up to the projection of p, and the projection.
double arc_length_of_projection(const Points2& path, const Vec2& p) {
  double best = std::numeric_limits<double>::infinity(), s_best = 0.0, s = 0.0;
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i) {
    const Vec2 a = vertex(path, i), b = vertex(path, i + 1);
    const Vec2 ab = b - a;
    const double l = ab.norm();
    const double t = l > 0.0 ? std::clamp((p - a).dot(ab) / (l * l), 0.0, 1.0) : 0.0;
    const double d = (a + t * ab - p).norm();
    if (d < best) best = d, s_best = s + t * l;
    s += l;
  }
  return s_best;
}

Vec2 point_at_arc_length(const Points2& path, double s) {
  if (path.rows() == 1 || s <= 0.0) return vertex(path, 0);
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i) {
    const Vec2 a = vertex(path, i), b = vertex(path, i + 1);
    const double l = (b - a).norm();
    if (s <= l) return l > 0.0 ? Vec2(a + (s / l) * (b - a)) : a;
    s -= l;
  }
  return vertex(path, path.rows() - 1);
}

double path_arc_length(const Points2& path) { return path.rows() < 2 ? 0.0 : path_length(path); }

// Risk of one point: WRS (eq. 18) of its deviation (eq. 17) from the central path.
class RiskField {
 public:
  RiskField(const Points2& path, const RiskZones& zones) : path_(path), zones_(zones), query_(1, 2) {}
  double operator()(double x, double y) const {
    if (path_.rows() == 0) return 0.0;
    query_(0, 0) = x;
    query_(0, 1) = y;
    return wrs(distance_to_path(query_, path_)[0], zones_);
  }
  double deviation(double x, double y) const {
    query_(0, 0) = x;
    query_(0, 1) = y;
    return distance_to_path(query_, path_)[0];
  }

 private:
  Points2 path_;
  RiskZones zones_;
  mutable Points2 query_;
};

// Sub-step count of an edge: OMPL's validSegmentCount() for a space whose
// longest valid segment is `step`.
unsigned int segment_count(double distance, double step) {
  return static_cast<unsigned int>(std::ceil(distance / step));
}

// ---------------------------------------------------------------- OMPL glue
const double* xy(const ob::State* s) { return s->as<ob::RealVectorStateSpace::StateType>()->values; }

class Checker : public ob::StateValidityChecker {
 public:
  Checker(const ob::SpaceInformationPtr& si, const PlanningMap& map, const RiskField* corridor, double half_width)
      : ob::StateValidityChecker(si), map_(map), corridor_(corridor), half_width_(half_width) {}
  bool isValid(const ob::State* s) const override {
    const double* v = xy(s);
    if (!point_is_free(map_, Vec2(v[0], v[1]))) return false;
    return !corridor_ || corridor_->deviation(v[0], v[1]) <= half_width_;
  }

 private:
  const PlanningMap& map_;
  const RiskField* corridor_;
  double half_width_;
};

// Exact segment/obstacle tests (no sampling gaps); the optional corridor
// constraint is checked every `step` metres.
class MotionChecker : public ob::MotionValidator {
 public:
  MotionChecker(const ob::SpaceInformationPtr& si, const PlanningMap& map, const RiskField* corridor,
                double half_width, double step)
      : ob::MotionValidator(si), map_(map), corridor_(corridor), half_width_(half_width), step_(step) {}

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
    if (!segment_is_free(map_, a, b)) return false;
    if (!corridor_) return true;
    const unsigned int n = std::max(1u, segment_count((b - a).norm(), step_));
    for (unsigned int j = 0; j <= n; ++j) {
      const Vec2 p = a + (static_cast<double>(j) / n) * (b - a);
      if (corridor_->deviation(p.x(), p.y()) > half_width_) return false;
    }
    return true;
  }
  const PlanningMap& map_;
  const RiskField* corridor_;
  double half_width_, step_;
};

// β-term of eq. 19: ∫ WRS ds, integrated along every motion (trapezoid rule,
// enableMotionCostInterpolation = true).
class WrsObjective : public ob::StateCostIntegralObjective {
 public:
  WrsObjective(const ob::SpaceInformationPtr& si, const RiskField& risk)
      : ob::StateCostIntegralObjective(si, true), risk_(risk) {
    description_ = "weighted risk score (SafeNav eq. 18) integrated along the path";
  }
  ob::Cost stateCost(const ob::State* s) const override {
    const double* v = xy(s);
    return ob::Cost(risk_(v[0], v[1]));
  }

 private:
  const RiskField& risk_;
};

class SeededSampler : public ob::RealVectorStateSampler {
 public:
  SeededSampler(const ob::StateSpace* space, std::uint_fast32_t seed) : ob::RealVectorStateSampler(space) {
    rng_.setLocalSeed(seed);
  }
};

class SeededRRTstar : public og::RRTstar {
 public:
  SeededRRTstar(const ob::SpaceInformationPtr& si, std::uint_fast32_t seed) : og::RRTstar(si) {
    rng_.setLocalSeed(seed);
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

// splitmix64: independent 32-bit seeds for each random source.
std::uint_fast32_t derive_seed(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z ^= z >> 31;
  return static_cast<std::uint_fast32_t>(z & 0xFFFFFFFFULL);
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

void check_point(const PlanningProblem& problem, const PlannerSettings& settings, const Vec2& p,
                 const std::string& name) {
  if (!p.allFinite()) bad(name + " " + fmt(p) + " is not finite");
  if (!in_bounds(problem.map, p))
    bad(name + " " + fmt(p) + " is outside the field " + fmt(problem.map.lower) + "–" + fmt(problem.map.upper));
  if (!point_is_free(problem.map, p)) bad(name + " " + fmt(p) + " is inside an obstacle (or within its clearance)");
  if (settings.stay_in_corridor) {
    const RiskField f(problem.central_path, problem.zones);
    const double d = f.deviation(p.x(), p.y());
    if (d > problem.zones.half_width)
      bad(name + " " + fmt(p) + " is " + std::to_string(d) + " m from the central path, outside the corridor (half_width " +
          std::to_string(problem.zones.half_width) + ")");
  }
}

}  // namespace

// ---------------------------------------------------------------- validation
void PlanningMap::validate() const {
  if (!lower.allFinite() || !upper.allFinite()) bad("field bounds " + fmt(lower) + "–" + fmt(upper) + " are not finite");
  if (!(upper.x() > lower.x()) || !(upper.y() > lower.y()))
    bad("field upper corner " + fmt(upper) + " must exceed lower corner " + fmt(lower));
  if (!std::isfinite(clearance) || clearance < 0.0) bad("clearance must be >= 0, got " + std::to_string(clearance));
  for (std::size_t i = 0; i < circles.size(); ++i) {
    const auto& c = circles[i];
    if (!c.center.allFinite()) bad("circle " + std::to_string(i) + " has non-finite center " + fmt(c.center));
    if (!std::isfinite(c.radius) || c.radius <= 0.0)
      bad("circle " + std::to_string(i) + " radius must be > 0, got " + std::to_string(c.radius));
  }
  for (std::size_t i = 0; i < polygons.size(); ++i) {
    const Points2 p = open_polygon(polygons[i]);
    if (p.rows() < 3) bad("polygon " + std::to_string(i) + " needs >= 3 vertices, got " + std::to_string(p.rows()));
    if (!p.allFinite()) bad("polygon " + std::to_string(i) + " has a non-finite vertex");
  }
}

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
}

std::string to_string(PlanStatus status) {
  switch (status) {
    case PlanStatus::Exact: return "exact";
    case PlanStatus::Approximate: return "approximate";
    case PlanStatus::NoPath: return "no_path";
  }
  return "unknown";
}

// ---------------------------------------------------------------- geometry API
bool point_is_free(const PlanningMap& map, const Vec2& p) {
  if (!in_bounds(map, p)) return false;
  for (const auto& c : map.circles)
    if ((p - c.center).norm() <= c.radius + map.clearance) return false;
  for (const auto& raw : map.polygons) {
    const Points2 poly = open_polygon(raw);
    if (point_in_polygon(p, poly)) return false;
    const Eigen::Index n = poly.rows();
    for (Eigen::Index i = 0; i < n; ++i)
      if (point_segment_distance(p, vertex(poly, i), vertex(poly, (i + 1) % n)) <= map.clearance) return false;
  }
  return true;
}

bool segment_is_free(const PlanningMap& map, const Vec2& a, const Vec2& b) {
  if (!a.allFinite() || !b.allFinite()) bad("segment " + fmt(a) + "–" + fmt(b) + " is not finite");
  // The field is convex: both ends inside means the whole segment is.
  if (!in_bounds(map, a) || !in_bounds(map, b)) return false;
  for (const auto& c : map.circles)
    if (point_segment_distance(c.center, a, b) <= c.radius + map.clearance) return false;
  for (const auto& raw : map.polygons) {
    const Points2 poly = open_polygon(raw);
    if (point_in_polygon(a, poly)) return false;  // a segment inside the polygon touches no edge
    const Eigen::Index n = poly.rows();
    for (Eigen::Index i = 0; i < n; ++i)
      if (segment_segment_distance(a, b, vertex(poly, i), vertex(poly, (i + 1) % n)) <= map.clearance) return false;
  }
  return true;
}

bool path_is_free(const PlanningMap& map, const Eigen::Ref<const Points2>& path) {
  if (path.rows() == 1) return point_is_free(map, Vec2(path(0, 0), path(0, 1)));
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i)
    if (!segment_is_free(map, Vec2(path(i, 0), path(i, 1)), Vec2(path(i + 1, 0), path(i + 1, 1)))) return false;
  return true;
}

Vec2 point_ahead(const Eigen::Ref<const Points2>& path, const Vec2& position, double distance) {
  if (path.rows() == 0) bad("point_ahead needs a non-empty path");
  if (!path.allFinite()) bad("path has a non-finite point");
  if (!position.allFinite()) bad("position " + fmt(position) + " is not finite");
  if (!std::isfinite(distance)) bad("distance " + std::to_string(distance) + " is not finite");
  const Points2 p = path;
  return point_at_arc_length(p, arc_length_of_projection(p, position) + distance);
}

PathCost path_cost(const Eigen::Ref<const Points2>& path, const PlanningProblem& problem,
                   const PlannerSettings& settings) {
  settings.validate();
  if (!path.allFinite()) bad("path has a non-finite point");
  const RiskField risk(problem.central_path, problem.zones);
  // The same step as OMPL's longest valid segment (extent · fraction).
  const double extent = (problem.map.upper - problem.map.lower).norm();
  const double step = extent * (settings.resolution / extent);
  PathCost c;
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i) {
    const Vec2 a(path(i, 0), path(i, 1)), b(path(i + 1, 0), path(i + 1, 1));
    const double len = (b - a).norm();
    c.length += len;
    if (problem.central_path.rows() == 0) continue;
    const unsigned int n = std::max(1u, segment_count(len, step));
    Vec2 prev = a;
    double r_prev = risk(a.x(), a.y());
    for (unsigned int j = 1; j <= n; ++j) {
      const Vec2 q = j == n ? b : Vec2(a + (static_cast<double>(j) / n) * (b - a));
      const double r = risk(q.x(), q.y());
      c.risk += 0.5 * (r_prev + r) * (q - prev).norm();
      prev = q;
      r_prev = r;
    }
  }
  c.total = settings.alpha * c.length + settings.beta * c.risk;
  return c;
}

// ---------------------------------------------------------------- planning
PlanResult plan(const PlanningProblem& problem, const PlannerSettings& settings) {
  problem.validate();
  settings.validate();
  const bool has_risk = problem.central_path.rows() > 0;
  if (settings.stay_in_corridor && !has_risk) bad("stay_in_corridor needs a central_path");
  if (settings.alpha == 0.0 && !has_risk) bad("alpha = 0 needs a central_path for the risk term");
  check_point(problem, settings, problem.start, "start");
  check_point(problem, settings, problem.goal, "goal");

  ompl::msg::setLogLevel(ompl::msg::LOG_ERROR);
  const PlanningMap& map = problem.map;
  const RiskField risk(problem.central_path, problem.zones);
  const RiskField* corridor = settings.stay_in_corridor ? &risk : nullptr;

  auto space = std::make_shared<ob::RealVectorStateSpace>(2);
  ob::RealVectorBounds bounds(2);
  bounds.setLow(0, map.lower.x());
  bounds.setLow(1, map.lower.y());
  bounds.setHigh(0, map.upper.x());
  bounds.setHigh(1, map.upper.y());
  space->setBounds(bounds);
  const std::uint_fast32_t sampler_seed = derive_seed(settings.seed, 0);
  space->setStateSamplerAllocator(
      [sampler_seed](const ob::StateSpace* s) { return std::make_shared<SeededSampler>(s, sampler_seed); });
  space->setLongestValidSegmentFraction(settings.resolution / space->getMaximumExtent());

  auto si = std::make_shared<ob::SpaceInformation>(space);
  si->setStateValidityChecker(std::make_shared<Checker>(si, map, corridor, problem.zones.half_width));
  si->setMotionValidator(
      std::make_shared<MotionChecker>(si, map, corridor, problem.zones.half_width, settings.resolution));
  si->setup();

  // α·length + β·∫WRS (eqs. 16, 19) as a sum of OMPL objectives.
  ob::OptimizationObjectivePtr length = std::make_shared<ob::PathLengthOptimizationObjective>(si);
  ob::OptimizationObjectivePtr objective;
  if (settings.beta == 0.0 || !has_risk) {
    objective = settings.alpha == 1.0 ? length : settings.alpha * length;
  } else {
    ob::OptimizationObjectivePtr wrs_term = std::make_shared<WrsObjective>(si, risk);
    objective = settings.alpha == 0.0 ? settings.beta * wrs_term : settings.alpha * length + settings.beta * wrs_term;
  }
  // Never "good enough": optimise until the budget is spent.
  objective->setCostThreshold(ob::Cost(-std::numeric_limits<double>::infinity()));

  auto pdef = std::make_shared<ob::ProblemDefinition>(si);
  ob::ScopedState<ob::RealVectorStateSpace> start(space), goal(space);
  start[0] = problem.start.x();
  start[1] = problem.start.y();
  goal[0] = problem.goal.x();
  goal[1] = problem.goal.y();
  pdef->setStartAndGoalStates(start, goal, settings.goal_tolerance);
  pdef->setOptimizationObjective(objective);

  auto planner = std::make_shared<SeededRRTstar>(si, derive_seed(settings.seed, 1));
  if (settings.range > 0.0) planner->setRange(settings.range);
  planner->setGoalBias(settings.goal_bias);
  // Radius neighbourhoods (r ≤ range) instead of k-nearest: no long edges, each
  // costing a full WRS integral, while the tree is sparse.
  planner->setKNearest(false);
  planner->setProblemDefinition(pdef);
  planner->setup();

  PlanResult result;
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

  const bool exact = status == ob::PlannerStatus::EXACT_SOLUTION && pdef->hasExactSolution();
  const bool approximate = !exact && pdef->hasSolution() && settings.allow_approximate;
  if (!exact && !approximate) {
    result.status = PlanStatus::NoPath;
    result.path.resize(0, 2);
    result.cost = PathCost{};
    return result;
  }
  auto path = std::static_pointer_cast<og::PathGeometric>(pdef->getSolutionPath());
  og::PathGeometric solution(*path);
  Points2 points = to_points(solution);
  if (settings.smooth && solution.getStateCount() > 2) {
    SeededSimplifier simplifier(si, objective, derive_seed(settings.seed, 2));
    og::PathGeometric smoothed(solution);
    // Cost-aware shortcuts (the objective judges every shortcut), then a
    // dense re-check: the smoothed path is kept only if it is free and cheaper.
    simplifier.shortcutPath(smoothed);
    if (settings.beta == 0.0 || !has_risk) simplifier.reduceVertices(smoothed);
    const Points2 candidate = to_points(smoothed);
    bool ok = path_is_free(map, candidate);
    if (ok && corridor) {
      for (Eigen::Index i = 0; ok && i + 1 < candidate.rows(); ++i) {
        const Vec2 a(candidate(i, 0), candidate(i, 1)), b(candidate(i + 1, 0), candidate(i + 1, 1));
        const unsigned int n = std::max(1u, segment_count((b - a).norm(), settings.resolution));
        for (unsigned int j = 0; ok && j <= n; ++j) {
          const Vec2 q = a + (static_cast<double>(j) / n) * (b - a);
          ok = risk.deviation(q.x(), q.y()) <= problem.zones.half_width;
        }
      }
    }
    if (ok && path_cost(candidate, problem, settings).total <= path_cost(points, problem, settings).total)
      points = candidate;
  }
  result.status = exact ? PlanStatus::Exact : PlanStatus::Approximate;
  result.success = exact;
  result.path = points;
  result.cost = path_cost(points, problem, settings);
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
  const Points2& path = problem.central_path;
  const double total = path_arc_length(path);
  double s = arc_length_of_projection(path, position) + lookahead;
  Vec2 goal = point_at_arc_length(path, s);
  // Slide the goal past whatever blocks it (Algorithm 4: a point ahead on the safe path).
  while (!point_is_free(problem.map, goal) && s < total) {
    s += settings.resolution;
    goal = point_at_arc_length(path, s);
  }
  if (!point_is_free(problem.map, goal))
    bad("no free point on the central path ahead of " + fmt(position) + " (the path's end " + fmt(goal) +
        " is blocked)");
  return replan_to(problem, position, goal, settings);
}

}  // namespace safenav
