// safenav/geometry — planar geometry on CGAL: convex hulls (convex_hull_2),
// point location (bounded_side_2), simple polygons (is_simple_2).
#include "safenav/geometry.hpp"

#include <iterator>
#include <stdexcept>

#include <CGAL/convex_hull_2.h>

#include "cgal_util.hpp"

namespace safenav {

namespace {

using cgal::K;
using cgal::Point;
using cgal::from_cgal;
using cgal::inside_or_on;
using cgal::to_cgal;

}  // namespace

// ------------------------------------------------------------- free functions

Points2 convex_hull(const Eigen::Ref<const Points2>& points) {
  check_points(points, "convex_hull input", 1);
  const std::vector<Point> in = to_cgal(points);
  std::vector<Point> out;
  CGAL::convex_hull_2(in.begin(), in.end(), std::back_inserter(out), K());
  return from_cgal(out);
}

BoolVector points_in_polygon(const Eigen::Ref<const Points2>& points, const Eigen::Ref<const Points2>& polygon) {
  check_points(points, "points", 0);
  check_points(polygon, "polygon", 3);
  const std::vector<Point> poly = to_cgal(polygon);
  if (!CGAL::is_simple_2(poly.begin(), poly.end(), K()))
    throw std::invalid_argument("polygon is not simple (its edges cross or it has repeated vertices)");
  BoolVector out(points.rows());
  for (Eigen::Index i = 0; i < points.rows(); ++i) out[i] = inside_or_on(poly, Point(points(i, 0), points(i, 1)));
  return out;
}

bool is_simple_polygon(const Eigen::Ref<const Points2>& polygon) {
  check_points(polygon, "polygon", 3);
  const std::vector<Point> poly = to_cgal(polygon);
  return CGAL::is_simple_2(poly.begin(), poly.end(), K());
}

}  // namespace safenav
