// Landmark placement, the tables the global-optimum ILP is built from
// [Placement §II] (safenav.placement in Python): per (edge, candidate) the
// pieces of the Lemma 2 interval, per (vertex, candidate) the interval of
// turned angle, and the alignments (non-coincidence, [Placement LPP cond. 2]).
#include "placement_internal.hpp"

namespace safenav {

using namespace placement_detail;

namespace {
VisibilityTable to_table(const std::vector<int>& e0, const std::vector<Seen>& s0) {
  // One row per piece (without occluders: one per candidate, its Lemma 2 interval).
  std::vector<int> e;
  std::vector<Seen> s;
  for (size_t i = 0; i < s0.size(); ++i)
    for (const auto& p : s0[i].pieces) {
      e.push_back(e0[i]);
      s.push_back(s0[i]);
      s.back().iv = p;
    }
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

VisibilityTable edge_visibility(const Points2& route, const Points2& candidates, const Camera& camera,
                          const Occluders& occluders) {
  const CandidateSet set(route, candidates, camera, occluders);
  const Grid& grid = set.grid;
  const std::vector<char>& close = set.close;
  std::vector<int> edge;
  std::vector<Seen> rows;
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e)
    for (const auto& s : seen_on_edge(route, e, candidates, grid, close, camera, set.occ)) {
      edge.push_back(static_cast<int>(e));
      rows.push_back(s);
    }
  return to_table(edge, rows);
}

VisibilityTable corner_visibility(const Points2& route, const Points2& candidates, const Camera& camera,
                          const Occluders& occluders) {
  const CandidateSet set(route, candidates, camera, occluders);
  const Grid& grid = set.grid;
  const std::vector<char>& close = set.close;
  const Eigen::VectorXd turns = turn_angles(route);
  std::vector<int> vert;
  std::vector<Seen> rows;
  for (Eigen::Index v = 1; v + 1 < route.rows(); ++v) {
    if (std::abs(turns(v - 1)) <= kEps) continue;
    const double theta_in = std::atan2(route(v, 1) - route(v - 1, 1), route(v, 0) - route(v - 1, 0));
    for (const auto& s : seen_at_corner(route.row(v).transpose(), theta_in, turns(v - 1), candidates, grid, close,
                                        camera, set.occ)) {
      vert.push_back(static_cast<int>(v));
      rows.push_back(s);
    }
  }
  return to_table(vert, rows);
}

AlignmentTable alignments(const Points2& route, const Points2& candidates, const Camera& camera,
                          const Occluders& occluders) {
  const CandidateSet set(route, candidates, camera, occluders);
  const Grid& grid = set.grid;
  const std::vector<char>& close = set.close;
  std::vector<int> e_, f_, s_;
  std::vector<double> t_;
  for (Eigen::Index e = 0; e + 1 < route.rows(); ++e) {
    const auto seen = seen_on_edge(route, e, candidates, grid, close, camera, set.occ);
    for (size_t i = 0; i < seen.size(); ++i)
      for (size_t j = i + 1; j < seen.size(); ++j) {
        double t;
        if (!aligned_in_view(seen[i], seen[j], &t)) continue;
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

}  // namespace safenav
