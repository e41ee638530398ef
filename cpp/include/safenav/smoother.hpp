// safenav/smoother.hpp — a fixed-lag Rauch–Tung–Striebel smoother beside the
// causal EKF (plain Ekf or AugmentedEkf) of [SafeNav eqs. 10–14].
//
// The filter feeds it around every prediction (eq. 11): the filtered mean and
// covariance (x_k, P_k) at t_k after all of t_k's updates, then the
// prediction (x⁻_{k+1}, P⁻_{k+1}) to t_{k+1} and the transition Jacobian F_k
// the EKF linearised with (Ekf::last_transition, AugmentedEkf::last_transition:
// one model, one place).  Each node k keeps the RTS gain
//     C_k = P_k F_kᵀ (P⁻_{k+1})⁻¹                          (RTS 1965, eq. for the gain)
// computed once, when its prediction arrives.  The smoothed estimate at t_i
// given the data up to t_j ≥ t_i is the backward recursion from j:
//     x^s_k = x_k + C_k (x^s_{k+1} ⊖ x⁻_{k+1})
//     P^s_k = P_k + C_k (P^s_{k+1} − P⁻_{k+1}) C_kᵀ,   k = j−1, …, i
// (the heading residual wrapped).  An output node i (an output time: a
// motion input's) becomes final once the filter predicts from a time
// t ≥ t_i + lag; it is then smoothed from j = the newest node at or before
// t_i + lag, i.e. with exactly the data up to t_i + lag.  Each output costs a
// backward pass over the window (O(window)); finish() smooths what is left
// with all the data.
//
// Late measurements (the localizer's history) re-run the filter from an
// older time: a node at or after the time a prediction starts from is
// dropped and recorded again.  An output already emitted stays as emitted.
// cut() (the filter was restarted) ends the chain: no smoothing across it.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "safenav/motion.hpp"

namespace safenav {

/// One smoothed estimate: the 4-state (x, y, v, θ) marginal at time t.
struct SmoothedEstimate {
  double t = 0.0;
  State x = State::Zero();
  StateCov P = StateCov::Zero();
};

class FixedLagSmoother {
 public:
  /// lag [s]: finite and ≥ 0 (std::invalid_argument naming `lag` otherwise).
  explicit FixedLagSmoother(double lag);
  double lag() const { return lag_; }

  /// The filtered (x, P) at t after all of t's updates, right before a
  /// prediction from t.  Emits the outputs that became final.
  void filtered(double t, const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::MatrixXd>& P);
  /// That prediction: (x⁻, P⁻) at t1 and its F; `output`: t1 is an output time.
  void predicted(double t1, const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::MatrixXd>& P,
                 const Eigen::Ref<const Eigen::MatrixXd>& F, bool output);
  /// The filter restarted: the next node starts a new chain (and is an output).
  void cut() { cut_ = true; }
  /// End of the data: the filtered (x, P) at t is the last node; every output
  /// not yet emitted is smoothed with all the data.
  void finish(double t, const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::MatrixXd>& P);

  /// The final estimates emitted so far, oldest first; the caller may clear it.
  std::vector<SmoothedEstimate>& outputs() { return out_; }
  /// Nodes held (the window).
  std::size_t window() const { return nodes_.size() - head_; }

 private:
  struct Node {
    double t = 0.0, t1 = 0.0;
    Eigen::VectorXd x, xp;  // filtered at t; predicted to t1
    Eigen::MatrixXd P, Pp, C;  // filtered; predicted; RTS gain
    bool linked = false;      // a prediction to t1 = the next node's t (same chain)
    bool output = false;      // t is an output time
    bool output_next = false;  // t1 is one
    bool done = false;        // emitted or not an output
  };
  Node& push();
  void emit(double t_closed, bool all);
  void smooth(std::size_t i, std::size_t j, SmoothedEstimate& e);
  void prune();

  double lag_;
  std::vector<Node> nodes_, spare_;
  std::size_t head_ = 0;  // first live node
  bool cut_ = true;
  double emitted_until_;  // time of the newest emitted output
  std::vector<SmoothedEstimate> out_;
  Eigen::VectorXd xs_, d_;
  Eigen::MatrixXd Ps_, T_, CT_;
  Eigen::LLT<Eigen::MatrixXd> llt_;  // of P⁻, for the gain
};

}  // namespace safenav
