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

constexpr double kPi = 3.14159265358979323846;
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
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    if (!p.row(i).allFinite()) fail(std::string(what) + "[" + std::to_string(i) + "] = " +
                                    point_str(p.row(i).transpose()) + " is not finite");
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

void check_candidates(const Points2& c) {
  check_points(c, "candidates");
  std::vector<int> order(c.rows());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return c(a, 0) < c(b, 0) || (c(a, 0) == c(b, 0) && c(a, 1) < c(b, 1));
  });
  for (size_t i = 1; i < order.size(); ++i)
    if (c(order[i], 0) == c(order[i - 1], 0) && c(order[i], 1) == c(order[i - 1], 1)) {
      int a = std::min(order[i], order[i - 1]), b = std::max(order[i], order[i - 1]);
      fail("candidates[" + std::to_string(a) + "] and candidates[" + std::to_string(b) + "] coincide at " +
           point_str(c.row(a).transpose()) + " (two landmarks on one bearing)");
    }
}

void check_k(int k) {
  if (k < 1) fail("k = " + std::to_string(k) + " must be >= 1");
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
    if (b < a) return false;
    *out = {a, b};
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
               if (fov.interval(s.local, f.length, &s.iv)) out.push_back(s);
             });
  std::sort(out.begin(), out.end(), [](const Seen& x, const Seen& y) { return x.idx < y.idx; });
  return out;
}

double bearing_at(const Eigen::Vector2d& local, double t) { return std::atan2(local.y(), local.x() - t); }

/// The point t where the line through two landmarks (edge frame) meets the
/// edge's line with both on one ray from it; false when there is none.
bool alignment_point(const Eigen::Vector2d& p, const Eigen::Vector2d& q, double* t) {
  if (!((p.y() > 0 && q.y() > 0) || (p.y() < 0 && q.y() < 0))) return false;
  if (p.y() == q.y()) return false;
  *t = p.x() - p.y() * (q.x() - p.x()) / (q.y() - p.y());
  return true;
}

bool contains(const Interval& iv, double t) { return iv.start - kEps <= t && t <= iv.end + kEps; }

/// Number of distinct values in a list of bearings (tolerance kBearingTol).
int distinct(std::vector<double>& bearings) {
  if (bearings.empty()) return 0;
  std::sort(bearings.begin(), bearings.end());
  int n = 1;
  for (size_t i = 1; i < bearings.size(); ++i)
    if (bearings[i] - bearings[i - 1] > kBearingTol) ++n;
  return n;
}

/// Non-coincidence repair on one edge: wherever two landmarks of `set` align
/// at a point that then has fewer than k distinct bearings in view, add the
/// candidate in view there with a new bearing that reaches farthest.
void repair_alignments(std::vector<Seen>& set, const std::vector<Seen>& pool, std::vector<char>& taken, int k,
                       std::vector<int>* added, std::vector<Interval>* uncovered) {
  for (int guard = 0; guard <= static_cast<int>(pool.size()); ++guard) {
    bool changed = false;
    for (size_t i = 0; i < set.size() && !changed; ++i)
      for (size_t j = i + 1; j < set.size() && !changed; ++j) {
        double t;
        if (!alignment_point(set[i].local, set[j].local, &t)) continue;
        if (!contains(set[i].iv, t) || !contains(set[j].iv, t)) continue;
        std::vector<double> brg;
        for (const auto& s : set)
          if (contains(s.iv, t)) brg.push_back(bearing_at(s.local, t));
        std::vector<double> sorted = brg;
        if (distinct(sorted) >= k) continue;
        int best = -1;
        for (size_t c = 0; c < pool.size(); ++c) {
          if (taken[c] || !contains(pool[c].iv, t)) continue;
          const double bc = bearing_at(pool[c].local, t);
          bool fresh = true;
          for (double x : brg) fresh = fresh && std::abs(x - bc) > kBearingTol;
          if (fresh && (best < 0 || pool[c].iv.end > pool[best].iv.end)) best = static_cast<int>(c);
        }
        if (best < 0) {
          bool known = false;
          for (const auto& u : *uncovered) known = known || (u.start == t && u.end == t);
          if (!known) uncovered->push_back({t, t});
          continue;
        }
        taken[best] = 1;
        set.push_back(pool[best]);
        added->push_back(best);
        changed = true;
      }
    if (!changed) return;
  }
}

/// Greedy cover of one edge (or turn) from a pool; returns pool indices picked.
CoverResult cover_pool(const std::vector<Seen>& pool, const std::vector<Interval>& preplaced, double length, int k) {
  std::vector<Interval> iv(pool.size());
  for (size_t i = 0; i < pool.size(); ++i) iv[i] = pool[i].iv;
  return greedy_cover(iv, length, k, preplaced);
}

void merge_sorted(std::vector<Interval>* v) {
  std::sort(v->begin(), v->end(), [](const Interval& a, const Interval& b) { return a.start < b.start; });
  std::vector<Interval> out;
  for (const auto& s : *v) {
    if (!out.empty() && s.start <= out.back().end + kEps) out.back().end = std::max(out.back().end, s.end);
    else out.push_back(s);
  }
  *v = std::move(out);
}

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
      if (iv.end < iv.start) return;
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
  CoverResult res;
  std::vector<Interval> have = preplaced;  // chosen + preplaced + skipped stretches
  std::vector<char> used(intervals.size(), 0);
  const size_t max_steps = intervals.size() + static_cast<size_t>(k) * (intervals.size() + 2) + 8;
  for (size_t step = 0; step < max_steps; ++step) {
    // Leftmost point covered fewer than k times: 0 (closed) or just right of an end b.
    auto covers_right_of = [&](const Interval& s, double c) { return s.start <= c + kEps && s.end > c + kEps; };
    double c = -1.0;
    bool open = false;
    {
      int n0 = 0;
      for (const auto& s : have) n0 += (s.start <= kEps && s.end >= 0.0);
      if (n0 < k) {
        c = 0.0;
      } else {
        std::vector<double> ends{0.0};
        for (const auto& s : have)
          if (s.end < length - kEps) ends.push_back(std::max(s.end, 0.0));
        std::sort(ends.begin(), ends.end());
        ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
        for (double b : ends) {
          if (b >= length - kEps) break;
          int n = 0;
          for (const auto& s : have) n += covers_right_of(s, b);
          if (n < k) {
            c = b;
            open = true;
            break;
          }
        }
      }
    }
    if (c < 0) break;  // covered
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
      have.push_back(intervals[best]);
      continue;
    }
    // Stuck: nothing covers c.  Skip to where the next candidate starts.
    double next = length;
    for (size_t i = 0; i < intervals.size(); ++i)
      if (!used[i] && intervals[i].start > c + kEps) next = std::min(next, intervals[i].start);
    have.push_back({c, std::max(next, c + 2 * kEps)});
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
    std::vector<Interval> pre_iv;
    for (const auto& s : pre) pre_iv.push_back(s.iv);
    const double d = (route.row(e + 1) - route.row(e)).norm();
    CoverResult r = cover_pool(pool, pre_iv, d, k);
    EdgePlacement ep;
    ep.n_candidates = static_cast<int>(all.size());
    ep.uncovered = r.uncovered;
    std::vector<char> taken(pool.size(), 0);
    std::vector<Seen> set = pre;
    for (int i : r.chosen) {
      taken[i] = 1;
      set.push_back(pool[i]);
    }
    std::vector<int> chosen = r.chosen;
    if (opt.distinct_bearings) repair_alignments(set, pool, taken, k, &chosen, &ep.uncovered);
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
      cp.uncovered = r.uncovered;
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
  check_points(candidates, "candidates");
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
  check_points(candidates, "candidates");
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
  check_points(candidates, "candidates");
  const Grid grid(candidates, 0.5 * camera.range);
  const std::vector<char> close = within(route, candidates, grid, camera.clearance);
  std::vector<int> e_, f_, s_;
  std::vector<double> t_;
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e) {
    const auto seen = seen_on_edge(route, e, candidates, grid, close, camera);
    for (size_t i = 0; i < seen.size(); ++i)
      for (size_t j = i + 1; j < seen.size(); ++j) {
        double t;
        if (!alignment_point(seen[i].local, seen[j].local, &t)) continue;
        if (!contains(seen[i].iv, t) || !contains(seen[j].iv, t)) continue;
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
  check_points(landmarks, "landmarks");
  check_k(k);
  CoverageReport rep;
  rep.min_count = std::numeric_limits<int>::max();
  rep.min_distance = landmarks.rows() ? distance_to_route(route, landmarks).minCoeff()
                                      : std::numeric_limits<double>::infinity();
  const Grid grid(landmarks, camera.range);
  std::vector<int> kind, index;
  std::vector<double> a_, b_;
  // Counts distinct bearings at the points of `pts` and between them; records deficient stretches.
  auto sweep = [&](std::vector<double> pts, double length, int kd, int idx, auto&& bearings_at) {
    pts.push_back(0.0);
    pts.push_back(length);
    for (auto& p : pts) p = std::clamp(p, 0.0, length);
    std::sort(pts.begin(), pts.end());
    pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
    std::vector<Interval> bad;
    auto note = [&](double a, double b, int n) {
      rep.min_count = std::min(rep.min_count, n);
      if (n >= k) return;
      if (!bad.empty() && a <= bad.back().end) bad.back().end = std::max(bad.back().end, b);
      else bad.push_back({a, b});
    };
    for (size_t i = 0; i < pts.size(); ++i) {
      std::vector<double> br = bearings_at(pts[i]);
      note(pts[i], pts[i], distinct(br));
      if (i + 1 < pts.size()) {
        std::vector<double> bm = bearings_at(0.5 * (pts[i] + pts[i + 1]));
        note(pts[i], pts[i + 1], distinct(bm));
      }
    }
    for (const auto& s : bad) {
      kind.push_back(kd);
      index.push_back(idx);
      a_.push_back(s.start);
      b_.push_back(s.end);
    }
  };
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e) {
    const auto seen = seen_on_edge(route, e, landmarks, grid, {}, camera);
    const double d = (route.row(e + 1) - route.row(e)).norm();
    std::vector<double> pts;
    for (size_t i = 0; i < seen.size(); ++i) {
      pts.push_back(seen[i].iv.start);
      pts.push_back(seen[i].iv.end);
      for (size_t j = i + 1; j < seen.size(); ++j) {
        double t;
        if (alignment_point(seen[i].local, seen[j].local, &t) && contains(seen[i].iv, t) && contains(seen[j].iv, t))
          pts.push_back(t);
      }
    }
    sweep(pts, d, 0, static_cast<int>(e), [&](double t) {
      std::vector<double> br;
      for (const auto& s : seen)
        if (contains(s.iv, t)) br.push_back(bearing_at(s.local, t));
      return br;
    });
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
      sweep(pts, std::abs(turns(v - 1)), 1, static_cast<int>(v), [&](double t) {
        std::vector<double> br;
        for (const auto& s : seen)
          if (contains(s.iv, t)) br.push_back(std::atan2(s.local.y(), s.local.x()));
        return br;
      });
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
