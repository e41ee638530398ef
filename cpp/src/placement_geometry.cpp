// Landmark placement, the geometry [Placement §II]: input checks, the
// candidates near a route, edge frames, [Placement Lemma 1], [Placement
// Lemma 2] and [Placement Cor. 1] and the turns at the route's vertices.
// Candidates are found per edge through a uniform bucket grid, so a route
// costs O(edges · candidates near an edge), not O(edges · all candidates).
// The occluders' shadows are placement_shadows.cpp's, the ILP's tables
// placement_tables.cpp's.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <string>

#include "errors.hpp"
#include "placement_internal.hpp"

namespace safenav {
namespace placement_detail {

namespace {

using detail::fmt;

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
    const std::string name = std::string(what) + "[" + std::to_string(i) + "] = " + fmt(p.row(i).transpose());
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
      fail("route[" + std::to_string(i) + "] = " + fmt(route.row(i).transpose()) + " repeats route[" +
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
           "] coincide at " + fmt(c.row(a).transpose()) + " (two landmarks on one bearing)");
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
    if (occ && hidden(*occ, v, pts.row(i).transpose())) return;  // hidden from the vertex
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

namespace {
// The edge's ends, checked before the frame is built from them.
const Eigen::Vector2d& frame_origin(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  if (!a.allFinite()) fail("EdgeFrame: a = " + fmt(a) + " is not finite");
  if (!b.allFinite()) fail("EdgeFrame: b = " + fmt(b) + " is not finite");
  if (!std::isfinite((b - a).norm()))
    fail("EdgeFrame: the edge " + fmt(a) + " -> " + fmt(b) + " is too long: its length overflows a double");
  return a;
}

Eigen::Vector2d finite_or_fail(const Eigen::Vector2d& out, const char* what, const Eigen::Vector2d& in) {
  if (!out.allFinite())
    fail(std::string("EdgeFrame.") + what + ": " + fmt(in) + " is not finite or too far for the frame, got " + fmt(out));
  return out;
}
}  // namespace

EdgeFrame::EdgeFrame(const Eigen::Vector2d& a, const Eigen::Vector2d& b)
    : origin(frame_origin(a, b)), heading(std::atan2(b.y() - a.y(), b.x() - a.x())), length((b - a).norm()) {
  cos_ = length > 0 ? (b.x() - a.x()) / length : 1.0;
  sin_ = length > 0 ? (b.y() - a.y()) / length : 0.0;
}

Eigen::Vector2d EdgeFrame::to_local(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d q = p - origin;
  return finite_or_fail({cos_ * q.x() + sin_ * q.y(), -sin_ * q.x() + cos_ * q.y()}, "to_local", p);
}

Eigen::Vector2d EdgeFrame::to_world(const Eigen::Vector2d& q) const {
  return finite_or_fail(origin + Eigen::Vector2d(cos_ * q.x() - sin_ * q.y(), sin_ * q.x() + cos_ * q.y()), "to_world",
                        q);
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
