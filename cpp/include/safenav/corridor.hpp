// safenav/corridor.hpp — the safe-path corridor of [SafeNav-ext §V-A3(iii)]:
// the safe buffer and its risk zones, the deviation [SafeNav eq. 17], WRS
// [SafeNav eq. 18] and AWRS [SafeNav-ext eq. 20]; and the path segments, convex
// hulls and sub-segment centroids used by SafeNav-CHull [SafeNav Alg. 1] and
// SafeNav-Centroid [SafeNav Alg. 2].  Citations follow docs/paper_map.md.
//
// Only Eigen and std types appear here; CGAL (convex hulls, orientation and
// point location) stays inside corridor.cpp.
#pragma once

#include <memory>
#include <vector>
#include <Eigen/Core>

#include "safenav/geometry.hpp"
#include "safenav/metrics.hpp"

namespace safenav {

/// The safe buffer of [SafeNav-ext §V-A3(iii)]: a corridor of half-width
/// d_max around a central polyline, split on each side into equal-width zones
/// with weights w_j (2, 4, 6, 8 in the paper).
struct RiskZones {
  double half_width = 8.0;                          ///< d_max [m] (the real-imitated field's buffer, as the scenario)
  std::vector<double> weights = {2.0, 4.0, 6.0, 8.0};  ///< w_1 … w_n; w_max = max
  void validate() const;
};

/// Distance from each point to the nearest point of the polyline (eq. 17).
Eigen::VectorXd distance_to_path(const Eigen::Ref<const Points2>& points,
                                 const Eigen::Ref<const Points2>& path);

/// WRS(d) of eq. 18 for one absolute deviation d:
///   d·(d/w_j)          if a_j ≤ d < b_j  (zone j = [ (j−1)·d_max/n, j·d_max/n ))
///   d_max·(d_max/w_max) if d ≥ d_max.
/// As written in the paper, WRS drops at each zone border (d²/w_j → d²/w_{j+1}).
double wrs(double deviation, const RiskZones& zones);
/// WRS of each point against the central path.
Eigen::VectorXd wrs(const Eigen::Ref<const Points2>& points, const Eigen::Ref<const Points2>& path,
                    const RiskZones& zones);
/// AWRS = mean WRS over the trajectory [SafeNav-ext eq. 20].
double awrs(const Eigen::Ref<const Points2>& points, const Eigen::Ref<const Points2>& path,
            const RiskZones& zones);

/// Orthogonal projection of a point onto the central path.
struct PathProjection {
  double arc_length = 0.0;     ///< s of the nearest path point, in [0, L]
  double distance = 0.0;       ///< deviation d (eq. 17): distance to the nearest path point
  int side = 0;                ///< +1 left of the path direction, −1 right, 0 on it
  int edge = 0;                ///< index of the path edge holding the nearest point
  Eigen::Vector2d foot{0, 0};  ///< the nearest path point
  double signed_offset() const { return side * distance; }
};

class PathSegments;
struct SegmentOptions;

/// The safe buffer: a corridor of half-width W = d_max around a central
/// polyline, cut into n equal-width zones per side with weights w_j
/// ([SafeNav-ext §V-A3(iii)]; RiskZones, default W = 8, w = 2, 4, 6, 8).
///
/// Consecutive duplicate path vertices are dropped; a path needs ≥ 2 distinct
/// vertices and a positive length.  Arc length s runs from 0 at the first
/// vertex to L at the last.  Nearest-point queries are O(M) per point for M
/// path edges; ties go to the smallest s.
class Corridor {
 public:
  explicit Corridor(const Eigen::Ref<const Points2>& path, RiskZones zones = RiskZones{});

  const Points2& path() const { return path_; }
  const RiskZones& zones() const { return zones_; }
  double half_width() const { return zones_.half_width; }
  int zone_count() const { return static_cast<int>(zones_.weights.size()); }
  double length() const { return cumulative_[cumulative_.size() - 1]; }
  /// Arc length at each path vertex (0, …, L).
  const Eigen::VectorXd& vertex_arc_lengths() const { return cumulative_; }

  PathProjection project(const Eigen::Vector2d& p) const;
  /// Point of the central path at arc length s (s clamped to [0, L]).
  Eigen::Vector2d point_at(double s) const;
  /// Unit direction of the path at arc length s (at a vertex: the outgoing edge's).
  Eigen::Vector2d tangent_at(double s) const;
  /// Inside the safe buffer: deviation d ≤ W (boundary included).
  bool contains(const Eigen::Vector2d& p) const;
  /// Zone index 0 … n−1 of deviation d (zone j covers [j·W/n, (j+1)·W/n)); n when d ≥ W.
  int zone(const Eigen::Vector2d& p) const;
  /// WRS of eq. 18 (safenav::wrs on this corridor's deviation).
  double wrs(const Eigen::Vector2d& p) const;

  // Batch forms (one row per point).
  Eigen::VectorXd distance(const Eigen::Ref<const Points2>& points) const;
  Eigen::VectorXd arc_length(const Eigen::Ref<const Points2>& points) const;
  Eigen::VectorXd signed_offset(const Eigen::Ref<const Points2>& points) const;
  Eigen::VectorXi side(const Eigen::Ref<const Points2>& points) const;
  Eigen::VectorXi zone(const Eigen::Ref<const Points2>& points) const;
  BoolVector contains(const Eigen::Ref<const Points2>& points) const;
  Eigen::VectorXd wrs(const Eigen::Ref<const Points2>& points) const;
  /// AWRS [SafeNav-ext eq. 20]: mean WRS over the points (≥ 1 point).
  double awrs(const Eigen::Ref<const Points2>& points) const;
  Points2 points_at(const Eigen::Ref<const Eigen::VectorXd>& s) const;

  /// Split the path into segments (see SegmentOptions).
  PathSegments segments(const SegmentOptions& options) const;

 private:
  Points2 path_;
  RiskZones zones_;
  Eigen::VectorXd cumulative_;
};

/// How the path is cut for Algorithms 1 and 2.
///
/// The path is cut at arc lengths s_0 = 0 < s_1 < … < s_K = L into K pieces
/// of equal arc length: K = `count` when count > 0, otherwise
/// K = ⌈L / `length`⌉ (so no piece is longer than `length`).
/// Each segment k is the central polyline between s_k and s_{k+1}: the cut
/// points plus the original vertices in between.
///   * points(k): that polyline densified so no step exceeds `spacing`.
///   * hull(k): CGAL convex hull of the buffer around the polyline.  Each
///     polyline vertex contributes a regular `disc_sides`-gon circumscribed
///     about the disc of radius W (circumradius W / cos(π/disc_sides)); the
///     hull of those polygons contains every disc, hence the whole buffer of
///     the segment (the buffer is the union of capsules = hulls of two
///     discs), and exceeds the buffer's hull by at most
///     W·(1/cos(π/disc_sides) − 1) (1.9 % of W for 16 sides).
///   * sub-segments (Algorithm 2): `sub_segments` equal arc-length pieces of
///     the segment; a centroid is the length-weighted centroid ∫p ds / ℓ of
///     the piece's polyline (sampling independent; on the path for a
///     straight piece).
struct SegmentOptions {
  int count = 0;            ///< K, the number of segments; 0 = derive K from `length`
  double length = 10.0;     ///< maximum segment arc length [m] when count == 0
  double spacing = 0.5;     ///< densification step of points(k) [m]
  int sub_segments = 4;     ///< Algorithm 2 sub-segments per segment
  int disc_sides = 16;      ///< sides of the polygon circumscribing each buffer disc (≥ 3)
  void validate() const;
};

/// The nearest sub-segment centroid ahead of a position (Algorithm 2).
struct CentroidTarget {
  int index = 0;        ///< row in PathSegments::centroids()
  int segment = 0;      ///< k
  int sub_segment = 0;  ///< j within segment k
  double arc_length = 0.0;  ///< mid arc length of the sub-segment
  Eigen::Vector2d point{0, 0};
  bool ahead = true;    ///< false when no centroid lies ahead (the last one is returned)
};

/// Segments of a safe path with their convex hulls and sub-segment centroids.
class PathSegments {
 public:
  PathSegments(const Corridor& corridor, const SegmentOptions& options);

  int size() const { return static_cast<int>(breaks_.size()) - 1; }
  const Corridor& corridor() const { return corridor_; }
  const SegmentOptions& options() const { return options_; }
  /// Cut arc lengths s_0 … s_K.
  const Eigen::VectorXd& breaks() const { return breaks_; }
  /// Segment holding arc length s (s clamped to [0, L]; a cut belongs to the later segment, L to the last).
  int segment_at(double s) const;

  /// Central polyline of segment k (cut points plus original vertices), densified.
  Points2 points(int k) const;
  /// The points the hull of segment k is built from (buffer disc polygons).
  Points2 hull_input(int k) const;
  /// Convex hull of segment k, counter-clockwise.
  const Points2& hull(int k) const;

  /// Inside or on the boundary of hull k (CGAL point location).
  bool hull_contains(int k, const Eigen::Vector2d& p) const;
  BoolVector hull_contains(int k, const Eigen::Ref<const Points2>& points) const;
  /// [SafeNav-ext Alg. 1 l. 13] (= [SafeNav-conf Alg. 1 l. 10]): inside hull k or
  /// hull k+1 (when it exists).
  bool in_current_or_next(int k, const Eigen::Vector2d& p) const;
  /// All segments whose hull contains p, ascending.
  std::vector<int> segments_containing(const Eigen::Vector2d& p) const;
  /// Per point: the first segment whose hull contains it, or −1.
  Eigen::VectorXi locate(const Eigen::Ref<const Points2>& points) const;

  /// Sub-segment centroids, K·m rows, segment-major (row = k·m + j).
  const Points2& centroids() const { return centroids_; }
  /// Mid arc length of each sub-segment (same rows as centroids()).
  const Eigen::VectorXd& centroid_arc_lengths() const { return centroid_s_; }
  /// The m centroids of segment k.
  Points2 segment_centroids(int k) const;
  /// Nearest centroid (Euclidean) among those whose sub-segment mid arc
  /// length is larger than the arc length of p's projection on the path.
  CentroidTarget nearest_centroid_ahead(const Eigen::Vector2d& p) const;

 private:
  void check_index(int k) const;
  Points2 polyline(double s0, double s1) const;

  Corridor corridor_;
  SegmentOptions options_;
  Eigen::VectorXd breaks_;
  std::vector<Points2> hulls_;
  Points2 centroids_;
  Eigen::VectorXd centroid_s_;
  struct Impl;
  std::shared_ptr<const Impl> impl_;  // CGAL polygons and bounding boxes
};

}  // namespace safenav
