// safenav/placement — landmark placement (the landmark placement paper,
// section II): edge frames, Lemmas 1–2 and Corollary 1, the greedy k-interval
// cover (Algorithm 1, Proposition 1), the union over edges, non-coincidence,
// corner coverage and an exact coverage check.  Candidates are found per edge
// through a uniform bucket grid, so a route costs O(edges · candidates near
// an edge), not O(edges · all candidates).
#include "safenav/placement.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace safenav {

namespace {

constexpr double kEps = 1e-9;         // [m] or [rad]: rounding slack of interval ends
constexpr double kBearingTol = 1e-9;  // [rad]: bearings closer than this are one bearing

double wrap(double a) {
  a = std::fmod(a + kPi, 2.0 * kPi);
  if (a <= 0.0) a += 2.0 * kPi;
  return a - kPi;
}

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument(msg); }

std::string point_str(const Eigen::Vector2d& p) {
  std::ostringstream os;
  os << "(" << p.x() << ", " << p.y() << ")";
  return os.str();
}

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

/// Finite and pairwise distinct: two landmarks at one spot are on one bearing.
void check_candidates(const Points2& c, const char* what = "candidates") {
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

/// Uniform bucket grid over a point set (CSR layout).
class Grid {
 public:
  Grid(const Points2& p, double cell) {
    const Eigen::Index n = p.rows();
    if (n == 0) return;
    x0_ = p.col(0).minCoeff();
    y0_ = p.col(1).minCoeff();
    const double ex = p.col(0).maxCoeff() - x0_, ey = p.col(1).maxCoeff() - y0_;
    h_ = std::max({cell, ex / 1024.0, ey / 1024.0, 1e-9});
    nx_ = static_cast<int>(ex / h_) + 1;
    ny_ = static_cast<int>(ey / h_) + 1;
    start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
    std::vector<int> cell_of(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      cell_of[i] = cell_index(p(i, 0), p(i, 1));
      ++start_[cell_of[i] + 1];
    }
    std::partial_sum(start_.begin(), start_.end(), start_.begin());
    items_.resize(n);
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (Eigen::Index i = 0; i < n; ++i) items_[fill[cell_of[i]]++] = static_cast<int>(i);
  }

  /// Calls f(i) for every point in cells overlapping the box (a superset of the box).
  template <class F>
  void query(double xmin, double ymin, double xmax, double ymax, F&& f) const {
    if (nx_ == 0) return;
    const int i0 = clampx((xmin - x0_) / h_), i1 = clampx((xmax - x0_) / h_);
    const int j0 = clampy((ymin - y0_) / h_), j1 = clampy((ymax - y0_) / h_);
    if ((xmax - x0_) / h_ < 0 || (ymax - y0_) / h_ < 0 || (xmin - x0_) / h_ >= nx_ || (ymin - y0_) / h_ >= ny_) return;
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const int c = j * nx_ + i;
        for (int s = start_[c]; s < start_[c + 1]; ++s) f(items_[s]);
      }
  }

 private:
  int clampx(double v) const { return std::clamp(static_cast<int>(std::floor(v)), 0, nx_ - 1); }
  int clampy(double v) const { return std::clamp(static_cast<int>(std::floor(v)), 0, ny_ - 1); }
  int cell_index(double x, double y) const { return clampy((y - y0_) / h_) * nx_ + clampx((x - x0_) / h_); }

  double x0_ = 0, y0_ = 0, h_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<int> start_, items_;
};

double segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double l2 = ab.squaredNorm();
  const double s = l2 > 0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

/// Candidates within `p` of the route (distance ≤ p).
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
    const double a = std::max(x - h, 0.0);                                       // eq. (1)/(3)
    const double b = circular ? std::min(x + h, length)                          // eq. (4), typo fixed
                              : std::min(x - ay * cot_half, length);             // eq. (2)
    if (b < a - kEps) return false;  // empty by more than the rounding slack (α = 180°: cot(α/2) ≈ 6e-17)
    *out = {a, std::max(a, b)};
    return true;
  }
  double R, R2;
  bool circular;
  double ymax, cot_half;
};

/// A candidate's Lemma 2 interval on one edge with its position in the edge frame.
struct Seen {
  int idx;
  Interval iv;
  Eigen::Vector2d local;
};

/// All candidates (not excluded) with a non-empty interval on edge e, sorted by index.
std::vector<Seen> seen_on_edge(const Points2& route, Eigen::Index e, const Points2& pts, const Grid& grid,
                               const std::vector<char>& excluded, const Camera& cam) {
  const Eigen::Vector2d a = route.row(e).transpose(), b = route.row(e + 1).transpose();
  const EdgeFrame f(a, b);
  const double R = cam.range;
  const Fov fov(cam);
  std::vector<Seen> out;
  grid.query(std::min(a.x(), b.x()) - R, std::min(a.y(), b.y()) - R, std::max(a.x(), b.x()) + R,
             std::max(a.y(), b.y()) + R, [&](int i) {
               if (!excluded.empty() && excluded[i]) return;
               Seen s{i, {}, f.to_local(pts.row(i).transpose())};
               if (std::abs(s.local.y()) <= kEps) s.local.y() = 0.0;  // on the edge's line: bearing 0 or π
               if (fov.interval(s.local, f.length, &s.iv)) out.push_back(s);
             });
  std::sort(out.begin(), out.end(), [](const Seen& x, const Seen& y) { return x.idx < y.idx; });
  return out;
}

double bearing_at(const Eigen::Vector2d& local, double t) { return std::atan2(local.y(), local.x() - t); }

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

bool contains(const Interval& iv, double t) { return iv.start - kEps <= t && t <= iv.end + kEps; }

/// Two landmarks seen on one bearing from a point of the edge where both are in view.
bool aligned_in_view(const Seen& a, const Seen& b, double* t) {
  return alignment_point(a.local, b.local, t) && contains(a.iv, *t) && contains(b.iv, *t);
}

/// In view from (t, 0): inside its interval and not at the camera itself (no bearing there).
bool in_view_at(const Seen& s, double t) {
  return contains(s.iv, t) && (s.local - Eigen::Vector2d(t, 0.0)).norm() > kEps;
}

bool same_bearing(double a, double b) { return std::abs(wrap(a - b)) <= kBearingTol; }

/// Number of distinct values in a list of bearings (tolerance kBearingTol, across ±π too).
int distinct(std::vector<double> bearings) {
  if (bearings.empty()) return 0;
  std::sort(bearings.begin(), bearings.end());
  int n = 1;
  for (size_t i = 1; i < bearings.size(); ++i)
    if (bearings[i] - bearings[i - 1] > kBearingTol) ++n;
  if (n > 1 && same_bearing(bearings.front(), bearings.back())) --n;
  return n;
}

/// Bearings (edge frame) of the landmarks in view from (t, 0).
std::vector<double> bearings_on_edge(const std::vector<Seen>& seen, double t) {
  std::vector<double> br;
  for (const auto& s : seen)
    if (in_view_at(s, t)) br.push_back(bearing_at(s.local, t));
  return br;
}

/// Points of an edge where the number of distinct bearings can change:
/// interval ends, alignment points, and the position of a landmark on the
/// edge's line (its bearing flips from 0 to π there).
std::vector<double> edge_events(const std::vector<Seen>& seen) {
  std::vector<double> pts;
  for (size_t i = 0; i < seen.size(); ++i) {
    pts.push_back(seen[i].iv.start);
    pts.push_back(seen[i].iv.end);
    if (seen[i].local.y() == 0.0) pts.push_back(seen[i].local.x());
    for (size_t j = i + 1; j < seen.size(); ++j) {
      double t;
      if (aligned_in_view(seen[i], seen[j], &t)) pts.push_back(t);
    }
  }
  return pts;
}

/// A stretch [where.start, where.end] of an edge (or turn) with fewer than k
/// distinct bearings in view, and the point `probe` that shows it.
struct Deficit {
  Interval where;
  double probe;
};

/// Exact count over [0, length]: the distinct bearings at every point of
/// `pts` (with 0 and length) and at the midpoint between consecutive ones,
/// where the count is constant.  Returns the deficits in order; lowers *min_count.
template <class Bearings>
std::vector<Deficit> deficits(std::vector<double> pts, double length, int k, Bearings&& bearings_at,
                              int* min_count) {
  pts.push_back(0.0);
  pts.push_back(length);
  for (auto& p : pts) p = std::clamp(p, 0.0, length);
  std::sort(pts.begin(), pts.end());
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  std::vector<Deficit> out;
  auto note = [&](double a, double b, double probe) {
    const int n = distinct(bearings_at(probe));
    *min_count = std::min(*min_count, n);
    if (n < k) out.push_back({{a, b}, probe});
  };
  for (size_t i = 0; i < pts.size(); ++i) {
    note(pts[i], pts[i], pts[i]);
    if (i + 1 < pts.size()) note(pts[i], pts[i + 1], 0.5 * (pts[i] + pts[i + 1]));
  }
  return out;
}

std::vector<Deficit> edge_deficits(const std::vector<Seen>& seen, double length, int k, int* min_count) {
  return deficits(edge_events(seen), length, k, [&](double t) { return bearings_on_edge(seen, t); }, min_count);
}

/// Non-coincidence on one edge, part 1: candidates on the edge's own line
/// (y = 0) share one bearing wherever two are in view (0 ahead, π behind;
/// those on the edge itself are within p and gone).  On each side their
/// intervals are nested, so keep only the longest, and none on a side where
/// a landmark already placed (`pre`) sits: a second one there would add a
/// count the exact check does not see.
void one_per_line_side(std::vector<Seen>* pool, const std::vector<Seen>& pre) {
  for (const bool ahead : {true, false}) {
    auto on_side = [&](const Seen& s) { return s.local.y() == 0.0 && (s.local.x() > 0) == ahead; };
    const bool placed = std::any_of(pre.begin(), pre.end(), on_side);
    const Seen* keep = nullptr;
    for (const auto& s : *pool)
      if (on_side(s) && !placed && (!keep || s.iv.end - s.iv.start > keep->iv.end - keep->iv.start)) keep = &s;
    const int keep_idx = keep ? keep->idx : -1;
    pool->erase(std::remove_if(pool->begin(), pool->end(),
                               [&](const Seen& s) { return on_side(s) && s.idx != keep_idx; }),
                pool->end());
  }
}

/// Non-coincidence on one edge, part 2: while the exact count finds a point
/// with fewer than k distinct bearings where an unused candidate is in view
/// with a fresh bearing, add at the first such point the one reaching
/// farthest.  Each round takes one candidate, so it ends.
void repair(std::vector<Seen>& set, const std::vector<Seen>& pool, std::vector<char>& taken, double length, int k,
            std::vector<int>* added) {
  for (;;) {
    int worst = k;
    int best = -1;
    for (const Deficit& g : edge_deficits(set, length, k, &worst)) {
      const std::vector<double> brg = bearings_on_edge(set, g.probe);
      for (size_t c = 0; c < pool.size(); ++c) {
        if (taken[c] || !in_view_at(pool[c], g.probe)) continue;
        const double bc = bearing_at(pool[c].local, g.probe);
        const bool fresh = std::none_of(brg.begin(), brg.end(), [&](double b) { return same_bearing(b, bc); });
        if (fresh && (best < 0 || pool[c].iv.end > pool[best].iv.end)) best = static_cast<int>(c);
      }
      if (best >= 0) break;
    }
    if (best < 0) return;
    taken[best] = 1;
    set.push_back(pool[best]);
    added->push_back(best);
  }
}

/// Greedy cover of one edge (or turn) from a pool; returns pool indices picked.
CoverResult cover_pool(const std::vector<Seen>& pool, const std::vector<Interval>& preplaced, double length, int k) {
  std::vector<Interval> iv(pool.size());
  for (size_t i = 0; i < pool.size(); ++i) iv[i] = pool[i].iv;
  return greedy_cover(iv, length, k, preplaced);
}

/// Closed intervals kept as sorted starts and ends: the number covering
/// just right of b is #(start ≤ b + ε) − #(end ≤ b + ε).
class IntervalCount {
 public:
  void add(const Interval& s) {
    starts_.insert(std::upper_bound(starts_.begin(), starts_.end(), s.start), s.start);
    ends_.insert(std::upper_bound(ends_.begin(), ends_.end(), s.end), s.end);
  }
  int right_of(double b) const { return upto(starts_, b + kEps) - upto(ends_, b + kEps); }
  int at_zero() const {  // start ≤ ε and end ≥ 0
    return upto(starts_, kEps) - static_cast<int>(std::lower_bound(ends_.begin(), ends_.end(), 0.0) - ends_.begin());
  }
  const std::vector<double>& ends() const { return ends_; }

 private:
  static int upto(const std::vector<double>& v, double x) {
    return static_cast<int>(std::upper_bound(v.begin(), v.end(), x) - v.begin());
  }
  std::vector<double> starts_, ends_;
};

/// Candidates around one interior vertex with their interval of turned angle.
std::vector<Seen> seen_at_corner(const Eigen::Vector2d& v, double theta_in, double turn, const Points2& pts,
                                 const Grid& grid, const std::vector<char>& excluded, const Camera& cam) {
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
    out.push_back({i, iv, rel});
  });
  std::sort(out.begin(), out.end(), [](const Seen& x, const Seen& y) { return x.idx < y.idx; });
  return out;
}

}  // namespace

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

std::vector<Interval> deficient_stretches(const std::vector<Interval>& iv, double length, int k) {
  std::vector<double> pts{0.0, length};
  for (const auto& s : iv) {
    if (s.start > 0 && s.start < length) pts.push_back(s.start);
    if (s.end > 0 && s.end < length) pts.push_back(s.end);
  }
  std::sort(pts.begin(), pts.end());
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  auto count = [&](double t) {
    int n = 0;
    for (const auto& s : iv) n += contains(s, t);
    return n;
  };
  std::vector<Interval> out;
  auto add = [&](double a, double b) {
    if (!out.empty() && a <= out.back().end) out.back().end = std::max(out.back().end, b);
    else out.push_back({a, b});
  };
  for (size_t i = 0; i < pts.size(); ++i) {
    if (count(pts[i]) < k) add(pts[i], pts[i]);
    if (i + 1 < pts.size() && count(0.5 * (pts[i] + pts[i + 1])) < k) add(pts[i], pts[i + 1]);
  }
  std::vector<Interval> real;
  for (const auto& s : out)
    if (s.end - s.start > kEps) real.push_back(s);
  return real;
}

CoverResult greedy_cover(const std::vector<Interval>& intervals, double length, int k,
                         const std::vector<Interval>& preplaced) {
  check_k(k);
  if (!std::isfinite(length) || length < 0) fail("cover length = " + std::to_string(length) + " must be >= 0");
  for (size_t i = 0; i < intervals.size(); ++i)
    if (!std::isfinite(intervals[i].start) || !std::isfinite(intervals[i].end) || intervals[i].end < intervals[i].start)
      fail("interval " + std::to_string(i) + " = [" + std::to_string(intervals[i].start) + ", " +
           std::to_string(intervals[i].end) + "] is not a finite interval");
  for (size_t i = 0; i < preplaced.size(); ++i)
    if (!std::isfinite(preplaced[i].start) || !std::isfinite(preplaced[i].end) || preplaced[i].end < preplaced[i].start)
      fail("preplaced interval " + std::to_string(i) + " is not a finite interval");
  CoverResult res;
  IntervalCount have;     // chosen + preplaced
  IntervalCount skipped;  // stretches nothing covers: count as k, so the cost does not grow with k
  for (const auto& s : preplaced) have.add(s);
  std::vector<char> used(intervals.size(), 0);
  auto covers_right_of = [](const Interval& s, double c) { return s.start <= c + kEps && s.end > c + kEps; };
  auto short_right_of = [&](double b) { return have.right_of(b) + (skipped.right_of(b) > 0 ? k : 0) < k; };
  double last = 0.0;  // deficits only move right
  // Each round takes an interval or skips to the next start: at most 2n + 2 rounds.
  for (size_t round = 0; round < 2 * intervals.size() + 2; ++round) {
    // Leftmost point covered fewer than k times: 0 (closed) or just right of an end b.
    double c = -1.0;
    bool open = false;
    if (have.at_zero() + (skipped.at_zero() > 0 ? k : 0) < k) {
      c = 0.0;
    } else {
      std::vector<double> ends = have.ends();
      ends.push_back(0.0);
      ends.insert(ends.end(), skipped.ends().begin(), skipped.ends().end());
      std::sort(ends.begin(), ends.end());
      for (double b : ends) {
        if (b < last) continue;
        if (b >= length - kEps) break;
        if (short_right_of(b)) {
          c = b;
          open = true;
          break;
        }
      }
    }
    if (c < 0) break;  // covered
    last = c;
    int best = -1;
    for (size_t i = 0; i < intervals.size(); ++i) {
      if (used[i]) continue;
      const Interval& s = intervals[i];
      const bool ok = open ? covers_right_of(s, c) : (s.start <= c + kEps && s.end >= c - kEps);
      if (ok && (best < 0 || s.end > intervals[best].end)) best = static_cast<int>(i);
    }
    if (best >= 0) {
      used[best] = 1;
      res.chosen.push_back(best);
      have.add(intervals[best]);
      continue;
    }
    // Stuck: nothing covers c.  Skip to where the next candidate starts.
    double next = length;
    for (size_t i = 0; i < intervals.size(); ++i)
      if (!used[i] && intervals[i].start > c + kEps) next = std::min(next, intervals[i].start);
    skipped.add({c, std::max(next, c + 2 * kEps)});
  }
  std::vector<Interval> real = preplaced;
  for (int i : res.chosen) real.push_back(intervals[i]);
  res.uncovered = deficient_stretches(real, length, k);
  return res;
}

bool Placement::covered() const {
  for (const auto& e : edges)
    if (!e.uncovered.empty()) return false;
  for (const auto& c : corners)
    if (!c.uncovered.empty()) return false;
  return true;
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

Placement place_landmarks(const Points2& route, const Points2& candidates, const Camera& camera,
                          const PlacementOptions& opt) {
  camera.validate();
  check_route(route);
  check_candidates(candidates);
  check_k(opt.k);
  const int k = opt.k;
  const Grid grid(candidates, 0.5 * camera.range);
  const std::vector<char> close = within(route, candidates, grid, camera.clearance);
  Placement out;
  for (Eigen::Index i = 0; i < candidates.rows(); ++i)
    if (close[i]) out.too_close.push_back(static_cast<int>(i));
  std::vector<char> picked(candidates.rows(), 0);

  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e) {
    std::vector<Seen> all = seen_on_edge(route, e, candidates, grid, close, camera);
    std::vector<Seen> pool, pre;
    for (const auto& s : all) (opt.reuse && picked[s.idx] ? pre : pool).push_back(s);
    if (opt.distinct_bearings) one_per_line_side(&pool, pre);
    std::vector<Interval> pre_iv;
    for (const auto& s : pre) pre_iv.push_back(s.iv);
    const double d = (route.row(e + 1) - route.row(e)).norm();
    CoverResult r = cover_pool(pool, pre_iv, d, k);
    EdgePlacement ep;
    ep.n_candidates = static_cast<int>(all.size());
    std::vector<char> taken(pool.size(), 0);
    std::vector<Seen> set = pre;
    for (int i : r.chosen) {
      taken[i] = 1;
      set.push_back(pool[i]);
    }
    std::vector<int> chosen = r.chosen;
    if (opt.distinct_bearings) repair(set, pool, taken, d, k, &chosen);
    for (int i : chosen) {
      ep.landmarks.push_back(pool[i].idx);
      picked[pool[i].idx] = 1;
    }
    std::sort(ep.landmarks.begin(), ep.landmarks.end());
    out.edges.push_back(std::move(ep));
  }

  if (opt.corners) {
    const Eigen::VectorXd turns = turn_angles(route);
    for (Eigen::Index v = 1; v + 1 < route.rows(); ++v) {
      const double turn = turns(v - 1);
      if (std::abs(turn) <= kEps) continue;
      const double theta_in = std::atan2(route(v, 1) - route(v - 1, 1), route(v, 0) - route(v - 1, 0));
      std::vector<Seen> all = seen_at_corner(route.row(v).transpose(), theta_in, turn, candidates, grid, close, camera);
      // Landmarks on one ray from the vertex are one bearing for the whole turn:
      // keep one per ray, an already placed one first, else the nearest.
      std::vector<int> order(all.size());
      std::iota(order.begin(), order.end(), 0);
      std::vector<double> brg(all.size());
      for (size_t i = 0; i < all.size(); ++i) brg[i] = std::atan2(all[i].local.y(), all[i].local.x());
      std::sort(order.begin(), order.end(), [&](int a, int b) {
        if (brg[a] != brg[b]) return brg[a] < brg[b];
        if (picked[all[a].idx] != picked[all[b].idx]) return picked[all[a].idx] > picked[all[b].idx];
        return all[a].local.norm() < all[b].local.norm();
      });
      std::vector<Seen> pool, pre;
      double last = -10.0;
      for (int i : order) {
        if (opt.distinct_bearings && brg[i] - last <= kBearingTol) continue;
        last = brg[i];
        (picked[all[i].idx] ? pre : pool).push_back(all[i]);
      }
      std::vector<Interval> pre_iv;
      for (const auto& s : pre) pre_iv.push_back(s.iv);
      CoverResult r = cover_pool(pool, pre_iv, std::abs(turn), k);
      CornerPlacement cp;
      cp.vertex = static_cast<int>(v);
      cp.turn = turn;
      for (int i : r.chosen) {
        cp.landmarks.push_back(pool[i].idx);
        picked[pool[i].idx] = 1;
      }
      std::sort(cp.landmarks.begin(), cp.landmarks.end());
      out.corners.push_back(std::move(cp));
    }
  }
  for (Eigen::Index i = 0; i < candidates.rows(); ++i)
    if (picked[i]) out.landmarks.push_back(static_cast<int>(i));
  // The certificate: the exact check of the final landmarks, never the greedy's own count.
  Points2 placed(static_cast<Eigen::Index>(out.landmarks.size()), 2);
  for (size_t i = 0; i < out.landmarks.size(); ++i) placed.row(static_cast<Eigen::Index>(i)) = candidates.row(out.landmarks[i]);
  const CoverageReport rep = check_coverage(route, placed, camera, k, opt.corners);
  for (Eigen::Index i = 0; i < rep.start.size(); ++i) {
    const Interval s{rep.start(i), rep.end(i)};
    if (rep.kind(i) == 0) {
      out.edges[rep.index(i)].uncovered.push_back(s);
    } else {
      for (auto& cp : out.corners)
        if (cp.vertex == rep.index(i)) cp.uncovered.push_back(s);
    }
  }
  return out;
}

namespace {
VisibilityTable to_table(const std::vector<int>& e, const std::vector<Seen>& s) {
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

VisibilityTable edge_visibility(const Points2& route, const Points2& candidates, const Camera& camera) {
  camera.validate();
  check_route(route);
  check_candidates(candidates);
  const Grid grid(candidates, 0.5 * camera.range);
  const std::vector<char> close = within(route, candidates, grid, camera.clearance);
  std::vector<int> edge;
  std::vector<Seen> rows;
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e)
    for (const auto& s : seen_on_edge(route, e, candidates, grid, close, camera)) {
      edge.push_back(static_cast<int>(e));
      rows.push_back(s);
    }
  return to_table(edge, rows);
}

VisibilityTable corner_visibility(const Points2& route, const Points2& candidates, const Camera& camera) {
  camera.validate();
  const Eigen::VectorXd turns = turn_angles(route);
  check_candidates(candidates);
  const Grid grid(candidates, 0.5 * camera.range);
  const std::vector<char> close = within(route, candidates, grid, camera.clearance);
  std::vector<int> vert;
  std::vector<Seen> rows;
  for (Eigen::Index v = 1; v + 1 < route.rows(); ++v) {
    if (std::abs(turns(v - 1)) <= kEps) continue;
    const double theta_in = std::atan2(route(v, 1) - route(v - 1, 1), route(v, 0) - route(v - 1, 0));
    for (const auto& s : seen_at_corner(route.row(v).transpose(), theta_in, turns(v - 1), candidates, grid, close,
                                        camera)) {
      vert.push_back(static_cast<int>(v));
      rows.push_back(s);
    }
  }
  return to_table(vert, rows);
}

AlignmentTable alignments(const Points2& route, const Points2& candidates, const Camera& camera) {
  camera.validate();
  check_route(route);
  check_candidates(candidates);
  const Grid grid(candidates, 0.5 * camera.range);
  const std::vector<char> close = within(route, candidates, grid, camera.clearance);
  std::vector<int> e_, f_, s_;
  std::vector<double> t_;
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e) {
    const auto seen = seen_on_edge(route, e, candidates, grid, close, camera);
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

CoverageReport check_coverage(const Points2& route, const Points2& landmarks, const Camera& camera, int k,
                              bool corners) {
  camera.validate();
  check_route(route);
  check_candidates(landmarks, "landmarks");
  check_k(k);
  CoverageReport rep;
  rep.min_count = std::numeric_limits<int>::max();
  rep.min_distance = landmarks.rows() ? distance_to_route(route, landmarks).minCoeff()
                                      : std::numeric_limits<double>::infinity();
  const Grid grid(landmarks, camera.range);
  std::vector<int> kind, index;
  std::vector<double> a_, b_;
  // Deficient stretches of one edge or turn, adjacent ones merged.
  auto record = [&](const std::vector<Deficit>& found, int kd, int idx) {
    const size_t first = a_.size();
    for (const Deficit& g : found) {
      if (a_.size() > first && g.where.start <= b_.back()) {
        b_.back() = std::max(b_.back(), g.where.end);
        continue;
      }
      kind.push_back(kd);
      index.push_back(idx);
      a_.push_back(g.where.start);
      b_.push_back(g.where.end);
    }
  };
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e) {
    const auto seen = seen_on_edge(route, e, landmarks, grid, {}, camera);
    const double d = (route.row(e + 1) - route.row(e)).norm();
    record(edge_deficits(seen, d, k, &rep.min_count), 0, static_cast<int>(e));
  }
  if (corners) {
    const Eigen::VectorXd turns = turn_angles(route);
    for (Eigen::Index v = 1; v + 1 < route.rows(); ++v) {
      if (std::abs(turns(v - 1)) <= kEps) continue;
      const double theta_in = std::atan2(route(v, 1) - route(v - 1, 1), route(v, 0) - route(v - 1, 0));
      const auto seen = seen_at_corner(route.row(v).transpose(), theta_in, turns(v - 1), landmarks, grid, {}, camera);
      std::vector<double> pts;
      for (const auto& s : seen) {
        pts.push_back(s.iv.start);
        pts.push_back(s.iv.end);
      }
      auto bearings = [&](double u) {
        std::vector<double> br;
        for (const auto& s : seen)
          if (contains(s.iv, u)) br.push_back(std::atan2(s.local.y(), s.local.x()));
        return br;
      };
      record(deficits(pts, std::abs(turns(v - 1)), k, bearings, &rep.min_count), 1, static_cast<int>(v));
    }
  }
  if (rep.min_count == std::numeric_limits<int>::max()) rep.min_count = 0;
  const Eigen::Index n = static_cast<Eigen::Index>(a_.size());
  rep.kind = Eigen::Map<Eigen::VectorXi>(kind.data(), n);
  rep.index = Eigen::Map<Eigen::VectorXi>(index.data(), n);
  rep.start = Eigen::Map<Eigen::VectorXd>(a_.data(), n);
  rep.end = Eigen::Map<Eigen::VectorXd>(b_.data(), n);
  return rep;
}

}  // namespace safenav
