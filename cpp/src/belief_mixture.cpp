// The expected belief over the vehicle's deviation from the path
// (BeliefSettings::deviation_mixture; docs/belief_planning.md, "The model").
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "belief_cuts.hpp"
#include "belief_gate.hpp"
#include "belief_model.hpp"
#include "belief_normal.hpp"
#include "belief_strata.hpp"
#include "errors.hpp"

namespace safenav::belief {
namespace {

using detail::bad;

/// Whether the strata are one Gaussian again: every one took the same
/// updates and their filter covariances agree to within 1 % of their norm
/// (Frobenius).  Mid-transition, when some have seen a landmark and some
/// not, the mixture is far from Gaussian, and stratifying it anew would
/// move the late strata's error toward the rest.
template <int K>
bool one_gaussian(const std::vector<Stratum<K>>& st) {
  constexpr double tol = 1e-2;
  for (std::size_t i = 1; i < st.size(); ++i) {
    if (!same_view(st[i].seen, st[0].seen)) return false;
    if ((st[i].P - st[0].P).norm() > tol * st[0].P.norm()) return false;
  }
  return true;
}

/// The mixture's bounds on splitting (the most strata at once are the
/// rule's and BeliefSettings::deviation_free_strata more, 1 009 for the
/// 3 × 3 rule and 1 027 for 3³ by default, or twice the rule's where that is more):
/// the room kept for the step's cuts (the closest strata are joined first,
/// never two further apart than kRoomApart), and how close two adjacent
/// strata's filter covariances must be to join again (the cuts' own bounds:
/// belief_cuts.hpp).
constexpr std::size_t kRoom = 8;
constexpr double kRoomApart = 0.5;
constexpr double kJoinTolerance = 0.1;
/// The least share a branch that changes between turned away and not is
/// kept at (gate_step): joined, its vehicles' count would never reach the
/// reset.
constexpr double kMinCountShare = 1e-6;

/// The step's cuts (cut_at_view_change, or where it cuts nothing, cut_at_heading with the
/// step's heading noise `fresh`), at most `room`: each stratum's near part in its place,
/// the far part appended.  With more cuts than room, those that hold the most squared position
/// error beyond the view change (the far part's share times tr (P + N)_xy) are made: in the
/// strata's order a tail's cut came late and found the room taken.  `again`: the step's second
/// pass, which cuts the cells once more where a fix still comes or goes within one (no heading
/// cut): where a step brings many views at once, as at a turn toward a cluster, a cell can hold
/// two changes of its fix, and one cut left the vehicles between the second change and the cell's
/// end with the mean's view (docs/belief_planning.md, "Two cuts at a first fix").  A heading
/// cut's far part, which sees as its heading and not as its mean, is left as it is.  `settled`
/// marks the strata in which the first pass found no cut: the second, which looks for fewer,
/// finds none there either, so it skips them (the caller clears the marks where strata are
/// joined between the passes).
template <int K, typename View, typename ViewE>
void split_at_view_changes(std::vector<Stratum<K>>& st, std::size_t room, const View& view, const ViewE& view_e,
                           double fresh, bool again, std::vector<char>& settled) {
  if (!again) settled.assign(st.size(), 0);
  if (room == 0) return;
  using Cut = std::pair<std::size_t, std::array<Stratum<K>, 2>>;
  std::vector<Cut> cuts;
  for (std::size_t i = 0; i < st.size(); ++i) {
    // The second pass leaves a heading cut's far part: it sees as its heading, not its mean.
    if (again && (settled[i] || !same_view(view(st[i], st[i].mean), st[i].seen))) continue;
    if (Cut c{i, {}}; cut_at_view_change<K>(st[i], view, c.second, again) ||
                      (!again && cut_at_heading<K>(st[i], view_e, fresh, c.second)))
      cuts.push_back(std::move(c));
    else
      settled[i] = 1;
  }
  if (cuts.size() > room) {
    const auto held = [](const Cut& c) {  // the far part's share times its mean square position error
      return c.second[1].w * (c.second[1].P + c.second[1].N).block(0, 0, 2, 2).trace();
    };
    std::stable_sort(cuts.begin(), cuts.end(), [&](const Cut& a, const Cut& b) { return held(a) > held(b); });
    cuts.resize(room);
    std::sort(cuts.begin(), cuts.end(), [](const Cut& a, const Cut& b) { return a.first < b.first; });
  }
  for (auto& [i, c] : cuts) st[i] = c[0], st.push_back(c[1]);
  settled.resize(st.size(), 0);
}

/// The axis on which the cells of strata a and b touch to make a box (the
/// same interval on every other axis), K where the cells are the same (the
/// gate split a cell's vehicles, gate_step), or −1; also −1 unless they take
/// the same updates this step.
template <int K>
int adjacent(const Stratum<K>& a, const Stratum<K>& b) {
  int axis = -1;
  for (int d = 0; d < K; ++d) {
    if (a.lo[d] == b.lo[d] && a.hi[d] == b.hi[d]) continue;
    if (axis >= 0 || !(a.hi[d] == b.lo[d] || b.hi[d] == a.lo[d])) return -1;
    axis = d;
  }
  if (!same_view(a.seen, b.seen) || a.turned_away != b.turned_away) return -1;
  return axis >= 0 ? axis : K;
}

/// How far apart two strata's filter covariances are (Frobenius, relative).
template <int K>
double apart(const Stratum<K>& a, const Stratum<K>& b) {
  return (a.P - b.P).norm() / std::max(a.P.norm(), b.P.norm());
}

/// Stratum j joined to stratum i on `axis`, moment for moment: the weights
/// add; the error's mean, second moment, the filter covariance and B are
/// the weighted means, and so are the shares by fixes turned away; the cell
/// is their union (the same cell: axis K).
template <int K>
void join(std::vector<Stratum<K>>& st, std::size_t i, std::size_t j, int axis) {
  Stratum<K>& s = st[i];
  const Stratum<K>& t = st[j];
  const double w = s.w + t.w, u = s.w / w, v = t.w / w;
  const StateCov moment = u * (s.P + s.N) + v * (t.P + t.N);
  s.P = u * s.P + v * t.P;
  s.N = moment - s.P;
  s.m = u * s.m + v * t.m;
  s.B = u * s.B + v * t.B;
  if (axis < K) {
    const Interval c = interval(std::min(s.lo[axis], t.lo[axis]), std::max(s.hi[axis], t.hi[axis]));
    s.lo[axis] = c.lo, s.hi[axis] = c.hi, s.mean[axis] = c.mean, s.var[axis] = c.var;
  }
  for (std::size_t c = 0; c < s.counts.size(); ++c) s.counts[c] = u * s.counts[c] + v * t.counts[c];
  s.w = w;
  st.erase(st.begin() + static_cast<std::ptrdiff_t>(j));
}

/// Cells cut at a view change that take the same updates again and whose
/// filter covariances are within `tol` are joined (`join`).  Without this a
/// boundary that moves across a cell step by step leaves a sliver behind
/// each step.
template <int K>
void merge_alike(std::vector<Stratum<K>>& st, double tol) {
  for (std::size_t i = 0; i < st.size(); ++i)
    for (std::size_t j = i + 1; j < st.size();) {
      const int a = adjacent(st[i], st[j]);
      if (a >= 0 && apart(st[i], st[j]) <= tol)
        join(st, i, j, a), j = i + 1;
      else
        ++j;
    }
}

/// Joins the closest pair of adjacent strata that take the same updates
/// (`apart`), to make room for a cut; false when there is none within
/// kRoomApart.  Weights do not count: the slivers are the vehicles far off
/// (cut off blind, turned away by the gate), whose error the mixture is
/// there to keep.  Nor are two strata joined whose filters differ by more
/// than half: a blind stratum joined to a fixed neighbour would put its
/// vehicles' error at their mean, and the next view change would be probed
/// from there (world 23's P1: the 0.5 % that miss the fixes before a turn
/// are then 0.05 %; docs/belief_planning.md, "Room made only among alike
/// strata").  The step then makes fewer cuts and keeps fewer of the gate's
/// branches apart, the least loaded first.
template <int K>
bool make_room(std::vector<Stratum<K>>& st) {
  double best = std::numeric_limits<double>::infinity();
  std::size_t bi = 0, bj = 0;
  int axis = -1;
  for (std::size_t i = 0; i < st.size(); ++i)
    for (std::size_t j = i + 1; j < st.size(); ++j) {
      const int a = adjacent(st[i], st[j]);
      const double d = a >= 0 ? apart(st[i], st[j]) : best;
      if (d < best) best = d, bi = i, bj = j, axis = a;
    }
  if (axis < 0 || !(best <= kRoomApart)) return false;
  join(st, bi, bj, axis);
  return true;
}

/// BeliefSettings::gate_probability: stratum s's step where its fix may be
/// turned away (gate_branches; turned_away_branches for a stratum turned
/// away already), after its prediction (s.N is F N Fᵀ, s.m and s.B are
/// still the prior's).  Each branch that holds at least kMinShare of the
/// vehicles becomes a stratum of its own, with its own filter covariance
/// and error (the same cell): the vehicles whose fix has not come yet, those
/// whose fix passed, those turned away (by sector), those whose position
/// restarts.  Joined in one, the turned-away vehicles' error would look like
/// a tail of the updated ones', and the updated ones' covariance would make
/// the gate turn away vehicles still waiting for their first fix.  A branch
/// under kMinShare (kMinCountShare where it changes between turned away and
/// not), or one with no `room` left, is joined, moment for moment, to the
/// kept branch whose filter covariance is closest.  The first kept branch
/// stays in s, the others go to `away`.  Only where o.gating is Branches
/// (StepOutcome::Gating).
template <int K>
void gate_step(const Gate& gate, const StepOutcome& o, std::size_t room, Stratum<K>& s,
               std::vector<Stratum<K>>& away) {
  std::array<GateBranch, 2 + kGateSectors> br;  // fixed room: no allocation per step
  int B = static_cast<int>(br.size());
  if (s.turned_away) {
    const auto b = turned_away_branches(o, o.F * s.m, s.N, s.counts, gate.reset_after);
    std::copy(b.begin(), b.end(), br.begin());
    B = static_cast<int>(b.size());
  } else {
    br = gate_branches(o, o.F * s.m, s.N, gate.reset_after, gate.gamma);
  }
  // Which kept branch each joins (−1: none yet); the heaviest is kept first.
  std::array<int, 2 + kGateSectors> into, order;
  into.fill(-1);
  for (int b = 0; b < B; ++b) order[static_cast<std::size_t>(b)] = b;
  std::sort(order.begin(), order.begin() + B, [&](int a, int b) { return br[a].share > br[b].share; });
  std::size_t kept = 0;
  const auto ranked = [&](int k) { return order[static_cast<std::size_t>(k)]; };  // the first B
  for (int k = 0; k < B; ++k) {
    const int b = ranked(k);
    if (!(br[b].share > 0.0)) continue;
    // A branch whose vehicles change from seeing their fixes pass to having
    // them turned away, or back, is kept however small (joined, their count
    // would never reach the reset); merge_alike joins it to the last step's.
    const double floor = br[b].turned_away != s.turned_away ? kMinCountShare : kMinShare;
    if (kept == 0 || (br[b].share * s.w >= floor && kept <= room)) {
      into[b] = b, ++kept;
      continue;
    }
    double best = std::numeric_limits<double>::infinity();
    for (int l = 0; l < B; ++l)
      if (const int c = ranked(l); into[c] == c && (br[b].P - br[c].P).norm() < best)
        best = (br[b].P - br[c].P).norm(), into[b] = c;
  }
  const Eigen::Matrix<double, 4, K> FB = o.F * s.B;
  const Stratum<K> prior = s;
  bool first = true;
  for (int k = 0; k < B; ++k) {
    const int c = ranked(k);
    if (into[c] != c) continue;
    Stratum<K> t = prior;
    double total = 0.0, heaviest = -1.0;
    StateCov P = StateCov::Zero(), M = StateCov::Zero();
    Eigen::Vector4d m = Eigen::Vector4d::Zero();
    Eigen::Matrix4d T = Eigen::Matrix4d::Zero();
    for (int b = 0; b < B; ++b) {
      if (into[b] != c) continue;
      const GateBranch& g = br[b];
      total += g.share, P += g.share * g.P, M += g.share * g.M, m += g.share * g.m, T += g.share * g.T;
      if (g.share > heaviest) heaviest = g.share, t.turned_away = g.turned_away, t.counts = g.counts;
    }
    t.w = prior.w * total;
    t.P = P / total, t.m = m / total, t.B = (T / total) * FB;
    t.P = 0.5 * (t.P + t.P.transpose());
    t.N = M / total - t.P;
    t.N = 0.5 * (t.N + t.N.transpose());
    if (first) s = t, first = false;
    else away.push_back(t);
  }
}

/// Stratum s's step (Model::step at what it sees): its filter covariance,
/// and its error's mean, B and second moment beyond P moved by the step's
/// factors; where the gate branches (gate_step), the branches other than
/// the first go to `away`, with `room` slots left.  Adds the stratum's
/// prior second moment to mix_m and leaves the step's F in F.
template <int K>
void step_stratum(const Model& model, const Gate& gate, std::size_t room, Stratum<K>& s,
                  std::vector<Stratum<K>>& away, StateCov& mix_m, Eigen::Matrix4d& F) {
  StepOutcome o;
  model.step(s.seen, s.P, &o, true);
  F = o.F;
  s.N = F * s.N * F.transpose();
  mix_m += s.w * (o.Pm + s.N);
  if (o.gating == StepOutcome::Gating::Branches) {
    gate_step<K>(gate, o, room, s, away);
    return;
  }
  if (o.gating == StepOutcome::Gating::Passes) {  // its fixes pass: their noise, not its error, decides
    s.turned_away = false;
    s.counts.fill(0.0);
  }
  Eigen::Matrix4d T;
  if (o.p_fix < 1.0) {  // a fix that may not arrive: each branch moves the error by its own factor
    const StateCov X = s.N;
    s.N = o.p_fix * o.T_fix * X * o.T_fix.transpose() + (1.0 - o.p_fix) * o.T_none * X * o.T_none.transpose();
    T = o.p_fix * o.T_fix + (1.0 - o.p_fix) * o.T_none;
  } else {
    T = o.Pm.ldlt().solve(s.P.transpose()).transpose();  // P_i (P_i⁻)⁻¹ = I − K_i H_i
    s.N = T * s.N * T.transpose();
  }
  s.m = T * (F * s.m);
  s.B = T * (F * s.B);
  s.N = 0.5 * (s.N + s.N.transpose());
}

/// Row `row` of the trace: each stratum's weight, where its vehicles are
/// (`locate`) and its second moment; returns the mixture's second moment Σ w_i (P_i + N_i).
template <int K>
StateCov record_stage(StrataTrace& trace, Eigen::Index row, const std::vector<Stratum<K>>& st) {
  if (const auto need = static_cast<Eigen::Index>(st.size()); need > trace.weight.cols()) {
    // More strata than slots so far: twice the slots (zeros where no stratum was).
    const Eigen::Index cols = std::max(need, 2 * trace.weight.cols());
    const auto widen = [&](Eigen::MatrixXd& x, Eigen::Index c) {
      Eigen::MatrixXd y = Eigen::MatrixXd::Zero(x.rows(), c);
      y.leftCols(x.cols()) = x;
      x.swap(y);
    };
    widen(trace.weight, cols), widen(trace.positions, 2 * cols), widen(trace.msq, cols), widen(trace.position_cov, 3 * cols);
  }
  StateCov mix = StateCov::Zero();
  for (std::size_t i = 0; i < st.size(); ++i) {
    const Stratum<K>& s = st[i];
    mix += s.w * (s.P + s.N);
    const auto col = static_cast<Eigen::Index>(i);
    trace.weight(row, col) = s.w;
    trace.msq(row, col) = s.P(0, 0) + s.N(0, 0) + s.P(1, 1) + s.N(1, 1);
    trace.positions.block<1, 2>(row, 2 * col) = s.at.transpose();
    trace.position_cov.block<1, 3>(row, 3 * col) = s.at_cov.transpose();
  }
  return mix;
}

}  // namespace

/// BeliefSettings::deviation_mixture: the vehicle's error, stratified on its
/// part across the leg and in heading, u = H e (H's rows: the leg's left
/// normal n and the heading; K = 3 with deviation_along: the leg's direction
/// first), at the n^K Gauss–Hermite nodes z_i of N(0, I_K)
/// (n = BeliefSettings::deviation_nodes; with 3, per axis −√3, 0, √3 with
/// weights 1/6, 2/3, 1/6), or with deviation_split at cells of z (`rule`),
/// cut where the view changes (belief_cuts.hpp: by the cell, or for a blind
/// stratum by the heading that the step's noise gives its vehicles afresh).
/// Stratum i is the error given u = L z_i (L Lᵀ = H M Hᵀ, M the error's
/// covariance): mean m_i = M Hᵀ L⁻ᵀ z_i and covariance M − M Hᵀ (H M Hᵀ)⁻¹ H M
/// (`stratify`).  The vehicle drives its estimate along the path, so
/// stratum i's vehicles are off it by −m_i: they see from the nominal pose
/// moved by −n·m_i across the leg (and by −t·m_i along it, K = 3) and turned
/// by −m_i,θ, and their filter takes the updates of what is in view from
/// there.  Each stratum's filter covariance P_i follows the filter's
/// recursion; its error's second moment is P_i + N_i, where N_i, the part
/// the stratum's selection adds, moves with the filter's error dynamics:
/// N_i ← T_i F N_i Fᵀ T_iᵀ, m_i ← T_i F m_i, T_i = P_i (P_i⁻)⁻¹ = I − K_i H_i
/// (the optimal gain's); a step whose fix may not arrive (StepOutcome)
/// moves N_i by each branch's factor, weighted by the branch's probability,
/// and m_i (and B_i) by their mean.  So the strata that see a landmark late
/// are the ones whose error lies on that side, and the reported covariance
/// Σ w_i (P_i + N_i) keeps their larger error until they see it.  While the
/// strata are one Gaussian (one_gaussian), they are stratified anew from
/// its covariance each step, so the deviation follows the current error.
/// A[k−1] = M[k] (M⁻)⁻¹ F as in the single recursion, M⁻ the mixture's
/// prior, within_marginals.  `trace` receives each stratum's weight, where
/// it saw from and its second moment.
template <int K>
void mixture_recursion(const Model& model, const std::vector<Step>& steps, std::vector<StateCov>& P,
                       std::vector<Eigen::Matrix4d>& A, StrataTrace& trace) {
  using VecK = Eigen::Matrix<double, K, 1>;
  const BeliefSettings& settings = model.settings();
  const std::vector<Stratum<K>> fresh = rule<K>(Quadrature(settings.deviation_nodes), settings.deviation_split);
  std::vector<Stratum<K>> st = fresh;
  for (Stratum<K>& s : st) s.P = P[0];
  const auto n = static_cast<Eigen::Index>(steps.size());
  const std::size_t cap =
      settings.deviation_split
          ? std::max(fresh.size() + static_cast<std::size_t>(settings.deviation_free_strata), 2 * fresh.size())
          : fresh.size();
  const auto slots = static_cast<Eigen::Index>(std::min(cap, 2 * fresh.size() + kRoom));  // widened as needed
  trace.weight = Eigen::MatrixXd::Zero(n, slots);
  trace.positions = Eigen::MatrixXd::Zero(n, 2 * slots);
  trace.msq = Eigen::MatrixXd::Zero(n, slots);
  trace.position_cov = Eigen::MatrixXd::Zero(n, 3 * slots);
  // Row 0: every stratum at the start, with the prior (their views are taken at step 1).
  for (Stratum<K>& s : st) s.seen.end = s.at = steps.empty() ? Eigen::Vector2d::Zero() : steps[0].end;
  if (n > 0) record_stage<K>(trace, 0, st);
  std::vector<double> arc(steps.size(), 0.0);  // metres along the steps
  for (std::size_t k = 1; k < steps.size(); ++k) arc[k] = arc[k - 1] + steps[k].length;
  Eigen::Index used = static_cast<Eigen::Index>(st.size());
  bool merged = true;
  const Gate gate(settings.gate_probability);
  std::vector<Stratum<K>> away;  // a step's strata whose fix the gate turned away
  std::vector<char> settled;     // the strata in which a step's first pass found no cut
  for (std::size_t k = 1; k < steps.size(); ++k) {
    const double h = steps[k].x[kTheta];
    Eigen::Matrix<double, K, 4> H;
    if constexpr (K == 2) H = lateral_axes(h); else H = full_axes(h);
    if (merged) stratify<K>(H, fresh, st);
    // What a vehicle with error e sees: it is off the path by minus its error (the vehicles of
    // stratum s at z: e = m + B (z − z̄)).
    const auto view_e = [&](const Eigen::Vector4d& e) {
      const VecK d = -(H * e);
      if (!(d.squaredNorm() > 0.0)) return steps[k];
      if constexpr (K == 3) return ahead_view(model, steps, arc, k, e);
      else return model.offset(steps[k], d[0], d[K - 1]);
    };
    const auto view = [&](const Stratum<K>& s, const VecK& z) { return view_e(s.m + s.B * (z - s.mean)); };
    for (Stratum<K>& s : st) s.seen = view(s, s.mean);
    if (settings.deviation_split)
      for (const bool again : {false, true}) {
        const std::size_t before = st.size();
        while (st.size() + kRoom > cap && make_room<K>(st)) {}
        if (st.size() != before) settled.assign(st.size(), 0);
        split_at_view_changes<K>(st, cap - std::min(cap, st.size()), view, view_e,
                                 model.process_noise(steps[k])(kTheta, kTheta), again, settled);
      }
    const auto where = [&](const Eigen::Vector4d& e) -> Eigen::Vector2d {
      if constexpr (K == 3) {
        const Ahead a = ahead_of(steps, arc, k, e);
        return steps[a.j].end + a.shift;
      } else {
        const Eigen::Vector2d nrm(-std::sin(h), std::cos(h));
        return steps[k].end - nrm * nrm.dot(e.head<2>());
      }
    };
    for (Stratum<K>& s : st) locate<K>(s, where);
    StateCov mix = StateCov::Zero(), mix_m = StateCov::Zero();
    Eigen::Matrix4d F;
    away.clear();
    const std::size_t stepped = st.size();
    for (std::size_t i = 0; i < stepped; ++i)
      step_stratum<K>(model, gate, cap - std::min(cap, stepped + away.size()), st[i], away, mix_m, F);
    st.insert(st.end(), away.begin(), away.end());
    mix = record_stage<K>(trace, static_cast<Eigen::Index>(k), st);
    used = std::max(used, static_cast<Eigen::Index>(st.size()));
    P[k] = 0.5 * (mix + mix.transpose());
    A[k - 1] = within_marginals(mix_m.ldlt().solve(P[k].transpose()).transpose() * F, P[k - 1], P[k]);
    merged = one_gaussian(st);
    if (settings.deviation_split && !merged) merge_alike<K>(st, kJoinTolerance);
  }
  trace.weight.conservativeResize(Eigen::NoChange, used);
  trace.positions.conservativeResize(Eigen::NoChange, 2 * used);
  trace.msq.conservativeResize(Eigen::NoChange, used);
  trace.position_cov.conservativeResize(Eigen::NoChange, 3 * used);
}

void deviation_mixture(const Model& model, const std::vector<Step>& steps, std::vector<StateCov>& P,
                       std::vector<Eigen::Matrix4d>& A, StrataTrace& trace) {
  if (model.settings().deviation_along)
    mixture_recursion<3>(model, steps, P, A, trace);
  else
    mixture_recursion<2>(model, steps, P, A, trace);
}

}  // namespace safenav::belief
