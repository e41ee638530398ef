// Landmark placement, occlusion (ours; the placement paper has no
// obstacles): the occluders' checks, the sight test and the shadows of the
// occluders on an edge as seen from a landmark.  See the header comment of
// safenav/placement.hpp for the convention.  The sight test is the world's
// (sight.hpp: one exact predicate for ObstacleChecker::line_of_sight and for
// placement), and the shadows' exact decisions are sight.hpp's predicates.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <CGAL/Exact_rational.h>

#include "cgal_util.hpp"
#include "errors.hpp"
#include "placement_internal.hpp"
#include "sight.hpp"

namespace safenav {
namespace placement_detail {
namespace {

using detail::fmt;
using Q = CGAL::Exact_rational;
using V2 = Eigen::Vector2d;
using sight::open_polygon;

double scale_of(std::initializer_list<V2> pts, double r = 0.0) {
  double s = std::max(1.0, r);
  for (const auto& p : pts) s = std::max(s, p.cwiseAbs().maxCoeff());
  return s;
}

struct Box {
  double x0, y0, x1, y1;
  bool overlaps(const Box& o) const { return x0 <= o.x1 && o.x0 <= x1 && y0 <= o.y1 && o.y0 <= y1; }
};
Box box_of(std::initializer_list<V2> pts) {
  Box b{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
        -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const auto& p : pts) {
    b.x0 = std::min(b.x0, p.x());
    b.y0 = std::min(b.y0, p.y());
    b.x1 = std::max(b.x1, p.x());
    b.y1 = std::max(b.y1, p.y());
  }
  return b;
}
Box box_of(const Points2& p) {
  return {p.col(0).minCoeff(), p.col(1).minCoeff(), p.col(0).maxCoeff(), p.col(1).maxCoeff()};
}
Box circle_box(const CircleObstacle& c) {
  return {c.center.x() - c.radius, c.center.y() - c.radius, c.center.x() + c.radius, c.center.y() + c.radius};
}

/// Sorted, overlapping or touching intervals merged.
std::vector<Interval> merged(std::vector<Interval> v) {
  std::sort(v.begin(), v.end(), [](const Interval& x, const Interval& y) { return x.start < y.start; });
  std::vector<Interval> out;
  for (const auto& s : v) {
    if (!out.empty() && s.start <= out.back().end) out.back().end = std::max(out.back().end, s.end);
    else out.push_back(s);
  }
  return out;
}

/// `s` minus the (sorted, disjoint) closed `cuts`, the pieces kept closed:
/// their ends next to a cut are hidden too (on the safe side).
std::vector<Interval> minus(const Interval& s, const std::vector<Interval>& cuts) {
  std::vector<Interval> out;
  double lo = s.start;
  for (const auto& c : cuts) {
    if (c.end < lo) continue;
    if (c.start > s.end) break;
    if (c.start > lo) out.push_back({lo, c.start});
    lo = std::max(lo, c.end);
  }
  if (lo <= s.end) out.push_back({lo, s.end});
  return out;
}

/// Where the ray from c through s, beyond s, meets the edge's line y = 0 (edge frame).
bool ray_hit(const V2& c, const V2& s, double* t) {
  const double dy = s.y() - c.y();
  if (dy == 0.0) return false;
  const double lam = -c.y() / dy;
  if (!(lam >= 1.0 - 1e-12)) return false;
  *t = c.x() + lam * (s.x() - c.x());
  return std::isfinite(*t);
}

/// Collects points of the boundary of the shadow region on [0, d] (with a
/// little slack, clamped); its hull is the shadow of one convex piece.
struct Hull {
  double d, tol;
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  void add(double t) {
    if (!(t >= -tol && t <= d + tol)) return;
    t = std::clamp(t, 0.0, d);
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  bool empty() const { return lo > hi; }
};

/// The point a + (t / d)(b − a) of the edge, inside or on the polygon:
/// exact rational arithmetic on the doubles (a route along an obstacle's
/// edge is on its boundary, which a rounded point would miss).
bool edge_point_in_polygon(const Points2& poly, const V2& a, const V2& b, double d, double t) {
  const Q s = Q(t) / Q(d);
  const Q px = Q(a.x()) + s * (Q(b.x()) - Q(a.x())), py = Q(a.y()) + s * (Q(b.y()) - Q(a.y()));
  bool inside = false;
  const Eigen::Index n = poly.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Q ax(poly(i, 0)), ay(poly(i, 1)), bx(poly((i + 1) % n, 0)), by(poly((i + 1) % n, 1));
    const Q o = (bx - ax) * (py - ay) - (by - ay) * (px - ax);
    if (o == 0 && CGAL::min(ax, bx) <= px && px <= CGAL::max(ax, bx) && CGAL::min(ay, by) <= py &&
        py <= CGAL::max(ay, by))
      return true;  // on the boundary
    if ((ay > py) != (by > py)) {
      const Q x = ax + (py - ay) * (bx - ax) / (by - ay);
      if (x > px) inside = !inside;
    }
  }
  return inside;
}

/// The part of the edge a → b inside the polygon (closed pieces, each
/// shrunk by 2·kShadowPad and kept only when its ends are inside, exactly,
/// so that no point outside is exempted by rounding).
std::vector<Interval> polygon_on_line(const Points2& poly, const std::vector<V2>& loc, const V2& a, const V2& b,
                                      const EdgeFrame& f, double tol) {
  std::vector<double> ts{0.0, f.length};
  const size_t n = loc.size();
  for (size_t i = 0; i < n; ++i) {
    const V2& p = loc[i];
    const V2& q = loc[(i + 1) % n];
    if (std::abs(p.y()) <= tol) ts.push_back(p.x());
    if ((p.y() < 0 && q.y() > 0) || (p.y() > 0 && q.y() < 0)) ts.push_back(p.x() + (q.x() - p.x()) * p.y() / (p.y() - q.y()));
  }
  for (auto& t : ts) t = std::clamp(t, 0.0, f.length);
  std::sort(ts.begin(), ts.end());
  ts.erase(std::unique(ts.begin(), ts.end()), ts.end());
  std::vector<Interval> out;
  auto in = [&](double t) { return edge_point_in_polygon(poly, a, b, f.length, t); };
  for (size_t i = 0; i + 1 < ts.size(); ++i) {
    const Interval s{ts[i] + 2 * kShadowPad, ts[i + 1] - 2 * kShadowPad};
    if (s.end > s.start && in(0.5 * (ts[i] + ts[i + 1])) && in(s.start) && in(s.end)) out.push_back(s);
  }
  return merged(out);
}

/// The shadow of the disc `circ` on [0, d] of the edge a → b (frame f) as
/// seen from c (cl in the edge frame): the tangents from c and the near arc
/// bound it; the stretch of the route surely inside the disc is exempt (the
/// disc does not hide from there).  Appends its pieces to `shadows`.
void disc_shadow(const EdgeFrame& f, const V2& a, const V2& b, const V2& c, const V2& cl, const CircleObstacle& circ,
                 std::vector<Interval>* shadows) {
  const double d = f.length;
  const V2& o = circ.center;
  const double r = circ.radius;
  if (sight::in_disc(o, r, c)) return;  // a landmark on or in the obstacle is seen from outside it
  const double tol = 1e-9 * scale_of({o, a, b, c}, r);
  Hull h{d, tol};
  const V2 ol = f.to_local(o);
  const V2 w = cl - ol;
  const double D = w.norm();
  if (D <= r + 1e-12 * scale_of({o, c}, r)) {
    // c just outside the boundary (exactly): the tangents from c are within
    // rounding of the tangent line at c, so take the half-plane beyond that
    // line (it holds the true wedge: on the safe side).
    const V2 n = -w / D;  // from c towards the centre
    // the line {q : (q − c)·n = 0} meets y = 0 where (t − c.x) n.x − c.y n.y = 0
    if (n.x() != 0.0) h.add(cl.x() + cl.y() * n.y() / n.x());
    if ((V2(0.0, 0.0) - cl).dot(n) >= 0.0) h.add(0.0);
    if ((V2(d, 0.0) - cl).dot(n) >= 0.0) h.add(d);
  } else {
    const double g = std::acos(std::clamp(r / D, -1.0, 1.0));
    const V2 u = w / D;
    for (const double sg : {1.0, -1.0}) {
      const V2 ur(std::cos(sg * g) * u.x() - std::sin(sg * g) * u.y(), std::sin(sg * g) * u.x() + std::cos(sg * g) * u.y());
      double t;
      if (ray_hit(cl, ol + r * ur, &t)) h.add(t);  // the tangent ray beyond the tangent point
    }
    if (std::abs(ol.y()) <= r) {
      const double hh = std::sqrt(std::max(r * r - ol.y() * ol.y(), 0.0));
      h.add(ol.x() - hh);  // the near arc meets the line between the chord's ends
      h.add(ol.x() + hh);
    }
    if (sight::disc_meets_segment(o, r, c, a)) h.add(0.0);
    if (sight::disc_meets_segment(o, r, c, b)) h.add(d);
  }
  if (h.empty()) return;
  const Interval s{h.lo, h.hi};
  std::vector<Interval> exempt;  // route points inside the disc: this obstacle does not hide from there
  if (std::abs(ol.y()) < r) {
    const double hh = std::sqrt(std::max(r * r - ol.y() * ol.y(), 0.0));
    // 1e-7 m in from both ends (the chord's ends are ill-conditioned near a
    // tangent), and only what is surely inside (the disc is convex: both ends)
    const Interval e{ol.x() - hh + 1e-7, ol.x() + hh - 1e-7};
    auto deep = [&](double t) { return (f.to_world(V2(t, 0.0)) - o).norm() <= r - tol; };
    if (e.end > e.start && deep(e.start) && deep(e.end)) exempt.push_back(e);
  }
  for (const auto& piece : exempt.empty() ? std::vector<Interval>{s} : minus(s, exempt)) shadows->push_back(piece);
}

/// The shadow of the simple polygon `poly` (open) on [0, d] of the edge
/// a → b (frame f) as seen from c (cl in the edge frame): per polygon edge,
/// the wedge from c through its ends, beyond it, is convex and meets the
/// edge's line in one interval; the route's stretches inside the polygon are
/// exempt.  Appends its pieces to `shadows`.
void polygon_shadow(const EdgeFrame& f, const V2& a, const V2& b, const V2& c, const V2& cl, const Points2& poly,
                    std::vector<Interval>* shadows) {
  const double d = f.length;
  const sight::Occluder shape(poly);
  if (shape.contains(c)) return;  // seen from outside the obstacle it stands on
  double sc = scale_of({a, b, c});
  for (Eigen::Index i = 0; i < poly.rows(); ++i) sc = std::max(sc, poly.row(i).cwiseAbs().maxCoeff());
  const double tol = 1e-9 * sc, ytol = 1e-12 * sc;
  std::vector<V2> loc(poly.rows());
  for (Eigen::Index i = 0; i < poly.rows(); ++i) loc[i] = f.to_local(poly.row(i).transpose());
  std::vector<Interval> mine;
  const cgal::Segment ca(cgal::point(c), cgal::point(a)), cb(cgal::point(c), cgal::point(b));
  const size_t n = loc.size();
  for (size_t i = 0; i < n; ++i) {
    // One polygon edge: the wedge from c through its ends, beyond it, is convex.
    const V2 &v0 = loc[i], &v1 = loc[(i + 1) % n];
    const cgal::Segment& edge = shape.edges()[i];
    Hull h{d, tol};
    double t;
    if (ray_hit(cl, v0, &t)) h.add(t);
    if (ray_hit(cl, v1, &t)) h.add(t);
    if (std::abs(v0.y()) <= ytol) h.add(v0.x());
    if (std::abs(v1.y()) <= ytol) h.add(v1.x());
    if ((v0.y() < 0 && v1.y() > 0) || (v0.y() > 0 && v1.y() < 0))
      h.add(v0.x() + (v1.x() - v0.x()) * v0.y() / (v0.y() - v1.y()));
    if (CGAL::do_intersect(ca, edge)) h.add(0.0);
    if (CGAL::do_intersect(cb, edge)) h.add(d);
    if (!h.empty()) mine.push_back({h.lo, h.hi});
  }
  if (mine.empty()) return;
  mine = merged(mine);
  const std::vector<Interval> exempt = polygon_on_line(poly, loc, a, b, f, ytol);
  for (const auto& s : mine)
    for (const auto& piece : exempt.empty() ? std::vector<Interval>{s} : minus(s, exempt)) shadows->push_back(piece);
}

}  // namespace

std::vector<Interval> edge_shadows(const V2& a, const V2& b, const V2& c, const Occluders& occ, const Interval& range) {
  const EdgeFrame f(a, b);
  const V2 cl = f.to_local(c);
  const V2 p0 = f.to_world(V2(range.start, 0.0)), p1 = f.to_world(V2(range.end, 0.0));
  const Box tri = box_of({c, p0, p1});  // every sight line from range to c lies in this triangle
  std::vector<Interval> shadows;
  for (const auto& circ : occ.circles)
    if (circle_box(circ).overlaps(tri)) disc_shadow(f, a, b, c, cl, circ, &shadows);
  for (const auto& raw : occ.polygons) {
    const Points2 poly = open_polygon(raw);
    if (box_of(poly).overlaps(tri)) polygon_shadow(f, a, b, c, cl, poly, &shadows);
  }
  return merged(shadows);
}

bool hidden(const Occluders& occ, const V2& a, const V2& b) {
  const sight::Sight s(a, b);
  for (const auto& c : occ.circles)
    if (sight::Occluder(c.center, c.radius).hides(s)) return true;
  const Box seg = box_of({a, b});
  for (const auto& raw : occ.polygons) {
    const Points2 poly = open_polygon(raw);
    if (!box_of(poly).overlaps(seg)) continue;  // apart (hides() would say so): not worth preparing
    if (sight::Occluder(poly).hides(s)) return true;
  }
  return false;
}

}  // namespace placement_detail

using namespace placement_detail;

void Occluders::validate() const {
  for (size_t i = 0; i < circles.size(); ++i) {
    const auto& c = circles[i];
    const std::string name = "occluder circle " + std::to_string(i);
    if (!c.center.allFinite() || c.center.cwiseAbs().maxCoeff() > kMaxCoordinate)
      fail(name + " has center " + fmt(c.center) + ": not finite or beyond 1e6 m");
    if (!std::isfinite(c.radius) || c.radius <= 0.0 || c.radius > kMaxCoordinate)
      fail(name + " radius = " + std::to_string(c.radius) + " must be finite and > 0");
  }
  for (size_t i = 0; i < polygons.size(); ++i) {
    const std::string name = "occluder polygon " + std::to_string(i);
    if (polygons[i].cols() != 2) fail(name + " must be an (n, 2) array");
    const Points2 p = open_polygon(polygons[i]);
    if (p.rows() < 3) fail(name + " needs >= 3 vertices, got " + std::to_string(p.rows()));
    for (Eigen::Index j = 0; j < p.rows(); ++j)
      if (!p.row(j).allFinite() || p.row(j).cwiseAbs().maxCoeff() > kMaxCoordinate)
        fail(name + " vertex " + std::to_string(j) + " = " + fmt(p.row(j).transpose()) +
             " is not finite or beyond 1e6 m");
    const auto cp = cgal::to_cgal(p);
    if (!CGAL::is_simple_2(cp.begin(), cp.end(), cgal::K()))
      fail(name + " is not a simple polygon (its edges cross or a vertex repeats)");
  }
}

Occluders Occluders::from_map(const PlanningMap& map) {
  Occluders o;
  o.circles = map.circles;
  o.polygons = map.polygons;
  return o;
}

bool sight_blocked(const Occluders& occ, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  occ.validate();
  if (!a.allFinite()) fail("sight_blocked: a = " + fmt(a) + " is not finite");
  if (!b.allFinite()) fail("sight_blocked: b = " + fmt(b) + " is not finite");
  return hidden(occ, a, b);
}

std::vector<Interval> shadows_on_edge(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                                      const Occluders& occluders) {
  occluders.validate();
  if (!a.allFinite() || !b.allFinite() || !c.allFinite()) fail("shadows_on_edge: points must be finite");
  if ((b - a).norm() <= 1e-12) fail("shadows_on_edge: the edge from " + fmt(a) + " has zero length");
  return edge_shadows(a, b, c, occluders, {0.0, (b - a).norm()});
}

std::vector<Interval> cut_shadows(const Interval& iv, const std::vector<Interval>& shadows) {
  std::vector<Interval> pad;
  for (const auto& s : shadows) pad.push_back({s.start - kShadowPad, s.end + kShadowPad});
  pad = merged(pad);
  std::vector<Interval> out;
  double lo = iv.start;
  for (const auto& s : pad) {
    if (s.end < lo) continue;
    if (s.start > iv.end) break;
    if (s.start > lo) out.push_back({lo, s.start});
    lo = std::max(lo, s.end);
    if (lo > iv.end) return out;
  }
  // The rest: [lo, end] unless a cut ended exactly at the end.
  if (lo <= iv.end && (lo == iv.start || lo < iv.end)) out.push_back({lo, iv.end});
  return out;
}

}  // namespace safenav
