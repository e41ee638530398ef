// The mixture's cuts (belief_mixture.cpp, BeliefSettings::deviation_split): where a
// stratum's vehicles see otherwise than its mean, by their deviation (the cell's) or by
// the heading that the step gives them afresh.
#pragma once

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "belief_model.hpp"
#include "belief_normal.hpp"
#include "belief_strata.hpp"

namespace safenav::belief {

/// Whether two views take the same updates (landmarks in view, fix, ranges).
inline bool same_view(const Step& a, const Step& b) { return a.seen == b.seen && a.fix == b.fix && a.ranges == b.ranges; }

/// The cuts' bounds: the least share a cut may leave on either side, where an
/// unbounded cell (or the heading) is probed (P(z > 3.09) = 10⁻³), and the
/// bisection's steps.
constexpr double kMinShare = 1e-4;
constexpr double kProbeTail = 3.090232306167813;
constexpr int kBisections = 12;

/// BeliefSettings::deviation_split: where stratum `s`'s cell holds vehicles
/// that see otherwise than its mean (probed at the cell's ends along each
/// axis, an unbounded end at ±kProbeTail), the cell is cut where the view
/// changes (bisection between the mean and that end; of several such ends,
/// the one whose change lies nearest the mean), and the part beyond becomes
/// a stratum of its own, with its exact share of N(0, I), its mean and
/// variance, and the same residual error: P + N − m mᵀ − B V Bᵀ.  At most
/// one cut per stratum and step.  `view(s, z)` is what a vehicle at z of s sees.
/// False where no cut is made; else `parts` holds the near and the far part.
template <int K, typename View>
bool cut_at_view_change(const Stratum<K>& s, const View& view, std::array<Stratum<K>, 2>& parts) {
  using VecK = Eigen::Matrix<double, K, 1>;
  // Of the axis ends that see otherwise, the one whose view changes nearest the mean (in z):
  // the boundary's steepest axis, along which one cut follows it best.
  int a = -1;
  double nearest = std::numeric_limits<double>::infinity();
  Interval near, far;
  for (int b = 0; b < K; ++b)
    for (const double sd : {-1.0, 1.0}) {
      double end = sd < 0.0 ? s.lo[b] : s.hi[b];
      if (!std::isfinite(end)) end = sd * kProbeTail;
      if (!((end - s.mean[b]) * sd > 0.0)) continue;
      VecK z = s.mean;
      z[b] = end;
      if (same_view(view(s, z), s.seen)) continue;
      double in = s.mean[b], out = end;
      for (int i = 0; i < kBisections; ++i) {
        z[b] = 0.5 * (in + out);
        (same_view(view(s, z), s.seen) ? in : out) = z[b];
      }
      const double c = 0.5 * (in + out);
      if (!(std::abs(c - s.mean[b]) < nearest)) continue;
      const Interval n = sd < 0.0 ? interval(c, s.hi[b]) : interval(s.lo[b], c);
      const Interval f = sd < 0.0 ? interval(s.lo[b], c) : interval(c, s.hi[b]);
      if (std::min(n.mass, f.mass) * s.w / interval(s.lo[b], s.hi[b]).mass < kMinShare) continue;
      nearest = std::abs(c - s.mean[b]), a = b, near = n, far = f;
    }
  if (a < 0) return false;
  const double whole = interval(s.lo[a], s.hi[a]).mass;  // the cell's along axis a
  // The error's spread with z, B V Bᵀ, held within its whole spread Σ = P + N − m mᵀ: the gate's
  // branches condition the error on its innovation and shrink Σ, but keep B (docs/belief_planning.md,
  // "B within the error's spread").
  const Eigen::Matrix<double, 4, K> B =
      s.B / excess(s.B * s.var.asDiagonal() * s.B.transpose(), s.P + s.N - s.m * s.m.transpose());
  const StateCov residual = s.N - s.m * s.m.transpose() - B * s.var.asDiagonal() * B.transpose();
  parts[0] = s, parts[1] = s;
  int p = 0;
  for (const Interval* c : {&near, &far}) {
    Stratum<K>& t = parts[p++];
    t.B = B;
    t.lo[a] = c->lo, t.hi[a] = c->hi;
    t.w = s.w * c->mass / whole;
    t.m = s.m + B.col(a) * (c->mean - s.mean[a]);
    t.mean[a] = c->mean, t.var[a] = c->var;
    t.N = residual + t.m * t.m.transpose() + t.B * t.var.asDiagonal() * t.B.transpose();
    t.seen = view(t, t.mean);
  }
  return true;
}

/// Where a fresh heading shows stratum s a fix (cut_at_heading): at each of the position's
/// unscented points, each side whose probe at kProbeTail σ sees a fix where the stratum's
/// mean sees none, with the point's weight, the heading beyond the view change (bisected, in
/// σ of the viewed heading), the mean deviation there (position, and the error's heading) and
/// the view.
struct HeadingBeyond {
  double w;
  Interval c;
  Eigen::Vector3d d;
  Step view;
};
struct HeadingProbes {
  std::array<HeadingBeyond, 10> found;
  std::size_t n = 0;
  double vt = 0.0, rho = 1.0;  ///< Var(e_θ | position), and e_θ's share of the viewed heading's variance
};

template <int K, typename ViewE>
HeadingProbes probe_heading(const Stratum<K>& s, const StateCov& S, const ViewE& view_e, double fresh) {
  HeadingProbes out;
  const Eigen::Matrix2d Sxy = S.block(0, 0, 2, 2);
  const Eigen::Vector2d Sxt(S(0, kTheta), S(1, kTheta));
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(Sxy);
  Eigen::Vector2d g = Eigen::Vector2d::Zero();  // E[δθ | δxy] = g·δxy
  for (int i = 0; i < 2; ++i)
    if (es.eigenvalues()[i] > 1e-12 * std::max(1.0, Sxy.trace()))
      g += es.eigenvectors().col(i) * es.eigenvectors().col(i).dot(Sxt) / es.eigenvalues()[i];
  out.vt = std::max(0.0, S(kTheta, kTheta) - Sxt.dot(g));
  const double var = out.vt + fresh;
  if (!(var > 0.0)) return out;
  const double sd = std::sqrt(var);
  out.rho = out.vt / var;
  for (int j = 0; j < 5; ++j) {  // the centre (1/3), then ±√3 along each axis (1/6 each): locate's rule
    Eigen::Vector2d dxy = Eigen::Vector2d::Zero();
    if (j > 0)
      dxy = ((j % 2) ? 1.0 : -1.0) * std::sqrt(3.0 * std::max(0.0, es.eigenvalues()[(j - 1) / 2])) *
            es.eigenvectors().col((j - 1) / 2);
    Eigen::Vector4d e = s.m;
    e.head<2>() += dxy;
    e[kTheta] += g.dot(dxy);
    if (j > 0 && !same_view(view_e(e), s.seen)) continue;  // a change by position is the cell's to cut
    for (const double sg : {-1.0, 1.0}) {
      Eigen::Vector4d x = e;
      x[kTheta] = e[kTheta] + sg * kProbeTail * sd;
      Step far = view_e(x);
      if (same_view(far, s.seen) || !(far.fix || far.ranges)) continue;
      double in = 0.0, beyond = kProbeTail;
      for (int b = 0; b < kBisections; ++b) {
        x[kTheta] = e[kTheta] + sg * sd * 0.5 * (in + beyond);
        (same_view(view_e(x), s.seen) ? in : beyond) = 0.5 * (in + beyond);
      }
      const Interval c = interval(0.5 * (in + beyond), std::numeric_limits<double>::infinity());
      out.found[out.n++] = {j == 0 ? 1.0 / 3.0 : 1.0 / 6.0, c,
                            Eigen::Vector3d(dxy.x(), dxy.y(), g.dot(dxy) + sg * out.rho * sd * c.mean), std::move(far)};
    }
  }
  return out;
}

/// BeliefSettings::deviation_split, where no cut of the cell applies and stratum s's mean
/// sees no fix: the share of its vehicles whose heading shows them one at this step.  The
/// camera looks from the truth after the step's motion, and against the estimate's
/// prediction (on the path) the truth's heading is off by the prior error −(F e + w)_θ:
/// the error's heading and the step's process noise w ~ N(0, Q), `fresh` = Q_θθ, which no
/// cell holds and which each step draws anew.  Over the stratum's spread
/// S = P + N − m mᵀ (at the position's unscented points, and the heading given the position
/// there, N(g·δ, Var(e_θ | δ) + Q_θθ): `probe_heading`), the vehicles beyond the view change
/// on every point and side that sees the most common fixing view become the far part, with
/// their exact moments in (x, y, θ) (a truncated normal in the viewed heading, of which e_θ
/// carries the share ρ = Var(e_θ | δ) / (Var(e_θ | δ) + Q_θθ)); the speed follows them
/// linearly.  The near part keeps the whole's moments less the far part's.  Both keep the
/// cell, B (held within their spread) and the filter covariance; the far part sees the fix.
/// A stratum that sees a fix at its mean is left whole: a vehicle that misses one fix of a
/// run loses a step's dead reckoning, a blind one that takes its first gains its whole error.
template <int K, typename ViewE>
bool cut_at_heading(const Stratum<K>& s, const ViewE& view_e, double fresh, std::array<Stratum<K>, 2>& parts) {
  if (s.seen.fix || s.seen.ranges) return false;
  StateCov S = s.P + s.N - s.m * s.m.transpose();
  S = 0.5 * (S + S.transpose());
  const HeadingProbes h = probe_heading<K>(s, S, view_e, fresh);
  // The most common fixing view, by share, and the share that sees it.
  std::size_t best = 0;
  double p = 0.0;
  for (std::size_t a = 0; a < h.n; ++a) {
    double share = 0.0;
    for (std::size_t b = 0; b < h.n; ++b)
      if (same_view(h.found[b].view, h.found[a].view)) share += h.found[b].w * h.found[b].c.mass;
    if (share > p) p = share, best = a;
  }
  if (!(std::min(p, 1.0 - p) * s.w >= kMinShare)) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();  // about the whole's mean
  for (std::size_t b = 0; b < h.n; ++b) {
    const HeadingBeyond& f = h.found[b];
    if (!same_view(f.view, h.found[best].view)) continue;
    const double q = f.w * f.c.mass / p;
    mean += q * f.d;
    second += q * (f.d * f.d.transpose());
    second(2, 2) += q * (h.vt * (1.0 - h.rho) + h.rho * h.rho * (h.vt + fresh) * f.c.var);
  }
  // u = (x, y, θ) of the error; the speed follows u linearly (G = S Uᵀ (U S Uᵀ)⁺).
  Eigen::Matrix<double, 4, 3> U = Eigen::Matrix<double, 4, 3>::Zero();
  U(0, 0) = U(1, 1) = U(kTheta, 2) = 1.0;
  const Eigen::Matrix3d Suu = U.transpose() * S * U;
  const Eigen::Matrix<double, 4, 3> G = (S * U) * Suu.completeOrthogonalDecomposition().pseudoInverse();
  const StateCov rest = S - G * Suu * G.transpose();
  const Eigen::Vector3d near_mean = -p * mean / (1.0 - p);
  const std::array<Eigen::Vector3d, 2> means{near_mean, mean};
  const std::array<Eigen::Matrix3d, 2> covs{
      Eigen::Matrix3d((Suu - p * second) / (1.0 - p) - near_mean * near_mean.transpose()),
      Eigen::Matrix3d(second - mean * mean.transpose())};
  for (std::size_t q = 0; q < 2; ++q) {
    Stratum<K>& t = parts[q] = s;
    t.w = s.w * (q ? p : 1.0 - p);
    t.m = s.m + G * means[q];
    StateCov Sq = rest + G * covs[q] * G.transpose();
    Sq = 0.5 * (Sq + Sq.transpose());
    t.B = s.B / excess(s.B * s.var.asDiagonal() * s.B.transpose(), Sq);
    t.N = Sq + t.m * t.m.transpose() - t.P;
    t.N = 0.5 * (t.N + t.N.transpose());
  }
  parts[1].seen = h.found[best].view;
  return true;
}

}  // namespace safenav::belief
