// The mixture's cuts (belief_mixture.cpp, BeliefSettings::deviation_split): where a
// stratum's vehicles see otherwise than its mean, by their deviation (the cell's) or by
// the heading that the step gives them afresh.
#pragma once

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

/// The cuts' bounds: the least share of the vehicles a cut may leave on
/// either side, where an unbounded cell (or the heading) is probed, and the
/// bisection's steps.  A part that takes a fix where the rest does not, or
/// misses one that the rest takes, loses or keeps its whole error: it is cut
/// down to kMinFixShare, a hundredth of the default risk budget ε = 10⁻⁴ (a
/// bin whose σ a gate's or a view's tail decides holds 10⁻⁴–10⁻³ of the
/// vehicles, in parts of a small stratum).  A part that sees other landmarks
/// only changes its fix's covariance: kMinShare.  The probe reaches where
/// 10⁻⁵ of a cell's vehicles lie beyond (P(z > 4.26)), a tenth of ε: the
/// vehicles that start 3.2–3.6 σ off, beyond the probe at 3.09 σ (10⁻³)
/// before, are the tail that decides such a bin (docs/belief_planning.md,
/// "The tail of a small stratum").
constexpr double kMinShare = 1e-4;
constexpr double kMinFixShare = 1e-6;
constexpr double kProbeTail = 4.264890793922825;
constexpr int kBisections = 12;

/// Whether a view takes a position fix (a fix profile's, or one from ranges).
inline bool takes_fix(const Step& v) { return v.fix || v.ranges; }

/// Where the view changes between `in` (seen as the mean sees) and `out` (seen otherwise),
/// to kBisections halvings: `same(x)` says whether x is seen as the mean sees.
template <typename Same>
double bisect_change(double in, double out, const Same& same) {
  for (int i = 0; i < kBisections; ++i) {
    const double mid = 0.5 * (in + out);
    (same(mid) ? in : out) = mid;
  }
  return 0.5 * (in + out);
}

/// BeliefSettings::deviation_split: where stratum `s`'s cell holds vehicles
/// that see otherwise than its mean (probed at the cell's ends along each
/// axis, an unbounded end at ±kProbeTail), the cell is cut where the view
/// changes (bisection between the mean and that end; of several such ends,
/// the one whose change lies nearest the mean), and the part beyond becomes
/// a stratum of its own, with its exact share of N(0, I), its mean and
/// variance, and the same residual error: P + N − m mᵀ − B V Bᵀ.  At most
/// one cut per stratum and call, none that leaves a part under kMinShare of
/// the vehicles (kMinFixShare where the end takes a fix and the mean does
/// not, or the reverse); with `fix_only`, only ends whose vehicles take a fix
/// where the mean does not, or the reverse, are cut (the step's second pass,
/// split_at_view_changes).  `view(s, z)` is what a vehicle at z of s sees.
/// False where no cut is made; else `parts` holds the near and the far part.
template <int K, typename View>
bool cut_at_view_change(const Stratum<K>& s, const View& view, std::array<Stratum<K>, 2>& parts,
                        bool fix_only = false) {
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
      const Step seen_end = view(s, z);
      if (same_view(seen_end, s.seen) || (fix_only && takes_fix(seen_end) == takes_fix(s.seen))) continue;
      const double least = takes_fix(seen_end) != takes_fix(s.seen) ? kMinFixShare : kMinShare;
      const double c = bisect_change(s.mean[b], end, [&](double x) {
        z[b] = x;
        return same_view(view(s, z), s.seen);
      });
      if (!(std::abs(c - s.mean[b]) < nearest)) continue;
      const Interval n = sd < 0.0 ? interval(c, s.hi[b]) : interval(s.lo[b], c);
      const Interval f = sd < 0.0 ? interval(s.lo[b], c) : interval(c, s.hi[b]);
      if (std::min(n.mass, f.mass) * s.w / interval(s.lo[b], s.hi[b]).mass < least) continue;
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

/// BeliefSettings::deviation_split, where no cut of the cell applies and stratum s's mean
/// sees no fix: the vehicles whose heading shows them one at this step.  The camera looks
/// from the truth after the step's motion, and against the estimate's prediction (on the
/// path) the truth's heading is off by the prior error −(F e + w)_θ: the error's heading and
/// the step's process noise w ~ N(0, Q), `fresh` = Q_θθ, which no cell holds and which each
/// step draws anew.  So the view is probed along the viewed heading h = e_θ + w,
/// h ~ N(m_θ, S_θθ + Q_θθ) (S = P + N − m mᵀ, the stratum's spread), a vehicle at h having
/// the error E[e | h] = m + a (h − m_θ) / σ_h, a = S_·θ / σ_h: at ±kProbeTail σ_h, and of the
/// sides that show a fix, the one whose change (bisected) lies nearest the mean is cut there.
/// Each part is the stratum given h on its side, as a cut of the cell is given z: its exact
/// share, mean m + a μ and spread S − a aᵀ (1 − v) (μ, v the truncated normal's); the far part
/// sees the fix; neither is under kMinFixShare of the vehicles.  Both keep the cell, B (held
/// within their spread) and the filter covariance.
/// A stratum that sees a fix at its mean is left whole: a vehicle that misses one fix of a run
/// loses a step's dead reckoning, a blind one that takes its first loses its whole error.
template <int K, typename ViewE>
bool cut_at_heading(const Stratum<K>& s, const ViewE& view_e, double fresh, std::array<Stratum<K>, 2>& parts) {
  if (takes_fix(s.seen)) return false;
  StateCov S = s.P + s.N - s.m * s.m.transpose();
  S = 0.5 * (S + S.transpose());
  const double var = S(kTheta, kTheta) + fresh;
  if (!(var > 0.0)) return false;
  const double sh = std::sqrt(var);
  const Eigen::Vector4d a = S.col(kTheta) / sh;  // Cov(e, h) / σ_h
  const auto at = [&](double t) {               // what a vehicle t σ_h off in viewed heading sees
    Eigen::Vector4d e = s.m + a * t;
    e[kTheta] = s.m[kTheta] + t * sh;  // the viewed heading holds the step's noise as well
    return view_e(e);
  };
  double nearest = std::numeric_limits<double>::infinity();
  Interval near, far;
  Step seen;
  for (const double sg : {-1.0, 1.0}) {
    Step end = at(sg * kProbeTail);
    if (same_view(end, s.seen) || !takes_fix(end)) continue;
    const double c = bisect_change(0.0, kProbeTail, [&](double t) { return same_view(at(sg * t), s.seen); });
    if (!(c < nearest)) continue;
    const double inf = std::numeric_limits<double>::infinity();
    const Interval n = sg > 0.0 ? interval(-inf, c) : interval(-c, inf);
    const Interval f = sg > 0.0 ? interval(c, inf) : interval(-inf, -c);
    if (std::min(n.mass, f.mass) * s.w < kMinFixShare) continue;
    nearest = c, near = n, far = f, seen = std::move(end);
  }
  if (!std::isfinite(nearest)) return false;
  std::size_t q = 0;
  for (const Interval* c : {&near, &far}) {
    Stratum<K>& t = parts[q++] = s;
    t.w = s.w * c->mass;
    t.m = s.m + a * c->mean;
    StateCov Sq = S - a * a.transpose() * (1.0 - c->var);
    Sq = 0.5 * (Sq + Sq.transpose());
    t.B = s.B / excess(s.B * s.var.asDiagonal() * s.B.transpose(), Sq);
    t.N = Sq + t.m * t.m.transpose() - t.P;
    t.N = 0.5 * (t.N + t.N.transpose());
  }
  parts[1].seen = std::move(seen);
  return true;
}

}  // namespace safenav::belief
