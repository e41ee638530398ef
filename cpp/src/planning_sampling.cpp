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

bool SeededSampler::sample_within(ob::State* state, const Vec2& f1, const Vec2& f2, double D,
                                  unsigned int attempts) {
  if (!std::isfinite(D)) {
    sampleUniform(state);
    return true;
  }
  const double c = (f2 - f1).norm();
  if (!(D >= c)) return false;
  const auto* space = space_->as<ob::RealVectorStateSpace>();
  const auto& bounds = space->getBounds();
  // Direct draws when the ellipse's area is below the field's, else rejection.
  const double ellipse_area = boost::math::double_constants::pi * 0.25 * D * std::sqrt(D * D - c * c);
  const bool direct = ellipse_area < space->getMeasure();
  double* v = values(state);
  for (unsigned int i = 0; i < attempts; ++i) {
    Vec2 p;
    if (!corridor_sample(p)) {
      if (direct) {
        p = ellipse_sample(f1, f2, D);
      } else {
        ob::RealVectorStateSampler::sampleUniform(state);
        p = Vec2(v[0], v[1]);
      }
    }
    const bool in_field = p.x() >= bounds.low[0] && p.x() <= bounds.high[0] && p.y() >= bounds.low[1] &&
                          p.y() <= bounds.high[1];
    if (in_field && (p - f1).norm() + (p - f2).norm() <= D) {
      v[0] = p.x();
      v[1] = p.y();
      return true;
    }
  }
  return false;
}

// ---------------------------------------------------------------- informed sampler
EllipseInformedSampler::EllipseInformedSampler(const ob::ProblemDefinitionPtr& pdef, unsigned int attempts,
                                               double alpha, const Vec2& start, const Vec2& goal,
                                               double goal_tolerance)
    : ob::InformedSampler(pdef, attempts), alpha_(alpha), tolerance_(goal_tolerance), start_(start), goal_(goal) {
  // The space's sampler allocator gives the planner's seeded sampler (same seed, same stream).
  sampler_ = std::dynamic_pointer_cast<SeededSampler>(pdef->getSpaceInformation()->allocStateSampler());
  if (!sampler_) throw std::logic_error("informed sampling needs the planner's seeded sampler");
}

double EllipseInformedSampler::diameter(const ob::Cost& cost) const {
  if (!std::isfinite(cost.value()) || !(alpha_ > 0.0)) return std::numeric_limits<double>::infinity();
  return cost.value() / alpha_ + tolerance_;
}

bool EllipseInformedSampler::sampleUniform(ob::State* state, const ob::Cost& max_cost) {
  return sampler_->sample_within(state, start_, goal_, diameter(max_cost), numIters_);
}

bool EllipseInformedSampler::sampleUniform(ob::State* state, const ob::Cost&, const ob::Cost& max_cost) {
  return sampleUniform(state, max_cost);  // the ring between two costs is not needed by RRT*
}

double EllipseInformedSampler::getInformedMeasure(const ob::Cost& current_cost) const {
  const double field = space_->getMeasure(), D = diameter(current_cost), c = (goal_ - start_).norm();
  if (!std::isfinite(D)) return field;
  if (!(D >= c)) return 0.0;
  return std::min(field, boost::math::double_constants::pi * 0.25 * D * std::sqrt(D * D - c * c));
}

}  // namespace safenav::planning_detail
