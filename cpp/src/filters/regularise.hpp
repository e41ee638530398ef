// Private: the kernel arithmetic shared by ParticleFilter (pf_impl.hpp, the kernel
// update of the adaptive Gaussian mixture filter) and AugmentedParticleFilter
// (augmented_pf.cpp, regularisation after resampling).  The methods and their
// references are documented at those classes; the pieces here:
//
//  bandwidth    h = c · (4 / (N (d + 2)))^{1/(d+4)}       [Musso et al. 2001]
//  conditioned  P_k = h²Σ⁻ − h⁴ C_xy (h² C_yy + R)⁻¹ C_xyᵀ: the kernel h²Σ⁻
//               of the prior cloud updated by statistical linearisation
//               (C_xy, C_yy the weighted state–residual and residual
//               covariances of the particles), as the ensemble Kalman filter
//               and the adaptive Gaussian mixture filter of Stordal et al.
//               2011 update a member / a kernel
//  excess       E = Σ_x|h·tr(A C_hh)/n: what a sampled gain takes beyond
//               the Gaussian update (gain_sampling_excess)
//  factor       L Lᵀ = P₊ for the kernel draws
//  floor        P_reported = P̂ + (h² C_u − P̂)₊ ⪰ P̂ and ⪰ h² C_u, with P̂ the
//               weighted and C_u the unweighted covariance of the particles
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace safenav::detail {

/// h = scale · (4 / (N (d + 2)))^{1/(d+4)}: the bandwidth of a Gaussian kernel
/// that minimises the mean integrated squared error for a Gaussian density
/// [Musso et al. 2001, h_opt = A·N^{−1/(d+4)}, A = (4/(d+2))^{1/(d+4)}],
/// capped at 1 (the shrinkage √(1 − h²) needs h ≤ 1).  scale = 0 gives 0.
inline double kernel_bandwidth(int n_particles, int dim, double scale) {
  if (!(scale > 0.0)) return 0.0;
  const double h = scale * std::pow(4.0 / (static_cast<double>(n_particles) * (dim + 2.0)), 1.0 / (dim + 4.0));
  return std::min(h, 1.0);
}

/// g = 1/(1 − Σw²) = ESS/(ESS − 1), ESS = 1/Σw² (Kish): the weighted
/// covariance Σ̂ = Σ w_i (x_i − m̂)(x_i − m̂)ᵀ about the weighted mean m̂ has
/// expectation (1 − Σw²)·Σ (the reliability-weights bias; the missing
/// Σ·Σw² = Σ/ESS is the covariance of m̂'s Monte Carlo error), so g·Σ̂ is
/// the unbiased estimate, of the posterior covariance and of the covariance
/// of the error truth − m̂ alike.  Resampling turns that Σ/ESS into an error
/// of the mean that no later update sees; put back at each resampling, the
/// cloud stops losing (1 − 1/ESS) of its spread per cycle.  ESS ≤ 1 + 1e-9
/// (one particle holds the weight; Σ̂ ≈ 0) gives 1.
inline double monte_carlo_gain(double ess) { return ess > 1.0 + 1e-9 ? ess / (ess - 1.0) : 1.0; }

/// The kernel h²Σ conditioned on the measurement by statistical linearisation:
/// P_k = h²Σ − h⁴ C_xy (h² C_yy + R)⁻¹ C_xyᵀ, symmetrised.  C_xy is the
/// weighted covariance of the states with the residuals (n × m), C_yy that of
/// the residuals (m × m), R the measurement noise.  PSD by construction (a
/// Schur complement of a PSD joint covariance, R ≻ 0); rounding is clamped
/// later by psd_factor.
template <class MatN, class MatNM, class MatM>
MatN conditioned_kernel(const MatN& Sigma, const MatNM& Cxy, const MatM& Cyy, const MatM& R, double h) {
  const double h2 = h * h;
  const MatM S = h2 * Cyy + R;
  const MatNM G = S.ldlt().solve(Cxy.transpose()).transpose();  // C_xy S⁻¹
  MatN P = h2 * Sigma;
  P.noalias() -= (h2 * h2) * G * Cxy.transpose();
  return 0.5 * (P + P.transpose());
}

/// The covariance that an update by a sampled gain takes beyond the Gaussian
/// update [Furrer & Bengtsson 2007; Sacher & Bartello 2008]: a gain made of
/// the cloud's own moments, C_xh = Cov_w(x, h(x)) and C_hh = Cov_w(h(x)),
/// regresses x on h(x) with B̂ = C_xh C_hh⁻¹, whose sampling error has
/// covariance Σ_x|h ⊗ C_hh⁻¹ / n (multivariate regression; n the effective
/// sample size, Σ_x|h = Σ − C_xh C_hh⁻¹ C_hx the part of x that h(x) does
/// not explain).  An update that removes B̂ Δ B̂ᵀ, Δ = C_hh A C_hh, removes in
/// expectation B Δ Bᵀ + Σ_x|h·tr(C_hh⁻¹ Δ)/n: the second term is the excess,
///   E = Σ_x|h · tr(A C_hh) / n,
/// which a component that the measurement does not see (position under an
/// IMU update of (v, θ)) loses at every update while the cloud stays the
/// same size.  A is the update's gain weight: for the kernel update of
/// ParticleFilter at bandwidth h, S = h² C_hh + R,
///   A = (2h² − h⁴) S⁻¹ − (1 − h²) h⁴ S⁻¹ C_hh S⁻¹
/// (the shrunk centres a(I − KH) plus the kernel h²Σ − K S Kᵀ; A = S⁻¹ at
/// h = 1, the ensemble Kalman update).  Returns 0 when C_hh is singular or
/// n ≤ 1.
template <class MatN, class MatNM, class MatM>
MatN gain_sampling_excess(const MatN& Sigma, const MatNM& Cxh, const MatM& Chh, const MatM& R, double h, double n) {
  MatN E = MatN::Zero(Sigma.rows(), Sigma.cols());
  if (!(n > 1.0)) return E;
  const Eigen::LDLT<MatM> ch(Chh);
  if (ch.info() != Eigen::Success || !(ch.vectorD().array() > 0.0).all()) return E;
  const double h2 = h * h;
  const Eigen::LDLT<MatM> ls(h2 * Chh + R);
  const MatM SiC = ls.solve(Chh);  // S⁻¹ C_hh
  const double tr = (2.0 * h2 - h2 * h2) * SiC.trace() - (1.0 - h2) * h2 * h2 * (SiC * SiC).trace();
  if (!(tr > 0.0)) return E;
  MatN cond = Sigma - Cxh * ch.solve(Cxh.transpose());
  cond = 0.5 * (cond + cond.transpose()).eval();
  return (tr / n) * cond;
}

/// L with L Lᵀ = A₊ (A symmetric; its negative eigenvalues, from rounding,
/// set to 0).  `es` is caller-owned scratch (no allocation at a fixed size).
template <class Mat, class Solver>
void psd_factor(const Mat& A, Solver& es, Mat& L) {
  es.compute(A);
  L = es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

/// A + (B − A)₊: the smallest correction of A, along the eigenvectors of
/// B − A, that makes it ⪰ B (it stays ⪰ A).  A is returned unchanged when
/// A ⪰ B already.
template <class Mat, class Solver>
Mat loewner_floor(const Mat& A, const Mat& B, Solver& es) {
  Mat D = B - A;
  D = 0.5 * (D + D.transpose()).eval();
  es.compute(D);
  if (es.eigenvalues().maxCoeff() <= 0.0) return A;
  return A + es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).asDiagonal() * es.eigenvectors().transpose();
}

}  // namespace safenav::detail
