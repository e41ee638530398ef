// Internal (not installed): the CGAL kernel and Eigen <-> CGAL conversions
// shared by geometry.cpp and planning.cpp.  Public headers stay CGAL-free.
#pragma once

#include <vector>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2_algorithms.h>
#include <Eigen/Core>

#include "safenav/metrics.hpp"

namespace safenav {
namespace cgal {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_2;
using Segment = K::Segment_2;

inline Point point(const Eigen::Vector2d& p) { return Point(p.x(), p.y()); }

inline std::vector<Point> to_cgal(const Eigen::Ref<const Points2>& p) {
  std::vector<Point> out;
  out.reserve(static_cast<size_t>(p.rows()));
  for (Eigen::Index i = 0; i < p.rows(); ++i) out.emplace_back(p(i, 0), p(i, 1));
  return out;
}

inline Points2 from_cgal(const std::vector<Point>& pts) {
  Points2 out(static_cast<Eigen::Index>(pts.size()), 2);
  for (size_t i = 0; i < pts.size(); ++i) {
    out(static_cast<Eigen::Index>(i), 0) = pts[i].x();
    out(static_cast<Eigen::Index>(i), 1) = pts[i].y();
  }
  return out;
}

/// Inside or on the boundary of a polygon (CGAL::bounded_side_2).
inline bool inside_or_on(const std::vector<Point>& poly, const Point& q) {
  return CGAL::bounded_side_2(poly.begin(), poly.end(), q, K()) != CGAL::ON_UNBOUNDED_SIDE;
}

}  // namespace cgal
}  // namespace safenav
