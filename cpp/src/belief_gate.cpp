// The filter's χ² gate in the expected belief (belief_gate.hpp).
#include "belief_gate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "safenav/localizer.hpp"

namespace safenav::belief {

Gate::Gate(double probability) : gamma(probability > 0.0 ? chi2_quantile(probability, 2) : 0.0) {
  const LocalizerSettings loop;
  for (int n : {loop.reset_after_consistent, loop.reset_after_rejections > 0 ? loop.reset_after_rejections + 1 : 0})
    if (n > 0) reset_after = reset_after > 0 ? std::min(reset_after, n) : n;
  reset_after = std::min(reset_after, kMaxCount + 1);  // the loop's: 3
}

namespace {

/// Antiderivatives in r of r e^{−r²/2} times 1, r and r² (the radial
/// density of N(0, I₂) in polar coordinates, times 2π), with their limits at
/// r = ∞; at r = 0 they are −1, 0 and −2.
struct Radial {
  double f0, f1, f2;
  explicit Radial(double r) {
    if (!std::isfinite(r)) {
      f0 = 0.0, f1 = std::sqrt(kPi / 2.0), f2 = 0.0;
      return;
    }
    const double g = std::exp(-0.5 * r * r);
    f0 = -g;
    f1 = -r * g + std::sqrt(kPi / 2.0) * std::erf(r / std::sqrt(2.0));
    f2 = -(r * r + 2.0) * g;
  }
};

}  // namespace

GateParts gate_parts(const Eigen::Vector2d& c, const Eigen::Matrix2d& C, const Eigen::Matrix2d& S, double gamma,
                     int angles) {
  // In the gate's whitened coordinates (L Lᵀ = S) the test is |b + A w|² ≤ γ.
  const Eigen::LLT<Eigen::Matrix2d> llt(S);
  const Eigen::Vector2d b = llt.matrixL().solve(c);
  const Eigen::Matrix2d A = llt.matrixL().solve(C);
  const double inf = std::numeric_limits<double>::infinity();
  const Radial zero(0.0), end(inf);
  constexpr int P = 1 + kGateSectors;
  std::array<double, P> mass{};
  std::array<Eigen::Vector2d, P> first;
  std::array<Eigen::Matrix2d, P> second;
  first.fill(Eigen::Vector2d::Zero());
  second.fill(Eigen::Matrix2d::Zero());
  const auto add = [&](int part, const Eigen::Vector2d& d, const Radial& from, const Radial& to) {
    mass[part] += to.f0 - from.f0;
    first[part] += (to.f1 - from.f1) * d;
    second[part] += (to.f2 - from.f2) * (d * d.transpose());
  };
  for (int j = 0; j < angles; ++j) {
    const double phi = 2.0 * kPi * (j + 0.5) / angles;
    const Eigen::Vector2d d(std::cos(phi), std::sin(phi));
    const Eigen::Vector2d a = A * d;
    // |b + r a|² − γ = qa r² + 2 qb r + qc: inside between its roots.
    const double qa = a.squaredNorm(), qb = b.dot(a), qc = b.squaredNorm() - gamma;
    const double disc = qb * qb - qa * qc;
    double r1 = 0.0, r2 = 0.0;  // the passing stretch (empty when equal)
    if (!(qa > 0.0)) {
      r2 = qc <= 0.0 ? inf : 0.0;
    } else if (disc > 0.0) {
      const double root = std::sqrt(disc);
      r1 = std::max(0.0, (-qb - root) / qa);
      r2 = std::max(0.0, (-qb + root) / qa);
    }
    const Radial in1(r1), in2(r2);
    const int sector = 1 + j * kGateSectors / angles;
    add(0, d, in1, in2);
    add(sector, d, zero, in1);
    add(sector, d, in2, end);
  }
  GateParts out;
  for (int p = 0; p < P; ++p) {
    out.mass[p] = mass[p] / angles;
    if (!(out.mass[p] > 0.0)) continue;
    out.mean[p] = first[p] / (angles * out.mass[p]);
    out.second[p] = second[p] / (angles * out.mass[p]);
  }
  return out;
}

namespace {

/// The branch without the fix: the step's other updates only (P_none, T_none).
GateBranch without_fix(const StepOutcome& o, const Eigen::Vector4d& mu, const StateCov& Nm) {
  GateBranch b;
  b.P = o.P_none;
  b.T = o.T_none;
  b.m = o.T_none * mu;
  b.M = o.P_none + o.T_none * Nm * o.T_none.transpose();
  return b;
}

/// The localizer's reset of `b` from the step's fix (Localizer, InputStatus::Reset):
/// P_xy ← R, the position's cross-covariances 0, the position error the fix's.
void restart_from_fix(GateBranch& b, const Eigen::Matrix2d& R) {
  b.turned_away = false;
  b.counts.fill(0.0);
  b.P.topLeftCorner<2, 2>() = R;
  b.P.topRightCorner<2, 2>().setZero();
  b.P.bottomLeftCorner<2, 2>().setZero();
  b.M.topLeftCorner<2, 2>() = R;
  b.M.topRightCorner<2, 2>().setZero();
  b.M.bottomLeftCorner<2, 2>().setZero();
  b.m.head<2>().setZero();
  b.T.topRows<2>().setZero();
}

}  // namespace

std::array<GateBranch, 2 + kGateSectors> gate_branches(const StepOutcome& o, const Eigen::Vector4d& mu,
                                                       const StateCov& Nm, int reset_after, double gamma) {
  std::array<GateBranch, 2 + kGateSectors> br;
  // [0] No fix: the step's other updates only.
  br[0] = without_fix(o, mu, Nm);
  br[0].share = 1.0 - o.p_fix;
  // The innovation ν = v − H e = c + C w, w ~ N(0, I₂); the error given it,
  // e = μ + U w + η, U = −Σ Hᵀ C⁻ᵀ, η ~ N(0, Σ − U Uᵀ) independent of w.
  StateCov Sigma = o.Pm + Nm - mu * mu.transpose();
  Sigma = 0.5 * (Sigma + Sigma.transpose());
  const Eigen::Vector2d c = -mu.head<2>();
  const Eigen::Matrix2d G = Sigma.topLeftCorner<2, 2>() + o.R;
  const Eigen::Matrix2d C = Eigen::LLT<Eigen::Matrix2d>(G).matrixL();
  const Eigen::Matrix<double, 4, 2> U =
      -C.triangularView<Eigen::Lower>().solve(Sigma.topRows<2>()).transpose();
  const StateCov eta = Sigma - U * U.transpose();
  const Eigen::Matrix2d S = o.Pm.topLeftCorner<2, 2>() + o.R;
  const GateParts parts = gate_parts(c, C, S, gamma);
  // E[a + β w][a + β w]ᵀ over a part, plus `rest`.
  const auto moments = [&](int p, const Eigen::Vector4d& a, const Eigen::Matrix<double, 4, 2>& beta,
                           const StateCov& rest, Eigen::Vector4d& mean, StateCov& M) {
    const Eigen::Vector4d shift = beta * parts.mean[static_cast<std::size_t>(p)];
    mean = a + shift;
    M = a * a.transpose() + a * shift.transpose() + shift * a.transpose() +
        beta * parts.second[static_cast<std::size_t>(p)] * beta.transpose() + rest;
    M = 0.5 * (M + M.transpose());
  };
  // [1] Through the gate: e⁺ = T e + K_f v + (the other updates' noise)
  //     = D e + K_f ν + …, D = T + K_f H, K_f = P_fix Hᵀ R⁻¹ (the fix's gain in
  //     the step's joint update), the other noise's covariance
  //     P_fix − T P⁻ Tᵀ − K_f R K_fᵀ (the Joseph form's parts).
  GateBranch& pass = br[1];
  pass.share = o.p_fix * parts.mass[0];
  pass.P = o.P_fix;
  pass.T = o.T_fix;
  const Eigen::Matrix<double, 4, 2> Kf = o.P_fix.leftCols<2>() * o.R.inverse();
  Eigen::Matrix4d D = o.T_fix;
  D.leftCols<2>() += Kf;
  const StateCov other = o.P_fix - o.T_fix * o.Pm * o.T_fix.transpose() - Kf * o.R * Kf.transpose();
  moments(0, D * mu + Kf * c, D * U + Kf * C, D * eta * D.transpose() + other, pass.m, pass.M);
  // [2 …] Turned away: e keeps its prediction, then the other updates.
  for (int sector = 1; sector <= kGateSectors; ++sector) {
    GateBranch& away = br[static_cast<std::size_t>(1 + sector)];
    away.share = o.p_fix * parts.mass[static_cast<std::size_t>(sector)];
    away.P = o.P_none;
    away.T = o.T_none;
    away.turned_away = true;
    away.counts[0] = 1.0;
    Eigen::Vector4d e_mean;
    StateCov e_M;
    moments(sector, mu, U, eta, e_mean, e_M);
    away.m = o.T_none * e_mean;
    away.M = o.T_none * e_M * o.T_none.transpose() + o.P_none - o.T_none * o.Pm * o.T_none.transpose();
    away.M = 0.5 * (away.M + away.M.transpose());
    if (reset_after == 1) restart_from_fix(away, o.R);
  }
  return br;
}

std::array<GateBranch, 2> turned_away_branches(const StepOutcome& o, const Eigen::Vector4d& mu, const StateCov& Nm,
                                               const Counts& counts, int reset_after) {
  std::array<GateBranch, 2> br;
  br.fill(without_fix(o, mu, Nm));
  GateBranch &keep = br[0], &reset = br[1];
  keep.turned_away = true;
  // A fix moves count c to c + 1; from reset_after − 1 it restarts the position.
  const int last = std::clamp(reset_after - 1, 0, kMaxCount);
  const double p = o.p_fix;
  reset.share = last > 0 ? p * counts[static_cast<std::size_t>(last - 1)] : 0.0;
  keep.share = 1.0 - reset.share;
  for (int c = last; c >= 1; --c) {
    const auto i = static_cast<std::size_t>(c - 1);
    keep.counts[i] = (1.0 - p) * counts[i] + (c > 1 ? p * counts[i - 1] : 0.0);
  }
  if (last == 0) keep.counts = counts;  // never reset: the count does not matter
  if (keep.share > 0.0)
    for (double& x : keep.counts) x /= keep.share;
  restart_from_fix(reset, o.R);
  return br;
}

}  // namespace safenav::belief
