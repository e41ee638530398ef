// safenav/placement.hpp — landmark placement for guaranteed observability
// [Placement §II], with k-cover, corner coverage
// and the tables the global-optimum ILP (Python, safenav.placement) needs.
//
// A route is a polyline of n ≥ 2 points (n−1 edges).  A landmark is in view
// of the camera at a route point when its distance is ≤ R and its bearing
// relative to the direction of travel is within ±α/2 (sector field of view)
// or anywhere (circular field of view, Corollary 1).
//
// Citations follow docs/paper_map.md; every number below is the placement
// paper's (its Algorithm 1 is the greedy, not SafeNav's CHull).
//
// Edge frame [Placement §II-A]: each edge (t_i, t_{i+1}) is moved by a rigid
// transform to (0, 0) → (d, 0); a landmark at (x_k, y_k) in that frame is in
// view from (t, 0) for t in the interval of [Placement Lemma 2, eqs. 1–2],
//   t_s = max(x_k − √(R² − y_k²), 0),  t_d = min(x_k − |y_k|·cot(α/2), d),
// and, for a circular field of view ([Placement Cor. 1, eq. 4], with the typo fixed:
// the printed "0" in t_d is d),
//   t_d = min(x_k + √(R² − y_k²), d).
//
// Non-coincidence ([Placement LPP cond. 2], §I-B): two landmarks on one bearing
// from the camera count as one, so coverage is the number of *distinct
// bearings* in view (bearings equal within 1e-9 rad are one; a landmark at the
// camera's own position has no bearing and is not in view).  Two landmarks off
// the edge's line align only at the single point where the line through them
// meets it; two landmarks on the edge's line (|y| ≤ 1e-9 m in the edge frame,
// snapped to y = 0) share one bearing wherever both are in view (0 ahead, π
// behind).  Intervals are closed; gaps shorter than 1e-9 m are rounding.
//
// Occlusion (ours; not in the paper, which has no obstacles): every
// entry point takes optional Occluders (circles and simple polygons, treated
// as tall and not grown).  A landmark c is in view from a route point a only
// when, besides Lemma 2, the segment a–c meets no occluder that contains
// neither a nor c (boundary included; a landmark on or in an obstacle is seen
// from outside it, and an occluder the route runs through does not hide what
// is seen from inside it): the world's line of sight
// (ObstacleChecker::line_of_sight), one exact predicate for both.  On an edge the occluded set of t (a shadow) is a
// union of closed intervals, computed in closed form: per polygon edge, and
// per circle, the region beyond the obstacle as seen from c (the wedge
// through the edge's endpoints, or between the tangents, beyond the
// obstacle) is convex, so it meets the edge's line in one interval whose ends
// are where the wedge's boundary crosses it.  The candidate's Lemma 2
// interval minus its shadows is a list of *pieces*.  Each shadow is widened
// by kShadowPad = 2e-9 m on both sides before it is cut out, so with the
// 1e-9 m slack of every interval end the pieces stay inside the truly
// visible set (rounding of the shadow's ends is far below that): pieces are
// never larger than the truth, which keeps every certificate sound; they may
// miss up to ~3e-9 m next to a shadow.  With no occluders every candidate has
// exactly one piece, its Lemma 2 interval, and every result is as before.
//
// Certificates: every `uncovered` list and `covered()` below come from the
// exact check (check_coverage) of the final landmark set, so a placement is
// reported covered exactly when check_coverage finds ≥ k everywhere.
#pragma once

#include <vector>
#include <Eigen/Core>

#include "safenav/types.hpp"
#include "safenav/world.hpp"

namespace safenav {

/// Upper bound on k (landmarks in view), checked up front everywhere: far
/// beyond any camera's useful count, and it keeps every loop bounded.
inline constexpr int kMaxLandmarksInView = 1000;

/// Largest |coordinate| [m] accepted: beyond it a double's spacing exceeds
/// the 1e-9 m rounding slack, and the checks would no longer be exact.
inline constexpr double kMaxCoordinate = 1e6;

/// Obstacles that hide landmarks from the camera (see the header comment):
/// circles and simple polygons (≥ 3 vertices, open or closed), not grown.
/// Empty (the default): nothing is hidden, as in the paper.
struct Occluders {
  std::vector<CircleObstacle> circles;
  std::vector<Points2> polygons;
  bool empty() const { return circles.empty() && polygons.empty(); }
  /// Throws std::invalid_argument naming the first bad obstacle.
  void validate() const;
  /// The map's circles and polygons (not grown by its clearance; hazards do not hide).
  static Occluders from_map(const PlanningMap& map);
};

/// Whether the segment a–b is blocked by the occluders: it meets one (boundary
/// included) that contains neither a nor b.  The world's predicate:
/// sight_blocked(Occluders::from_map(m), a, b) == !ObstacleChecker(m).line_of_sight(a, b),
/// exact on the double inputs at any finite coordinates and symmetric in a, b
/// (see ObstacleChecker::line_of_sight).  Throws std::invalid_argument naming
/// a bad occluder or a non-finite a or b.
bool sight_blocked(const Occluders& occluders, const Eigen::Vector2d& a, const Eigen::Vector2d& b);

/// Shape of the camera's field of view.
enum class FieldOfView { Sector, Circular };

/// The camera and the collision-avoidance distance (the paper's R, α, p).
struct Camera {
  double range = 2.0;                            ///< R [m], viewing range (> clearance)
  double angle = 50.0 * kPi / 180.0;  ///< α [rad], full viewing angle, in (0, π]
  double clearance = 0.05;                       ///< p [m], landmarks must be farther than p from the route
  FieldOfView fov = FieldOfView::Sector;
  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// A closed interval [start, end] of an edge (arc length) or of a turn (angle).
struct Interval {
  double start = 0.0;
  double end = 0.0;
};

/// Rigid transform of the edge a → b to (0, 0) → (d, 0) ([Placement §II-A], steps 1–2).
/// The constructor throws std::invalid_argument naming a non-finite end, or
/// an edge whose length overflows a double; to_local and to_world throw
/// naming a point whose image is not finite.
struct EdgeFrame {
  EdgeFrame(const Eigen::Vector2d& a, const Eigen::Vector2d& b);
  Eigen::Vector2d origin;  ///< t_i
  double heading;          ///< θ = atan2(y_{i+1} − y_i, x_{i+1} − x_i)
  double length;           ///< d
  Eigen::Vector2d to_local(const Eigen::Vector2d& p) const;
  Eigen::Vector2d to_world(const Eigen::Vector2d& q) const;

 private:
  double cos_, sin_;       // of heading
};

/// [Placement Lemma 1], the four conditions as printed (sector field of view): necessary
/// for the landmark at `local` (edge frame) to be in view from some point of
/// an edge of length `length`.  For the circular field of view: within R of
/// the edge.
bool in_region_of_influence(const Eigen::Vector2d& local, double length, const Camera& camera);

/// [Placement Lemma 2] (sector) or [Placement Cor. 1] (circular): the closed interval of the
/// edge [0, length] from which the landmark at `local` is in view.  Returns
/// false (and leaves `out` alone) when it is never in view.
bool visibility_interval(const Eigen::Vector2d& local, double length, const Camera& camera, Interval* out);

/// The shadows of the occluders on the edge a → b as seen from the landmark
/// c: closed intervals of arc length t ∈ [0, |b − a|] where the segment
/// c–p(t) is blocked (sight_blocked), sorted and merged, not widened.  Ends
/// next to a part of the edge inside an occluder are closed here although
/// those points are not hidden (the convention exempts them): a slight
/// over-estimate, on the safe side.
std::vector<Interval> shadows_on_edge(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                                      const Occluders& occluders);

/// The pieces of `interval` left when the shadows, each widened by
/// kShadowPad on both sides, are cut out (sorted, disjoint, closed).
std::vector<Interval> cut_shadows(const Interval& interval, const std::vector<Interval>& shadows);

/// Widening of a shadow on both sides before it is cut out [m].
inline constexpr double kShadowPad = 2e-9;
/// Result of a k-interval cover of [0, length].
struct CoverResult {
  std::vector<int> chosen;          ///< indices into the interval list, in the order picked
  std::vector<Interval> uncovered;  ///< maximal stretches covered fewer than k times (empty: covered)
};

/// [Placement Alg. 1] generalised to 1 ≤ k ≤ kMaxLandmarksInView: cover every point of [0, length] by at
/// least k of the given closed intervals with the fewest intervals.  At the
/// leftmost point covered fewer than k times, take the interval reaching
/// farthest among those containing it (for k = 2 and no `preplaced`
/// intervals this is [Placement Alg. 1]).  Optimal ([Placement Prop. 1]);
/// `preplaced` intervals count as already chosen and cost nothing.  When a
/// point cannot be covered the greedy skips the stretch, carries on, and
/// reports the stretch in `uncovered`.
CoverResult greedy_cover(const std::vector<Interval>& intervals, double length, int k,
                         const std::vector<Interval>& preplaced = {});

/// Stretches of [0, length] covered fewer than k times by closed intervals.
std::vector<Interval> deficient_stretches(const std::vector<Interval>& intervals, double length, int k);

struct PlacementOptions {
  int k = 2;                     ///< landmarks in view at every point (the paper: 2), in [1, kMaxLandmarksInView]
  bool corners = false;          ///< also cover the in-place turn at every interior vertex
  bool reuse = false;            ///< edges after the first count landmarks already placed (the paper: false)
  bool distinct_bearings = true; ///< enforce non-coincidence (the paper's Algorithm 1 does not); the
                                 ///< certificate counts distinct bearings either way
};

/// The landmarks picked for one edge (its own picks, candidate indices).
struct EdgePlacement {
  std::vector<int> landmarks;
  std::vector<Interval> uncovered;  ///< arc-length stretches of the edge with < k (zero length: an alignment point)
  int n_candidates = 0;             ///< candidates whose Lemma 2 interval is not empty (and not wholly hidden)
};

/// The landmarks picked for the in-place turn at one interior vertex.
struct CornerPlacement {
  int vertex = 0;                   ///< route point index
  double turn = 0.0;                ///< signed turn angle wrap(θ_out − θ_in) [rad]
  std::vector<int> landmarks;
  std::vector<Interval> uncovered;  ///< stretches of turned angle [0, |turn|] with < k
};

struct Placement {
  std::vector<int> landmarks;       ///< chosen candidate indices, sorted
  std::vector<EdgePlacement> edges;
  std::vector<CornerPlacement> corners;
  std::vector<int> too_close;       ///< candidates within the clearance p of the route (removed)
  bool covered() const;
};

/// The paper's placement for a whole route: per edge the greedy cover, then
/// the union over edges [Placement §II-B], with candidates closer than p to the
/// route removed first and, optionally, non-coincidence, reuse and corners.
/// With non-coincidence, candidates on an edge's own line keep only the one
/// reaching farthest (they all share one bearing), and a repair adds, at
/// the first point of an edge the exact count finds below k, the candidate
/// with a fresh bearing there that reaches farthest.  The stretches reported
/// uncovered are those of check_coverage on the final landmarks.
///
/// With occluders, each candidate covers its pieces (Lemma 2 interval minus
/// shadows) and the greedy covers with pieces: each piece is an interval of
/// its own, and picking one piece places the landmark, so its other pieces
/// on that edge are added for free (they are disjoint, so no point counts a
/// landmark twice).  The greedy stays a valid cover, but with pieces it is
/// no longer optimal per edge (Prop. 1 assumes one interval per landmark).
/// At a corner a landmark hidden from the vertex does not count.
Placement place_landmarks(const Points2& route, const Points2& candidates, const Camera& camera,
                          const PlacementOptions& options = PlacementOptions(), const Occluders& occluders = {});

/// Every (edge, candidate) pair with a non-empty Lemma 2 interval, for
/// candidates farther than p from the route; with occluders one row per
/// piece (a candidate hidden from the whole interval has no row).  (x, y) is the candidate in the
/// edge frame.  For corners (corner_visibility): `edge` is the vertex index,
/// [start, end] the interval of turned angle, (x, y) the candidate relative to
/// the vertex.
struct VisibilityTable {
  Eigen::VectorXi edge, candidate;
  Eigen::VectorXd start, end, x, y;
};
VisibilityTable edge_visibility(const Points2& route, const Points2& candidates, const Camera& camera,
                                const Occluders& occluders = {});
/// Corners: a candidate hidden from the vertex has no row.
VisibilityTable corner_visibility(const Points2& route, const Points2& candidates, const Camera& camera,
                                  const Occluders& occluders = {});

/// Signed turn wrap(θ_{i} − θ_{i−1}) at every interior vertex i = 1 … n−2.
Eigen::VectorXd turn_angles(const Points2& route);

/// Pairs of candidates (first < second) on one bearing from the camera at an
/// edge point t where both are in view.
struct AlignmentTable {
  Eigen::VectorXi edge, first, second;
  Eigen::VectorXd t;
};
AlignmentTable alignments(const Points2& route, const Points2& candidates, const Camera& camera,
                          const Occluders& occluders = {});

/// Distance from each point to the route polyline.
Eigen::VectorXd distance_to_route(const Points2& route, const Points2& points);

/// Exact coverage check of a set of landmarks (pairwise distinct): at every
/// interval endpoint, alignment point, on-line landmark position and the
/// midpoint between consecutive ones, count distinct bearings in view.  The
/// count is constant between those points, so the check is exact.  Deficient
/// stretches of zero length are single points (an alignment).
struct CoverageReport {
  int min_count = 0;            ///< fewest distinct bearings in view anywhere checked
  double min_distance = 0.0;    ///< closest landmark to the route
  Eigen::VectorXi kind;         ///< per deficient stretch: 0 edge, 1 corner
  Eigen::VectorXi index;        ///< edge index or vertex index
  Eigen::VectorXd start, end;   ///< the stretch (arc length, or turned angle)
};
/// With occluders a landmark counts only on its pieces (and, at a corner,
/// only if not hidden from the vertex); piece ends are events too.
CoverageReport check_coverage(const Points2& route, const Points2& landmarks, const Camera& camera, int k,
                              bool corners = false, const Occluders& occluders = {});

}  // namespace safenav
