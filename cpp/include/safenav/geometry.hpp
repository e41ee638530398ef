// safenav/geometry.hpp — planar geometry on CGAL: convex hulls, point in
// polygon, simple polygons.  The safe-path corridor and its segments are
// corridor.hpp's.
//
// Only Eigen and std types appear here; CGAL (convex hulls, orientation and
// point location) stays inside geometry.cpp.
#pragma once

#include <Eigen/Core>

#include "safenav/types.hpp"

namespace safenav {

/// Convex hull of a point set (CGAL::convex_hull_2): the extreme points in
/// counter-clockwise order, collinear boundary points dropped.  The vertices
/// are a subset of the input rows.  Needs ≥ 1 finite point.
Points2 convex_hull(const Eigen::Ref<const Points2>& points);

/// For each point: inside or on the boundary of the simple polygon `polygon`
/// (CGAL::bounded_side_2).  The polygon needs ≥ 3 vertices, in either order.
BoolVector points_in_polygon(const Eigen::Ref<const Points2>& points, const Eigen::Ref<const Points2>& polygon);

}  // namespace safenav

namespace safenav {

/// Whether the open polygon (≥ 3 vertices, either orientation) is simple: no
/// repeated vertex, and no two edges meet except adjacent ones at their shared
/// vertex (CGAL::is_simple_2, an O(n log n) sweep with exact predicates).
bool is_simple_polygon(const Eigen::Ref<const Points2>& polygon);

}  // namespace safenav
