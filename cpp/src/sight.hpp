// Internal (not installed): the one line-of-sight predicate, shared by the
// world's ObstacleChecker::line_of_sight / visible_from (world.cpp) and by
// landmark placement's sight test and shadows (placement_shadows.cpp).  The
// papers model no occlusion; the rule is ours (see world.hpp):
//
//   b is seen from a unless an obstacle that contains neither a nor b
//   (boundary included) meets the closed segment a–b.
//
// Every answer is exact on the double inputs, at any finite coordinates:
// polygons by CGAL's exact predicates (bounded_side_2, do_intersect), discs by
// the sign of closed-form polynomials in the inputs, evaluated in interval
// arithmetic (CGAL::Interval_nt, which rounds outward) and exactly
// (CGAL::MP_Float) when the interval cannot decide.  Cheap double filters
// come first; they decide only when the double result is farther from the
// threshold than 1e-9 of the largest coordinate, a margin millions of times
// their rounding error, and they stand aside when the coordinates are too
// large to square in a double.
//
// Symmetric by construction: a Sight puts its ends in lexicographic order
// before anything is computed, so (a, b) and (b, a) run the very same
// arithmetic.
#pragma once

#include <algorithm>
#include <vector>

#include <Eigen/Core>

#include "cgal_util.hpp"
#include "safenav/types.hpp"

namespace safenav::sight {

using Vec2 = Eigen::Vector2d;

/// A polygon with a repeated closing vertex removed.
inline Points2 open_polygon(const Points2& poly) {
  if (poly.rows() > 1 && poly.row(0) == poly.row(poly.rows() - 1)) return poly.topRows(poly.rows() - 1);
  return poly;
}

/// The squared distance from p to the closed segment a–b, in doubles.
inline double segment_point_distance2(const Vec2& a, const Vec2& b, const Vec2& p) {
  const Vec2 ab = b - a;
  const double L2 = ab.squaredNorm();
  const double t = L2 > 0.0 ? std::clamp((p - a).dot(ab) / L2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).squaredNorm();
}

/// The segment p–q with its ends in lexicographic order (x, then y), its
/// bounding box and the largest |coordinate| of its ends.
struct Sight {
  Sight(const Vec2& p, const Vec2& q);
  Vec2 a, b;  ///< a ≤ b lexicographically
  Vec2 lo, hi;
  double scale;
  cgal::Segment ab;
};

/// p lies in the closed disc (c, r): |p − c|² ≤ r², exact.
bool in_disc(const Vec2& c, double r, const Vec2& p);
/// The closed segment p–q meets the closed disc (c, r), exact and symmetric in p, q.
bool disc_meets_segment(const Vec2& c, double r, const Vec2& p, const Vec2& q);

/// One obstacle prepared for sight queries: a disc, or a simple polygon
/// (open, ≥ 3 vertices) with its edges and its bounding circle (vertex mean,
/// farthest vertex), built once.
class Occluder {
 public:
  Occluder(const Vec2& center, double radius);
  explicit Occluder(const Points2& open);
  /// p lies in it (boundary included), exact.
  bool contains(const Vec2& p) const;
  /// It hides s.b from s.a: it meets the closed segment and contains neither end.
  bool hides(const Sight& s) const;

  bool is_disc() const { return disc_; }
  const Vec2& center() const { return center_; }  ///< the disc's, or the polygon's bounding circle's
  double radius() const { return radius_; }       ///< likewise
  const std::vector<cgal::Point>& vertices() const { return polygon_; }
  const std::vector<cgal::Segment>& edges() const { return edges_; }

 protected:
  bool disc_;
  Vec2 center_;
  double radius_;
  Vec2 lo_, hi_;  // bounding box
  double scale_;  // max(1, radius, |coordinate| of the centre and the box)
  std::vector<cgal::Point> polygon_;
  std::vector<cgal::Segment> edges_;

 private:
  bool apart(const Sight& s) const;
};

/// Whether one of the occluders hides s.b from s.a.
bool blocked(const std::vector<Occluder>& occluders, const Sight& s);

}  // namespace safenav::sight
