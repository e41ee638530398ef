// Landmark placement, the exact coverage check: at every point of each edge
// (and, with corners, of each turn) the number of distinct bearings in view,
// counted at every interval end and alignment point and between them, where
// the count is constant (DESIGN.md: checking at sample points is not exact).
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "placement_internal.hpp"

namespace safenav {
namespace placement_detail {

namespace {

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

/// Points of an edge where the number of distinct bearings can change:
/// interval ends, alignment points, and the position of a landmark on the
/// edge's line (its bearing flips from 0 to π there).
std::vector<double> edge_events(const std::vector<Seen>& seen) {
  std::vector<double> pts;
  for (size_t i = 0; i < seen.size(); ++i) {
    for (const auto& p : seen[i].pieces) {
      pts.push_back(p.start);
      pts.push_back(p.end);
    }
    if (seen[i].local.y() == 0.0) pts.push_back(seen[i].local.x());
    for (size_t j = i + 1; j < seen.size(); ++j) {
      double t;
      if (aligned_in_view(seen[i], seen[j], &t)) pts.push_back(t);
    }
  }
  return pts;
}

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

}  // namespace

std::vector<double> bearings_on_edge(const std::vector<Seen>& seen, double t) {
  std::vector<double> br;
  for (const auto& s : seen)
    if (in_view_at(s, t)) br.push_back(bearing_at(s.local, t));
  return br;
}

std::vector<Deficit> edge_deficits(const std::vector<Seen>& seen, double length, int k, int* min_count) {
  return deficits(edge_events(seen), length, k, [&](double t) { return bearings_on_edge(seen, t); }, min_count);
}

}  // namespace placement_detail

using namespace placement_detail;

CoverageReport check_coverage(const Points2& route, const Points2& landmarks, const Camera& camera, int k,
                              bool corners, const Occluders& occluders) {
  camera.validate();
  check_route(route);
  check_candidates(landmarks, "landmarks");
  check_k(k);
  occluders.validate();
  const Occluders* occ = occluders.empty() ? nullptr : &occluders;
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
    const auto seen = seen_on_edge(route, e, landmarks, grid, {}, camera, occ);
    const double d = (route.row(e + 1) - route.row(e)).norm();
    record(edge_deficits(seen, d, k, &rep.min_count), 0, static_cast<int>(e));
  }
  if (corners) {
    const Eigen::VectorXd turns = turn_angles(route);
    for (Eigen::Index v = 1; v + 1 < route.rows(); ++v) {
      if (std::abs(turns(v - 1)) <= kEps) continue;
      const double theta_in = std::atan2(route(v, 1) - route(v - 1, 1), route(v, 0) - route(v - 1, 0));
      const auto seen =
          seen_at_corner(route.row(v).transpose(), theta_in, turns(v - 1), landmarks, grid, {}, camera, occ);
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
