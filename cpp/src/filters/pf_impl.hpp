// Private: the particle filter's state and passes (ParticleFilter::Impl,
// used by pf.cpp only): storage, weights, resampling, regularisation
// (regularise.hpp; the method is documented at ParticleFilter in
// safenav/filters.hpp), the kernel and ensemble updates and the noisy
// prediction; the per-particle passes are the kernels in pf_kernels.hpp.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <new>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "checks.hpp"
#include "pf_columns.hpp"
#include "pf_kernels.hpp"
#include "regularise.hpp"
#include "safenav/filters.hpp"

namespace safenav {

using namespace detail;  // the kernels of pf_kernels.hpp

struct ParticleFilter::Impl {
  // Particle columns: x, y, v, θ, cos θ, sin θ; weight columns: log w, w.
  enum Column : int { kCos = 4, kSin = 5, kParticleColumns = 6 };
  // Weight columns: log w, w, 1/N (for the unweighted moments), the
  // log-likelihood log p(z | x_i) of an update.
  enum WeightColumn : int { kLogW = 0, kW = 1, kUniform = 2, kGain = 3, kWeightColumns = 4 };
  Bmm bmm;
  detail::BatchRng rng;
  double resample_threshold;
  int N = 0;
  Columns S, S_next;          // particles; S_next receives a resampled set
  Columns W;                  // log-weights and normalised weights
  double ess = 0.0;           // 1/Σw², kept with w
  int n_resampled = 0;
  double h = 0.0;             // kernel bandwidth (0: plain SIR, no jitter, no floor)
  std::vector<double> trial_logw;  // kernel log-weights of an update (kernel_weights)
  std::vector<int> ancestor;  // the particle each one descends from at the last resampling
  mutable std::vector<double> lineage_w;  // scratch: the weight of each lineage
  double gate_probability = 0.0;     // NIS gate (0 = off)
  std::vector<double> gate_thresholds;  // chi-square quantile per measurement dimension
  // scratch
  Columns noise;              // ε_x, ε_y, ε_v, ε_θ of every particle
  std::vector<int> start;     // resampling: the particle of each pointer
  Eigen::MatrixXd Y;          // residuals of a general measurement model
  Eigen::Matrix4d Sigma_prior;        // the prior cloud's weighted covariance (of an update)
  Eigen::MatrixXd Cxy, Cyy;           // weighted state–residual and residual covariances
  double log_det_s = 0.0;             // log det (C_yy + R) of the last likelihood()
  Eigen::VectorXd ybar;               // weighted mean residual
  Eigen::MatrixXd Yraw;               // residuals of a general model (before whitening)
  Eigen::MatrixXd U;                  // y_i − ȳ of a kernel update
  State m_lik = State::Zero();        // the weighted mean of the last likelihood() of an IMU update
  mutable Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es;

  Impl(const BmmParams& p, std::uint64_t seed, double thr, int n, double bandwidth_scale)
      : bmm(p), rng(seed), resample_threshold(thr), N(n), h(kernel_bandwidth(n, 4, bandwidth_scale)) {
    S.resize(N, kParticleColumns);
    S_next.resize(N, kParticleColumns);
    W.resize(N, kWeightColumns);
    std::fill_n(W.col(kUniform), N, 1.0 / N);  // padding stays 0
    noise.resize(N, 4);
    start.resize(static_cast<std::size_t>(N) + 1);
    trial_logw.resize(N);
    lineage_w.resize(N);
    ancestor.resize(N);
    for (int i = 0; i < N; ++i) ancestor[i] = i;
  }

  int n() const { return N; }
  double* col(int c) { return S.col(c); }
  const double* col(int c) const { return S.col(c); }
  double* logw() { return W.col(kLogW); }
  double* w() { return W.col(kW); }
  const double* w() const { return W.col(kW); }
  /// The particles as the columns of a 4 × N matrix (MeasurementModel::residuals).
  StatesView states() const { return StatesView(S.col(0), 4, N, Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>(1, S.stride())); }
  void reset_weights() {
    std::fill_n(logw(), N, -std::log(static_cast<double>(N)));
    std::fill_n(w(), N, 1.0 / N);
    ess = N;
  }

  /// Normalise the log-weights (mx = their maximum).  Weights below e^−300 of
  /// the best particle's are floored there: such particles are dead either
  /// way, and the floor keeps exp() and w² out of subnormal numbers, which are
  /// ~100× slower.
  void normalise(double mx) {
    constexpr double kLogFloor = -300.0;
    detail::dispatch<exp_weights>(N, logw(), w(), mx, kLogFloor);
    const double sum = detail::dispatch<sum_weights<32>, sum_weights<16>>(N, w());  // ≥ 1: exp(0) is in it
    ess = 1.0 / detail::dispatch<scale_weights<32>, scale_weights<16>>(N, logw(), w(), 1.0 / sum, mx + std::log(sum));
  }

  /// The effective sample size of the lineages, 1/Σ_a W_a², W_a the weight
  /// of the particles that descend from one particle a of the last
  /// resampling: copies of one particle move together, so the weighted mean's
  /// Monte Carlo covariance is about Σ/ESS_lineage, not Σ·Σw² (≤ the Kish ESS;
  /// equal when no two particles share a parent).
  double lineage_ess() const {
    std::fill(lineage_w.begin(), lineage_w.end(), 0.0);
    for (int i = 0; i < N; ++i) lineage_w[ancestor[i]] += w()[i];
    double s2 = 0.0;
    for (double v : lineage_w) s2 += v * v;
    return 1.0 / s2;
  }

  /// Systematic resampling: pointers u_j = (j + U)/N, j = 0..N−1, one
  /// U ~ U[0, 1); particle i gets the pointers in (C_{i−1}, C_i], C_i = Σ_{k≤i} w_k:
  /// n_i = #{j : u_j ≤ C_i} − #{j : u_j ≤ C_{i−1}} copies, so E[n_i] = N w_i and
  /// n_i is ⌊N w_i⌋ or ⌈N w_i⌉.  Branch-free (the old while-loop search
  /// mispredicted about once per particle): with c_i = #{j : u_j ≤ C_i},
  /// pointers from c_i on belong to particles after i, so start[c_i] = i + 1
  /// (the last such i wins), and a running maximum of `start` gives every
  /// pointer its particle.
  void resample() {
    const double U = rng.uniform();
    std::fill(start.begin(), start.end(), 0);
    int* st = start.data();
    const double* ww = w();
    double acc = 0.0;
    for (int i = 0; i < N - 1; ++i) {
      acc += ww[i];
      const double t = acc * N - U;  // u_j ≤ C_i  ⇔  j ≤ t
      const int c = t < 0.0 ? 0 : std::min(static_cast<int>(t) + 1, N);
      st[c] = i + 1;
    }
    static_assert(kParticleColumns == 6, "one copy per column below");
    copy_selected(N, st, S.col(0), S.col(1), S.col(2), S.col(3), S.col(4), S.col(5), S_next.col(0), S_next.col(1),
                  S_next.col(2), S_next.col(3), S_next.col(4), S_next.col(5));
    S.swap(S_next);
    for (int j = 0, src = 0; j < N; ++j) ancestor[j] = src = std::max(src, st[j]);
    reset_weights();
    ++n_resampled;
  }

  /// Mean under the weights in column `wc` of W (circular mean for θ).
  State mean(int wc = kW) const {
    const Sums5 s = detail::dispatch<mean_sums<32>, mean_sums<16>>(N, col(kX), col(kY), col(kV), col(kCos),
                                                                    col(kSin), W.col(wc));
    return State(s.s[0], s.s[1], s.s[2], std::atan2(s.s[4], s.s[3]));  // circular mean for θ
  }

  /// Covariance Σ w_i d_i d_iᵀ about m under the weights in column `wc` of W, θ deviations wrapped.
  StateCov covariance(const State& m, int wc = kW) const {
    const Sums10 t = detail::dispatch<covariance_sums<32>, covariance_sums<16>>(N, col(kX), col(kY), col(kV),
                                                                                col(kTheta), W.col(wc), &m);
    const double* s = t.s;
    StateCov P;
    P << s[0], s[1], s[2], s[3],
         s[1], s[4], s[5], s[6],
         s[2], s[5], s[7], s[8],
         s[3], s[6], s[8], s[9];
    if (!P.allFinite()) {  // deviations beyond ~1e154 (e.g. one ulp of positions near 1e308) square to inf
      std::ostringstream os;
      os << "particle covariance about (" << m[0] << ", " << m[1] << ", " << m[2] << ", " << m[3] << ")";
      check_finite_result(P, "particle filter P", os.str());
    }
    return P;
  }

  /// The reported covariance: the weighted one about m, corrected for the
  /// Monte Carlo error of the weighted mean (monte_carlo_gain, regularise.hpp),
  /// floored by the kernel covariance h²·C_u of the unweighted cloud.
  StateCov reported_covariance(const State& m) const {
    const StateCov P = covariance(m);
    if (h <= 0.0) return P;
    const StateCov floor = (h * h) * covariance(mean(kUniform), kUniform);
    return loewner_floor(StateCov(monte_carlo_gain(lineage_ess()) * P), floor, es);
  }

  /// log p(z | x_i) (up to a constant) of every particle into the gain
  /// column; returns the NIS of the weighted-mean prediction (ȳ, S = Cov_w(y)
  /// + R under the current weights), and keeps C_yy = Cov_w(y) and, when
  /// `cross`, C_xy = Σ w_i (x_i − m)(y_i − ȳ)ᵀ for the kernel (regularise.hpp).
  /// The NIS ȳᵀ S⁻¹ ȳ of S = C_yy + R, keeping log det S in log_det_s (one factorisation for both).
  double innovation(const Eigen::MatrixXd& R) {
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(Cyy + R);
    log_det_s = ldlt.vectorD().array().log().sum();
    return ybar.dot(ldlt.solve(ybar));
  }

  double likelihood(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z,
                    const Eigen::MatrixXd& R, bool cross) {
    const int m = model.dim();
    double* gain = W.col(kGain);
    if (model.kind() == MeasurementKind::Position) {
      // Fast path: 2-D residuals, log-likelihood and NIS moments in one pass (C_xy follows from Σ⁻).
      const Eigen::Matrix2d Ri = R.inverse();
      const PositionParams a{z[0], z[1], 0.5 * Ri(0, 0), Ri(0, 1), 0.5 * Ri(1, 1)};
      std::fill_n(gain, N, 0.0);
      const Sums5 t = detail::dispatch<position_loglik<32>, position_loglik<16>>(N, col(kX), col(kY), w(), gain, &a);
      const double* ps = t.s;
      const double s0 = ps[0], s1 = ps[1];
      ybar = Eigen::Vector2d(s0, s1);
      Cyy.resize(2, 2);
      Cyy << ps[2] - s0 * s0, ps[3] - s0 * s1, ps[3] - s0 * s1, ps[4] - s1 * s1;
      return innovation(R);
    }
    if (model.kind() == MeasurementKind::SpeedHeading && z[1] > -kPi && z[1] <= kPi) {
      // Fast path: the IMU's (v, θ), every moment in one pass (imu_moments), C_xy always.
      const Eigen::Matrix2d Ri = R.inverse();
      m_lik = mean();
      const ImuParams a{z[0], z[1], 0.5 * Ri(0, 0), Ri(0, 1), 0.5 * Ri(1, 1), {m_lik[0], m_lik[1], m_lik[2], m_lik[3]}};
      const Sums17 t = detail::dispatch<imu_moments<32>, imu_moments<16>>(N, col(kX), col(kY), col(kV), col(kTheta),
                                                                          w(), gain, &a);
      const double* q = t.s;
      ybar = Eigen::Vector2d(q[0], q[1]);
      Cyy.resize(2, 2);
      Cyy << q[2] - q[0] * q[0], q[3] - q[0] * q[1], q[3] - q[0] * q[1], q[4] - q[1] * q[1];
      Cxy.resize(4, 2);
      for (int k = 0; k < 4; ++k)
        for (int j = 0; j < 2; ++j) Cxy(k, j) = q[9 + 4 * j + k] - q[5 + k] * ybar[j];
      return innovation(R);
    }
    // Residual of every particle, y_i = z ⊖ h(x_i), one per column.
    Y.resize(m, N);
    model.residuals(z, states(), Y);
    const Eigen::Map<const Eigen::VectorXd> wv(w(), N);
    ybar = Y * wv;
    const Eigen::MatrixXd D = Y.colwise() - ybar;
    Cyy = D * wv.asDiagonal() * D.transpose();
    const double nis = innovation(R);
    if (cross) {
      const State m0 = mean();
      // C_xy += (w_i dx_i) y_iᵀ element by element: the sums of Eigen's outer
      // product, in its order, without a dynamic-size temporary per particle.
      Cxy.setZero(4, m);
      double* cxy = Cxy.data();
      const double *x = col(kX), *y = col(kY), *v = col(kV), *th = col(kTheta);
      for (int i = 0; i < N; ++i) {
        const double a[4] = {wv[i] * (x[i] - m0[kX]), wv[i] * (y[i] - m0[kY]), wv[i] * (v[i] - m0[kV]),
                             wv[i] * wrap_angle(th[i] - m0[kTheta])};
        const double* d = D.col(i).data();
        for (int c = 0; c < m; ++c)
          for (int r = 0; r < 4; ++r) cxy[4 * c + r] += d[c] * a[r];
      }
      Yraw = Y;
    }
    // log-likelihood −½ yᵀR⁻¹y = −½‖L⁻¹y‖²
    model.noise().whiten(Y);
    Eigen::Map<Eigen::ArrayXd>(gain, N) = -0.5 * Y.colwise().squaredNorm().transpose().array();
    return nis;
  }

  /// Residual y_i = z ⊖ h(x_i) of particle i (Yraw holds a general model's).
  void residual_of(MeasurementKind kind, const Eigen::Ref<const Eigen::VectorXd>& z, int i, Eigen::VectorXd& y) const {
    if (kind == MeasurementKind::Position) {
      y << z[0] - col(kX)[i], z[1] - col(kY)[i];
    } else if (kind == MeasurementKind::SpeedHeading) {  // as likelihood() computed it (both kinds of path)
      y << z[0] - col(kV)[i], wrap_angle(z[1] - col(kTheta)[i]);
    } else {
      y = Yraw.col(i);
    }
  }

  /// The kernel weights at bandwidth hh into trial_logw: log w_i − ½ y_c,iᵀ
  /// S_h⁻¹ y_c,i, y_c,i = ȳ + a(y_i − ȳ), S_h = hh²C_yy + R; returns their
  /// ESS.  Needs U = (y_i − ȳ) filled (kernel_update).
  double kernel_weights(const Eigen::MatrixXd& R, double hh) {
    const double a = std::sqrt(std::max(0.0, 1.0 - hh * hh));
    const Eigen::MatrixXd Si = (hh * hh * Cyy + R).inverse();
    const Eigen::VectorXd b = Si * ybar;
    // y_cᵀS⁻¹y_c = ȳᵀS⁻¹ȳ + 2a bᵀu + a² uᵀS⁻¹u, u = y − ȳ
    const Eigen::ArrayXd q = ybar.dot(b) + (2.0 * a) * (b.transpose() * U).transpose().array() +
                             (a * a) * (U.array() * (Si * U).array()).colwise().sum().transpose();
    Eigen::Map<Eigen::ArrayXd> t(trial_logw.data(), N);
    t = Eigen::Map<const Eigen::ArrayXd>(logw(), N) - 0.5 * q;
    const double mx = t.maxCoeff();
    const Eigen::ArrayXd e = (t - mx).exp();
    return e.sum() * e.sum() / e.square().sum();
  }

  /// The bandwidth of one kernel update [Stordal et al. 2011, adaptive h]:
  /// the smallest h_u² = h² + t(1 − h²), t ∈ [0, 1] (bisection to 1/64),
  /// whose kernel weights keep ESS ≥ resample_threshold·N, or h_u = 1 (the
  /// ensemble Kalman update: the kernel weights are the prior weights) when
  /// none does.  Leaves trial_logw at h_u.
  double adaptive_bandwidth(const Eigen::MatrixXd& R) {
    const double target = resample_threshold * N, h2 = h * h;
    auto at = [&](double t) { return std::sqrt(h2 + t * (1.0 - h2)); };
    if (kernel_weights(R, h) >= target) return h;
    double lo = 0.0, hi = 1.0, last = 0.0;
    for (int k = 0; k < 6; ++k) {
      last = 0.5 * (lo + hi);
      (kernel_weights(R, at(last)) >= target ? hi : lo) = last;
    }
    if (hi >= 1.0) return 1.0;  // exactly: a = 0 (kernel_update resets the weights)
    if (last != hi) kernel_weights(R, at(hi));
    return at(hi);
  }

  /// The regularised update (see ParticleFilter in safenav/filters.hpp): each
  /// particle is the centre of a kernel N(c_i, h_u²Σ⁻), c_i = m + a(x_i − m),
  /// a = √(1 − h_u²), h_u = adaptive_bandwidth(); the kernels are updated by
  /// statistical linearisation (one gain K for all), weighted by their own
  /// predictive likelihood N(y_c,i; 0, S_h), and each particle is redrawn
  /// from its updated kernel (C_xh = −C_xy):
  ///   S_h = h_u²C_yy + R,  K = h_u²C_xh S_h⁻¹,  P_k = h_u²Σ⁻ − K S_h Kᵀ
  ///   y_c,i = ȳ + a(y_i − ȳ),  log w_i += −½ y_c,iᵀ S_h⁻¹ y_c,i
  ///   x_i ← c_i + K y_c,i + d_i,  d_i from redraw() with L Lᵀ = P_k
  ///         (+ (g − 1)Σ_c when resampled, the Monte Carlo term)
  /// with systematic resampling before the redraw when ESS <
  /// resample_threshold·N.  Needs likelihood() called first under the prior
  /// weights (ȳ, C_yy, C_xy).
  void kernel_update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z,
                     const Eigen::MatrixXd& R) {
    const bool position = model.kind() == MeasurementKind::Position;
    const State m0 = mean();
    const Eigen::Matrix4d Sigma = covariance(m0);
    if (position) Cxy = -Sigma.leftCols<2>();  // y = z − (x, y): C_xy = −Σ⁻Hᵀ with H = [I₂ 0]
    U.resize(model.dim(), N);
    Eigen::VectorXd y(model.dim());
    for (int i = 0; i < N; ++i) {
      residual_of(model.kind(), z, i, y);
      U.col(i) = y - ybar;
    }
    const double hu = adaptive_bandwidth(R);
    // h_u = 1: a = 0, every kernel has the one centre m + Kȳ, so the mixture
    // is one Gaussian whatever the weights: the particles are redrawn from it
    // with uniform weights (exact), and the Monte Carlo error of m (P/ESS of
    // the prior lineages) goes into the redraw, as at a resampling.
    const bool ensemble = hu >= 1.0;
    const double n_prior = lineage_ess();
    const double h2 = hu * hu, a = ensemble ? 0.0 : std::sqrt(std::max(0.0, 1.0 - h2));
    const Eigen::LLT<Eigen::MatrixXd> llt(h2 * Cyy + R);
    // The gain of x on h(x) is h²C_xh S_h⁻¹, and C_xh = −C_xy (y = z ⊖ h(x)).
    const Eigen::MatrixXd K = llt.solve((-h2 * Cxy).transpose()).transpose();
    // The kernel conditioned on z, plus twice what the sampled gain takes
    // beyond the Gaussian update (regularise.hpp, gain_sampling_excess, with
    // n the prior lineage ESS): once for the spread it takes, once for the
    // error it adds to the mean.
    const double g = ensemble ? monte_carlo_gain(n_prior) : 1.0;
    const Eigen::Matrix4d Pk = g * conditioned_kernel(Sigma, Cxy, Cyy, R, hu) +
                               2.0 * gain_sampling_excess(Sigma, Cxy, Cyy, R, hu, n_prior);
    double* c[4] = {col(kX), col(kY), col(kV), col(kTheta)};
    double mx = -std::numeric_limits<double>::infinity();
    for (int i = 0; i < N; ++i) {
      logw()[i] = trial_logw[i];
      mx = std::max(mx, trial_logw[i]);
      Eigen::Vector4d d(c[0][i] - m0[0], c[1][i] - m0[1], c[2][i] - m0[2], wrap_angle(c[3][i] - m0[3]));
      d = a * d + K * (ybar + a * U.col(i));  // the updated kernel's centre
      for (int k = 0; k < 4; ++k) c[k][i] = m0[k] + d[k];
    }
    if (ensemble) {
      reset_weights();
      for (int i = 0; i < N; ++i) ancestor[i] = i;  // independent draws from here
    } else {
      normalise(mx);
    }
    Eigen::Matrix4d L;
    if (ess < resample_threshold * N) {
      // The variance that resampling turns into Monte Carlo error of the
      // mean goes back into the redraw (regularise.hpp, monte_carlo_gain):
      // P_k + (g − 1)·Σ_c, Σ_c the weighted covariance of the updated centres.
      psd_factor(Eigen::Matrix4d(Pk + (monte_carlo_gain(lineage_ess()) - 1.0) * covariance(mean())), es, L);
      resample();  // copies centres (cos/sin are rewritten below)
    } else {
      psd_factor(Pk, es, L);
    }
    redraw(L);
  }

  /// x_i += d_i − Σ_j w_j d_j, d_i = L T(ε_i − ε̄) (v clamped to [v_min,
  /// v_max], θ wrapped): the draws are moment-matched, so the redraw moves
  /// no weighted mean and adds exactly L Lᵀ to the weighted covariance.
  void redraw(const Eigen::Matrix4d& L) {
    rng.fill_normal(noise.col(0), 4L * noise.stride());
    double* e[4] = {noise.col(0), noise.col(1), noise.col(2), noise.col(3)};
    // Moment matching: ε_i ← T(ε_i − ε̄), T Cov_w(ε) Tᵀ = I, so that the
    // d_i = L ε_i have weighted mean 0 and weighted covariance L Lᵀ exactly.
    Eigen::Vector4d ebar = Eigen::Vector4d::Zero();
    for (int i = 0; i < N; ++i) ebar += w()[i] * Eigen::Vector4d(e[0][i], e[1][i], e[2][i], e[3][i]);
    Eigen::Matrix4d Ce = Eigen::Matrix4d::Zero();
    for (int i = 0; i < N; ++i) {
      const Eigen::Vector4d d = Eigen::Vector4d(e[0][i], e[1][i], e[2][i], e[3][i]) - ebar;
      Ce.noalias() += (w()[i] * d) * d.transpose();
    }
    const Eigen::LLT<Eigen::Matrix4d> lc(Ce);
    // Matched only when Cov_w(ε) is well estimated (ESS > 2d = 8); else centred only.
    const bool match = lc.info() == Eigen::Success && ess > 8.0;
    const Eigen::Matrix4d M = match ? Eigen::Matrix4d(L * lc.matrixL().solve(Eigen::Matrix4d::Identity())) : L;
    Eigen::Vector4d dbar = Eigen::Vector4d::Zero();
    for (int i = 0; i < N; ++i) {
      const Eigen::Vector4d d = M * (Eigen::Vector4d(e[0][i], e[1][i], e[2][i], e[3][i]) - ebar);
      for (int k = 0; k < 4; ++k) e[k][i] = d[k];
      dbar += w()[i] * d;
    }
    const double vmin = bmm.params().min_speed(), vmax = bmm.params().max_speed;
    double* c[4] = {col(kX), col(kY), col(kV), col(kTheta)};
    for (int i = 0; i < N; ++i) {
      c[0][i] += e[0][i] - dbar[0];
      c[1][i] += e[1][i] - dbar[1];
      c[2][i] = std::clamp(c[2][i] + e[2][i] - dbar[2], vmin, vmax);
      const double t = wrap_angle(c[3][i] + e[3][i] - dbar[3]);  // a local: cos and sin share one sincos
      c[3][i] = t;
      col(kCos)[i] = std::cos(t);
      col(kSin)[i] = std::sin(t);
    }
  }

  /// Moment matching of Kc columns of standard normal draws e (one row per
  /// particle) against the particles' deviations d about m: the draws
  ///   e ← T (e − ē − Bᵀ(d − d̄)),  B = G⁻¹ C_de,  T = L⁻¹,  L Lᵀ = C_ee − C_deᵀ B
  /// (G, C_de, C_ee the weighted covariances of d and e; ē, d̄ their weighted
  /// means) have weighted mean 0, weighted covariance I and no weighted
  /// covariance with the state, exactly up to rounding: sampled noise then
  /// adds exactly its covariance to the cloud and no spurious correlation
  /// with the state (with N draws the sample cross-covariance of a state
  /// component with a noise column is ~σ/√N, which a later update on that
  /// noise's component would read as information about the state).  From
  /// one pass of sums (draw_moments; G from covariance_sums).  B = 0 when G
  /// is not positive definite; returns false, with T = I, when the residual
  /// draws' covariance is not.  Writes the map e ← T e + Q d + c.
  template <int Kc>
  bool match(const DrawSums<Kc>& t, const State& m, Eigen::Matrix<double, Kc, Kc>& T,
             Eigen::Matrix<double, Kc, 4>& Q, Eigen::Matrix<double, Kc, 1>& c) {
    using MatK = Eigen::Matrix<double, Kc, Kc>;
    const Eigen::Map<const Eigen::Vector4d> dbar(t.d);
    const Eigen::Map<const Eigen::Matrix<double, Kc, 1>> ebar(t.e);
    const Eigen::Matrix<double, 4, Kc> Cde =
        Eigen::Map<const Eigen::Matrix<double, 4, Kc, Eigen::RowMajor>>(&t.de[0][0]) - dbar * ebar.transpose();
    MatK Cee;
    for (int j = 0, q = 0; j < Kc; ++j)
      for (int l = j; l < Kc; ++l, ++q) Cee(j, l) = Cee(l, j) = t.ee[q] - ebar[j] * ebar[l];
    const Eigen::Matrix4d G = covariance(m) - dbar * dbar.transpose();
    Eigen::Matrix<double, 4, Kc> B = Eigen::Matrix<double, 4, Kc>::Zero();
    const Eigen::LDLT<Eigen::Matrix4d> gd(G);
    if (gd.info() == Eigen::Success && (gd.vectorD().array() > 0.0).all()) B = gd.solve(Cde);
    const MatK C = Cee - Cde.transpose() * B;
    const Eigen::LLT<MatK> lc(C);
    const bool whitened = lc.info() == Eigen::Success;
    T = whitened ? MatK(lc.matrixL().solve(MatK::Identity())) : MatK(MatK::Identity());
    Q = -T * B.transpose();
    c = -T * ebar - Q * dbar;
    return whitened;
  }

  /// The draws and their moments for match(): Kc columns of noise filled with N(0, 1).
  template <int Kc>
  DrawSums<Kc> draws(const State& m) {
    rng.fill_normal(noise.col(0), long(Kc) * noise.stride());
    DrawColumns<Kc> a{{col(kX), col(kY), col(kV), col(kTheta), w()}, {m[0], m[1], m[2], m[3]}};
    for (int j = 0; j < Kc; ++j) a.p[5 + j] = noise.col(j);
    return detail::dispatch<draw_moments<32, Kc>, draw_moments<16, Kc>>(N, &a);
  }

  /// The ensemble Kalman update with perturbed observations [Burgers, van
  /// Leeuwen & Evensen 1998] for a linear model that does not see the
  /// position (the IMU's (v, θ)): x_i ← x_i + K(y_i + L_R η_i), K = C_xh S⁻¹,
  /// S = C_yy + R, L_R L_Rᵀ = R, η_i drawn from N(0, I) and moment-matched
  /// (match): the weighted mean moves by Kȳ and the weighted covariance
  /// becomes exactly Σ − C_xh S⁻¹ C_hx, the Gaussian update of the cloud's
  /// own moments; the weights stay, nothing is resampled, and the cloud keeps
  /// its shape.  Needs likelihood() of the model first (ȳ, C_yy, C_xy about
  /// m_lik, z_θ in (−π, π]); one pass (imu_apply) after the draws' moments.
  void ensemble_update(const Eigen::Ref<const Eigen::VectorXd>& z, const Eigen::MatrixXd& R) {
    const Eigen::Matrix<double, 4, 2> K = (-Cxy) * (Cyy + R).llt().solve(Eigen::MatrixXd::Identity(2, 2));
    const State m = m_lik;
    Eigen::Matrix2d T;
    Eigen::Matrix<double, 2, 4> Q;
    Eigen::Vector2d c;
    match<2>(draws<2>(m), m, T, Q, c);  // T = I when not whitened: centred and regressed only
    const Eigen::Matrix2d Lr = Eigen::Matrix2d(R).llt().matrixL();
    const Eigen::Matrix<double, 4, 2> A = K * Lr * T;  // K L_R η_i = A e_i + (K L_R Q) d_i + K L_R c
    const Eigen::Matrix4d AQ = K * Lr * Q;
    const Eigen::Vector4d Ac = K * Lr * c;
    ImuApply p{z[0], z[1], {m[0], m[1], m[2], m[3]}, {}, {}, {}, {}, bmm.params().min_speed(), bmm.params().max_speed};
    for (int k = 0; k < 4; ++k) {
      for (int j = 0; j < 2; ++j) p.K[k][j] = K(k, j), p.A[k][j] = A(k, j);
      for (int j = 0; j < 4; ++j) p.Q[k][j] = AQ(k, j);
      p.c[k] = Ac[k];
    }
    double* dth = noise.col(2);
    const long n_big = detail::dispatch<imu_apply>(N, col(kX), col(kY), col(kV), col(kTheta), col(kCos), col(kSin),
                                                   static_cast<const double*>(noise.col(0)),
                                                   static_cast<const double*>(noise.col(1)), dth, &p);
    if (n_big > 0) exact_turns(dth);
  }

  /// Heading and (cos θ, sin θ) recomputed exactly for the particles whose
  /// heading moved by more than kSmallTurn (dth: each one's move).
  void exact_turns(const double* dth) {
    double* th = col(kTheta);
    for (int i = 0; i < N; ++i) {
      if (dth[i] > kSmallTurn || dth[i] < -kSmallTurn) {
        th[i] = wrap_angle(th[i]);
        col(kCos)[i] = std::cos(th[i]);
        col(kSin)[i] = std::sin(th[i]);
      }
    }
  }

  /// Noisy BMM for every particle (eqs. 6–9, the body of Bmm::transition).
  /// θ moves by a small δ_i per step, so cos/sin of the new heading come from
  /// rotating the cached (cos θ, sin θ) by δ_i (particles_step); turns larger
  /// than kSmallTurn are redone with std::cos/std::sin.
  void predict(double desired_speed, double heading_step) {
    const auto& p = bmm.params();
    const double k = p.terrain_factor() * p.dt;
    if (h > 0.0 && ess > 16.0) {  // regularised: moment-matched process noise (match)
      const State m = mean();
      const DrawSums<4> t = draws<4>(m);  // all four columns (and their padding)
      Eigen::Matrix4d T, Q;
      Eigen::Vector4d c;
      if (match<4>(t, m, T, Q, c)) {  // else the draws stay as they are
        NoiseMap a{};
        for (int k = 0; k < 4; ++k) {
          for (int j = 0; j < 4; ++j) a.T[k][j] = T(k, j), a.Q[k][j] = Q(k, j);
          a.c[k] = c[k];
          a.m[k] = m[k];
        }
        detail::dispatch<map_noise<32>, map_noise<16>>(N, static_cast<const double*>(col(kX)),
                                                       static_cast<const double*>(col(kY)),
                                                       static_cast<const double*>(col(kV)),
                                                       static_cast<const double*>(col(kTheta)), noise.col(0),
                                                       noise.col(1), noise.col(2), noise.col(3),
                                                       static_cast<const NoiseMap*>(&a));
      }
    } else {
      rng.fill_normal(noise.col(0), 4L * noise.stride());  // all four columns (and their padding)
    }
    double* x = col(kX);
    double* y = col(kY);
    double* v = col(kV);
    double* th = col(kTheta);
    double* cs = col(kCos);
    double* sn = col(kSin);
    const double* ex = noise.col(0);
    const double* ey = noise.col(1);
    const double* ev = noise.col(2);
    const double* et = noise.col(3);
    // With `unicycle` the speed follows the input (Bmm::next_speed): steps of
    // 2·v_max reach any desired speed in [−v_max, v_max] from any speed there.
    const double up = p.unicycle ? 2.0 * p.max_speed : p.acceleration * p.dt;
    const double down = p.unicycle ? 2.0 * p.max_speed : p.deceleration * p.dt;
    const StepParams a{desired_speed, heading_step, up,          down,          p.min_speed(),
                       p.max_speed,   k,            p.speed_noise, p.heading_noise, p.position_noise};
    const long n_big = detail::dispatch<particles_step>(N, x, y, v, th, cs, sn, ex, ey, ev, et, &a);
    if (n_big > 0) {  // rare: large turns get exact trigonometry
      for (int i = 0; i < N; ++i) {
        const double d = heading_step + p.heading_noise * et[i];  // as in particles_step
        if (d > kSmallTurn || d < -kSmallTurn) {
          th[i] = wrap_angle(th[i]);
          const double ce = std::cos(th[i]), se = std::sin(th[i]);
          x[i] += k * v[i] * (ce - cs[i]);
          y[i] += k * v[i] * (se - sn[i]);
          cs[i] = ce;
          sn[i] = se;
        }
      }
    }
  }
};

}  // namespace safenav
