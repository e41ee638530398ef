// The belief planner (safenav/belief.hpp, docs/belief_planning.md): a
// probabilistic roadmap of collision-free edges, searched best-first over
// (vertex, covariance) beliefs with RRBT's partial-order pruning (Bry & Roy
// 2011) and a per-stage chance constraint (CC-RRT*, Luders et al. 2013).
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <queue>
#include <unordered_set>

#include "belief_model.hpp"
#include "errors.hpp"
#include "filters/checks.hpp"
#include "rng.hpp"
#include "safenav/belief.hpp"
#include "safenav/localizer.hpp"

namespace safenav {

using detail::bad;
using detail::fmt;
using detail::num;

std::string to_string(BeliefPlanStatus status) {
  switch (status) {
    case BeliefPlanStatus::Exact: return "exact";
    case BeliefPlanStatus::Infeasible: return "infeasible";
    case BeliefPlanStatus::NoPath: return "no_path";
    case BeliefPlanStatus::Budget: return "budget";
  }
  return "unknown";
}

void BeliefProblem::validate() const {
  map.validate();
  bmm.validate();
  sensors.validate();
  if (!start.allFinite()) bad("BeliefProblem.start = " + fmt(start) + ": must be finite");
  if (!goal.allFinite()) bad("BeliefProblem.goal = " + fmt(goal) + ": must be finite");
  if (start == goal) bad("BeliefProblem.goal = " + fmt(goal) + ": equals the start");
  check_prior(State::Zero(), start_cov, "x0", "BeliefProblem.start_cov");
  for (std::size_t i = 0; i < guide_paths.size(); ++i)
    if (!guide_paths[i].allFinite()) bad("BeliefProblem.guide_paths[" + std::to_string(i) + "] is not finite");
}

namespace {

using Vec2 = Eigen::Vector2d;

/// BeliefPlannerSettings::max_time from the call's start: the roadmap and the search stop at it.
struct Deadline {
  bool on = false;
  std::chrono::steady_clock::time_point at;
  Deadline(std::chrono::steady_clock::time_point t0, double max_time) : on(max_time > 0.0) {
    if (on) at = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(max_time));
  }
  bool passed() const { return on && std::chrono::steady_clock::now() >= at; }
};

/// An undirected roadmap; each edge has a directed id per direction (the
/// belief along an edge depends on the heading: the field of view).
struct Roadmap {
  std::vector<Vec2> v;
  std::vector<std::vector<std::pair<int, int>>> adj;  // (neighbour, directed edge id)
  std::unordered_set<std::uint64_t> keys;
  int edges = 0;

  int add_vertex(const Vec2& p) {
    v.push_back(p);
    adj.emplace_back();
    return static_cast<int>(v.size()) - 1;
  }
  /// The vertex at p: an existing one at exactly p (a guide's end on the
  /// start or goal, guides that share a point), else a new one.  So no edge
  /// has zero length: such a leg has no heading, and would hide the turn at
  /// its ends from the turn limit.
  int vertex_at(const Vec2& p) {
    for (std::size_t i = 0; i < v.size(); ++i)
      if (v[i] == p) return static_cast<int>(i);
    return add_vertex(p);
  }
  void add_edge(int i, int j, const ObstacleChecker& free) {
    if (i == j) return;
    const auto a = static_cast<std::uint64_t>(std::min(i, j)), b = static_cast<std::uint64_t>(std::max(i, j));
    if (!keys.insert((a << 32) | b).second) return;
    if (!free.segment_free(v[static_cast<std::size_t>(i)], v[static_cast<std::size_t>(j)])) return;
    adj[static_cast<std::size_t>(i)].emplace_back(j, 2 * edges);
    adj[static_cast<std::size_t>(j)].emplace_back(i, 2 * edges + 1);
    ++edges;
  }
  bool connected(int s, int t) const {
    std::vector<char> seen(v.size(), 0);
    std::deque<int> q{s};
    seen[static_cast<std::size_t>(s)] = 1;
    while (!q.empty()) {
      const int u = q.front();
      q.pop_front();
      if (u == t) return true;
      for (const auto& [w, e] : adj[static_cast<std::size_t>(u)])
        if (!seen[static_cast<std::size_t>(w)]) seen[static_cast<std::size_t>(w)] = 1, q.push_back(w);
    }
    return false;
  }
};

/// Start, goal, guide points and seeded uniform samples, each joined to its
/// nearest neighbours within max_edge by free edges.
/// The roadmap; false (and a partial g) where the deadline passed while it was built.
bool build_roadmap(const BeliefProblem& pb, const BeliefPlannerSettings& st, const ObstacleChecker& free,
                   const Deadline& deadline, Roadmap& g) {
  g.add_vertex(pb.start);
  g.add_vertex(pb.goal);
  for (const Points2& path : pb.guide_paths) {
    int prev = -1;
    for (Eigen::Index i = 0; i < path.rows(); ++i) {
      const Vec2 b = path.row(i).transpose();
      const Vec2 a = i > 0 ? Vec2(path.row(i - 1).transpose()) : b;
      // In double: a leg 10¹⁰ times the spacing has more pieces than an int holds (the deadline stops it).
      const double pieces = std::max(1.0, std::ceil((b - a).norm() / st.guide_spacing));
      for (double j = i > 0 ? 1.0 : pieces; j <= pieces; ++j) {
        if (deadline.passed()) return false;
        const Vec2 p = a + (b - a) * (j / pieces);
        if (!free.point_free(p)) {
          prev = -1;
          continue;
        }
        const int id = g.vertex_at(p);
        if (prev >= 0) g.add_edge(prev, id, free);
        prev = id;
      }
    }
  }
  detail::Rng rng(st.seed);
  const Vec2 lo = pb.map.lower, span = pb.map.upper - pb.map.lower;
  for (std::int64_t k = 0, got = 0; got < st.samples && k < 50LL * st.samples; ++k) {
    const double ux = rng.uniform();
    const Vec2 p = lo + Vec2(ux * span.x(), rng.uniform() * span.y());
    if (free.point_free(p)) g.add_vertex(p), ++got;
    if (deadline.passed()) return false;
  }
  const int n = static_cast<int>(g.v.size());
  std::vector<std::pair<double, int>> near;
  for (int i = 0; i < n; ++i) {
    if (deadline.passed()) return false;
    near.clear();
    for (int j = 0; j < n; ++j) {
      const double d = (g.v[static_cast<std::size_t>(i)] - g.v[static_cast<std::size_t>(j)]).norm();
      if (j != i && d <= st.max_edge) near.emplace_back(d, j);
    }
    const std::size_t k = std::min(near.size(), static_cast<std::size_t>(st.neighbours));
    std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(k), near.end());
    for (std::size_t m = 0; m < k; ++m) g.add_edge(i, near[m].second, free);
  }
  return true;
}

/// The chance constraint at one stage: clearance − vehicle_radius − margin ≥
/// k·σ, with σ = √λ_max first and, only where that fails, σ toward the
/// nearest obstacle (CC-RRT*'s tightening along the constraint's normal).
bool feasible(const belief::Model& model, const BeliefPlannerSettings& st, belief::Step& s, const StateCov& P,
              double sigma) {
  const double need = s.clearance - st.belief.inflation.clearance();
  if (!std::isfinite(s.clearance) || st.k_sigma * sigma <= need) return true;
  return st.k_sigma * model.sigma_toward(s, P) <= need;
}

/// Steps P along the polyline pts[from..] (each leg's steps built anew);
/// false at the first stage that breaks the chance constraint.
bool feasible_along(const belief::Model& model, const BeliefPlannerSettings& st, const std::vector<Vec2>& pts,
                    std::size_t from, StateCov P) {
  std::vector<belief::Step> steps;
  for (std::size_t i = from; i + 1 < pts.size(); ++i) {
    steps.clear();
    model.leg(pts[i], pts[i + 1], steps);
    for (belief::Step& s : steps) {
      model.step(s, P);
      if (!feasible(model, st, s, P, position_std(P))) return false;
    }
  }
  return true;
}

/// The turn at b between the legs a → b and b → c [rad, 0..π]; 0 where a
/// leg has no length.
double turn_at(const Vec2& a, const Vec2& b, const Vec2& c) {
  const Vec2 u = b - a, w = c - b;
  if (u.squaredNorm() == 0.0 || w.squaredNorm() == 0.0) return 0.0;
  return std::atan2(std::abs(u.x() * w.y() - u.y() * w.x()), u.dot(w));
}

/// Whether the turns that end pts (its last inner vertex, and the inner
/// vertices less than turn_window metres of path before it) add up to at
/// most max_turn (BeliefPlannerSettings::max_turn).  The one rule of the
/// turn limit: turns_ok applies it at every vertex, Search::may_turn at the
/// vertex a belief turns at.
bool last_turns_ok(const std::vector<Vec2>& pts, const BeliefPlannerSettings& st) {
  const std::size_t last = pts.size() - 2;
  double total = turn_at(pts[last - 1], pts[last], pts[last + 1]), back = 0.0;
  for (std::size_t k = last - 1; k >= 1; --k) {
    back += (pts[k + 1] - pts[k]).norm();
    if (back >= st.turn_window) break;
    total += turn_at(pts[k - 1], pts[k], pts[k + 1]);
  }
  return total <= st.max_turn;
}

/// Whether every stretch of the polyline keeps the turn limit (last_turns_ok
/// at each inner vertex).
bool turns_ok(const std::vector<Vec2>& pts, const BeliefPlannerSettings& st) {
  std::vector<Vec2> head;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    head.push_back(pts[i]);
    if (head.size() >= 3 && !last_turns_ok(head, st)) return false;
  }
  return true;
}

/// Greedy shortcuts of a feasible path: from each vertex in turn, the
/// farthest later vertex joined by a free segment, such that the path still
/// keeps the turn limit (turns_ok) and the belief along the new segment and
/// along the rest of the path still meets the chance constraint.
std::vector<Vec2> shortcut(std::vector<Vec2> pts, const StateCov& P0, const belief::Model& model,
                           const ObstacleChecker& free, const BeliefPlannerSettings& st) {
  StateCov P = P0;  // the belief at pts[i]
  std::vector<belief::Step> steps;
  for (std::size_t i = 0; i + 2 < pts.size(); ++i) {
    for (std::size_t j = pts.size() - 1; j >= i + 2; --j) {
      if (pts[j] == pts[i] || !free.segment_free(pts[i], pts[j])) continue;
      std::vector<Vec2> whole(pts.begin(), pts.begin() + static_cast<std::ptrdiff_t>(i + 1));
      whole.insert(whole.end(), pts.begin() + static_cast<std::ptrdiff_t>(j), pts.end());
      if (!turns_ok(whole, st)) continue;
      std::vector<Vec2> trial{pts[i]};
      trial.insert(trial.end(), pts.begin() + static_cast<std::ptrdiff_t>(j), pts.end());
      if (!feasible_along(model, st, trial, 0, P)) continue;
      pts.erase(pts.begin() + static_cast<std::ptrdiff_t>(i + 1), pts.begin() + static_cast<std::ptrdiff_t>(j));
      break;
    }
    steps.clear();
    model.leg(pts[i], pts[i + 1], steps);
    for (belief::Step& s : steps) model.step(s, P);
  }
  return pts;
}

struct Belief {
  int vertex;
  int from;  ///< the vertex it came from (−1 at the start): the turns it may take next
  int parent;
  double cost;
  StateCov P;
  bool alive;
};

class Search {
 public:
  Search(const BeliefProblem& pb, const BeliefPlannerSettings& st, belief::Model& model, Roadmap& g,
         const Deadline& deadline)
      : pb_(pb), st_(st), model_(model), g_(g), deadline_(deadline), steps_(2 * static_cast<std::size_t>(g.edges)),
        ready_(steps_.size(), 0), at_(g.v.size()) {}

  /// Best-first over beliefs; the goal belief's index, −1 (none), −2 (max_expansions ran out) or
  /// −3 (the deadline passed).
  int run(BeliefPlanResult& res);
  const std::vector<Belief>& beliefs() const { return nodes_; }

 private:
  std::vector<belief::Step>& edge_steps(int e, int from, int to) {
    auto& s = steps_[static_cast<std::size_t>(e)];
    if (!ready_[static_cast<std::size_t>(e)]) {
      model_.leg(g_.v[static_cast<std::size_t>(from)], g_.v[static_cast<std::size_t>(to)], s);
      ready_[static_cast<std::size_t>(e)] = 1;
    }
    return s;
  }
  /// Whether belief b may turn toward vertex w: last_turns_ok on its path's
  /// vertices within turn_window metres before the turn, then w.
  bool may_turn(const Belief& b, int w) const {
    if (b.from < 0) return true;
    const auto at = [this](int i) -> const Vec2& { return g_.v[static_cast<std::size_t>(i)]; };
    recent_.assign({at(w), at(b.vertex), at(b.from)});  // backward; reversed below
    double back = (at(b.vertex) - at(b.from)).norm();
    for (const Belief* c = &b; back < st_.turn_window && c->parent >= 0;) {
      const Belief& p = nodes_[static_cast<std::size_t>(c->parent)];  // at c->from
      if (p.from < 0) break;
      recent_.push_back(at(p.from));
      back += (at(p.vertex) - at(p.from)).norm();
      c = &p;
    }
    std::reverse(recent_.begin(), recent_.end());
    return last_turns_ok(recent_, st_);
  }
  /// Whether a and b came along the same vertices over the last turn_window
  /// metres (at least the last edge): then every turn the limit lets one of
  /// them take later, it lets the other take too.
  bool same_recent_path(const Belief& a, const Belief& b) const {
    double back = 0.0;
    for (const Belief *ca = &a, *cb = &b;;) {
      if (ca->from != cb->from) return false;
      if (ca->from < 0) return true;
      back += (g_.v[static_cast<std::size_t>(ca->vertex)] - g_.v[static_cast<std::size_t>(ca->from)]).norm();
      if (back >= st_.turn_window) return true;
      ca = &nodes_[static_cast<std::size_t>(ca->parent)];
      cb = &nodes_[static_cast<std::size_t>(cb->parent)];
    }
  }
  /// a ≺ b in Bry & Roy's partial order, relaxed by ε: c_a ≤ (1+ε)c_b and
  /// (1+ε)P_b − P_a ⪰ 0; with the turn limit on, only between beliefs that
  /// came the same way over the turn window (same_recent_path), since the
  /// edges a belief may take next depend on it.
  bool dominates(const Belief& a, const Belief& b, double eps) const {
    if (a.cost > (1.0 + eps) * b.cost + 1e-12) return false;
    const bool limit = st_.max_turn < kPi || st_.turn_window > 0.0;
    if (limit && !same_recent_path(a, b)) return false;
    const StateCov D = (1.0 + eps) * b.P - a.P;
    const double scale = std::max(1e-300, b.P.diagonal().maxCoeff());
    return Eigen::SelfAdjointEigenSolver<StateCov>(D, Eigen::EigenvaluesOnly).eigenvalues()(0) >= -1e-12 * scale;
  }
  /// Inserts b at its vertex unless a belief there dominates it; retires the ones it dominates.
  bool insert(Belief b, BeliefPlanResult& res);

  const BeliefProblem& pb_;
  const BeliefPlannerSettings& st_;
  belief::Model& model_;
  Roadmap& g_;
  const Deadline& deadline_;
  std::vector<std::vector<belief::Step>> steps_;
  std::vector<char> ready_;
  std::vector<std::vector<int>> at_;  // live beliefs per vertex
  std::vector<Belief> nodes_;
  mutable std::vector<Vec2> recent_;  // may_turn's scratch
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open_;
};

bool Search::insert(Belief b, BeliefPlanResult& res) {
  auto& here = at_[static_cast<std::size_t>(b.vertex)];
  for (int i : here)
    if (dominates(nodes_[static_cast<std::size_t>(i)], b, st_.dominance_tolerance)) return false;
  here.erase(std::remove_if(here.begin(), here.end(),
                            [&](int i) {
                              Belief& o = nodes_[static_cast<std::size_t>(i)];
                              if (!dominates(b, o, 0.0)) return false;
                              o.alive = false;
                              return true;
                            }),
             here.end());
  if (static_cast<int>(here.size()) >= st_.max_beliefs) {
    ++res.capped;
    return false;
  }
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(std::move(b));
  here.push_back(id);
  ++res.beliefs;
  const Belief& n = nodes_.back();
  open_.emplace(n.cost + st_.alpha * (g_.v[static_cast<std::size_t>(n.vertex)] - pb_.goal).norm(), id);
  return true;
}

int Search::run(BeliefPlanResult& res) {
  insert(Belief{0, -1, -1, 0.0, pb_.start_cov, true}, res);
  while (!open_.empty()) {
    const int id = open_.top().second;
    open_.pop();
    if (!nodes_[static_cast<std::size_t>(id)].alive) continue;
    const Belief cur = nodes_[static_cast<std::size_t>(id)];
    if (cur.vertex == 1) return id;
    if (++res.expansions > st_.max_expansions) return -2;
    if (deadline_.passed()) return -3;
    for (const auto& [w, e] : g_.adj[static_cast<std::size_t>(cur.vertex)]) {
      if (w == cur.from || !may_turn(cur, w)) continue;
      Belief next{w, cur.vertex, id, cur.cost, cur.P, true};
      bool ok = true;
      for (belief::Step& s : edge_steps(e, cur.vertex, w)) {
        model_.step(s, next.P);
        const double sigma = position_std(next.P);
        next.cost += (st_.alpha + st_.sigma_weight * sigma) * s.length;
        if (!feasible(model_, st_, s, next.P, sigma)) {
          ok = false;
          break;
        }
      }
      if (ok) insert(std::move(next), res);
    }
  }
  return -1;
}

}  // namespace

BeliefPlanResult plan_belief(const BeliefProblem& problem, const BeliefPlannerSettings& settings) {
  const auto t0 = std::chrono::steady_clock::now();
  problem.validate();
  settings.validate();
  BeliefPlanResult res;
  auto done = [&](BeliefPlanStatus s, std::string why) {
    res.status = s;
    res.success = s == BeliefPlanStatus::Exact;
    res.detail = std::move(why);
    res.planning_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return res;
  };
  PlanningMap grown = problem.map;
  grown.clearance = std::max(grown.clearance, settings.belief.inflation.clearance());
  const ObstacleChecker free(grown);
  for (const auto& [p, name] : {std::pair{problem.start, "start"}, std::pair{problem.goal, "goal"}})
    if (!free.point_free(p))
      return done(BeliefPlanStatus::NoPath, std::string(name) + " " + fmt(p) + " is not free (clearance " +
                                                num(grown.clearance) + " m)");
  belief::Model model(problem.bmm, problem.sensors, problem.map, settings.belief);
  const double need = model.clearance_at(problem.start) - settings.belief.inflation.clearance();
  if (settings.k_sigma * position_std(problem.start_cov) > need)
    return done(BeliefPlanStatus::Infeasible, "the start breaks the chance constraint: k*sigma = " +
                                                  num(settings.k_sigma * position_std(problem.start_cov)) +
                                                  " m > clearance left " + num(need) + " m");
  const Deadline deadline(t0, settings.max_time);
  const auto out_of_time = [&](const char* in) {
    return done(BeliefPlanStatus::Budget, "max_time = " + num(settings.max_time) + " s ran out " + in);
  };
  Roadmap g;
  const bool built = build_roadmap(problem, settings, free, deadline, g);
  res.vertices = static_cast<int>(g.v.size());
  res.edges = g.edges;
  if (!built) return out_of_time("building the roadmap");
  Search search(problem, settings, model, g, deadline);
  const int found = search.run(res);
  if (found == -2) return done(BeliefPlanStatus::Budget, "max_expansions = " + std::to_string(settings.max_expansions) + " ran out");
  if (found == -3) return out_of_time("in the search");
  if (found < 0) {
    if (!g.connected(0, 1))
      return done(BeliefPlanStatus::NoPath, "the roadmap (" + std::to_string(res.vertices) + " vertices, " +
                                                std::to_string(res.edges) + " edges) does not join start and goal");
    return done(BeliefPlanStatus::Infeasible,
                "no roadmap path keeps clearance >= " + num(settings.k_sigma) + "*sigma + " +
                    num(settings.belief.inflation.clearance()) + " m and turns by at most max_turn = " +
                    num(settings.max_turn) + " rad at a vertex and within turn_window = " +
                    num(settings.turn_window) + " m");
  }
  std::vector<Vec2> pts;
  for (int i = found; i >= 0; i = search.beliefs()[static_cast<std::size_t>(i)].parent)
    pts.push_back(g.v[static_cast<std::size_t>(search.beliefs()[static_cast<std::size_t>(i)].vertex)]);
  std::reverse(pts.begin(), pts.end());
  if (settings.shortcut) pts = shortcut(std::move(pts), problem.start_cov, model, free, settings);
  res.path.resize(static_cast<Eigen::Index>(pts.size()), 2);
  for (std::size_t i = 0; i < pts.size(); ++i) res.path.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
  res.profile = propagate_belief(res.path, problem.bmm, problem.sensors, problem.map, problem.start_cov,
                                 settings.belief);
  // The cost of the returned path, as the search sums it: (α + w_σ·σ_k)·(stage length).
  res.cost = settings.alpha * res.profile.length;
  for (Eigen::Index k = 1; k < res.profile.positions.rows(); ++k)
    res.cost += settings.sigma_weight * res.profile.sigma[k] *
                (res.profile.positions.row(k) - res.profile.positions.row(k - 1)).norm();
  return done(BeliefPlanStatus::Exact, "found");
}

}  // namespace safenav
