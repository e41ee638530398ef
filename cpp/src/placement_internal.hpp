// Private: what the parts of landmark placement [Placement §II] share (the
// public API is safenav/placement.hpp):
//   placement_geometry.cpp  checks, the candidate grid, [Placement Lemma 1,
//                           Lemma 2, Cor. 1], edge frames and turns;
//   placement_shadows.cpp   occlusion (ours): the sight test (sight.hpp's,
//                           shared with the world) and the shadows on an edge;
//   placement_tables.cpp    the tables for the ILP;
//   placement_cover.cpp     the greedy k-interval cover [Placement Alg. 1], the
//                           union over edges, non-coincidence and corners;
//   placement_check.cpp     the exact coverage check.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "safenav/placement.hpp"

namespace safenav::placement_detail {

constexpr double kEps = 1e-9;         // [m] or [rad]: rounding slack of interval ends
constexpr double kBearingTol = 1e-9;  // [rad]: bearings closer than this are one bearing

inline double wrap(double a) {
  a = std::fmod(a + kPi, 2.0 * kPi);
  if (a <= 0.0) a += 2.0 * kPi;
  return a - kPi;
}

[[noreturn]] inline void fail(const std::string& msg) { throw std::invalid_argument(msg); }

// Input checks: each throws std::invalid_argument naming the bad entry.
/// Finite and within kMaxCoordinate of the origin.
void check_points(const Points2& p, const char* what);
/// At least 2 points, checked as above, no edge of zero length.
void check_route(const Points2& route);
/// Finite and pairwise distinct: two landmarks at one spot are on one bearing.
void check_candidates(const Points2& c, const char* what = "candidates");
/// 1 ≤ k ≤ kMaxLandmarksInView.
void check_k(int k);

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

/// Candidates within `p` of the route (distance ≤ p).
std::vector<char> within(const Points2& route, const Points2& pts, const Grid& grid, double p);

/// The candidates of one query: checked with the camera and the route (in
/// that order: camera, route, candidates, occluders), bucketed for range
/// searches, and those within the camera's clearance p of the route marked
/// (they may not hold a landmark).  `occ` is null without occluders.
struct CandidateSet {
  CandidateSet(const Points2& route, const Points2& candidates, const Camera& camera,
               const Occluders& occluders = {});
  Grid grid;
  std::vector<char> close;
  const Occluders* occ = nullptr;
};

/// A candidate's Lemma 2 interval on one edge with its position in the edge
/// frame, and the pieces of it where no occluder hides it (just {iv}
/// without occluders; never empty).
struct Seen {
  int idx;
  Interval iv;
  Eigen::Vector2d local;
  std::vector<Interval> pieces;
};

/// All candidates (not excluded) with a non-empty interval on edge e and at
/// least one piece left by the occluders (`occ`, may be null), sorted by index.
std::vector<Seen> seen_on_edge(const Points2& route, Eigen::Index e, const Points2& pts, const Grid& grid,
                               const std::vector<char>& excluded, const Camera& cam, const Occluders* occ = nullptr);

/// Candidates around one interior vertex with their interval of turned
/// angle; those the occluders hide from the vertex are left out.
std::vector<Seen> seen_at_corner(const Eigen::Vector2d& v, double theta_in, double turn, const Points2& pts,
                                 const Grid& grid, const std::vector<char>& excluded, const Camera& cam,
                                 const Occluders* occ = nullptr);

/// sight_blocked without the checks: the occluders hide b from a (sight.hpp).
bool hidden(const Occluders& occ, const Eigen::Vector2d& a, const Eigen::Vector2d& b);

/// shadows_on_edge, considering only occluders that can hide c from some
/// t in `range` (the others cannot change the pieces of that interval).
std::vector<Interval> edge_shadows(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                                   const Occluders& occ, const Interval& range);

/// In one of the candidate's pieces (with the 1e-9 slack of every interval end).
inline bool in_pieces(const Seen& s, double t);
/// End of the piece containing t (the "reach" of the greedy), or -inf.
inline double reach_at(const Seen& s, double t);

inline double bearing_at(const Eigen::Vector2d& local, double t) { return std::atan2(local.y(), local.x() - t); }

inline bool contains(const Interval& iv, double t) { return iv.start - kEps <= t && t <= iv.end + kEps; }

inline bool in_pieces(const Seen& s, double t) {
  for (const auto& p : s.pieces)
    if (contains(p, t)) return true;
  return false;
}

inline double reach_at(const Seen& s, double t) {
  for (const auto& p : s.pieces)
    if (contains(p, t)) return p.end;
  return -std::numeric_limits<double>::infinity();
}

inline double pieces_length(const Seen& s) {
  double n = 0.0;
  for (const auto& p : s.pieces) n += p.end - p.start;
  return n;
}

/// Two landmarks seen on one bearing from a point of the edge where both are in view.
bool aligned_in_view(const Seen& a, const Seen& b, double* t);

/// In view from (t, 0): inside one of its pieces and not at the camera itself (no bearing there).
inline bool in_view_at(const Seen& s, double t) {
  return in_pieces(s, t) && (s.local - Eigen::Vector2d(t, 0.0)).norm() > kEps;
}

inline bool same_bearing(double a, double b) { return std::abs(wrap(a - b)) <= kBearingTol; }

/// Bearings (edge frame) of the landmarks in view from (t, 0).
std::vector<double> bearings_on_edge(const std::vector<Seen>& seen, double t);

/// A stretch [where.start, where.end] of an edge (or turn) with fewer than k
/// distinct bearings in view, and the point `probe` that shows it.
struct Deficit {
  Interval where;
  double probe;
};

/// The deficits of one edge (exact count over its events); lowers *min_count.
std::vector<Deficit> edge_deficits(const std::vector<Seen>& seen, double length, int k, int* min_count);

}  // namespace safenav::placement_detail
