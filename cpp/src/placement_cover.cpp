// Landmark placement, the cover [Placement §II]: the greedy k-interval cover
// of one edge [Placement Alg. 1] (optimal per edge by [Placement Prop. 1]),
// the union over the route's edges, non-coincidence of
// bearings, and the corners.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

#include "placement_internal.hpp"

namespace safenav {

using namespace placement_detail;

namespace {

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
      if (on_side(s) && !placed && (!keep || pieces_length(s) > pieces_length(*keep))) keep = &s;
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
        if (fresh && (best < 0 || reach_at(pool[c], g.probe) > reach_at(pool[best], g.probe))) best = static_cast<int>(c);
      }
      if (best >= 0) break;
    }
    if (best < 0) return;
    taken[best] = 1;
    set.push_back(pool[best]);
    added->push_back(best);
  }
}

CoverResult greedy_groups(const std::vector<Interval>& intervals, const std::vector<int>& group, double length, int k,
                          const std::vector<Interval>& preplaced);

/// Greedy cover of one edge (or turn) from a pool, one interval per piece;
/// returns pool indices picked (a candidate once).
CoverResult cover_pool(const std::vector<Seen>& pool, const std::vector<Interval>& preplaced, double length, int k) {
  std::vector<Interval> iv;
  std::vector<int> group;
  for (size_t i = 0; i < pool.size(); ++i)
    for (const auto& p : pool[i].pieces) {
      iv.push_back(p);
      group.push_back(static_cast<int>(i));
    }
  CoverResult r = greedy_groups(iv, group, length, k, preplaced);
  for (int& c : r.chosen) c = group[c];
  return r;
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

}  // namespace

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
  std::vector<int> group(intervals.size());
  std::iota(group.begin(), group.end(), 0);
  return greedy_groups(intervals, group, length, k, preplaced);
}

namespace {
/// The greedy over intervals in groups (the pieces of one candidate): taking
/// one interval takes its whole group, whose other intervals then count as
/// chosen too (they are disjoint, so no point counts a group twice).  With
/// one interval per group this is [Placement Alg. 1] generalised to k.
/// `chosen` holds the interval picked per group.
CoverResult greedy_groups(const std::vector<Interval>& intervals, const std::vector<int>& group, double length, int k,
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
      res.chosen.push_back(best);
      for (size_t i = 0; i < intervals.size(); ++i)
        if (group[i] == group[best] && !used[i]) {
          used[i] = 1;
          have.add(intervals[i]);
        }
      continue;
    }
    // Stuck: nothing covers c.  Skip to where the next candidate starts.
    double next = length;
    for (size_t i = 0; i < intervals.size(); ++i)
      if (!used[i] && intervals[i].start > c + kEps) next = std::min(next, intervals[i].start);
    skipped.add({c, std::max(next, c + 2 * kEps)});
  }
  std::vector<Interval> real = preplaced;
  for (size_t i = 0; i < intervals.size(); ++i)
    if (used[i]) real.push_back(intervals[i]);
  res.uncovered = deficient_stretches(real, length, k);
  return res;
}
}  // namespace

bool Placement::covered() const {
  for (const auto& e : edges)
    if (!e.uncovered.empty()) return false;
  for (const auto& c : corners)
    if (!c.uncovered.empty()) return false;
  return true;
}

namespace {
/// One edge: the greedy cover by the candidates' pieces (those picked on
/// earlier edges preplaced when reusing), then the non-coincidence repair.
EdgePlacement place_on_edge(const Points2& route, Eigen::Index e, const Points2& candidates, const Camera& camera,
                            const PlacementOptions& opt, const CandidateSet& cs, std::vector<char>* picked) {
  const int k = opt.k;
  std::vector<Seen> all = seen_on_edge(route, e, candidates, cs.grid, cs.close, camera, cs.occ);
  std::vector<Seen> pool, pre;
  for (const auto& s : all) (opt.reuse && (*picked)[s.idx] ? pre : pool).push_back(s);
  if (opt.distinct_bearings) one_per_line_side(&pool, pre);
  std::vector<Interval> pre_iv;
  for (const auto& s : pre) pre_iv.insert(pre_iv.end(), s.pieces.begin(), s.pieces.end());
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
    (*picked)[pool[i].idx] = 1;
  }
  std::sort(ep.landmarks.begin(), ep.landmarks.end());
  return ep;
}

/// The in-place turn at interior vertex v (turn ≠ 0): the greedy cover of
/// the turned angle, landmarks already placed counting for free.
CornerPlacement place_at_corner(const Points2& route, Eigen::Index v, double turn, const Points2& candidates,
                                const Camera& camera, const PlacementOptions& opt, const CandidateSet& cs,
                                std::vector<char>* picked) {
  const std::vector<char>& was = *picked;
  const double theta_in = std::atan2(route(v, 1) - route(v - 1, 1), route(v, 0) - route(v - 1, 0));
  std::vector<Seen> all =
      seen_at_corner(route.row(v).transpose(), theta_in, turn, candidates, cs.grid, cs.close, camera, cs.occ);
  // Landmarks on one ray from the vertex are one bearing for the whole turn:
  // keep one per ray, an already placed one first, else the nearest.
  std::vector<int> order(all.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> brg(all.size());
  for (size_t i = 0; i < all.size(); ++i) brg[i] = std::atan2(all[i].local.y(), all[i].local.x());
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    if (brg[a] != brg[b]) return brg[a] < brg[b];
    if (was[all[a].idx] != was[all[b].idx]) return was[all[a].idx] > was[all[b].idx];
    return all[a].local.norm() < all[b].local.norm();
  });
  std::vector<Seen> pool, pre;
  double last = -10.0;
  for (int i : order) {
    if (opt.distinct_bearings && brg[i] - last <= kBearingTol) continue;
    last = brg[i];
    (was[all[i].idx] ? pre : pool).push_back(all[i]);
  }
  std::vector<Interval> pre_iv;
  for (const auto& s : pre) pre_iv.push_back(s.iv);
  CoverResult r = cover_pool(pool, pre_iv, std::abs(turn), opt.k);
  CornerPlacement cp;
  cp.vertex = static_cast<int>(v);
  cp.turn = turn;
  for (int i : r.chosen) {
    cp.landmarks.push_back(pool[i].idx);
    (*picked)[pool[i].idx] = 1;
  }
  std::sort(cp.landmarks.begin(), cp.landmarks.end());
  return cp;
}

/// The certificate: the exact check of the final landmarks, never the
/// greedy's own count, fills every `uncovered` list.
void certify(const Points2& route, const Points2& candidates, const Camera& camera, const PlacementOptions& opt,
             const Occluders& occluders, Placement* out) {
  Points2 placed(static_cast<Eigen::Index>(out->landmarks.size()), 2);
  for (size_t i = 0; i < out->landmarks.size(); ++i)
    placed.row(static_cast<Eigen::Index>(i)) = candidates.row(out->landmarks[i]);
  const CoverageReport rep = check_coverage(route, placed, camera, opt.k, opt.corners, occluders);
  for (Eigen::Index i = 0; i < rep.start.size(); ++i) {
    const Interval s{rep.start(i), rep.end(i)};
    if (rep.kind(i) == 0) {
      out->edges[rep.index(i)].uncovered.push_back(s);
    } else {
      for (auto& cp : out->corners)
        if (cp.vertex == rep.index(i)) cp.uncovered.push_back(s);
    }
  }
}
}  // namespace

Placement place_landmarks(const Points2& route, const Points2& candidates, const Camera& camera,
                          const PlacementOptions& opt, const Occluders& occluders) {
  const CandidateSet set(route, candidates, camera, occluders);
  check_k(opt.k);
  Placement out;
  for (Eigen::Index i = 0; i < candidates.rows(); ++i)
    if (set.close[i]) out.too_close.push_back(static_cast<int>(i));
  std::vector<char> picked(candidates.rows(), 0);
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e)
    out.edges.push_back(place_on_edge(route, e, candidates, camera, opt, set, &picked));
  if (opt.corners) {
    const Eigen::VectorXd turns = turn_angles(route);
    for (Eigen::Index v = 1; v + 1 < route.rows(); ++v)
      if (std::abs(turns(v - 1)) > kEps)
        out.corners.push_back(place_at_corner(route, v, turns(v - 1), candidates, camera, opt, set, &picked));
  }
  for (Eigen::Index i = 0; i < candidates.rows(); ++i)
    if (picked[i]) out.landmarks.push_back(static_cast<int>(i));
  certify(route, candidates, camera, opt, occluders, &out);
  return out;
}

}  // namespace safenav
