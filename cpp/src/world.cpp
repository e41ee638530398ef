// The map and its collision checker [SafeNav-ext §V-A3(ii)] (= [SafeNav-conf §V-A.2(ii)]).  See world.hpp.
#include "safenav/world.hpp"
#include "safenav/params.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "cgal_util.hpp"
#include "errors.hpp"

namespace safenav {
namespace {

using Vec2 = Eigen::Vector2d;

using detail::bad;
using detail::fmt;

// Polygon with a repeated closing vertex removed.
Points2 open_polygon(const Points2& poly) {
  if (poly.rows() > 1 && poly.row(0) == poly.row(poly.rows() - 1)) return poly.topRows(poly.rows() - 1);
  return poly;
}

double segment_point_distance2(const Vec2& a, const Vec2& b, const Vec2& p) {
  const Vec2 ab = b - a;
  const double L2 = ab.squaredNorm();
  const double t = L2 > 0.0 ? std::clamp((p - a).dot(ab) / L2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).squaredNorm();
}

Vec2 row(const Eigen::Ref<const Points2>& p, Eigen::Index i) { return Vec2(p(i, 0), p(i, 1)); }

void check_finite(const Eigen::Ref<const Points2>& p, const char* what) {
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    if (!p.row(i).allFinite())
      bad(std::string(what) + " " + std::to_string(i) + " " + fmt(row(p, i)) + " is not finite");
}

void check_margin(double margin) {
  if (!(margin >= 0.0) || !std::isfinite(margin)) bad("margin must be finite and >= 0, got " + std::to_string(margin));
}

// One disc or simple polygon as CGAL objects, built once.  A point or segment
// touches the shape grown by `grow` when it is inside or on the polygon
// (CGAL::bounded_side_2), crosses an edge (CGAL::do_intersect) or comes
// within `grow` of it (CGAL::squared_distance).
class Shape {
 public:
  explicit Shape(const CircleObstacle& c) : disc_(true), center_(c.center), radius_(c.radius) {}
  explicit Shape(const Points2& raw) : disc_(false) {
    const Points2 open = open_polygon(raw);
    polygon_ = cgal::to_cgal(open);
    for (std::size_t i = 0; i < polygon_.size(); ++i)
      edges_.emplace_back(polygon_[i], polygon_[(i + 1) % polygon_.size()]);
    // Bounding circle (vertex mean, farthest vertex) for a cheap reject.
    center_ = open.colwise().mean().transpose();
    radius_ = (open.rowwise() - center_.transpose()).rowwise().norm().maxCoeff();
  }

  bool contains(const Vec2& p, double grow) const {
    if (disc_) return (p - center_).norm() <= radius_ + grow;
    if ((p - center_).squaredNorm() > cull2(grow)) return false;
    const cgal::Point q = cgal::point(p);
    if (cgal::inside_or_on(polygon_, q)) return true;
    for (const auto& e : edges_)
      if (CGAL::squared_distance(q, e) <= grow * grow) return true;
    return false;
  }

  bool touches(const cgal::Segment& ab, const Vec2& a, const Vec2& b, double grow) const {
    if (disc_) {
      const double r = radius_ + grow;
      return CGAL::squared_distance(cgal::point(center_), ab) <= r * r;
    }
    if (segment_point_distance2(a, b, center_) > cull2(grow)) return false;
    // A segment inside the polygon touches no edge.
    if (cgal::inside_or_on(polygon_, ab.source())) return true;
    for (const auto& e : edges_)
      if (CGAL::do_intersect(ab, e) || CGAL::squared_distance(ab, e) <= grow * grow) return true;
    return false;
  }

 private:
  // Squared radius beyond which nothing touches the polygon grown by `grow`.
  // The slack keeps the farthest vertex itself inside: radius_ = √d², and
  // radius_² can round below d².
  double cull2(double grow) const {
    const double r = radius_ + grow;
    return r * r * (1.0 + 1e-12);
  }

  bool disc_;
  Vec2 center_;    // the disc's, or the polygon's bounding circle's
  double radius_;  // likewise
  std::vector<cgal::Point> polygon_;
  std::vector<cgal::Segment> edges_;
};

// A map's obstacles (circles, then polygons) and hazards, built once.
class Obstacles {
 public:
  explicit Obstacles(const PlanningMap& m) : map(m) {
    for (const auto& c : map.circles) obstacles.emplace_back(c);
    for (const auto& p : map.polygons) obstacles.emplace_back(p);
    for (const auto& h : map.hazards) {
      if (h.polygon.rows() == 0) hazards.emplace_back(h.disc);
      else hazards.emplace_back(h.polygon);
    }
  }

  bool point_free(const Vec2& p) const {
    if (!map.in_field(p)) return false;
    for (const auto& s : obstacles)
      if (s.contains(p, map.clearance)) return false;
    return true;
  }

  bool segment_free(const Vec2& a, const Vec2& b) const {
    // The field is convex: both ends inside means the whole segment is.
    if (!map.in_field(a) || !map.in_field(b)) return false;
    const cgal::Segment ab(cgal::point(a), cgal::point(b));
    for (const auto& s : obstacles)
      if (s.touches(ab, a, b, map.clearance)) return false;
    return true;
  }

  PlanningMap map;
  std::vector<Shape> obstacles;  // circles, then polygons
  std::vector<Shape> hazards;    // in map.hazards' order
};

}  // namespace

void PlanningMap::validate() const {
  if (!lower.allFinite() || !upper.allFinite()) bad("field bounds " + fmt(lower) + "–" + fmt(upper) + " are not finite");
  if (!(upper.x() > lower.x()) || !(upper.y() > lower.y()))
    bad("field upper corner " + fmt(upper) + " must exceed lower corner " + fmt(lower));
  if (!std::isfinite(clearance) || clearance < 0.0) bad("clearance must be >= 0, got " + std::to_string(clearance));
  auto check_circle = [](const CircleObstacle& c, const std::string& name) {
    if (!c.center.allFinite()) bad(name + " has non-finite center " + fmt(c.center));
    if (!std::isfinite(c.radius) || c.radius <= 0.0) bad(name + " radius must be > 0, got " + std::to_string(c.radius));
  };
  auto check_polygon = [](const Points2& raw, const std::string& name) {
    const Points2 p = open_polygon(raw);
    if (p.rows() < 3) bad(name + " needs >= 3 vertices, got " + std::to_string(p.rows()));
    if (!p.allFinite()) bad(name + " has a non-finite vertex");
  };
  for (std::size_t i = 0; i < circles.size(); ++i) check_circle(circles[i], "circle " + std::to_string(i));
  for (std::size_t i = 0; i < polygons.size(); ++i) check_polygon(polygons[i], "polygon " + std::to_string(i));
  for (std::size_t i = 0; i < hazards.size(); ++i) {
    const HazardZone& h = hazards[i];
    const std::string name = "hazard " + std::to_string(i);
    if (h.polygon.rows() == 0) check_circle(h.disc, name);
    else check_polygon(h.polygon, name);
    if (!(h.risk > 0.0 && h.risk <= 1.0)) bad(name + " risk must be in (0, 1], got " + std::to_string(h.risk));
  }
  param_set<PlanningMap>().check(*this);
}

bool PlanningMap::in_field(const Vec2& p) const {
  return p.x() >= lower.x() && p.x() <= upper.x() && p.y() >= lower.y() && p.y() <= upper.y();
}

struct ObstacleChecker::Impl : Obstacles {
  using Obstacles::Obstacles;
};

ObstacleChecker::ObstacleChecker(const PlanningMap& map) {
  map.validate();
  impl_ = std::make_shared<const Impl>(map);
}

bool ObstacleChecker::point_free(const Vec2& p) const {
  if (!p.allFinite()) bad("point " + fmt(p) + " is not finite");
  return impl_->point_free(p);
}

bool ObstacleChecker::segment_free(const Vec2& a, const Vec2& b) const {
  if (!a.allFinite() || !b.allFinite()) bad("segment " + fmt(a) + "–" + fmt(b) + " is not finite");
  return impl_->segment_free(a, b);
}

std::size_t ObstacleChecker::obstacle_count() const { return impl_->obstacles.size(); }

BoolMatrix ObstacleChecker::obstacles_at(const Eigen::Ref<const Points2>& points, double margin) const {
  check_finite(points, "point");
  check_margin(margin);
  const double grow = impl_->map.clearance + margin;
  const auto& shapes = impl_->obstacles;
  BoolMatrix out(points.rows(), static_cast<Eigen::Index>(shapes.size()));
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    for (std::size_t k = 0; k < shapes.size(); ++k)
      out(i, static_cast<Eigen::Index>(k)) = shapes[k].contains(row(points, i), grow);
  return out;
}

BoolMatrix ObstacleChecker::obstacles_hit(const Eigen::Ref<const Points2>& a, const Eigen::Ref<const Points2>& b,
                                          double margin) const {
  if (a.rows() != b.rows())
    bad("segments need as many start points as end points, got " + std::to_string(a.rows()) + " and " +
        std::to_string(b.rows()));
  check_finite(a, "segment start");
  check_finite(b, "segment end");
  check_margin(margin);
  const double grow = impl_->map.clearance + margin;
  const auto& shapes = impl_->obstacles;
  BoolMatrix out(a.rows(), static_cast<Eigen::Index>(shapes.size()));
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    const Vec2 p = row(a, i), q = row(b, i);
    const cgal::Segment pq(cgal::point(p), cgal::point(q));
    for (std::size_t k = 0; k < shapes.size(); ++k)
      out(i, static_cast<Eigen::Index>(k)) = p == q ? shapes[k].contains(p, grow) : shapes[k].touches(pq, p, q, grow);
  }
  return out;
}

Eigen::VectorXd ObstacleChecker::hazard_risk(const Eigen::Ref<const Points2>& points) const {
  check_finite(points, "point");
  const auto& hazards = impl_->map.hazards;
  Eigen::VectorXd out = Eigen::VectorXd::Zero(points.rows());
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    for (std::size_t k = 0; k < hazards.size(); ++k)
      if (hazards[k].risk > out[i] && impl_->hazards[k].contains(row(points, i), 0.0)) out[i] = hazards[k].risk;
  return out;
}

bool point_is_free(const PlanningMap& map, const Vec2& p) { return Obstacles(map).point_free(p); }

bool segment_is_free(const PlanningMap& map, const Vec2& a, const Vec2& b) {
  if (!a.allFinite() || !b.allFinite()) bad("segment " + fmt(a) + "–" + fmt(b) + " is not finite");
  return Obstacles(map).segment_free(a, b);
}

bool path_is_free(const PlanningMap& map, const Eigen::Ref<const Points2>& path) {
  const Obstacles obstacles(map);
  if (path.rows() == 1) return obstacles.point_free(row(path, 0));
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i) {
    const Vec2 a = row(path, i), b = row(path, i + 1);
    if (!a.allFinite() || !b.allFinite()) bad("segment " + fmt(a) + "–" + fmt(b) + " is not finite");
    if (!obstacles.segment_free(a, b)) return false;
  }
  return true;
}

}  // namespace safenav
