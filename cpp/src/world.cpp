// The map and its collision checker [SafeNav-ext §V-A3(ii)] (= [SafeNav-conf §V-A.2(ii)]).  See world.hpp.
#include "safenav/world.hpp"
#include "declare.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "cgal_util.hpp"
#include "errors.hpp"
#include "sight.hpp"

namespace safenav {

template <>
const ParamSet<PlanningMap>& param_set<PlanningMap>();  // defined below
template <>
const ParamSet<Inflation>& param_set<Inflation>();  // defined below
namespace {

using Vec2 = Eigen::Vector2d;

using detail::bad;
using detail::fmt;

using sight::open_polygon;
using sight::segment_point_distance2;

Vec2 row(const Eigen::Ref<const Points2>& p, Eigen::Index i) { return Vec2(p(i, 0), p(i, 1)); }

void check_finite(const Eigen::Ref<const Points2>& p, const char* what) {
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    if (!p.row(i).allFinite())
      bad(std::string(what) + " " + std::to_string(i) + " " + fmt(row(p, i)) + " is not finite");
}

void check_margin(double margin) {
  if (!(margin >= 0.0) || !std::isfinite(margin)) bad("margin must be finite and >= 0, got " + std::to_string(margin));
}

// One disc or simple polygon as CGAL objects, built once (sight::Occluder:
// its bounding circle, vertex mean and farthest vertex, for a cheap reject).
// A point or segment touches the shape grown by `grow` when it is inside or
// on the polygon (CGAL::bounded_side_2), crosses an edge (CGAL::do_intersect)
// or comes within `grow` of it (CGAL::squared_distance).  Whether it hides one
// point from another is the shared sight predicate, sight::Occluder::hides.
class Shape : public sight::Occluder {
 public:
  explicit Shape(const CircleObstacle& c) : Occluder(c.center, c.radius) {}
  explicit Shape(const Points2& raw) : Occluder(open_polygon(raw)) {}
  using Occluder::contains;

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

  // Length of the segment a–b inside the shape (boundary included): cut at
  // every boundary crossing, classify each piece at its midpoint.
  double length_inside(const Vec2& a, const Vec2& b) const {
    const Vec2 d = b - a;
    const double L = d.norm();
    if (L == 0.0) return 0.0;
    if (disc_) {
      // |a + t·d − c|² = r²: t = (−B ± √disc) / A, clipped to [0, 1].
      const Vec2 f = a - center_;
      const double A = d.squaredNorm(), B = f.dot(d), C = f.squaredNorm() - radius_ * radius_;
      const double disc = B * B - A * C;
      if (disc <= 0.0) return 0.0;  // misses, or tangent (one point: no length)
      const double s = std::sqrt(disc);
      const double t0 = std::max(0.0, (-B - s) / A), t1 = std::min(1.0, (-B + s) / A);
      return t1 > t0 ? (t1 - t0) * L : 0.0;
    }
    if (segment_point_distance2(a, b, center_) > cull2(0.0)) return 0.0;
    auto cross = [](const Vec2& u, const Vec2& v) { return u.x() * v.y() - u.y() * v.x(); };
    // Extra cut points only split a piece in two; a missed one would
    // misclassify a piece, so the tolerances err on the side of cutting.
    const double tol = 1e-9;
    std::vector<double> cuts{0.0, 1.0};
    auto cut = [&cuts](double t) {
      if (t > 0.0 && t < 1.0) cuts.push_back(t);
    };
    const std::size_t n = polygon_.size();
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2 p(polygon_[i].x(), polygon_[i].y());
      const Vec2 q(polygon_[(i + 1) % n].x(), polygon_[(i + 1) % n].y());
      const Vec2 e = q - p, w = p - a;
      const double den = cross(d, e);
      const double scale = L * std::max(e.norm(), 1e-300);
      if (std::abs(den) > tol * scale) {
        const double u = cross(w, d) / den;  // along the edge
        if (u >= -tol && u <= 1.0 + tol) cut(cross(w, e) / den);
      }
      // An end of the edge on (or next to) the segment's line: collinear and
      // nearly parallel edges (skipped above), vertex hits.  An edge that
      // crosses the line at an angle below tol has both ends within tol·|e|.
      const double near = tol * (1.0 + w.norm() + e.norm());
      if (std::abs(cross(w, d)) <= near * L) cut(w.dot(d) / (L * L));
      const Vec2 wq = q - a;
      if (std::abs(cross(wq, d)) <= near * L) cut(wq.dot(d) / (L * L));
    }
    std::sort(cuts.begin(), cuts.end());
    double inside = 0.0;
    for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
      const double t0 = cuts[i], t1 = cuts[i + 1];
      if (t1 <= t0) continue;
      if (cgal::inside_or_on(polygon_, cgal::point(a + (0.5 * (t0 + t1)) * d))) inside += (t1 - t0) * L;
    }
    return inside;
  }

  // A lower bound on distance(): the bounding circle's (0 inside it).
  double distance_bound(const Vec2& a, const Vec2& b) const {
    return std::max(0.0, std::sqrt(segment_point_distance2(a, b, center_)) - radius_);
  }

  // Distance from the segment a–b to the shape (0 when it touches it).
  double distance(const cgal::Segment& ab) const {
    if (disc_) return std::max(0.0, std::sqrt(CGAL::squared_distance(cgal::point(center_), ab)) - radius_);
    if (cgal::inside_or_on(polygon_, ab.source())) return 0.0;
    double d2 = std::numeric_limits<double>::infinity();
    for (const auto& e : edges_) {
      if (CGAL::do_intersect(ab, e)) return 0.0;
      d2 = std::min(d2, CGAL::to_double(CGAL::squared_distance(ab, e)));
    }
    return std::sqrt(d2);
  }

 private:
  // Squared radius beyond which nothing touches the polygon grown by `grow`.
  // The slack keeps the farthest vertex itself inside: radius_ = √d², and
  // radius_² can round below d².
  double cull2(double grow) const {
    const double r = radius_ + grow;
    return r * r * (1.0 + 1e-12);
  }
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
      if (h.risk >= map.forbidden_risk) forbidden.push_back(hazards.back());
    }
  }

  bool point_free(const Vec2& p) const {
    if (!map.in_field(p)) return false;
    for (const auto& s : obstacles)
      if (s.contains(p, map.clearance)) return false;
    for (const auto& s : forbidden)
      if (s.contains(p, map.clearance)) return false;
    return true;
  }

  bool segment_free(const Vec2& a, const Vec2& b) const {
    // The field is convex: both ends inside means the whole segment is.
    if (!map.in_field(a) || !map.in_field(b)) return false;
    const cgal::Segment ab(cgal::point(a), cgal::point(b));
    for (const auto& s : obstacles)
      if (s.touches(ab, a, b, map.clearance)) return false;
    for (const auto& s : forbidden)
      if (s.touches(ab, a, b, map.clearance)) return false;
    return true;
  }

  bool line_of_sight(const Vec2& a, const Vec2& b) const {
    if (a == b) return true;  // no obstacle lies between a point and itself
    const sight::Sight s(a, b);
    for (const auto& o : obstacles)
      if (o.hides(s)) return false;
    return true;
  }

  PlanningMap map;
  std::vector<Shape> obstacles;  // circles, then polygons
  std::vector<Shape> hazards;    // in map.hazards' order
  std::vector<Shape> forbidden;  // the hazards with risk >= map.forbidden_risk
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
  if (!(forbidden_risk > 0.0) || std::isnan(forbidden_risk))
    bad("forbidden_risk must be > 0, got " + std::to_string(forbidden_risk));
  param_set<PlanningMap>().check(*this);
}

void Inflation::validate() const { param_set<Inflation>().check(*this); }

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

std::size_t ObstacleChecker::hazard_count() const { return impl_->hazards.size(); }

Eigen::VectorXd ObstacleChecker::hazard_lengths(const Vec2& a, const Vec2& b) const {
  if (!a.allFinite() || !b.allFinite()) bad("segment " + fmt(a) + "–" + fmt(b) + " is not finite");
  const auto& hz = impl_->hazards;
  Eigen::VectorXd out(static_cast<Eigen::Index>(hz.size()));
  for (std::size_t k = 0; k < hz.size(); ++k) out[static_cast<Eigen::Index>(k)] = hz[k].length_inside(a, b);
  return out;
}

double ObstacleChecker::hazard_integral(const Vec2& a, const Vec2& b) const {
  const auto& hz = impl_->hazards;
  double sum = 0.0;
  for (std::size_t k = 0; k < hz.size(); ++k) sum += impl_->map.hazards[k].risk * hz[k].length_inside(a, b);
  return sum;
}

bool ObstacleChecker::line_of_sight(const Vec2& a, const Vec2& b) const {
  if (!a.allFinite()) bad("line of sight: a = " + fmt(a) + " is not finite");
  if (!b.allFinite()) bad("line of sight: b = " + fmt(b) + " is not finite");
  return impl_->line_of_sight(a, b);
}

Eigen::Matrix<bool, Eigen::Dynamic, 1> ObstacleChecker::visible_from(const Vec2& from,
                                                                     const Eigen::Ref<const Points2>& targets) const {
  if (!from.allFinite()) bad("visible_from: from = " + fmt(from) + " is not finite");
  check_finite(targets, "target");
  Eigen::Matrix<bool, Eigen::Dynamic, 1> out(targets.rows());
  for (Eigen::Index i = 0; i < targets.rows(); ++i) out[i] = impl_->line_of_sight(from, row(targets, i));
  return out;
}

namespace {
// The least distance from the segment a–b to `shapes`, below `d`; shapes whose
// bounding circle is no nearer than the best so far are skipped.
double nearest(const std::vector<Shape>& shapes, const Vec2& a, const Vec2& b, double d) {
  const cgal::Segment ab(cgal::point(a), cgal::point(b));
  for (const auto& s : shapes)
    if (s.distance_bound(a, b) < d) d = std::min(d, s.distance(ab));
  return d;
}
}  // namespace

double ObstacleChecker::obstacle_distance(const Vec2& a, const Vec2& b) const {
  if (!a.allFinite() || !b.allFinite()) bad("segment " + fmt(a) + "–" + fmt(b) + " is not finite");
  return nearest(impl_->obstacles, a, b, std::numeric_limits<double>::infinity());
}

ObstacleChecker::HazardStep ObstacleChecker::hazard_step(const Vec2& a, const Vec2& b) const {
  if (!a.allFinite() || !b.allFinite()) bad("segment " + fmt(a) + "–" + fmt(b) + " is not finite");
  const auto& hz = impl_->hazards;
  HazardStep out;
  for (std::size_t k = 0; k < hz.size(); ++k) {
    const double len = hz[k].length_inside(a, b);
    out.length += len;
    out.exposure += impl_->map.hazards[k].risk * len;
    out.inside = out.inside || hz[k].contains(b, 0.0);
  }
  return out;
}

double ObstacleChecker::keep_out_distance(const Vec2& a, const Vec2& b) const {
  return nearest(impl_->forbidden, a, b, obstacle_distance(a, b));
}

PathSafety path_safety(const Eigen::Ref<const Points2>& path, const PlanningMap& map) {
  check_finite(path, "path point");
  const ObstacleChecker checker(map);
  PathSafety out;
  out.hazard_length = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(map.hazards.size()));
  out.min_clearance = std::numeric_limits<double>::infinity();
  if (path.rows() == 1) out.min_clearance = checker.obstacle_distance(row(path, 0), row(path, 0));
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i) {
    const Vec2 a = row(path, i), b = row(path, i + 1);
    out.length += (b - a).norm();
    out.min_clearance = std::min(out.min_clearance, checker.obstacle_distance(a, b));
    out.hazard_length += checker.hazard_lengths(a, b);
  }
  for (std::size_t k = 0; k < map.hazards.size(); ++k)
    out.exposure += map.hazards[k].risk * out.hazard_length[static_cast<Eigen::Index>(k)];
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


// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<PlanningMap>& param_set<PlanningMap>() {
  static const ParamSet<PlanningMap> s =
      Declare<PlanningMap>{}
          .real("clearance", SN_REF(PlanningMap, clearance), "m", closed(0, 100), "planned paths keep this far from every obstacle")
          .real("forbidden_risk", SN_REF(PlanningMap, forbidden_risk), "", above(0, 1e6), "hazards with risk >= this are obstacles; above 1 = none (the paper)")
          .set;
  return s;
}

template <>
const ParamSet<Inflation>& param_set<Inflation>() {
  static const ParamSet<Inflation> s =
      Declare<Inflation>{}
          .real("vehicle_radius", SN_REF(Inflation, vehicle_radius), "m", closed(0, 50), "the vehicle's radius; clearance = vehicle_radius + margin")
          .real("margin", SN_REF(Inflation, margin), "m", closed(0, 50), "distance kept beyond the vehicle's body; clearance = vehicle_radius + margin")
          .set;
  return s;
}

template class ParamSet<PlanningMap>;
template class ParamSet<Inflation>;

}  // namespace safenav
