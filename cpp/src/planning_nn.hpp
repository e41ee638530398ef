// Private to the planner: an exact nearest-neighbour structure for RRT* in a
// 2-D box (OMPL's NearestNeighbors interface).
//
// OMPL's default for RRTstar, GNAT, is a metric tree for any space; in the
// plane a uniform grid of buckets answers the same queries several times
// faster.  The answers are the ones GNAT gives, so a plan does not change:
//   * nearest(): the element at the smallest distance;
//   * nearestR(): every element at distance ≤ r, sorted by distance;
//   * nearestK(): the k nearest, sorted by distance.
// Distances are RealVectorStateSpace::distance's, operation for operation.
// (Exact ties, which GNAT orders by memory address, keep insertion order here;
// with continuous samples they do not occur.)  The grid refines itself
// (halving its cell) as the tree fills, to keep about one element per cell.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/datastructures/NearestNeighbors.h>
#include <ompl/util/Exception.h>

namespace safenav::planning_detail {

/// OMPL's RealVectorStateSpace::distance in 2-D, operation for operation, so
/// that neighbours and costs computed here equal OMPL's bit for bit.
inline double ompl_distance_2d(const double* p, const double* q) {
  double dist = 0.0;
  const double dx = p[0] - q[0];
  dist += dx * dx;
  const double dy = p[1] - q[1];
  dist += dy * dy;
  return std::sqrt(dist);
}

/// T: a pointer to a motion with a `state` member in a 2-D RealVectorStateSpace.
template <class T>
class GridNearestNeighbors : public ompl::NearestNeighbors<T> {
 public:
  /// The box [lower, upper] (elements outside are clamped into border cells).
  GridNearestNeighbors(double x0, double y0, double x1, double y1) : x0_(x0), y0_(y0), x1_(x1), y1_(y1) {
    rebuild(1);
  }

  bool reportsSortedResults() const override { return true; }
  void clear() override {
    size_ = 0;
    rebuild(1);
  }
  std::size_t size() const override { return size_; }

  void add(const T& data) override {
    const double* p = coords(data);
    cells_[cell_of(p)].push_back({p[0], p[1], data});
    ++size_;
    if (size_ > 2 * cells_.size() && cells_.size() < kMaxCells) rebuild(2 * side_);
  }
  using ompl::NearestNeighbors<T>::add;

  bool remove(const T& data) override {
    auto& bucket = cells_[cell_of(coords(data))];
    const auto it = std::find_if(bucket.begin(), bucket.end(), [&](const Entry& e) { return e.data == data; });
    if (it == bucket.end()) return false;
    bucket.erase(it);
    --size_;
    return true;
  }

  T nearest(const T& data) const override {
    nearestK(data, 1, one_);
    if (one_.empty()) throw ompl::Exception("No elements found in nearest neighbors data structure");
    return one_.front();
  }

  void nearestK(const T& data, std::size_t k, std::vector<T>& nbh) const override {
    nbh.clear();
    if (k == 0 || size_ == 0) return;
    const int cx = col(coords(data)[0]), cy = row(coords(data)[1]);
    found_.clear();
    candidates_.clear();
    // Ring ρ holds the cells at Chebyshev distance ρ from the query's cell;
    // every point of ring ρ + 1 is at least ρ·cell away from the query.
    for (int ring = 0; ring <= side_; ++ring) {
      for_ring(cx, cy, ring, [&](const Bucket& bucket) { collect(coords(data), bucket, kInf); });
      if (found_.size() >= k) {
        std::nth_element(found_.begin(), found_.begin() + static_cast<std::ptrdiff_t>(k - 1), found_.end(), less);
        if (found_[k - 1].first <= ring * std::min(wx_, wy_)) break;
      }
    }
    finish(std::min(k, found_.size()), nbh);
  }

  void nearestR(const T& data, double radius, std::vector<T>& nbh) const override {
    nbh.clear();
    if (size_ == 0) return;
    const double* q = coords(data);
    const int c0 = col(q[0] - radius), c1 = col(q[0] + radius), r0 = row(q[1] - radius), r1 = row(q[1] + radius);
    found_.clear();
    candidates_.clear();
    for (int r = r0; r <= r1; ++r)
      for (int c = c0; c <= c1; ++c) collect(q, cells_[static_cast<std::size_t>(r) * side_ + c], radius);
    finish(found_.size(), nbh);
  }

  void list(std::vector<T>& data) const override {
    data.clear();
    data.reserve(size_);
    for (const auto& bucket : cells_)
      for (const Entry& e : bucket) data.push_back(e.data);
  }

 private:
  static constexpr std::size_t kMaxCells = std::size_t(1) << 20;
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  using Found = std::pair<double, std::size_t>;  // distance, order of discovery
  struct Entry {
    double x, y;  ///< the state's coordinates, kept beside it (no pointer chase per distance)
    T data;
  };
  using Bucket = std::vector<Entry>;

  static const double* coords(const T& data) {
    return data->state->template as<ompl::base::RealVectorStateSpace::StateType>()->values;
  }
  static bool less(const Found& a, const Found& b) { return a < b; }

  int clamp_index(double v) const {
    if (!(v > 0.0)) return 0;  // NaN and below the box
    return v >= side_ ? side_ - 1 : static_cast<int>(v);
  }
  int col(double x) const { return clamp_index((x - x0_) / wx_); }
  int row(double y) const { return clamp_index((y - y0_) / wy_); }
  std::size_t cell_of(const double* p) const {
    return static_cast<std::size_t>(row(p[1])) * side_ + col(p[0]);
  }

  void rebuild(int side) {
    std::vector<Entry> all;
    for (const auto& bucket : cells_) all.insert(all.end(), bucket.begin(), bucket.end());
    side_ = side;
    wx_ = (x1_ - x0_) / side_;
    wy_ = (y1_ - y0_) / side_;
    if (!(wx_ > 0.0) || !std::isfinite(wx_)) wx_ = 1.0;
    if (!(wy_ > 0.0) || !std::isfinite(wy_)) wy_ = 1.0;
    cells_.assign(static_cast<std::size_t>(side_) * side_, {});
    for (const Entry& e : all) {
      const double p[2] = {e.x, e.y};
      cells_[cell_of(p)].push_back(e);
    }
  }

  template <class F>
  void for_ring(int cx, int cy, int ring, F&& visit) const {
    const int c0 = std::max(cx - ring, 0), c1 = std::min(cx + ring, side_ - 1);
    const int r0 = std::max(cy - ring, 0), r1 = std::min(cy + ring, side_ - 1);
    for (int r = r0; r <= r1; ++r) {
      const bool edge_row = r == cy - ring || r == cy + ring;
      for (int c = c0; c <= c1; ++c)
        if (edge_row || c == cx - ring || c == cx + ring) visit(cells_[static_cast<std::size_t>(r) * side_ + c]);
    }
  }

  void collect(const double* q, const Bucket& bucket, double radius) const {
    for (const Entry& e : bucket) {
      const double p[2] = {e.x, e.y};
      const double dist = ompl_distance_2d(q, p);
      if (dist <= radius) {
        found_.emplace_back(dist, candidates_.size());
        candidates_.push_back(e.data);
      }
    }
  }

  void finish(std::size_t k, std::vector<T>& nbh) const {
    if (k == found_.size())
      std::sort(found_.begin(), found_.end(), less);
    else
      std::partial_sort(found_.begin(), found_.begin() + static_cast<std::ptrdiff_t>(k), found_.end(), less);
    nbh.resize(k);
    for (std::size_t i = 0; i < k; ++i) nbh[i] = candidates_[found_[i].second];
    found_.clear();
    candidates_.clear();
  }

  double x0_, y0_, x1_, y1_;
  int side_ = 1;
  double wx_ = 1.0, wy_ = 1.0;
  std::size_t size_ = 0;
  std::vector<Bucket> cells_;
  mutable std::vector<Found> found_;
  mutable std::vector<T> candidates_;
  mutable std::vector<T> one_;
};

}  // namespace safenav::planning_detail
