#include "safenav/trilateration.hpp"
#include "safenav/filters.hpp"
#include "safenav/measurement.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "rng.hpp"
#include "trilateration_models.hpp"

namespace safenav {

const char* to_string(LocalizationStatus status) {
  switch (status) {
    case LocalizationStatus::Ok: return "ok";
    case LocalizationStatus::TooFew: return "too_few";
    case LocalizationStatus::Degenerate: return "degenerate";
    case LocalizationStatus::DidNotConverge: return "did_not_converge";
  }
  return "unknown";
}

namespace {

using namespace trilateration_detail;

void check_inputs(const Eigen::Ref<const Anchors>& anchors, const Eigen::Ref<const Eigen::VectorXd>& z,
                  const Eigen::Ref<const Eigen::VectorXd>& sigmas, const char* zname, bool nonnegative) {
  std::ostringstream os;
  const auto n = anchors.rows();
  if (z.size() != n) {
    os << zname << " has " << z.size() << " entries but anchors has " << n << " rows";
    throw std::invalid_argument(os.str());
  }
  if (sigmas.size() != n) {
    os << "sigmas has " << sigmas.size() << " entries but anchors has " << n << " rows";
    throw std::invalid_argument(os.str());
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!anchors.row(i).allFinite()) {
      os << "anchor " << i << " has non-finite position (" << anchors(i, 0) << ", " << anchors(i, 1) << ")";
      throw std::invalid_argument(os.str());
    }
    if (!std::isfinite(z[i]) || (nonnegative && z[i] < 0.0)) {
      os << zname << "[" << i << "] = " << z[i] << " must be finite" << (nonnegative ? " and >= 0" : "");
      throw std::invalid_argument(os.str());
    }
    // σ², 1/σ² and the normal equations' weights must be finite and normal.
    const double s2 = sigmas[i] * sigmas[i];
    if (!(std::isfinite(sigmas[i]) && sigmas[i] > 0.0 && std::isfinite(s2) && s2 >= DBL_MIN &&
          std::isfinite(1.0 / s2))) {
      os << "sigmas[" << i << "] = " << sigmas[i] << " must be finite and > 0 with a finite, normal square "
         << "(about 1e-154 to 1e154)";
      throw std::invalid_argument(os.str());
    }
  }
}

/// Levenberg–Marquardt (Marquardt's diagonal scaling) from p0; pure
/// Gauss–Newton steps once λ has decayed.
template <class Model>
Fit levenberg_marquardt(const Model& m, const Problem& pr, const std::vector<int>& idx, Eigen::Vector2d p,
                        const LocalizationOptions& opt) {
  Fit f;
  double lambda = 1e-3;
  double cost = cost_at(m, pr, idx, p);
  Eigen::Matrix2d A;
  Eigen::Vector2d g;
  for (int it = 0; it < opt.max_iterations; ++it) {
    f.iterations = it + 1;
    normal_equations(m, pr, idx, p, A, g);
    bool stepped = false;
    while (lambda < 1e16) {
      Eigen::Matrix2d Ad = A;
      Ad.diagonal() *= (1.0 + lambda);
      const Eigen::Vector2d delta = Ad.fullPivLu().solve(g);
      if (!delta.allFinite()) break;
      const Eigen::Vector2d pn = p + delta;
      const double cn = cost_at(m, pr, idx, pn);
      const bool small = delta.norm() <= opt.tolerance * (1.0 + p.norm());
      if (cn <= cost) {
        p = pn;
        const double decrease = cost - cn;
        cost = cn;
        lambda = std::max(lambda * 0.1, 1e-15);
        stepped = true;
        if (small || decrease <= 1e-15 * cost) {
          f.converged = true;
        }
        break;
      }
      if (small) {  // no descent left at machine precision: a minimum
        f.converged = true;
        break;
      }
      lambda *= 10.0;
    }
    if (f.converged) break;
    if (!stepped) {
      // Damping exhausted: converged only if the gradient vanishes.
      f.converged = g.norm() <= 1e-9 * std::max(1.0, A.norm() * (1.0 + p.norm()));
      break;
    }
  }
  f.p = p;
  f.cost = cost;
  return f;
}

/// Centroid and unit normal of the anchors' best-fit line; ratio = spread
/// across / spread along (0 for collinear anchors).
void principal_line(const Problem& pr, const std::vector<int>& idx, Eigen::Vector2d& c, Eigen::Vector2d& normal,
                    double& ratio) {
  c.setZero();
  for (int i : idx) c += pr.a(i);
  c /= static_cast<double>(idx.size());
  Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
  for (int i : idx) S.noalias() += (pr.a(i) - c) * (pr.a(i) - c).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(S);
  normal = es.eigenvectors().col(0);
  const double lmax = es.eigenvalues()[1];
  ratio = lmax > 0.0 ? std::sqrt(std::max(0.0, es.eigenvalues()[0]) / lmax) : 0.0;
}

std::string point_str(const Eigen::Vector2d& p) {
  std::ostringstream os;
  os << "(" << p.x() << ", " << p.y() << ")";
  return os.str();
}

/// The cost minimised over the line y + t·b (b a unit vector): Gauss–Newton
/// in t with step halving from the best of 17 points, t = 0 and ±span·{1/64,
/// 1/32, …, 1/2, 3/4, 1}.  The cost along the line can have two minima (the
/// two arms of a curved valley) at any scale: a descent from t = 0 alone
/// stops in the shallower one, or at t = 0 itself where the two are
/// symmetric about it (a fold: anchors in line with the position).
template <class Model>
double profile_cost(const Model& m, const Problem& pr, const std::vector<int>& idx, Eigen::Vector2d y,
                    const Eigen::Vector2d& b, double span) {
  static constexpr double kOffsets[] = {1.0 / 64, 1.0 / 32, 1.0 / 16, 1.0 / 8, 0.25, 0.5, 0.75, 1.0};
  double c = cost_at(m, pr, idx, y);
  double best_t = 0.0;
  for (double f : kOffsets)
    for (double t : {-f * span, f * span}) {
      const double ct = cost_at(m, pr, idx, Eigen::Vector2d(y + t * b));
      if (ct < c) {
        c = ct;
        best_t = t;
      }
    }
  y += best_t * b;
  for (int it = 0; it < 50; ++it) {
    double a = 0.0, g = 0.0;
    for (int i : idx) {
      const double w = 1.0 / (pr.sigma[i] * pr.sigma[i]);
      const double jb = m.jacobian(y, pr.a(i)).dot(b);
      a += w * jb * jb;
      g += w * m.residual(y, pr.a(i), pr.z[i]) * jb;
    }
    double t = g / a;
    if (!std::isfinite(t)) break;
    double decrease = -1.0;
    for (int h = 0; h < 40 && decrease < 0.0; ++h, t *= 0.5) {
      const double cn = cost_at(m, pr, idx, Eigen::Vector2d(y + t * b));
      if (cn < c) {
        y += t * b;
        decrease = c - cn;
        c = cn;
      }
    }
    if (!(decrease > 1e-6 * (1.0 + c))) break;  // the rise is wanted to ~1e-3 of k²
  }
  return c;
}

/// The fix's covariance widened to its profile likelihood (ours; the
/// likelihood-based confidence region of Bates & Watts, "Nonlinear Regression
/// Analysis and Its Applications", 1988, ch. 6, in place of the linear one):
/// along each principal axis v_j of (Jᵀ W J)⁻¹, σ_j² its eigenvalue, the cost
/// minimised over the other axis (within twice that axis's contour) must rise
/// by k² (χ²₂ at LocalizationOptions::profile_probability) at p ± k σ_j v_j, as the
/// quadratic model says.  Where it rises by less than k²/1.1 — a curved or
/// flat valley: anchors nearly in line with the position, an anchor close to
/// it — σ_j² is scaled by k²/(1.1 · rise), and again from the new points, at
/// most 4 rounds, so that the Gaussian's contour at that probability reaches
/// out as far as the cost's does.  It never narrows, and a rise within 10 % of
/// the quadratic model's leaves the covariance as it is.
template <class Model>
void widen_to_profile(const Model& m, const Problem& pr, const std::vector<int>& idx, const Eigen::Vector2d& p,
                      double cost, const LocalizationOptions& opt, Eigen::Matrix2d& cov) {
  if (!(opt.profile_probability > 0.0) || !cov.allFinite()) return;
  const double k2 = chi2_quantile(opt.profile_probability, 2);
  constexpr double kTolerance = 1.1;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
  const Eigen::Matrix2d V = es.eigenvectors();
  Eigen::Vector2d lambda = es.eigenvalues().cwiseMax(0.0);
  bool any = false;
  for (int round = 0; round < 4; ++round) {
    bool widened = false;
    for (int j = 0; j < 2; ++j) {
      const Eigen::Vector2d v = V.col(j), other = V.col(1 - j);
      const double reach = std::sqrt(k2 * lambda[j]), span = 2.0 * std::sqrt(k2 * lambda[1 - j]);
      double rise = std::numeric_limits<double>::infinity();
      for (double sign : {-1.0, 1.0})
        rise = std::min(rise, profile_cost(m, pr, idx, Eigen::Vector2d(p + sign * reach * v), other, span) - cost);
      const double scale = k2 / (kTolerance * std::max(rise, 1e-12 * k2));
      if (scale > 1.01) {
        lambda[j] *= std::min(scale, 1e6);
        widened = true;
      }
    }
    if (!widened) break;
    any = true;
  }
  if (!any) return;  // (Jᵀ W J)⁻¹ as it was, bit for bit
  cov = V * lambda.asDiagonal() * V.transpose();
  cov = 0.5 * (cov + cov.transpose());
}

/// GDOP and covariance at p over idx.
template <class Model>
void geometry_at(const Model& m, const Problem& pr, const std::vector<int>& idx, const Eigen::Vector2d& p,
                 double& gdop, Eigen::Matrix2d& cov, bool bearings) {
  Eigen::Matrix2d G = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
  double mean_range = 0.0;
  for (int i : idx) {
    const Eigen::RowVector2d J = m.jacobian(p, pr.a(i));
    G.noalias() += J.transpose() * J;
    A.noalias() += (1.0 / (pr.sigma[i] * pr.sigma[i])) * J.transpose() * J;
    mean_range += landmark_geometry(p.x(), p.y(), pr.a(i).x(), pr.a(i).y()).r;
  }
  mean_range /= static_cast<double>(idx.size());
  Eigen::FullPivLU<Eigen::Matrix2d> luG(G), luA(A);
  const double inf = std::numeric_limits<double>::infinity();
  gdop = luG.isInvertible() ? std::sqrt(std::max(0.0, luG.inverse().trace())) : inf;
  if (bearings && std::isfinite(gdop)) gdop /= std::max(mean_range, 1e-300);
  if (luA.isInvertible()) {
    cov = luA.inverse();
    cov = 0.5 * (cov + cov.transpose());
  } else {
    cov.setConstant(inf);
  }
}

/// Why idx cannot give a fix before any is fitted (too few measurements,
/// parallel bearing lines, collinear anchors), or Ok.
template <class Model>
LocalizationStatus check_subset(const Problem& pr, const std::vector<int>& idx, const LocalizationOptions& opt,
                                double ratio, std::string& reason) {
  constexpr bool kBearings = std::is_same<Model, BearingModel>::value;
  const int k = static_cast<int>(idx.size());
  std::ostringstream os;
  if (k < Model::kMinimal) {
    os << Model::kMinimal << " " << Model::kWhat << " are needed, got " << k;
    reason = os.str();
    return LocalizationStatus::TooFew;
  }
  if (kBearings) {
    double best_sin = 0.0;
    for (int a = 0; a < k; ++a)
      for (int b = a + 1; b < k; ++b)
        best_sin = std::max(best_sin, std::abs(std::sin(pr.z[idx[a]] - pr.z[idx[b]])));
    if (best_sin < std::sin(opt.min_crossing_angle)) {
      os << "bearing lines are (nearly) parallel: widest crossing angle " << std::asin(std::min(1.0, best_sin))
         << " rad < min_crossing_angle " << opt.min_crossing_angle;
      reason = os.str();
      return LocalizationStatus::Degenerate;
    }
  } else if (ratio < 1e-9) {
    reason = "anchors are collinear: the ranges fit two mirror-image positions";
    return LocalizationStatus::Degenerate;
  }
  return LocalizationStatus::Ok;
}

/// Whether every bearing of idx points toward p (the lines' intersection
/// must lie behind every anchor's bearing); else why not, at `where`.
template <class Model>
bool bearings_face(const Model& m, const Problem& pr, const std::vector<int>& idx, const Eigen::Vector2d& p,
                   const char* where, std::string& reason) {
  for (int i : idx) {
    if (std::abs(m.residual(p, pr.a(i), pr.z[i])) > kPi / 2) {
      std::ostringstream os;
      os << "bearing " << i << " points away from anchor " << i << " at " << where << " " << point_str(p);
      reason = os.str();
      return false;
    }
  }
  return true;
}

/// Ranges: refit from f's mirror image across the anchors' principal line
/// (c, normal).  A second minimum that fits better replaces f; one that
/// fits about as well (within ambiguity_margin) makes the fix ambiguous,
/// and `reason` says so (returns false).
template <class Model>
bool resolve_mirror(const Model& m, const Problem& pr, const std::vector<int>& idx, const LocalizationOptions& opt,
                    const Eigen::Vector2d& c, const Eigen::Vector2d& normal, Fit& f, LocalizationResult& res) {
  const Eigen::Vector2d pm = f.p - 2.0 * (f.p - c).dot(normal) * normal;
  const double scale = 1.0 + f.p.norm();
  if ((pm - f.p).norm() <= 1e-9 * scale) return true;
  const Fit g = levenberg_marquardt(m, pr, idx, pm, opt);
  const double sep = (g.p - f.p).norm();
  const double sd = std::sqrt(std::max(0.0, res.covariance.trace()));
  if (!(g.converged && g.p.allFinite() && sep > std::max(3.0 * sd, 1e-6 * scale))) return true;
  res.ambiguity_gap = std::abs(g.cost - f.cost);
  if (g.cost < f.cost - opt.ambiguity_margin) {
    f = g;  // the linear start fell into the worse minimum
    geometry_at(m, pr, idx, f.p, res.gdop, res.covariance, false);
    return true;
  }
  if (std::abs(g.cost - f.cost) > opt.ambiguity_margin) return true;
  std::ostringstream os;
  os << "ambiguous geometry: " << point_str(f.p) << " (chi2 " << f.cost << ") and " << point_str(g.p) << " (chi2 "
     << g.cost << ") fit the ranges within ambiguity_margin " << opt.ambiguity_margin;
  res.reason = os.str();
  return false;
}

/// Solve on the measurement subset idx with every degeneracy check.
template <class Model>
LocalizationResult solve_subset(const Model& m, const Problem& pr, const std::vector<int>& idx,
                                const LocalizationOptions& opt) {
  LocalizationResult res;
  constexpr bool kBearings = std::is_same<Model, BearingModel>::value;
  const auto fail = [&res](LocalizationStatus status, bool nan_covariance = false) {
    res.status = status;
    if (nan_covariance) res.covariance.setConstant(kNaN);
    return res;
  };
  Eigen::Vector2d c, normal;
  double ratio = 0.0;
  if (static_cast<int>(idx.size()) >= Model::kMinimal) principal_line(pr, idx, c, normal, ratio);
  res.status = check_subset<Model>(pr, idx, opt, ratio, res.reason);
  if (res.status != LocalizationStatus::Ok) return res;
  Eigen::Vector2d p0;
  if (!linear_start(m, pr, idx, p0)) {
    res.reason = "the linear system for the starting point is rank deficient";
    return fail(LocalizationStatus::Degenerate);
  }
  if (kBearings && !bearings_face(m, pr, idx, p0, "the lines' intersection", res.reason))
    return fail(LocalizationStatus::Degenerate);
  Fit f = levenberg_marquardt(m, pr, idx, p0, opt);
  if (!f.converged || !f.p.allFinite()) {
    res.position = f.p;
    res.iterations = f.iterations;
    std::ostringstream os;
    os << "Levenberg-Marquardt did not converge in " << f.iterations << " iterations (max_iterations = "
       << opt.max_iterations << ")";
    res.reason = os.str();
    return fail(LocalizationStatus::DidNotConverge);
  }
  geometry_at(m, pr, idx, f.p, res.gdop, res.covariance, kBearings);
  if (!kBearings && !resolve_mirror(m, pr, idx, opt, c, normal, f, res)) {
    res.position = f.p;
    res.iterations = f.iterations;
    return fail(LocalizationStatus::Degenerate, true);
  }
  if (kBearings && !bearings_face(m, pr, idx, f.p, "the solution", res.reason))
    return fail(LocalizationStatus::Degenerate, true);
  widen_to_profile(m, pr, idx, f.p, f.cost, opt, res.covariance);
  res.position = f.p;
  res.iterations = f.iterations;
  res.chi2 = f.cost;
  if (!(res.gdop <= opt.max_gdop)) {
    std::ostringstream os;
    os << "GDOP " << res.gdop << " exceeds max_gdop " << opt.max_gdop << " (anchors nearly in line with the position)";
    res.reason = os.str();
    return fail(LocalizationStatus::Degenerate);
  }
  if (!res.covariance.allFinite()) {
    res.reason = "the position covariance is not finite (the weights 1/sigma^2 against the geometry overflow)";
    return fail(LocalizationStatus::Degenerate, true);
  }
  res.status = LocalizationStatus::Ok;
  return res;
}

template <class Model>
std::vector<int> inliers_at(const Model& m, const Problem& pr, const Eigen::Vector2d& p, double thr) {
  std::vector<int> in;
  for (int i = 0; i < pr.z.size(); ++i)
    if (std::abs(m.residual(p, pr.a(i), pr.z[i])) <= thr * pr.sigma[i]) in.push_back(i);
  return in;
}

/// Next k-combination of {0..n-1} in lexicographic order.
bool next_combination(std::vector<int>& c, int n) {
  const int k = static_cast<int>(c.size());
  for (int i = k - 1; i >= 0; --i) {
    if (c[i] < n - k + i) {
      ++c[i];
      for (int j = i + 1; j < k; ++j) c[j] = c[j - 1] + 1;
      return true;
    }
  }
  return false;
}

double n_choose_k(int n, int k) {
  double r = 1.0;
  for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
  return r;
}

/// Consensus over minimal sets (all of them, or max_subsets drawn at random):
/// the largest inlier set (cheapest on ties) into best_in, and every distinct
/// consensus set met, with the minimal-set fit that found it, into consensus.
template <class Model>
void consensus_search(const Model& m, const Problem& pr, const LocalizationOptions& opt, std::vector<int>& best_in,
                      std::vector<std::pair<std::vector<int>, Eigen::Vector2d>>& consensus) {
  const int n = static_cast<int>(pr.z.size());
  const int k = Model::kMinimal;
  double best_cost = std::numeric_limits<double>::infinity();
  auto consider = [&](const std::vector<int>& subset) {
    Eigen::Vector2d p0;
    if (!linear_start(m, pr, subset, p0)) return;
    const Fit f = levenberg_marquardt(m, pr, subset, p0, opt);
    if (!f.converged || !f.p.allFinite()) return;
    std::vector<int> in = inliers_at(m, pr, f.p, opt.outlier_threshold);
    if (static_cast<int>(in.size()) < k) return;
    const double c = cost_at(m, pr, in, f.p);
    bool known = false;
    for (const auto& s : consensus) known = known || s.first == in;
    if (!known) consensus.emplace_back(in, f.p);
    if (in.size() > best_in.size() || (in.size() == best_in.size() && c < best_cost)) {
      best_in = std::move(in);
      best_cost = c;
    }
  };
  std::vector<int> subset(k);
  if (n_choose_k(n, k) <= opt.max_subsets) {
    std::iota(subset.begin(), subset.end(), 0);
    do consider(subset);
    while (next_combination(subset, n));
  } else {
    detail::Rng rng(opt.seed);
    for (int s = 0; s < opt.max_subsets; ++s) {
      // k distinct indices (Floyd's algorithm), sorted.
      subset.clear();
      for (int j = n - k; j < n; ++j) {
        const int t = static_cast<int>(rng.uniform() * (j + 1));
        if (std::find(subset.begin(), subset.end(), t) == subset.end())
          subset.push_back(t);
        else
          subset.push_back(j);
      }
      std::sort(subset.begin(), subset.end());
      consider(subset);
    }
  }
}

/// Another consensus set as large as `in` that fits a position far from r's
/// about as well: which measurements are the outliers cannot be told.  Fills
/// amb (Degenerate, with the reason) and returns true then.
template <class Model>
bool ambiguous_outliers(const Model& m, const Problem& pr, const LocalizationOptions& opt, const LocalizationResult& r,
                        const std::vector<int>& in,
                        const std::vector<std::pair<std::vector<int>, Eigen::Vector2d>>& consensus,
                        LocalizationResult& amb) {
  const int n = static_cast<int>(pr.z.size());
  const double sd = std::sqrt(std::max(0.0, r.covariance.trace()));
  const double scale = 1.0 + r.position.norm();
  for (const auto& s : consensus) {
    if (s.first.size() != in.size() || s.first == in) continue;
    const Fit g = levenberg_marquardt(m, pr, s.first, s.second, opt);
    if (!g.converged || !g.p.allFinite()) continue;
    if (inliers_at(m, pr, g.p, opt.outlier_threshold).size() < in.size()) continue;
    const double sep = (g.p - r.position).norm();
    if (sep > std::max(3.0 * sd, 1e-6 * scale) && std::abs(g.cost - r.chi2) <= opt.ambiguity_margin) {
      auto list = [n](const std::vector<int>& keep) {
        std::ostringstream o;
        const char* sep_ = "";
        for (int i = 0; i < n; ++i)
          if (std::find(keep.begin(), keep.end(), i) == keep.end()) {
            o << sep_ << i;
            sep_ = ", ";
          }
        return o.str();
      };
      std::ostringstream os;
      os << "ambiguous outliers: rejecting " << Model::kWhat << " {" << list(in) << "} gives " << point_str(r.position)
         << " (chi2 " << r.chi2 << "), rejecting {" << list(s.first) << "} gives " << point_str(g.p) << " (chi2 "
         << g.cost << "), within ambiguity_margin " << opt.ambiguity_margin;
      amb.status = LocalizationStatus::Degenerate;
      amb.reason = os.str();
      amb.iterations = r.iterations;
      return true;
    }
  }
  return false;
}

template <class Model>
LocalizationResult localize(const Model& m, const Problem& pr, const LocalizationOptions& opt) {
  const int n = static_cast<int>(pr.z.size());
  std::vector<int> all(n);
  std::iota(all.begin(), all.end(), 0);
  auto finish = [&](LocalizationResult r, const std::vector<int>& in) {
    r.inliers = Eigen::Array<bool, Eigen::Dynamic, 1>::Constant(n, false);
    for (int i : in) r.inliers[i] = true;
    return r;
  };
  LocalizationResult full = solve_subset(m, pr, all, opt);
  if (!opt.reject_outliers || n <= Model::kMinimal) return finish(full, all);
  if (full.ok() && static_cast<int>(inliers_at(m, pr, full.position, opt.outlier_threshold).size()) == n)
    return finish(full, all);

  // Consensus over minimal sets (all of them, or max_subsets drawn at random).
  const int k = Model::kMinimal;
  std::vector<int> best_in;
  std::vector<std::pair<std::vector<int>, Eigen::Vector2d>> consensus;
  consensus_search(m, pr, opt, best_in, consensus);
  if (static_cast<int>(best_in.size()) < k) {
    // No minimal set agrees with enough others: report the full fit's problem.
    if (!full.ok()) return finish(full, all);
    LocalizationResult r;
    r.status = LocalizationStatus::TooFew;
    r.reason = std::string("no ") + std::to_string(k) + " " + Model::kWhat + " agree within outlier_threshold";
    return finish(r, {});
  }
  // Refit on the consensus set and re-evaluate it until it is stable.
  std::vector<int> in = best_in;
  LocalizationResult r;
  for (int round = 0; round < 10; ++round) {
    r = solve_subset(m, pr, in, opt);
    if (!r.ok()) break;
    std::vector<int> again = inliers_at(m, pr, r.position, opt.outlier_threshold);
    if (again == in || static_cast<int>(again.size()) < k) break;
    in = std::move(again);
  }
  if (r.ok() && static_cast<int>(in.size()) < n) {
    // Another consensus set as large as this one that fits a position far
    // away about as well: which measurements are the outliers cannot be told
    // (e.g. four ranges, one bad, where two triples each fit a point).
    LocalizationResult amb;
    if (ambiguous_outliers(m, pr, opt, r, in, consensus, amb)) return finish(amb, in);
    std::ostringstream os;
    os << n - static_cast<int>(in.size()) << " of " << n << " " << Model::kWhat << " rejected as outliers";
    r.reason = os.str();
  }
  return finish(r, in);
}

}  // namespace

LocalizationResult trilaterate(const Eigen::Ref<const Anchors>& anchors, const Eigen::Ref<const Eigen::VectorXd>& ranges,
                               const Eigen::Ref<const Eigen::VectorXd>& sigmas, const LocalizationOptions& options) {
  options.validate();
  check_inputs(anchors, ranges, sigmas, "ranges", true);
  const Problem pr{anchors, ranges, sigmas};
  return localize(RangeModel{}, pr, options);
}

LocalizationResult triangulate_bearings(const Eigen::Ref<const Anchors>& anchors,
                                        const Eigen::Ref<const Eigen::VectorXd>& bearings,
                                        const Eigen::Ref<const Eigen::VectorXd>& sigmas,
                                        const LocalizationOptions& options) {
  options.validate();
  check_inputs(anchors, bearings, sigmas, "bearings", false);
  const Problem pr{anchors, bearings, sigmas};
  return localize(BearingModel{}, pr, options);
}

}  // namespace safenav
