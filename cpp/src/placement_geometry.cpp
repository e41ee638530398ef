// Landmark placement, the geometry [Placement §II]: input checks, the
// candidates near a route, edge frames, [Placement Lemma 1], [Placement
// Lemma 2] and [Placement Cor. 1], the turns at the route's vertices, the
// occluders' shadows (ours, not the paper's), and the tables the ILP
// is built from.  Candidates are found per edge through a uniform bucket grid,
// so a route costs O(edges · candidates near an edge), not O(edges · all
// candidates).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <string>

#include <CGAL/Exact_rational.h>

#include "cgal_util.hpp"
#include "placement_internal.hpp"

namespace safenav {
namespace placement_detail {

namespace {

std::string point_str(const Eigen::Vector2d& p) {
  std::ostringstream os;
  os << "(" << p.x() << ", " << p.y() << ")";
  return os.str();
}

double segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double l2 = ab.squaredNorm();
  const double s = l2 > 0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

/// Lemma 2 / Corollary 1 with the camera's constants computed once.
struct Fov {
  explicit Fov(const Camera& cam)
      : R(cam.range), R2(cam.range * cam.range), circular(cam.fov == FieldOfView::Circular),
        ymax(circular ? cam.range : cam.range * std::sin(0.5 * cam.angle)),
        cot_half(circular ? 0.0 : std::cos(0.5 * cam.angle) / std::sin(0.5 * cam.angle)) {}
  bool interval(const Eigen::Vector2d& local, double length, Interval* out) const {
    const double x = local.x(), y = local.y(), ay = std::abs(y);
    if (ay > ymax || x < -R || x > length + R) return false;  // Lemma 1, condition 1 (and |x| bounds)
    const double h = std::sqrt(std::max(R2 - y * y, 0.0));
    const double a = std::max(x - h, 0.0);                                       // [Placement eq. 1]/[Placement eq. 3]
    const double b = circular ? std::min(x + h, length)                          // [Placement eq. 4], typo fixed
                              : std::min(x - ay * cot_half, length);             // [Placement eq. 2]
    if (b < a - kEps) return false;  // empty by more than the rounding slack (α = 180°: cot(α/2) ≈ 6e-17)
    *out = {a, std::max(a, b)};
    return true;
  }
  double R, R2;
  bool circular;
  double ymax, cot_half;
};

/// The point t where the line through two landmarks (edge frame) meets the
/// edge's line with both on one ray from it; false when there is none.  Two
/// landmarks on the edge's line (y = 0) share a bearing everywhere, not at
/// one point: the callers handle them.
bool alignment_point(const Eigen::Vector2d& p, const Eigen::Vector2d& q, double* t) {
  if (!((p.y() > 0 && q.y() > 0) || (p.y() < 0 && q.y() < 0))) return false;
  if (p.y() == q.y()) return false;
  *t = p.x() - p.y() * (q.x() - p.x()) / (q.y() - p.y());
  return true;
}

}  // namespace

void check_points(const Points2& p, const char* what) {
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const bool finite = p.row(i).allFinite();
    if (finite && p.row(i).cwiseAbs().maxCoeff() <= kMaxCoordinate) continue;
    const std::string name = std::string(what) + "[" + std::to_string(i) + "] = " + point_str(p.row(i).transpose());
    if (!finite) fail(name + " is not finite");
    fail(name + " is farther than " + std::to_string(static_cast<long>(kMaxCoordinate)) +
         " m from the origin: shift the coordinates to a local origin");
  }
}

void check_route(const Points2& route) {
  if (route.rows() < 2)
    fail("route must have at least 2 points, got " + std::to_string(route.rows()));
  check_points(route, "route");
  for (Eigen::Index i = 1; i < route.rows(); ++i)
    if ((route.row(i) - route.row(i - 1)).norm() <= 1e-12)
      fail("route[" + std::to_string(i) + "] = " + point_str(route.row(i).transpose()) + " repeats route[" +
           std::to_string(i - 1) + "]: an edge of zero length has no direction");
}

void check_candidates(const Points2& c, const char* what) {
  check_points(c, what);
  std::vector<int> order(c.rows());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return c(a, 0) < c(b, 0) || (c(a, 0) == c(b, 0) && c(a, 1) < c(b, 1));
  });
  for (size_t i = 1; i < order.size(); ++i)
    if (c(order[i], 0) == c(order[i - 1], 0) && c(order[i], 1) == c(order[i - 1], 1)) {
      int a = std::min(order[i], order[i - 1]), b = std::max(order[i], order[i - 1]);
      fail(std::string(what) + "[" + std::to_string(a) + "] and " + what + "[" + std::to_string(b) +
           "] coincide at " + point_str(c.row(a).transpose()) + " (two landmarks on one bearing)");
    }
}

void check_k(int k) {
  if (k < 1 || k > kMaxLandmarksInView)
    fail("k = " + std::to_string(k) + " must be in [1, " + std::to_string(kMaxLandmarksInView) + "]");
}

namespace {
const Points2& checked(const Points2& route, const Points2& candidates, const Camera& camera) {
  camera.validate();
  check_route(route);
  check_candidates(candidates);
  return candidates;
}
}  // namespace

CandidateSet::CandidateSet(const Points2& route, const Points2& candidates, const Camera& camera,
                           const Occluders& occluders)
    : grid(checked(route, candidates, camera), 0.5 * camera.range),
      close(within(route, candidates, grid, camera.clearance)) {
  occluders.validate();
  if (!occluders.empty()) occ = &occluders;
}

std::vector<char> within(const Points2& route, const Points2& pts, const Grid& grid, double p) {
  std::vector<char> close(pts.rows(), 0);
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e) {
    const Eigen::Vector2d a = route.row(e).transpose(), b = route.row(e + 1).transpose();
    grid.query(std::min(a.x(), b.x()) - p, std::min(a.y(), b.y()) - p, std::max(a.x(), b.x()) + p,
               std::max(a.y(), b.y()) + p, [&](int i) {
                 if (!close[i] && segment_distance(pts.row(i).transpose(), a, b) <= p) close[i] = 1;
               });
  }
  return close;
}

std::vector<Seen> seen_on_edge(const Points2& route, Eigen::Index e, const Points2& pts, const Grid& grid,
                               const std::vector<char>& excluded, const Camera& cam, const Occluders* occ) {
  const Eigen::Vector2d a = route.row(e).transpose(), b = route.row(e + 1).transpose();
  const EdgeFrame f(a, b);
  const double R = cam.range;
  const Fov fov(cam);
  std::vector<Seen> out;
  grid.query(std::min(a.x(), b.x()) - R, std::min(a.y(), b.y()) - R, std::max(a.x(), b.x()) + R,
             std::max(a.y(), b.y()) + R, [&](int i) {
               if (!excluded.empty() && excluded[i]) return;
               Seen s{i, {}, f.to_local(pts.row(i).transpose()), {}};
               if (std::abs(s.local.y()) <= kEps) s.local.y() = 0.0;  // on the edge's line: bearing 0 or π
               if (!fov.interval(s.local, f.length, &s.iv)) return;
               if (occ) {
                 s.pieces = cut_shadows(s.iv, edge_shadows(a, b, pts.row(i).transpose(), *occ, s.iv));
                 if (s.pieces.empty()) return;  // hidden from the whole interval
               } else {
                 s.pieces = {s.iv};
               }
               out.push_back(std::move(s));
             });
  std::sort(out.begin(), out.end(), [](const Seen& x, const Seen& y) { return x.idx < y.idx; });
  return out;
}

bool aligned_in_view(const Seen& a, const Seen& b, double* t) {
  return alignment_point(a.local, b.local, t) && in_pieces(a, *t) && in_pieces(b, *t);
}

std::vector<Seen> seen_at_corner(const Eigen::Vector2d& v, double theta_in, double turn, const Points2& pts,
                                 const Grid& grid, const std::vector<char>& excluded, const Camera& cam,
                                 const Occluders* occ) {
  const double R = cam.range, half = 0.5 * cam.angle, L = std::abs(turn), sgn = turn >= 0 ? 1.0 : -1.0;
  std::vector<Seen> out;
  grid.query(v.x() - R, v.y() - R, v.x() + R, v.y() + R, [&](int i) {
    if (!excluded.empty() && excluded[i]) return;
    const Eigen::Vector2d rel = pts.row(i).transpose() - v;
    const double r = rel.norm();
    if (r > R || r == 0.0) return;
    Interval iv{0.0, L};
    if (cam.fov == FieldOfView::Sector) {
      double u = wrap(sgn * (std::atan2(rel.y(), rel.x()) - theta_in));
      if (u + half < -kEps) u += 2.0 * kPi;
      iv = {std::max(u - half, 0.0), std::min(u + half, L)};
      if (iv.end < iv.start - kEps) return;
      iv.end = std::max(iv.end, iv.start);
    }
    if (occ && sight_blocked(*occ, v, pts.row(i).transpose())) return;  // hidden from the vertex
    out.push_back({i, iv, rel, {iv}});
  });
  std::sort(out.begin(), out.end(), [](const Seen& x, const Seen& y) { return x.idx < y.idx; });
  return out;
}

}  // namespace placement_detail

using namespace placement_detail;

void Camera::validate() const {
  auto bad = [](const std::string& name, double v, const std::string& why) {
    std::ostringstream os;
    os << "camera " << name << " = " << v << " " << why;
    fail(os.str());
  };
  if (!std::isfinite(range) || range <= 0) bad("range R", range, "must be finite and > 0");
  if (!std::isfinite(clearance) || clearance < 0) bad("clearance p", clearance, "must be finite and >= 0");
  if (range <= clearance) {
    std::ostringstream os;
    os << "camera range R = " << range << " must exceed the clearance p = " << clearance
       << ": no landmark could be both farther than p and in view";
    fail(os.str());
  }
  if (fov == FieldOfView::Sector && !(angle > 0 && angle <= kPi + 1e-12))
    bad("angle alpha", angle * 180.0 / kPi, "deg must be in (0, 180] for a sector field of view");
}

EdgeFrame::EdgeFrame(const Eigen::Vector2d& a, const Eigen::Vector2d& b)
    : origin(a), heading(std::atan2(b.y() - a.y(), b.x() - a.x())), length((b - a).norm()) {
  cos_ = length > 0 ? (b.x() - a.x()) / length : 1.0;
  sin_ = length > 0 ? (b.y() - a.y()) / length : 0.0;
}

Eigen::Vector2d EdgeFrame::to_local(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d q = p - origin;
  return {cos_ * q.x() + sin_ * q.y(), -sin_ * q.x() + cos_ * q.y()};
}

Eigen::Vector2d EdgeFrame::to_world(const Eigen::Vector2d& q) const {
  return origin + Eigen::Vector2d(cos_ * q.x() - sin_ * q.y(), sin_ * q.x() + cos_ * q.y());
}

bool in_region_of_influence(const Eigen::Vector2d& local, double length, const Camera& cam) {
  const double x = local.x(), y = local.y(), R = cam.range;
  if (cam.fov == FieldOfView::Circular) {
    const double dx = x < 0 ? x : (x > length ? x - length : 0.0);
    return dx * dx + y * y <= R * R;
  }
  const double half = 0.5 * cam.angle;
  if (std::abs(y) > R * std::sin(half)) return false;                      // 1) |y_k| ≤ R sin(α/2)
  if (!(x > 0)) return false;                                               // 2) x_k > 0
  if (std::abs(std::atan2(y, x)) > half) return false;                      // 3) |atan(y_k/x_k)| ≤ α/2
  if (x > length && (x - length) * (x - length) + y * y > R * R) return false;  // 4)
  return true;
}

bool visibility_interval(const Eigen::Vector2d& local, double length, const Camera& cam, Interval* out) {
  return Fov(cam).interval(local, length, out);
}

Eigen::VectorXd turn_angles(const Points2& route) {
  check_route(route);
  const Eigen::Index n = route.rows();
  Eigen::VectorXd out(std::max<Eigen::Index>(n - 2, 0));
  for (Eigen::Index i = 1; i + 1 < n; ++i) {
    const double a = std::atan2(route(i, 1) - route(i - 1, 1), route(i, 0) - route(i - 1, 0));
    const double b = std::atan2(route(i + 1, 1) - route(i, 1), route(i + 1, 0) - route(i, 0));
    out(i - 1) = wrap(b - a);
  }
  return out;
}

namespace {
VisibilityTable to_table(const std::vector<int>& e0, const std::vector<Seen>& s0) {
  // One row per piece (without occluders: one per candidate, its Lemma 2 interval).
  std::vector<int> e;
  std::vector<Seen> s;
  for (size_t i = 0; i < s0.size(); ++i)
    for (const auto& p : s0[i].pieces) {
      e.push_back(e0[i]);
      s.push_back(s0[i]);
      s.back().iv = p;
    }
  VisibilityTable t;
  const Eigen::Index n = static_cast<Eigen::Index>(s.size());
  t.edge.resize(n);
  t.candidate.resize(n);
  t.start.resize(n);
  t.end.resize(n);
  t.x.resize(n);
  t.y.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    t.edge(i) = e[i];
    t.candidate(i) = s[i].idx;
    t.start(i) = s[i].iv.start;
    t.end(i) = s[i].iv.end;
    t.x(i) = s[i].local.x();
    t.y(i) = s[i].local.y();
  }
  return t;
}
}  // namespace

VisibilityTable edge_visibility(const Points2& route, const Points2& candidates, const Camera& camera,
                          const Occluders& occluders) {
  const CandidateSet set(route, candidates, camera, occluders);
  const Grid& grid = set.grid;
  const std::vector<char>& close = set.close;
  std::vector<int> edge;
  std::vector<Seen> rows;
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e)
    for (const auto& s : seen_on_edge(route, e, candidates, grid, close, camera, set.occ)) {
      edge.push_back(static_cast<int>(e));
      rows.push_back(s);
    }
  return to_table(edge, rows);
}

VisibilityTable corner_visibility(const Points2& route, const Points2& candidates, const Camera& camera,
                          const Occluders& occluders) {
  const CandidateSet set(route, candidates, camera, occluders);
  const Grid& grid = set.grid;
  const std::vector<char>& close = set.close;
  const Eigen::VectorXd turns = turn_angles(route);
  std::vector<int> vert;
  std::vector<Seen> rows;
  for (Eigen::Index v = 1; v + 1 < route.rows(); ++v) {
    if (std::abs(turns(v - 1)) <= kEps) continue;
    const double theta_in = std::atan2(route(v, 1) - route(v - 1, 1), route(v, 0) - route(v - 1, 0));
    for (const auto& s : seen_at_corner(route.row(v).transpose(), theta_in, turns(v - 1), candidates, grid, close,
                                        camera, set.occ)) {
      vert.push_back(static_cast<int>(v));
      rows.push_back(s);
    }
  }
  return to_table(vert, rows);
}

AlignmentTable alignments(const Points2& route, const Points2& candidates, const Camera& camera,
                          const Occluders& occluders) {
  const CandidateSet set(route, candidates, camera, occluders);
  const Grid& grid = set.grid;
  const std::vector<char>& close = set.close;
  std::vector<int> e_, f_, s_;
  std::vector<double> t_;
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e) {
    const auto seen = seen_on_edge(route, e, candidates, grid, close, camera, set.occ);
    for (size_t i = 0; i < seen.size(); ++i)
      for (size_t j = i + 1; j < seen.size(); ++j) {
        double t;
        if (!aligned_in_view(seen[i], seen[j], &t)) continue;
        e_.push_back(static_cast<int>(e));
        f_.push_back(seen[i].idx);
        s_.push_back(seen[j].idx);
        t_.push_back(t);
      }
  }
  AlignmentTable out;
  const Eigen::Index n = static_cast<Eigen::Index>(t_.size());
  out.edge = Eigen::Map<Eigen::VectorXi>(e_.data(), n);
  out.first = Eigen::Map<Eigen::VectorXi>(f_.data(), n);
  out.second = Eigen::Map<Eigen::VectorXi>(s_.data(), n);
  out.t = Eigen::Map<Eigen::VectorXd>(t_.data(), n);
  return out;
}

Eigen::VectorXd distance_to_route(const Points2& route, const Points2& points) {
  check_route(route);
  check_points(points, "points");
  Eigen::VectorXd d(points.rows());
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (Eigen::Index e = 0; e + 1 < route.rows(); ++e)
      best = std::min(best, segment_distance(points.row(i).transpose(), route.row(e).transpose(),
                                             route.row(e + 1).transpose()));
    d(i) = best;
  }
  return d;
}

}  // namespace safenav

// ---------------------------------------------------------------------------
// Occlusion (issue 16; the placement paper has no obstacles).  See the
// header comment of safenav/placement.hpp for the convention.
// ---------------------------------------------------------------------------
namespace safenav {
namespace placement_detail {
namespace {

using Q = CGAL::Exact_rational;
using V2 = Eigen::Vector2d;

double scale_of(std::initializer_list<V2> pts, double r = 0.0) {
  double s = std::max(1.0, r);
  for (const auto& p : pts) s = std::max(s, p.cwiseAbs().maxCoeff());
  return s;
}

/// p in the closed disc (o, r), exact on the doubles (a double filter first).
bool in_disc(const V2& o, double r, const V2& p) {
  const double dd = (p - o).norm(), tol = 1e-9 * scale_of({o, p}, r);
  if (dd > r + tol) return false;
  if (dd < r - tol) return true;
  const Q dx = Q(p.x()) - Q(o.x()), dy = Q(p.y()) - Q(o.y());
  return dx * dx + dy * dy <= Q(r) * Q(r);
}

/// The segment a–b meets the closed disc (o, r), exact on the doubles.
bool disc_meets_segment(const V2& o, double r, const V2& a, const V2& b) {
  const double dd = segment_distance(o, a, b), tol = 1e-9 * scale_of({o, a, b}, r);
  if (dd > r + tol) return false;
  if (dd < r - tol) return true;
  const Q ax(a.x()), ay(a.y()), abx = Q(b.x()) - ax, aby = Q(b.y()) - ay;
  const Q aox = Q(o.x()) - ax, aoy = Q(o.y()) - ay, r2 = Q(r) * Q(r);
  const Q dot = aox * abx + aoy * aby, l2 = abx * abx + aby * aby;
  if (l2 == 0 || dot <= 0) return aox * aox + aoy * aoy <= r2;
  if (dot >= l2) {
    const Q bx = Q(o.x()) - Q(b.x()), by = Q(o.y()) - Q(b.y());
    return bx * bx + by * by <= r2;
  }
  const Q cr = aox * aby - aoy * abx;
  return cr * cr <= r2 * l2;
}

/// An open polygon (a closing repeat of the first vertex dropped).
Points2 open_ring(const Points2& p) {
  if (p.rows() > 1 && p.row(0) == p.row(p.rows() - 1)) return p.topRows(p.rows() - 1);
  return p;
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

}  // namespace

std::vector<Interval> edge_shadows(const V2& a, const V2& b, const V2& c, const Occluders& occ, const Interval& range) {
  const EdgeFrame f(a, b);
  const double d = f.length;
  const V2 cl = f.to_local(c);
  const V2 p0 = f.to_world(V2(range.start, 0.0)), p1 = f.to_world(V2(range.end, 0.0));
  const Box tri = box_of({c, p0, p1});  // every sight line from range to c lies in this triangle
  std::vector<Interval> shadows;
  for (const auto& circ : occ.circles) {
    const V2& o = circ.center;
    const double r = circ.radius;
    if (!circle_box(circ).overlaps(tri)) continue;
    if (in_disc(o, r, c)) continue;  // a landmark on or in the obstacle is seen from outside it
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
      if (disc_meets_segment(o, r, c, a)) h.add(0.0);
      if (disc_meets_segment(o, r, c, b)) h.add(d);
    }
    if (h.empty()) continue;
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
    for (const auto& piece : exempt.empty() ? std::vector<Interval>{s} : minus(s, exempt)) shadows.push_back(piece);
  }
  for (const auto& raw : occ.polygons) {
    const Points2 poly = open_ring(raw);
    if (!box_of(poly).overlaps(tri)) continue;
    const std::vector<cgal::Point> cp = cgal::to_cgal(poly);
    if (cgal::inside_or_on(cp, cgal::point(c))) continue;  // seen from outside the obstacle it stands on
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
      const cgal::Segment edge(cp[i], cp[(i + 1) % n]);
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
    if (mine.empty()) continue;
    mine = merged(mine);
    const std::vector<Interval> exempt = polygon_on_line(poly, loc, a, b, f, ytol);
    for (const auto& s : mine)
      for (const auto& piece : exempt.empty() ? std::vector<Interval>{s} : minus(s, exempt)) shadows.push_back(piece);
  }
  return merged(shadows);
}

}  // namespace placement_detail

using namespace placement_detail;

void Occluders::validate() const {
  for (size_t i = 0; i < circles.size(); ++i) {
    const auto& c = circles[i];
    const std::string name = "occluder circle " + std::to_string(i);
    if (!c.center.allFinite() || c.center.cwiseAbs().maxCoeff() > kMaxCoordinate)
      fail(name + " has center " + point_str(c.center) + ": not finite or beyond 1e6 m");
    if (!std::isfinite(c.radius) || c.radius <= 0.0 || c.radius > kMaxCoordinate)
      fail(name + " radius = " + std::to_string(c.radius) + " must be finite and > 0");
  }
  for (size_t i = 0; i < polygons.size(); ++i) {
    const std::string name = "occluder polygon " + std::to_string(i);
    if (polygons[i].cols() != 2) fail(name + " must be an (n, 2) array");
    const Points2 p = open_ring(polygons[i]);
    if (p.rows() < 3) fail(name + " needs >= 3 vertices, got " + std::to_string(p.rows()));
    for (Eigen::Index j = 0; j < p.rows(); ++j)
      if (!p.row(j).allFinite() || p.row(j).cwiseAbs().maxCoeff() > kMaxCoordinate)
        fail(name + " vertex " + std::to_string(j) + " = " + point_str(p.row(j).transpose()) +
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
  const Box seg = box_of({a, b});
  for (const auto& c : occ.circles) {
    if (!circle_box(c).overlaps(seg)) continue;
    if (in_disc(c.center, c.radius, a) || in_disc(c.center, c.radius, b)) continue;
    if (disc_meets_segment(c.center, c.radius, a, b)) return true;
  }
  for (const auto& raw : occ.polygons) {
    const Points2 poly = open_ring(raw);
    if (!box_of(poly).overlaps(seg)) continue;
    const auto cp = cgal::to_cgal(poly);
    if (cgal::inside_or_on(cp, cgal::point(a)) || cgal::inside_or_on(cp, cgal::point(b))) continue;
    const cgal::Segment s(cgal::point(a), cgal::point(b));
    for (size_t i = 0; i < cp.size(); ++i)
      if (CGAL::do_intersect(s, cgal::Segment(cp[i], cp[(i + 1) % cp.size()]))) return true;
  }
  return false;
}

std::vector<Interval> shadows_on_edge(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                                      const Occluders& occluders) {
  occluders.validate();
  if (!a.allFinite() || !b.allFinite() || !c.allFinite()) fail("shadows_on_edge: points must be finite");
  if ((b - a).norm() <= 1e-12) fail("shadows_on_edge: the edge from " + point_str(a) + " has zero length");
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
