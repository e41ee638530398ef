// Private: the one gated Kalman update in Joseph form [SafeNav eqs. 12–14],
// shared by Ekf (4 states; measurements of 1, 2 or m entries) and
// AugmentedEkf (n states, sized at run time; 1 or 2 entries).  Templated on
// the Eigen sizes, so that the EKF's fixed-size arithmetic is what it always
// was and the augmented filter, working in scratch sized once, allocates
// nothing per update.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <stdexcept>
#include <string>

#include "checks.hpp"
#include "safenav/filter.hpp"
#include "safenav/types.hpp"

namespace safenav {

/// The update's working matrices for an n-state filter and an m-entry
/// measurement, by reference: P Hᵀ, K, K R and A Hᵀ (n×m, or wider: the
/// first m columns are used), P' (n×n) and x' (n).
/// Sized by the owner; the update never resizes them.
template <class NM, class NN, class N1>
struct KalmanWork {
  NM& PHt;
  NM& K;
  NM& KR;
  NM& AHt;
  NN& P1;
  N1& x1;
};
template <class NM, class NN, class N1>
KalmanWork(NM&, NM&, NM&, NM&, NN&, N1&) -> KalmanWork<NM, NN, N1>;

namespace kalman {
/// The first m columns (rows) of A, of fixed width M when M is fixed.
/// The first m columns of a: a itself when it is m wide (the EKF's
/// exact-size matrices, whose fixed-size arithmetic then stays as it was),
/// else a block of fixed width M.
template <int M, class A>
decltype(auto) first_cols(A& a, int m) {
  if constexpr (A::ColsAtCompileTime == M) return (a);
  else return a.template leftCols<M>();
}
}  // namespace kalman

/// One gated update of the state (x, P) by the residual y = z − h(x̂) with
/// Jacobian H (m×n) and noise R (m×m), [SafeNav eqs. 12–14]:
///   S = H P Hᵀ + R (eq. 12); NIS = yᵀ S⁻¹ y, rejected when rejects(NIS, m);
///   K = P Hᵀ S⁻¹ (eq. 13); x' = x + K y, θ wrapped (eq. 14);
///   P' = (I − K H) P (I − K H)ᵀ + K R Kᵀ, the Joseph form of eq. 14, symmetrised.
/// When accepted, w.x1 and w.P1 hold x' and P' for the caller to commit.
/// Throws std::runtime_error when S is not positive definite and
/// std::invalid_argument when the NIS is not finite, naming `filter`.
template <int M, class X, class P, class Y, class H, class R, class Rejects, class NM, class NN, class N1>
UpdateResult kalman_update(const char* filter, MeasurementKind kind, const X& x, const P& Pm, const Y& y,
                           const H& Hm, const R& Rm, Rejects rejects, KalmanWork<NM, NN, N1> w) {
  using MatMM = Eigen::Matrix<double, M, M>;
  const int m = static_cast<int>(y.size());
  constexpr bool kFixed = NN::SizeAtCompileTime != Eigen::Dynamic;
  auto&& PHt = kalman::first_cols<M>(w.PHt, m);
  if constexpr (kFixed) PHt = Pm * Hm.transpose();
  else PHt.noalias() = Pm * Hm.transpose();
  const MatMM S = Hm * PHt + Rm;  // eq. 12
  const Eigen::LLT<MatMM> llt(S);
  if (llt.info() != Eigen::Success)
    throw std::runtime_error(std::string(filter) + " " + to_string(kind) +
                             " update: innovation covariance S is not positive definite");
  UpdateResult res;
  res.dim = m;
  res.nis = y.dot(llt.solve(y));
  res.log_det_s = log_det_from_cholesky(llt.matrixLLT().diagonal());
  check_nis(res.nis, filter, kind);
  check_log_det_s(res.log_det_s, filter, kind);
  if (rejects(res.nis, m)) {
    res.accepted = false;
    return res;
  }
  if constexpr (kFixed) {
    // Fixed n (the EKF): the expressions as Ekf::apply always wrote them, so
    // that Eigen evaluates them, and rounds, exactly as before.
    constexpr int Nf = NN::RowsAtCompileTime;
    const Eigen::Matrix<double, Nf, M> K = llt.solve(PHt.transpose()).transpose();  // eq. 13
    w.x1 = x + K * y;                                                               // eq. 14
    w.x1[kTheta] = wrap_angle(w.x1[kTheta]);
    const NN IKH = NN::Identity() - K * Hm;
    const NN P1 = IKH * Pm * IKH.transpose() + K * Rm * K.transpose();  // Joseph form of eq. 14
    w.P1 = 0.5 * (P1 + P1.transpose());
  } else {
    // Dynamic n (the augmented EKF): the same equations, each product into
    // the owner's scratch, so that nothing is allocated, in O(n² m).
    // K = P Hᵀ S⁻¹ with S⁻¹ (m×m, m ≤ 2) from the factor: a triangular solve
    // of the m×n Kᵀ costs more than the product at these sizes.
    auto&& K = kalman::first_cols<M>(w.K, m);
    K.noalias() = PHt * llt.solve(MatMM::Identity(m, m));  // eq. 13
    w.x1 = x;
    w.x1.noalias() += K * y;  // eq. 14
    w.x1[kTheta] = wrap_angle(w.x1[kTheta]);
    // Joseph form expanded, O(n² m): A = (I − K H) P = P − K (P Hᵀ)ᵀ;
    // P' = A (I − K H)ᵀ + K R Kᵀ = A − (A Hᵀ) Kᵀ + (K R) Kᵀ.
    w.P1 = Pm;
    w.P1.noalias() -= K * PHt.transpose();
    auto&& AHt = kalman::first_cols<M>(w.AHt, m);
    AHt.noalias() = w.P1 * Hm.transpose();
    auto&& KR = kalman::first_cols<M>(w.KR, m);
    KR.noalias() = K * Rm;
    w.P1.noalias() -= AHt * K.transpose();
    w.P1.noalias() += KR * K.transpose();  // Joseph form of eq. 14
    for (Eigen::Index i = 0; i < w.P1.rows(); ++i)
      for (Eigen::Index j = i + 1; j < w.P1.cols(); ++j) w.P1(i, j) = w.P1(j, i) = 0.5 * (w.P1(i, j) + w.P1(j, i));
  }
  return res;
}

}  // namespace safenav
