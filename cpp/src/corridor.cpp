// safenav/corridor — safe-path corridor [SafeNav-ext §V-A3(iii)]
// (= [SafeNav-conf §V-A.2(iii)]): risk zones, deviation [SafeNav eq. 17], WRS
// [SafeNav eq. 18], AWRS [SafeNav-ext eq. 20]; and the segments, hulls and
// centroids of [SafeNav Algs. 1–2].  CGAL does the convex hulls
// (convex_hull_2), orientation and point location (bounded_side_2).
#include "safenav/corridor.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <CGAL/convex_hull_2.h>

#include "cgal_util.hpp"
#include "declare.hpp"

namespace safenav {

template <>
const ParamSet<RiskZones>& param_set<RiskZones>();  // defined below
template <>
const ParamSet<SegmentOptions>& param_set<SegmentOptions>();  // defined below

namespace {

using cgal::K;
using cgal::Point;
using cgal::from_cgal;
using cgal::inside_or_on;
using cgal::to_cgal;

void check_point(const Eigen::Vector2d& p, const char* what) {
  if (!p.allFinite()) {
    std::ostringstream os;
    os << what << " = (" << p.x() << ", " << p.y() << ") is not finite";
    throw std::invalid_argument(os.str());
  }
}

double check_s(double s) {
  if (std::isnan(s)) throw std::invalid_argument("arc length s = nan is not a number");
  return s;
}

}  // namespace

// ----------------------------------------------------------------- risk zones

void RiskZones::validate() const {
  std::ostringstream os;
  if (!(std::isfinite(half_width) && half_width > 0.0)) {
    os << "RiskZones.half_width = " << half_width << " must be finite and > 0";
    throw std::invalid_argument(os.str());
  }
  if (weights.empty()) throw std::invalid_argument("RiskZones.weights must not be empty");
  for (size_t j = 0; j < weights.size(); ++j) {
    if (!(std::isfinite(weights[j]) && weights[j] > 0.0)) {
      os << "RiskZones.weights[" << j << "] = " << weights[j] << " must be finite and > 0";
      throw std::invalid_argument(os.str());
    }
  }
  // The largest WRS is below d_max·(d_max/w_min) (eq. 18): it must be representable.
  const double wmin = *std::min_element(weights.begin(), weights.end());
  if (!std::isfinite(half_width * (half_width / wmin))) {
    os << "RiskZones: half_width = " << half_width << " with weight " << wmin
       << " gives WRS = d_max^2/w beyond 1.8e308";
    throw std::invalid_argument(os.str());
  }
  param_set<RiskZones>().check(*this, "RiskZones.");
}

Eigen::VectorXd distance_to_path(const Eigen::Ref<const Points2>& points, const Eigen::Ref<const Points2>& path) {
  check_points(points, "points", 0);
  check_points(path, "path");
  auto nearest2 = [](const Eigen::RowVector2d& p, const Points2& q) {  // squared distance to the polyline q
    double best = (p - q.row(0)).squaredNorm();
    for (Eigen::Index k = 0; k + 1 < q.rows(); ++k) {
      const Eigen::RowVector2d a = q.row(k), ab = q.row(k + 1) - a;
      const double L2 = ab.squaredNorm();
      const double t = L2 > 0.0 ? std::clamp((p - a).dot(ab) / L2, 0.0, 1.0) : 0.0;
      best = std::min(best, (p - (a + t * ab)).squaredNorm());
    }
    return best;
  };
  // A point whose coordinates (or the path's) exceed 2^500 is measured with
  // everything scaled by one power of two (exact), so the squares cannot overflow.
  const Points2 Q = path;
  const double path_max = Q.cwiseAbs().maxCoeff();
  const double sc = overflow_scale(std::max(points.rows() ? points.cwiseAbs().maxCoeff() : 0.0, path_max));
  const Points2 Qs = Q * sc;
  Eigen::VectorXd d(points.rows());
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const Eigen::RowVector2d p = points.row(i);
    const bool big = overflow_scale(std::max(p.cwiseAbs().maxCoeff(), path_max)) != 1.0;
    d[i] = big ? std::sqrt(nearest2(p * sc, Qs)) / sc : std::sqrt(nearest2(p, Q));
    if (!std::isfinite(d[i])) {
      std::ostringstream os;
      os << "distance_to_path: point " << i << " = (" << p.x() << ", " << p.y()
         << ") is farther than 1.8e308 from the path";
      throw std::invalid_argument(os.str());
    }
  }
  return d;
}

double wrs(double deviation, const RiskZones& z) {
  if (!std::isfinite(deviation)) {
    std::ostringstream os;
    os << "WRS deviation = " << deviation << " is not finite";
    throw std::invalid_argument(os.str());
  }
  const double d = std::abs(deviation);
  const double dmax = z.half_width;
  const double wmax = *std::max_element(z.weights.begin(), z.weights.end());
  if (d >= dmax) return dmax * (dmax / wmax);
  const size_t n = z.weights.size();
  size_t j = static_cast<size_t>(d / (dmax / static_cast<double>(n)));
  j = std::min(j, n - 1);
  return d * (d / z.weights[j]);
}

Eigen::VectorXd wrs(const Eigen::Ref<const Points2>& points, const Eigen::Ref<const Points2>& path,
                    const RiskZones& zones) {
  zones.validate();
  Eigen::VectorXd d = distance_to_path(points, path);
  for (Eigen::Index i = 0; i < d.size(); ++i) d[i] = wrs(d[i], zones);
  return d;
}

double awrs(const Eigen::Ref<const Points2>& points, const Eigen::Ref<const Points2>& path, const RiskZones& zones) {
  check_points(points, "points");
  return finite_mean(wrs(points, path, zones));
}

// ------------------------------------------------------------------- Corridor

Corridor::Corridor(const Eigen::Ref<const Points2>& path, RiskZones zones) : zones_(std::move(zones)) {
  zones_.validate();
  check_points(path, "path", 2);
  // Drop consecutive duplicates (zero-length edges).
  std::vector<Eigen::Index> keep{0};
  for (Eigen::Index i = 1; i < path.rows(); ++i)
    if (path.row(i) != path.row(keep.back())) keep.push_back(i);
  if (keep.size() < 2) {
    std::ostringstream os;
    os << "path has zero length: all " << path.rows() << " points equal (" << path(0, 0) << ", " << path(0, 1) << ")";
    throw std::invalid_argument(os.str());
  }
  path_.resize(static_cast<Eigen::Index>(keep.size()), 2);
  for (size_t i = 0; i < keep.size(); ++i) path_.row(static_cast<Eigen::Index>(i)) = path.row(keep[i]);
  const double sc = overflow_scale(path_.cwiseAbs().maxCoeff());  // exact; squares cannot overflow
  cumulative_.resize(path_.rows());
  cumulative_[0] = 0.0;
  for (Eigen::Index i = 1; i < path_.rows(); ++i)
    cumulative_[i] = cumulative_[i - 1] + (path_.row(i) * sc - path_.row(i - 1) * sc).norm() / sc;
  if (!(length() > 0.0) || !std::isfinite(length())) {
    std::ostringstream os;
    os << "path length = " << length() << " must be finite and > 0";
    throw std::invalid_argument(os.str());
  }
}

PathProjection Corridor::project(const Eigen::Vector2d& p) const {
  check_point(p, "point");
  // Coordinates beyond 2^500 are scaled by a power of two (exact, so ordinary
  // inputs keep every bit): the squared distances below cannot overflow.
  const double sc = overflow_scale(std::max(p.cwiseAbs().maxCoeff(), path_.cwiseAbs().maxCoeff()));
  const Points2 scaled = sc == 1.0 ? Points2() : Points2(path_ * sc);
  const Points2& path = sc == 1.0 ? path_ : scaled;
  const Eigen::Vector2d q = p * sc;
  PathProjection best;
  double best_d2 = std::numeric_limits<double>::infinity();
  double best_t = 0.0;
  // Scaled, a short edge's squared length can underflow: take its direction from the unscaled edge.
  auto along_scaled = [&](const Eigen::Vector2d& w, Eigen::Index k) {
    const Eigen::Vector2d e = (path_.row(k + 1) - path_.row(k)).transpose();
    const double len = std::hypot(e.x(), e.y()), den = len * sc;
    return den > 0.0 ? w.dot(e / len) / den : 0.0;
  };
  for (Eigen::Index k = 0; k + 1 < path.rows(); ++k) {
    const Eigen::Vector2d a = path.row(k).transpose(), ab = path.row(k + 1).transpose() - a;
    const double t = std::clamp(sc == 1.0 ? (q - a).dot(ab) / ab.squaredNorm() : along_scaled(q - a, k), 0.0, 1.0);
    const Eigen::Vector2d foot = a + t * ab;
    const double d2 = (q - foot).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best_t = t;
      best.edge = static_cast<int>(k);
      best.foot = foot / sc;
    }
  }
  const Eigen::Index k = best.edge;
  best.distance = std::sqrt(best_d2) / sc;
  if (!std::isfinite(best.distance)) {
    std::ostringstream os;
    os << "point (" << p.x() << ", " << p.y() << ") is farther than 1.8e308 from the path";
    throw std::invalid_argument(os.str());
  }
  best.arc_length = std::min(cumulative_[k] + best_t * (cumulative_[k + 1] - cumulative_[k]), length());
  if (best.distance > 0.0) {
    const CGAL::Orientation o = CGAL::orientation(Point(path_(k, 0), path_(k, 1)),
                                                  Point(path_(k + 1, 0), path_(k + 1, 1)), Point(p.x(), p.y()));
    best.side = o == CGAL::LEFT_TURN ? 1 : (o == CGAL::RIGHT_TURN ? -1 : 0);
  }
  return best;
}

Eigen::Vector2d Corridor::point_at(double s) const {
  s = std::clamp(check_s(s), 0.0, length());
  const Eigen::Index n = cumulative_.size();
  Eigen::Index k = std::upper_bound(cumulative_.data(), cumulative_.data() + n, s) - cumulative_.data() - 1;
  k = std::clamp<Eigen::Index>(k, 0, n - 2);
  const double t = (s - cumulative_[k]) / (cumulative_[k + 1] - cumulative_[k]);
  return (path_.row(k) + t * (path_.row(k + 1) - path_.row(k))).transpose();
}

Eigen::Vector2d Corridor::tangent_at(double s) const {
  s = std::clamp(check_s(s), 0.0, length());
  const Eigen::Index n = cumulative_.size();
  Eigen::Index k = std::upper_bound(cumulative_.data(), cumulative_.data() + n, s) - cumulative_.data() - 1;
  k = std::clamp<Eigen::Index>(k, 0, n - 2);
  return (path_.row(k + 1) - path_.row(k)).normalized().transpose();
}

bool Corridor::contains(const Eigen::Vector2d& p) const { return project(p).distance <= half_width(); }

int Corridor::zone(const Eigen::Vector2d& p) const {
  const double d = project(p).distance;
  const int n = zone_count();
  if (d >= half_width()) return n;
  return std::min(static_cast<int>(d / (half_width() / n)), n - 1);
}

double Corridor::wrs(const Eigen::Vector2d& p) const { return safenav::wrs(project(p).distance, zones_); }

namespace {
template <class Out, class F>
Out per_point(const Eigen::Ref<const Points2>& pts, F f) {
  check_points(pts, "points", 0);
  Out out(pts.rows());
  for (Eigen::Index i = 0; i < pts.rows(); ++i) out[i] = f(Eigen::Vector2d(pts(i, 0), pts(i, 1)));
  return out;
}
}  // namespace

Eigen::VectorXd Corridor::distance(const Eigen::Ref<const Points2>& pts) const {
  return per_point<Eigen::VectorXd>(pts, [&](const Eigen::Vector2d& p) { return project(p).distance; });
}
Eigen::VectorXd Corridor::arc_length(const Eigen::Ref<const Points2>& pts) const {
  return per_point<Eigen::VectorXd>(pts, [&](const Eigen::Vector2d& p) { return project(p).arc_length; });
}
Eigen::VectorXd Corridor::signed_offset(const Eigen::Ref<const Points2>& pts) const {
  return per_point<Eigen::VectorXd>(pts, [&](const Eigen::Vector2d& p) { return project(p).signed_offset(); });
}
Eigen::VectorXi Corridor::side(const Eigen::Ref<const Points2>& pts) const {
  return per_point<Eigen::VectorXi>(pts, [&](const Eigen::Vector2d& p) { return project(p).side; });
}
Eigen::VectorXi Corridor::zone(const Eigen::Ref<const Points2>& pts) const {
  return per_point<Eigen::VectorXi>(pts, [&](const Eigen::Vector2d& p) { return zone(p); });
}
BoolVector Corridor::contains(const Eigen::Ref<const Points2>& pts) const {
  return per_point<BoolVector>(pts, [&](const Eigen::Vector2d& p) { return contains(p); });
}
Eigen::VectorXd Corridor::wrs(const Eigen::Ref<const Points2>& pts) const {
  return per_point<Eigen::VectorXd>(pts, [&](const Eigen::Vector2d& p) { return wrs(p); });
}
double Corridor::awrs(const Eigen::Ref<const Points2>& pts) const {
  check_points(pts, "points", 1);
  return finite_mean(wrs(pts));
}
Points2 Corridor::points_at(const Eigen::Ref<const Eigen::VectorXd>& s) const {
  Points2 out(s.size(), 2);
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    if (std::isnan(s[i])) {
      std::ostringstream os;
      os << "arc length s[" << i << "] = nan is not a number";
      throw std::invalid_argument(os.str());
    }
    out.row(i) = point_at(s[i]).transpose();
  }
  return out;
}

PathSegments Corridor::segments(const SegmentOptions& options) const { return PathSegments(*this, options); }

// --------------------------------------------------------------- PathSegments

void SegmentOptions::validate() const { param_set<SegmentOptions>().check(*this, "SegmentOptions."); }

struct PathSegments::Impl {
  std::vector<std::vector<Point>> hulls;
  std::vector<Eigen::Vector4d> boxes;  // xmin, ymin, xmax, ymax
  bool contains(size_t k, const Eigen::Vector2d& p) const {
    const Eigen::Vector4d& b = boxes[k];
    if (p.x() < b[0] || p.y() < b[1] || p.x() > b[2] || p.y() > b[3]) return false;
    return inside_or_on(hulls[k], Point(p.x(), p.y()));
  }
};

PathSegments::PathSegments(const Corridor& corridor, const SegmentOptions& options)
    : corridor_(corridor), options_(options) {
  options_.validate();
  const double L = corridor_.length();
  double nseg = options_.count > 0 ? options_.count : std::ceil(L / options_.length * (1.0 - 1e-12));
  nseg = std::max(nseg, 1.0);
  if (nseg > 1e6) {
    std::ostringstream os;
    os << "path of length " << L << " cut into segments of length " << options_.length << " gives " << nseg
       << " segments (limit 1e6)";
    throw std::invalid_argument(os.str());
  }
  const int nk = static_cast<int>(nseg);
  breaks_.resize(nk + 1);
  for (int k = 0; k <= nk; ++k) breaks_[k] = L * k / nk;
  breaks_[nk] = L;

  auto impl = std::make_shared<Impl>();
  const int m = options_.sub_segments;
  centroids_.resize(static_cast<Eigen::Index>(nk) * m, 2);
  centroid_s_.resize(static_cast<Eigen::Index>(nk) * m);
  for (int k = 0; k < nk; ++k) {
    const Points2 in = hull_input(k);
    const std::vector<Point> pts = to_cgal(in);
    std::vector<Point> hull;
    CGAL::convex_hull_2(pts.begin(), pts.end(), std::back_inserter(hull), K());
    hulls_.push_back(from_cgal(hull));
    const Points2& h = hulls_.back();
    impl->boxes.emplace_back(h.col(0).minCoeff(), h.col(1).minCoeff(), h.col(0).maxCoeff(), h.col(1).maxCoeff());
    impl->hulls.push_back(std::move(hull));

    for (int j = 0; j < m; ++j) {
      const double s0 = breaks_[k] + (breaks_[k + 1] - breaks_[k]) * j / m;
      const double s1 = j + 1 == m ? breaks_[k + 1] : breaks_[k] + (breaks_[k + 1] - breaks_[k]) * (j + 1) / m;
      const Points2 q = polyline(s0, s1);
      Eigen::RowVector2d acc(0, 0);
      double total = 0.0;
      for (Eigen::Index e = 0; e + 1 < q.rows(); ++e) {
        const double len = (q.row(e + 1) - q.row(e)).norm();
        acc += len * 0.5 * (q.row(e) + q.row(e + 1));
        total += len;
      }
      const Eigen::Index row = static_cast<Eigen::Index>(k) * m + j;
      centroids_.row(row) = total > 0.0 ? Eigen::RowVector2d(acc / total) : Eigen::RowVector2d(q.row(0));
      centroid_s_[row] = 0.5 * (s0 + s1);
    }
  }
  impl_ = std::move(impl);
}

void PathSegments::check_index(int k) const {
  if (k < 0 || k >= size()) {
    std::ostringstream os;
    os << "segment index " << k << " out of range [0, " << size() << ")";
    throw std::invalid_argument(os.str());
  }
}

int PathSegments::segment_at(double s) const {
  s = std::clamp(check_s(s), 0.0, corridor_.length());
  const Eigen::Index n = breaks_.size();
  Eigen::Index k = std::upper_bound(breaks_.data(), breaks_.data() + n, s) - breaks_.data() - 1;
  return static_cast<int>(std::clamp<Eigen::Index>(k, 0, n - 2));
}

Points2 PathSegments::polyline(double s0, double s1) const {
  const Eigen::VectorXd& cum = corridor_.vertex_arc_lengths();
  // The vertices strictly between s0 and s1, found by binary search: O(log M + vertices in range).
  const double* begin = cum.data();
  const Eigen::Index i0 = std::upper_bound(begin, begin + cum.size(), s0) - begin;
  const Eigen::Index i1 = std::max(i0, static_cast<Eigen::Index>(std::lower_bound(begin, begin + cum.size(), s1) - begin));
  std::vector<Eigen::RowVector2d> rows{corridor_.point_at(s0).transpose()};
  for (Eigen::Index i = i0; i < i1; ++i) rows.push_back(corridor_.path().row(i));
  rows.push_back(corridor_.point_at(s1).transpose());
  Points2 out(static_cast<Eigen::Index>(rows.size()), 2);
  for (size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = rows[i];
  return out;
}

Points2 PathSegments::points(int k) const {
  check_index(k);
  const Points2 q = polyline(breaks_[k], breaks_[k + 1]);
  std::vector<Eigen::RowVector2d> rows{q.row(0)};
  for (Eigen::Index e = 0; e + 1 < q.rows(); ++e) {
    const double len = (q.row(e + 1) - q.row(e)).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(len / options_.spacing)));
    for (int i = 1; i <= steps; ++i) rows.push_back(q.row(e) + (q.row(e + 1) - q.row(e)) * (double(i) / steps));
  }
  Points2 out(static_cast<Eigen::Index>(rows.size()), 2);
  for (size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = rows[i];
  return out;
}

Points2 PathSegments::hull_input(int k) const {
  check_index(k);
  const Points2 q = polyline(breaks_[k], breaks_[k + 1]);
  const int n = options_.disc_sides;
  const double R = corridor_.half_width() / std::cos(kPi / n);
  Points2 out(q.rows() * n, 2);
  for (Eigen::Index i = 0; i < q.rows(); ++i)
    for (int j = 0; j < n; ++j) {
      const double a = 2.0 * kPi * j / n;
      out.row(i * n + j) = q.row(i) + R * Eigen::RowVector2d(std::cos(a), std::sin(a));
    }
  return out;
}

const Points2& PathSegments::hull(int k) const {
  check_index(k);
  return hulls_[static_cast<size_t>(k)];
}

bool PathSegments::hull_contains(int k, const Eigen::Vector2d& p) const {
  check_index(k);
  check_point(p, "point");
  return impl_->contains(static_cast<size_t>(k), p);
}

BoolVector PathSegments::hull_contains(int k, const Eigen::Ref<const Points2>& pts) const {
  check_index(k);
  return per_point<BoolVector>(pts, [&](const Eigen::Vector2d& p) { return impl_->contains(static_cast<size_t>(k), p); });
}

bool PathSegments::in_current_or_next(int k, const Eigen::Vector2d& p) const {
  check_index(k);
  check_point(p, "point");
  return impl_->contains(static_cast<size_t>(k), p) || (k + 1 < size() && impl_->contains(static_cast<size_t>(k + 1), p));
}

std::vector<int> PathSegments::segments_containing(const Eigen::Vector2d& p) const {
  check_point(p, "point");
  std::vector<int> out;
  for (int k = 0; k < size(); ++k)
    if (impl_->contains(static_cast<size_t>(k), p)) out.push_back(k);
  return out;
}

Eigen::VectorXi PathSegments::locate(const Eigen::Ref<const Points2>& pts) const {
  return per_point<Eigen::VectorXi>(pts, [&](const Eigen::Vector2d& p) {
    for (int k = 0; k < size(); ++k)
      if (impl_->contains(static_cast<size_t>(k), p)) return k;
    return -1;
  });
}

Points2 PathSegments::segment_centroids(int k) const {
  check_index(k);
  const int m = options_.sub_segments;
  return centroids_.middleRows(static_cast<Eigen::Index>(k) * m, m);
}

CentroidTarget PathSegments::nearest_centroid_ahead(const Eigen::Vector2d& p) const {
  const double s = corridor_.project(p).arc_length;
  Eigen::Index best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < centroids_.rows(); ++i) {
    if (!(centroid_s_[i] > s)) continue;
    const double d2 = (centroids_.row(i).transpose() - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = i;
    }
  }
  CentroidTarget t;
  t.ahead = best >= 0;
  if (best < 0) best = centroids_.rows() - 1;
  t.index = static_cast<int>(best);
  t.segment = static_cast<int>(best / options_.sub_segments);
  t.sub_segment = static_cast<int>(best % options_.sub_segments);
  t.arc_length = centroid_s_[best];
  t.point = centroids_.row(best).transpose();
  return t;
}


// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

constexpr int kMaxZones = 64;  ///< RiskZones::weights entries

template <>
const ParamSet<RiskZones>& param_set<RiskZones>() {
  static const ParamSet<RiskZones> s =
      Declare<RiskZones>{}
          .real("half_width", SN_REF(RiskZones, half_width), "m", above(0, 1000), "d_max, the safe buffer's half-width [SafeNav eq. 18]")
          .list("weights", SN_REF(RiskZones, weights), "", above(0, 1e6), kMaxZones, "w_1..w_n, the zones' weights, inner to outer [SafeNav eq. 18]")
          .set;
  return s;
}

template <>
const ParamSet<SegmentOptions>& param_set<SegmentOptions>() {
  using S = SegmentOptions;
  // length and sub_segments first: NavigationSettings nests them as segment_length, sub_segments.
  static const ParamSet<S> s =
      Declare<S>{}
          .real("length", SN_REF(S, length), "m", above(0, 1e5), "longest segment arc length when count = 0 [SafeNav Alg. 1], [SafeNav Alg. 2]")
          .integer("sub_segments", SN_REF(S, sub_segments), closed(1, 1000), "sub-segments per segment [SafeNav Alg. 2]")
          .integer("count", SN_REF(S, count), closed(0, 1e6), "K, the number of equal arc-length segments; 0 = derive K from length (at most 1e6 either way)")
          .real("spacing", SN_REF(S, spacing), "m", above(0, 1e4), "densification step of a segment's central polyline")
          .integer("disc_sides", SN_REF(S, disc_sides), closed(3, 1000), "sides of the polygon circumscribing each buffer disc (hull error W (1/cos(pi/sides) - 1))")
          .set;
  return s;
}

template class ParamSet<RiskZones>;
template class ParamSet<SegmentOptions>;

}  // namespace safenav
