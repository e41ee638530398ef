// The deviation mixture's strata (belief_mixture.cpp): what one stratum holds, the fresh
// stratification of the deviation, and where a stratum's vehicles are and see from.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "belief_gate.hpp"
#include "belief_model.hpp"
#include "belief_normal.hpp"

namespace safenav::belief {

/// One stratum of the mixture: its share of the vehicles, the cell of the
/// deviation z ~ N(0, I_K) it stands for (a Gauss–Hermite node is a cell of
/// one point: lo = hi = mean, var 0), its filter covariance P, its error's
/// mean m and second moment P + N, and B, how its error's mean moves with z
/// across the cell (e = m + B (z − mean) + an error independent of z), and
/// whether its vehicles' last fix was turned away, with the shares of them
/// by the fixes turned away in a row (BeliefSettings::gate_probability).
template <int K>
struct Stratum {
  using VecK = Eigen::Matrix<double, K, 1>;
  VecK lo, hi, mean, var;
  double w = 1.0;
  StateCov P = StateCov::Zero(), N = StateCov::Zero();
  Eigen::Vector4d m = Eigen::Vector4d::Zero();
  Eigen::Matrix<double, 4, K> B = Eigen::Matrix<double, 4, K>::Zero();
  Step seen;  ///< what it sees this step
  Eigen::Vector2d at = Eigen::Vector2d::Zero();  ///< where its vehicles are on average (locate)
  Eigen::Vector3d at_cov = Eigen::Vector3d::Zero();  ///< and their spread: xx, xy, yy
  bool turned_away = false;
  Counts counts{};
};

/// The strata of a fresh stratification: the product rule of K copies of
/// the n-node rule.  Without `cells`, stratum i is the Gauss–Hermite node
/// z_i with its weight; with them, it is the box of z whose per-axis
/// intervals carry the nodes' weights as their mass (for 3 nodes, cut at
/// ±0.967), at the box's mean and with its variance.
template <int K>
std::vector<Stratum<K>> rule(const Quadrature& q, bool cells) {
  const std::size_t n = q.node.size();
  std::vector<Interval> axis(n);
  double below = 0.0, lo = -std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j < n; ++j) {
    below += q.weight[j];
    const double hi = j + 1 < n ? normal_isf(1.0 - below) : std::numeric_limits<double>::infinity();
    axis[j] = cells ? interval(lo, hi) : Interval{q.node[j], q.node[j], q.weight[j], q.node[j], 0.0};
    lo = hi;
  }
  std::size_t count = 1;
  for (int a = 0; a < K; ++a) count *= n;
  std::vector<Stratum<K>> out(count);
  for (std::size_t i = 0; i < count; ++i) {
    std::size_t rest = i;  // the last axis varies fastest
    for (int a = K - 1; a >= 0; --a) {
      const Interval& c = axis[rest % n];
      out[i].lo[a] = c.lo, out[i].hi[a] = c.hi, out[i].mean[a] = c.mean, out[i].var[a] = c.var;
      out[i].w *= c.mass;
      rest /= n;
    }
  }
  return out;
}

/// The strata anew from the mixture's error covariance
/// M = Σ w_i (P_i + N_i): stratum i is the error given z in its cell,
/// u = H e = L z (L Lᵀ = H M Hᵀ): mean m_i = B z̄_i, B = M Hᵀ L⁻ᵀ, and
/// second moment P_i + N_i = C + B (V_i + z̄_i z̄_iᵀ) Bᵀ, C = M − M Hᵀ (H M Hᵀ)⁻¹ H M.
/// Each keeps its filter covariance P_i; with another count of strata than
/// the rule's (cells split since the last stratification), each takes
/// their weighted mean.
template <int K>
void stratify(const Eigen::Matrix<double, K, 4>& H, const std::vector<Stratum<K>>& fresh, std::vector<Stratum<K>>& st) {
  using MatK = Eigen::Matrix<double, K, K>;
  StateCov M = StateCov::Zero(), Pbar = StateCov::Zero();
  for (const Stratum<K>& s : st) M += s.w * (s.P + s.N), Pbar += s.w * s.P;
  M = 0.5 * (M + M.transpose());
  if (st.size() != fresh.size()) {
    st = fresh;
    for (Stratum<K>& s : st) s.P = Pbar;
  }
  const Eigen::Matrix<double, 4, K> G = M * H.transpose();
  const MatK S = H * G;
  const Eigen::LLT<MatK> llt(S);
  double floor = 1e-12;  // 1e-12 tr(S)^K: the determinant's units
  for (int a = 0; a < K; ++a) floor *= S.trace();
  const bool ok = llt.info() == Eigen::Success && S.determinant() > floor;
  const StateCov C = ok ? StateCov(M - G * llt.solve(G.transpose())) : M;
  const Eigen::Matrix<double, 4, K> B =
      ok ? Eigen::Matrix<double, 4, K>(G * llt.matrixU().solve(MatK::Identity())) : Eigen::Matrix<double, 4, K>::Zero();
  for (std::size_t i = 0; i < st.size(); ++i) {
    Stratum<K>& s = st[i];
    s.lo = fresh[i].lo, s.hi = fresh[i].hi, s.mean = fresh[i].mean, s.var = fresh[i].var, s.w = fresh[i].w;
    s.m = ok ? Eigen::Vector4d(G * llt.matrixU().solve(s.mean)) : Eigen::Vector4d::Zero();
    s.B = B;
    s.turned_away = false;
    s.counts.fill(0.0);
    s.N = C - s.P + s.m * s.m.transpose();
    if (s.var.any()) s.N += B * s.var.asDiagonal() * B.transpose();
  }
}

/// u = H e at heading h: across the leg (its left normal) and the heading.
inline Eigen::Matrix<double, 2, 4> lateral_axes(double h) {
  Eigen::Matrix<double, 2, 4> H;
  H << -std::sin(h), std::cos(h), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0;
  return H;
}

/// u = H e at heading h: along the leg, across it and the heading.
inline Eigen::Matrix<double, 3, 4> full_axes(double h) {
  Eigen::Matrix<double, 3, 4> H;
  H << std::cos(h), std::sin(h), 0.0, 0.0, -std::sin(h), std::cos(h), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0;
  return H;
}

/// What a vehicle with mean error e (estimate − truth) sees at step k with
/// the along-track axis (BeliefSettings::deviation_along).  Its speed
/// follows the command, so its true progress along the path keeps to the
/// nominal's, and it is its estimate that runs e_along = t·e ahead; the
/// controller turns where the estimate is.  So it sees from the nominal
/// pose e_along further along the steps (`arc`: metres at each stage),
/// moved by −e in position and turned by −e_θ: on a straight leg that is
/// the nominal's arc, at a turn it turns early or late.
struct Ahead {
  std::size_t j;          ///< the stage it sees from
  Eigen::Vector2d shift;  ///< from that stage's end to where it is
};
inline Ahead ahead_of(const std::vector<Step>& steps, const std::vector<double>& arc, std::size_t k, const Eigen::Vector4d& e) {
  const double h = steps[k].x[kTheta];
  const double target = arc[k] + std::cos(h) * e[0] + std::sin(h) * e[1];
  const auto it = std::lower_bound(arc.begin() + 1, arc.end(), target);
  std::size_t j = static_cast<std::size_t>(it - arc.begin());
  if (j >= arc.size()) j = arc.size() - 1;
  if (j > 1 && target - arc[j - 1] < arc[j] - target) --j;  // the nearest stage
  // The rest of the way along stage j's own step.
  const Step& v = steps[j];
  const Eigen::Vector2d dir = v.length > 0.0 ? Eigen::Vector2d((v.end - v.x.head<2>()) / v.length)
                                             : Eigen::Vector2d(std::cos(v.x[kTheta]), std::sin(v.x[kTheta]));
  const double rest = std::clamp(target - arc[j], -v.length, j + 1 < arc.size() ? steps[j + 1].length : 0.0);
  return {j, rest * dir - e.head<2>()};
}
inline Step ahead_view(const Model& model, const std::vector<Step>& steps, const std::vector<double>& arc, std::size_t k,
                const Eigen::Vector4d& e) {
  const Ahead a = ahead_of(steps, arc, k, e);
  return model.seen_from(steps[k], steps[a.j], a.shift, -e[kTheta]);
}

/// Where stratum s's vehicles are as it sees: the mean and covariance (xx, xy, yy) of
/// `where(e)`, the true position of a vehicle with error e, by the unscented transform of
/// its error's position part (N(m, Σ_xy), Σ = P + N − m mᵀ): the rule of N(0, I_2) with
/// its centre (weight 1/3) and ±√3 along each axis (1/6 each), as belief.py spreads it.
template <int K, typename Where>
void locate(Stratum<K>& s, const Where& where) {
  const StateCov S = s.P + s.N - s.m * s.m.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(Eigen::Matrix2d(0.5 * (S.block(0, 0, 2, 2) + S.block(0, 0, 2, 2).transpose())));
  constexpr double w0 = 1.0 / 3.0, wi = 1.0 / 6.0;
  std::array<Eigen::Vector2d, 5> pts;
  pts[0] = where(s.m);
  for (int i = 0; i < 2; ++i)
    for (int sg = 0; sg < 2; ++sg) {
      Eigen::Vector4d e = s.m;
      e.head<2>() += (sg ? -1.0 : 1.0) * std::sqrt(3.0 * std::max(0.0, es.eigenvalues()[i])) * es.eigenvectors().col(i);
      pts[static_cast<std::size_t>(1 + 2 * i + sg)] = where(e);
    }
  s.at = w0 * pts[0];
  for (std::size_t i = 1; i < 5; ++i) s.at += wi * pts[i];
  Eigen::Matrix2d c = w0 * (pts[0] - s.at) * (pts[0] - s.at).transpose();
  for (std::size_t i = 1; i < 5; ++i) c += wi * (pts[i] - s.at) * (pts[i] - s.at).transpose();
  s.at_cov << c(0, 0), c(0, 1), c(1, 1);
}

}  // namespace safenav::belief
