// safenav/world.hpp — the map of SafeNav's battlefield [SafeNav-ext §V-A3(ii),
// Fig. 1] (= [SafeNav-conf §V-A.2(ii)], which has no such figure): a
// rectangular field with circle and polygon obstacles, which the vehicle may
// not enter, and hazard zones, which it may cross at a risk; and
// the collision checker that the planner (RAw-RRT*), the navigation loop and
// Python's safenav.world.World all ask.
//
// Geometry conventions: a point on an obstacle's boundary is inside it; a
// clearance or margin grows every obstacle by that distance (the Minkowski sum
// with a disc); segment tests are exact (CGAL's exact predicates for polygon
// containment and edge crossings), so a segment that grazes a corner is caught.
//
// Occlusion (ObstacleChecker::line_of_sight, visible_from): the obstacles
// themselves hide what lies behind them from a camera, as if tall enough to
// hide any landmark (heights are not modelled); hazards hide nothing.  The
// one query serves the simulated camera (SensorSettings::occlusion), the
// guard's look, landmark placement and the renderer.
//
// Hazards: a hazard is passable at its risk, unless its risk reaches the
// map's `forbidden_risk`; then it is an obstacle too (grown by the clearance
// like every obstacle).  The length of a segment inside a hazard is exact:
// the segment is cut at every crossing with the hazard's boundary (closed-form
// line/edge and line/circle intersections) and each piece is classified by
// CGAL's exact point-in-polygon predicate at its midpoint; no sampling.  A
// piece along a polygon's edge is inside (the boundary belongs to the hazard).
//
// CGAL stays inside cpp/src/world.cpp: this header exposes only Eigen and std types.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "safenav/types.hpp"

namespace safenav {

/// A disc obstacle.
struct CircleObstacle {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double radius = 1.0;  ///< [m], > 0
};

/// A hazard zone: a simple polygon, or (polygon with 0 rows) a disc, with a
/// risk level.  The paper gives hazards no numeric scale; the level is ours.
struct HazardZone {
  Points2 polygon = Points2(0, 2);  ///< ≥ 3 vertices, or 0 rows for the disc
  CircleObstacle disc;              ///< used when polygon has 0 rows
  double risk = 1.0;                ///< in (0, 1], 1 = most dangerous
};

/// Obstacle inflation (the model is Nav2's costmap inflation layer): a planned
/// path keeps clearance() = vehicle_radius + margin from every obstacle; that
/// is the PlanningMap's `clearance`.  Defaults 1 + 1 = 2 m, the clearance every
/// scenario used before these fields existed.
struct Inflation {
  double vehicle_radius = 1.0;  ///< the vehicle's radius [m], ≥ 0
  double margin = 1.0;          ///< extra distance kept beyond the vehicle's body [m], ≥ 0
  double clearance() const { return vehicle_radius + margin; }
  void validate() const;  ///< throws std::invalid_argument naming the bad value
};

/// The field, its obstacles and its hazards: what a state validity checker needs.
struct PlanningMap {
  Eigen::Vector2d lower = Eigen::Vector2d(0.0, 0.0);      ///< field's lower-left corner [m]
  Eigen::Vector2d upper = Eigen::Vector2d(200.0, 200.0);  ///< field's upper-right corner [m] ([SafeNav-ext §V-A3(ii)])
  std::vector<CircleObstacle> circles;
  std::vector<Points2> polygons;  ///< simple polygons, ≥ 3 vertices each, open (first ≠ last) or closed
  double clearance = 0.0;         ///< keep this far from every obstacle [m] (vehicle radius)
  std::vector<HazardZone> hazards;  ///< passable at their risk, unless forbidden
  /// Hazards with risk >= this are obstacles for point_free/segment_free (the
  /// planner's validity checker and motion validator).  Default 2 (above 1):
  /// none is forbidden, as in the paper.  > 0.
  double forbidden_risk = 2.0;
  void validate() const;          ///< throws std::invalid_argument naming the bad value
  bool in_field(const Eigen::Vector2d& p) const;  ///< within [lower, upper] (boundary included)
};

using BoolMatrix = Eigen::Matrix<bool, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Repeated collision queries against one map (the map's geometry is prepared
/// once; polygons are culled by bounding circles).  Copies share the data.
///
/// The batch queries number the obstacles circles first, then polygons, in
/// the map's order; `margin` (≥ 0) adds to the map's clearance.
class ObstacleChecker {
 public:
  explicit ObstacleChecker(const PlanningMap& map);
  /// Inside the field and at least `clearance` away from every obstacle.
  bool point_free(const Eigen::Vector2d& p) const;
  /// The whole segment a–b is free (exact tests, not sampling).
  bool segment_free(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;

  /// Number of obstacles (circles + polygons): the columns of the batch queries.
  std::size_t obstacle_count() const;
  /// N×M: point i lies in obstacle j grown by clearance + margin (boundary
  /// included).  The field's bounds play no part.
  BoolMatrix obstacles_at(const Eigen::Ref<const Points2>& points, double margin = 0.0) const;
  /// N×M: the segment a_i–b_i touches obstacle j grown by clearance + margin
  /// (a zero-length segment is its point).
  BoolMatrix obstacles_hit(const Eigen::Ref<const Points2>& a, const Eigen::Ref<const Points2>& b,
                           double margin = 0.0) const;
  /// The highest risk of the hazards containing each point (boundary
  /// included), 0 outside every hazard.
  Eigen::VectorXd hazard_risk(const Eigen::Ref<const Points2>& points) const;

  /// Number of hazards (the map's, in order).
  std::size_t hazard_count() const;
  /// Length [m] of the segment a–b inside each hazard (exact, see the header
  /// comment; boundary included; a zero-length segment gives 0).
  Eigen::VectorXd hazard_lengths(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  /// ∫ risk ds along a–b = Σ_k risk_k · length inside hazard k [m].
  /// Overlapping hazards add: each is its own threat, met independently, and
  /// the sum makes the planner's hazard cost equal to PathSafety::exposure,
  /// hazard by hazard (the max of hazard_risk() would hide a second threat).
  double hazard_integral(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  /// One step a–b through the hazards: Σ_k length inside hazard k [m], the
  /// exposure Σ_k risk_k · length_k [m], and whether b lies in a hazard
  /// (boundary included).
  struct HazardStep {
    double length = 0.0;
    double exposure = 0.0;
    bool inside = false;
  };
  HazardStep hazard_step(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  /// Line of sight (occlusion by obstacles): true when the segment a–b meets
  /// no obstacle (the map's circles and polygons themselves, not grown by
  /// the clearance; touching the boundary blocks), except that an obstacle
  /// containing a or b (boundary included) does not block: a landmark
  /// mounted on a boulder is seen from outside it.  Obstacles are treated as
  /// tall enough to hide anything behind them (heights are not modelled);
  /// hazards never occlude, not even forbidden ones.  A zero-length segment
  /// is always seen.  Exact: CGAL's exact predicates for polygon containment
  /// and edge crossings, and for circles the sign of the closed-form
  /// polynomials (inside: |p − c|² ≤ r²; touched: the foot of c on the line
  /// within the segment and cross(b − a, c − a)² ≤ r²·|b − a|²) evaluated in
  /// interval arithmetic, and exactly (CGAL::MP_Float) when that is unsure.
  /// Symmetric: the ends are put in lexicographic order before anything is
  /// computed, so line_of_sight(a, b) == line_of_sight(b, a) exactly, at any
  /// finite coordinates.  Landmark placement's sight_blocked is the same
  /// predicate.  Throws std::invalid_argument when a or b is not finite.
  bool line_of_sight(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  /// line_of_sight(from, targets.row(i)) for each row i of the N×2 targets.
  /// Throws std::invalid_argument naming a non-finite `from` or target.
  Eigen::Matrix<bool, Eigen::Dynamic, 1> visible_from(const Eigen::Vector2d& from,
                                                      const Eigen::Ref<const Points2>& targets) const;
  /// Distance [m] from the segment a–b to the nearest obstacle, not grown by
  /// the clearance (0 when it touches one; +inf with no obstacles).  Forbidden
  /// hazards are not obstacles here.
  double obstacle_distance(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  /// Distance [m] from the segment a–b to the nearest obstacle or forbidden
  /// hazard (risk >= forbidden_risk), not grown by the clearance: what the
  /// vehicle must keep out of (0 when it touches one; +inf with none).
  double keep_out_distance(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
};

/// What a path meets: its clearance to obstacles and its hazard exposure.
struct PathSafety {
  double length = 0.0;            ///< path length [m]
  double min_clearance = 0.0;     ///< distance to the nearest obstacle (not grown) [m]; +inf with no obstacles
  Eigen::VectorXd hazard_length;  ///< length inside each hazard (map order) [m]
  double exposure = 0.0;          ///< risk-weighted exposure Σ_k risk_k · hazard_length_k [m]
};

/// The safety report of a polyline path on a map (exact geometry, see ObstacleChecker).
PathSafety path_safety(const Eigen::Ref<const Points2>& path, const PlanningMap& map);

/// Whether p is inside the field and at least `clearance` away from every obstacle.
bool point_is_free(const PlanningMap& map, const Eigen::Vector2d& p);
/// Whether the whole segment a–b is free (exact segment/obstacle tests, not sampling).
bool segment_is_free(const PlanningMap& map, const Eigen::Vector2d& a, const Eigen::Vector2d& b);
/// Whether every edge of the polyline is free.
bool path_is_free(const PlanningMap& map, const Eigen::Ref<const Points2>& path);

}  // namespace safenav
