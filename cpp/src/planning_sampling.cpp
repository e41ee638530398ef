// The planner's samplers: seeded uniform / corridor-biased sampling, and
// informed sampling in the ellipse that bounds the states able to improve the
// best RAw-RRT* path (see planning_internal.hpp).
#include <algorithm>
#include <cmath>
#include <limits>

#include <boost/math/constants/constants.hpp>
#include <ompl/base/ProblemDefinition.h>

#include "planning_internal.hpp"

namespace safenav::planning_detail {

namespace {
double* values(ob::State* s) { return s->as<ob::RealVectorStateSpace::StateType>()->values; }
}  // namespace

// ---------------------------------------------------------------- seeded sampler
SeededSampler::SeededSampler(const ob::StateSpace* space, std::uint_fast32_t seed, const CentralPath* central,
                             double corridor_bias, double half_width)
    : ob::RealVectorStateSampler(space), central_(central), bias_(corridor_bias), half_width_(half_width) {
  rng_.setLocalSeed(seed);
}

bool SeededSampler::corridor_sample(Vec2& p) {
  if (!(bias_ > 0.0 && central_ && central_->length() > 0.0 && rng_.uniform01() < bias_)) return false;
  const double s = rng_.uniformReal(0.0, central_->length());
  const double offset = rng_.uniformReal(-half_width_, half_width_);
  const Vec2 t = central_->tangent_at(s);
  p = central_->point_at(s) + offset * Vec2(-t.y(), t.x());
  return true;
}

void SeededSampler::sampleUniform(ob::State* state) {
  Vec2 p;
  if (corridor_sample(p)) {
    double* v = values(state);
    v[0] = p.x();
    v[1] = p.y();
    space_->enforceBounds(state);
    return;
  }
  ob::RealVectorStateSampler::sampleUniform(state);
}

Vec2 SeededSampler::ellipse_sample(const Vec2& f1, const Vec2& f2, double D) {
  // Uniform in the unit disc, stretched to the semi-axes a = D/2 and
  // b = √(D² − c²)/2 (c = focal distance), turned onto the focal axis.
  const Vec2 axis = f2 - f1;
  const double c = axis.norm();
  const Vec2 u = c > 0.0 ? Vec2(axis / c) : Vec2(1.0, 0.0);
  const double r = std::sqrt(rng_.uniform01());
  const double phi = rng_.uniformReal(-boost::math::double_constants::pi, boost::math::double_constants::pi);
  const double x = 0.5 * D * r * std::cos(phi), y = 0.5 * std::sqrt(std::max(D * D - c * c, 0.0)) * r * std::sin(phi);
  return 0.5 * (f1 + f2) + x * u + y * Vec2(-u.y(), u.x());
}

bool SeededSampler::propose(ob::State* state, const Vec2& f1, const Vec2& f2, double D, Vec2& p) {
  const double c = (f2 - f1).norm();
  if (!(D >= c)) return false;
  const auto* space = space_->as<ob::RealVectorStateSpace>();
  const auto& bounds = space->getBounds();
  // Direct draws when the ellipse's area is below the field's, else uniform draws.
  const bool direct = boost::math::double_constants::pi * 0.25 * D * std::sqrt(D * D - c * c) < space->getMeasure();
  double* v = values(state);
  if (!corridor_sample(p)) {
    if (direct) {
      p = ellipse_sample(f1, f2, D);
    } else {
      ob::RealVectorStateSampler::sampleUniform(state);
      p = Vec2(v[0], v[1]);
    }
  }
  const bool in_field =
      p.x() >= bounds.low[0] && p.x() <= bounds.high[0] && p.y() >= bounds.low[1] && p.y() <= bounds.high[1];
  if (!in_field || (p - f1).norm() + (p - f2).norm() > D) return false;
  v[0] = p.x();
  v[1] = p.y();
  return true;
}

// ---------------------------------------------------------------- risk bound
WrsPrimitive::WrsPrimitive(const RiskZones& zones) : dmax_(zones.half_width) {
  constexpr int kCellsPerZone = 16;
  const int n = static_cast<int>(zones.weights.size());
  h_ = dmax_ / (n * kCellsPerZone);
  double w = 0.0;
  for (int k = 0; k < n * kCellsPerZone; ++k) {
    const double u = k * h_;
    // The smallest WRS in the cell is at its left end; the next double guards
    // a border that rounds into the zone before it.
    const double low = std::min(wrs(u, zones), wrs(std::nextafter(u, dmax_), zones));
    table_.push_back(w);
    left_.push_back(low);
    w += h_ * low;
  }
  table_.push_back(w);
  tail_ = wrs(dmax_, zones);
}

double WrsPrimitive::operator()(double d) const {
  if (!(d > 0.0)) return 0.0;
  if (d >= dmax_) return table_.back() + (d - dmax_) * tail_;
  const auto k = std::min(static_cast<std::size_t>(d / h_), left_.size() - 1);
  return table_[k] + (d - static_cast<double>(k) * h_) * left_[k];
}

// ---------------------------------------------------------------- informed sampler
CostBound::CostBound(double alpha, double beta, const CentralPath* risk, const Vec2& start, const Vec2& goal,
                     double goal_tolerance)
    : alpha_(alpha),
      beta_(risk && !risk->empty() ? beta : 0.0),
      tolerance_(goal_tolerance),
      risk_(risk),
      primitive_(risk ? risk->zones() : RiskZones{}),
      start_(start),
      goal_(goal) {
  if (beta_ > 0.0) {
    w_start_ = primitive_(risk_->deviation(start_));
    w_goal_ = primitive_(risk_->deviation(goal_));
  }
}

double CostBound::operator()(const Vec2& x) const {
  double h = alpha_ * std::max((x - start_).norm() + (x - goal_).norm() - tolerance_, 0.0);
  if (beta_ > 0.0) {
    const double w = primitive_(risk_->deviation(x));
    h += beta_ * (std::abs(w - w_start_) + std::abs(w - w_goal_));
  }
  return h;
}

EllipseInformedSampler::EllipseInformedSampler(const ob::ProblemDefinitionPtr& pdef, unsigned int attempts,
                                               const CostBound& bound)
    : ob::InformedSampler(pdef, attempts), bound_(bound) {
  // The space's sampler allocator gives the planner's seeded sampler (same seed, same stream).
  sampler_ = std::dynamic_pointer_cast<SeededSampler>(pdef->getSpaceInformation()->allocStateSampler());
  if (!sampler_) throw std::logic_error("informed sampling needs the planner's seeded sampler");
}

double EllipseInformedSampler::diameter(const ob::Cost& cost) const {
  const double alpha = bound_.alpha();
  if (!std::isfinite(cost.value()) || !(alpha > 0.0)) return std::numeric_limits<double>::infinity();
  return cost.value() / alpha + bound_.tolerance();
}

bool EllipseInformedSampler::sampleUniform(ob::State* state, const ob::Cost& max_cost) {
  const double c = max_cost.value();
  return sampler_->sample_within(state, bound_.start(), bound_.goal(), diameter(max_cost), numIters_,
                                 [this, c](const Vec2& x) { return bound_(x) <= c; });
}

bool EllipseInformedSampler::sampleUniform(ob::State* state, const ob::Cost&, const ob::Cost& max_cost) {
  return sampleUniform(state, max_cost);  // the ring between two costs is not needed by RRT*
}

double EllipseInformedSampler::getInformedMeasure(const ob::Cost& current_cost) const {
  const double field = space_->getMeasure(), D = diameter(current_cost);
  const double c = (bound_.goal() - bound_.start()).norm();
  if (!std::isfinite(D)) return field;
  if (!(D >= c)) return 0.0;
  return std::min(field, boost::math::double_constants::pi * 0.25 * D * std::sqrt(D * D - c * c));
}

}  // namespace safenav::planning_detail
