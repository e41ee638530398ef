// The one line-of-sight predicate (ours; the papers model no occlusion).  See sight.hpp.
#include "sight.hpp"

#include <algorithm>
#include <cmath>

#include <CGAL/Interval_nt.h>
#include <CGAL/MP_Float.h>

namespace safenav::sight {
namespace {

// Beyond this |coordinate| the double filters stand aside (their squares
// could overflow) and every answer comes from the exact evaluation.
constexpr double kFilterLimit = 1e150;
// The filters' margin, relative to the largest |coordinate| (at least 1 m):
// their rounding error is below 1e-14 of it.
constexpr double kFilterMargin = 1e-9;

double abs_max(const Vec2& p) { return std::max(std::abs(p.x()), std::abs(p.y())); }

// The sign of polynomials in the input doubles, generic in the number type:
// CGAL::Interval_nt<> gives an Uncertain answer, CGAL::MP_Float an exact one.

// p in the closed disc (c, r): |p − c|² ≤ r².
template <class NT>
CGAL::Uncertain<bool> contains_t(const NT& px, const NT& py, const NT& cx, const NT& cy, const NT& r) {
  const NT dx = px - cx, dy = py - cy;
  return CGAL::Uncertain<bool>(dx * dx + dy * dy <= r * r);
}

// The segment a–b comes within r of c at the foot of c on its line: a ≠ b,
// the foot lies within the segment, 0 ≤ (c − a)·d ≤ d·d with d = b − a, and
// the line is within r of c, cross(d, c − a)² ≤ r²·d·d.  (When the foot lies
// outside the segment, the nearest point is an end.)
template <class NT>
CGAL::Uncertain<bool> touched_t(const NT& ax, const NT& ay, const NT& bx, const NT& by, const NT& cx, const NT& cy,
                                const NT& r) {
  const NT dx = bx - ax, dy = by - ay, wx = cx - ax, wy = cy - ay;
  const NT along = wx * dx + wy * dy, dd = dx * dx + dy * dy, cr = dx * wy - dy * wx;
  const NT zero(0);
  return CGAL::Uncertain<bool>(zero < dd) & CGAL::Uncertain<bool>(zero <= along) &
         CGAL::Uncertain<bool>(along <= dd) & CGAL::Uncertain<bool>(cr * cr <= r * r * dd);
}

// The closed segment a–b meets the closed disc: an end in it, or touched.
template <class NT>
CGAL::Uncertain<bool> meets_t(const NT& ax, const NT& ay, const NT& bx, const NT& by, const NT& cx, const NT& cy,
                              const NT& r) {
  return contains_t<NT>(ax, ay, cx, cy, r) | contains_t<NT>(bx, by, cx, cy, r) |
         touched_t<NT>(ax, ay, bx, by, cx, cy, r);
}

// The disc hides: it meets the segment and contains neither end.
template <class NT>
CGAL::Uncertain<bool> hides_t(const NT& ax, const NT& ay, const NT& bx, const NT& by, const NT& cx, const NT& cy,
                              const NT& r) {
  return (!contains_t<NT>(ax, ay, cx, cy, r)) & (!contains_t<NT>(bx, by, cx, cy, r)) &
         touched_t<NT>(ax, ay, bx, by, cx, cy, r);
}

// Interval arithmetic first (it rounds outward), exact when it cannot
// decide: sign(NT()) evaluates the predicate in the number type NT.
template <class Sign>
bool exactly(const Sign& sign) {
  const CGAL::Uncertain<bool> f = sign(CGAL::Interval_nt<>());
  if (CGAL::is_certain(f)) return CGAL::get_certain(f);
  return CGAL::get_certain(sign(CGAL::MP_Float()));
}

// The filters' verdict on "distance d (squared: d2) ≤ r": -1 surely not, +1
// surely, 0 unsure (left to the exact evaluation).
int filter(double d2, double r, double scale) {
  if (scale > kFilterLimit) return 0;
  const double tol = kFilterMargin * scale;
  const double above = r + tol, below = r - tol;
  if (d2 > above * above) return -1;
  if (below > 0.0 && d2 < below * below) return 1;
  return 0;
}

double scale_of(double r, std::initializer_list<Vec2> pts) {
  double s = std::max(1.0, r);
  for (const auto& p : pts) s = std::max(s, abs_max(p));
  return s;
}

bool lexicographic_less(const Vec2& p, const Vec2& q) { return p.x() < q.x() || (p.x() == q.x() && p.y() < q.y()); }

}  // namespace

Sight::Sight(const Vec2& p, const Vec2& q)
    : a(lexicographic_less(q, p) ? q : p), b(lexicographic_less(q, p) ? p : q), lo(a.cwiseMin(b)),
      hi(a.cwiseMax(b)), scale(std::max(abs_max(a), abs_max(b))), ab(cgal::point(a), cgal::point(b)) {}

bool in_disc(const Vec2& c, double r, const Vec2& p) {
  const int f = filter((p - c).squaredNorm(), r, scale_of(r, {c, p}));
  if (f != 0) return f > 0;
  return exactly([&](auto nt) { return contains_t<decltype(nt)>(p.x(), p.y(), c.x(), c.y(), r); });
}

bool disc_meets_segment(const Vec2& c, double r, const Vec2& p, const Vec2& q) {
  const Sight s(p, q);
  const int f = filter(segment_point_distance2(s.a, s.b, c), r, scale_of(r, {c, s.a, s.b}));
  if (f != 0) return f > 0;
  return exactly([&](auto nt) { return meets_t<decltype(nt)>(s.a.x(), s.a.y(), s.b.x(), s.b.y(), c.x(), c.y(), r); });
}

Occluder::Occluder(const Vec2& center, double radius)
    : disc_(true), center_(center), radius_(radius), lo_((center.array() - radius).matrix()), hi_((center.array() + radius).matrix()),
      scale_(scale_of(radius, {center, lo_, hi_})) {}

Occluder::Occluder(const Points2& open) : disc_(false) {
  polygon_ = cgal::to_cgal(open);
  for (std::size_t i = 0; i < polygon_.size(); ++i) edges_.emplace_back(polygon_[i], polygon_[(i + 1) % polygon_.size()]);
  center_ = open.colwise().mean().transpose();
  radius_ = (open.rowwise() - center_.transpose()).rowwise().norm().maxCoeff();
  lo_ = open.colwise().minCoeff().transpose();
  hi_ = open.colwise().maxCoeff().transpose();
  scale_ = scale_of(radius_, {center_, lo_, hi_});
}

bool Occluder::contains(const Vec2& p) const {
  if (disc_) return in_disc(center_, radius_, p);
  return cgal::inside_or_on(polygon_, cgal::point(p));
}

// The segment surely misses it: their boxes are apart (exact: comparisons of
// doubles), or the segment passes the bounding circle by more than the margin.
bool Occluder::apart(const Sight& s) const {
  if (s.hi.x() < lo_.x() || s.hi.y() < lo_.y() || hi_.x() < s.lo.x() || hi_.y() < s.lo.y()) return true;
  return filter(segment_point_distance2(s.a, s.b, center_), radius_, std::max(scale_, s.scale)) < 0;
}

bool Occluder::hides(const Sight& s) const {
  if (s.a == s.b || apart(s)) return false;  // a point outside hides nothing from itself
  if (disc_)
    return exactly([&](auto nt) {
      return hides_t<decltype(nt)>(s.a.x(), s.a.y(), s.b.x(), s.b.y(), center_.x(), center_.y(), radius_);
    });
  if (cgal::inside_or_on(polygon_, s.ab.source()) || cgal::inside_or_on(polygon_, s.ab.target())) return false;
  for (const auto& e : edges_)
    if (CGAL::do_intersect(s.ab, e)) return true;
  return false;
}

bool blocked(const std::vector<Occluder>& occluders, const Sight& s) {
  for (const auto& o : occluders)
    if (o.hides(s)) return true;
  return false;
}

}  // namespace safenav::sight
