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
//
// The iterated variant (SmootherKind::Iterated, smoother_iterated.cpp) keeps
// each step's input (u, dt) and the measurements the filter accepted, and
// solves the window's nonlinear least-squares problem by Gauss–Newton in its
// Kalman form, the iterated extended Kalman smoother (Bell 1994: one IEKS
// pass is one Gauss–Newton step):
//   forward   x⁻ = f(x̄_k, u_k) + F_k (x_k ⊖ x̄_k),  P⁻ = F_k P_k F_kᵀ + Q_k    (eq. 11 at x̄_k)
//             y = z ⊖ h(x̄) − H (x⁻ ⊖ x̄), then eqs. 12–14 with H at x̄     (each accepted update)
//   backward  the RTS recursion above with the forward pass's P, P⁻ and F
// with f, F, Q from AugmentedEkf::transition and h, H from
// safenav/measurement.hpp, both evaluated at the linearisation points x̄,
// which are the previous pass's smoothed means (the causal means for steps no
// pass has reached).  The window for the output at t_i runs from i to j (as
// above); its prior at i is the forward pass's prediction to t_i of the
// previous output's solve (the window's marginalised past, re-linearised as
// GTSAM's BatchFixedLagSmoother marginalises at its last linearisation), or
// the causal prediction where no pass reached t_i.  `iterations` passes per
// output, warm-started: each step is re-linearised by every output whose
// window holds it.  Lag 0 is the causal filter for both kinds.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "safenav/augmented.hpp"
#include "safenav/filter.hpp"
#include "safenav/motion.hpp"

namespace safenav {

/// The fixed-lag smoother's algorithm: a Rauch–Tung–Striebel pass over the
/// filter's own linearisation, or the iterated window solve (header).
enum class SmootherKind { Rts, Iterated };
const char* to_string(SmootherKind kind);
/// "rts" or "iterated"; std::invalid_argument naming `name` otherwise.
SmootherKind smoother_kind(const std::string& name);

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
  /// The iterated window solve over `model`'s state and motion model
  /// (AugmentedEkf::transition; with no augmented states, the plain EKF's),
  /// `iterations` Gauss–Newton passes per output, in [1, 100].
  FixedLagSmoother(double lag, const AugmentedEkf& model, int iterations);
  double lag() const { return lag_; }
  SmootherKind kind() const { return model_ ? SmootherKind::Iterated : SmootherKind::Rts; }
  int iterations() const { return iterations_; }

  /// The filtered (x, P) at t after all of t's updates, right before a
  /// prediction from t.  Emits the outputs that became final.
  void filtered(double t, const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::MatrixXd>& P);
  /// That prediction: (x⁻, P⁻) at t1 and its F; `output`: t1 is an output time.
  void predicted(double t1, const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::MatrixXd>& P,
                 const Eigen::Ref<const Eigen::MatrixXd>& F, bool output);
  /// The same, with the prediction's input u over dt (the iterated solve re-evaluates f there).
  void predicted(double t1, const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::MatrixXd>& P,
                 const Eigen::Ref<const Eigen::MatrixXd>& F, const Control& u, double dt, bool output);
  /// An update the filter accepted at its current time (before the next
  /// prediction from that time); the RTS kind ignores them.  A rejected
  /// update is never passed: the window keeps the causal gate's decisions.
  void measured(const LandmarkMeasurement& m);
  void measured_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  void measured_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  /// The measurements recorded so far (a count), and a return to that count:
  /// the filter went back to a checkpoint taken at mark() (late
  /// measurements re-run the inputs after it, which are recorded again).
  std::size_t mark() const { return meas_base_ + meas_.size(); }
  void rewind(std::size_t mark);
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
    // The iterated kind only:
    Control u = Control::Zero();  // the prediction's input over dt to t1
    double dt = 0.0;
    std::size_t m0 = 0, m1 = 0;  // its measurements at t: [m0, m1) of mark()'s count
    Eigen::VectorXd xq, xbar, xf, xpp;  // prior at t (before t's updates); linearisation point; pass: filtered, predicted
    Eigen::MatrixXd Pq, Pf, Ppp, G;     // their covariances; the pass's RTS gain
  };
  /// A measurement as the filter applied it.
  struct Measurement {
    enum class Kind { Landmark, Position, SpeedHeading } kind = Kind::Landmark;
    LandmarkMeasurement m;  // Landmark
    Eigen::Vector2d z = Eigen::Vector2d::Zero();  // Position, SpeedHeading
    Eigen::Matrix2d R = Eigen::Matrix2d::Zero();
  };
  /// The iterated solve's scratch, sized once for the model's n states.
  struct Work {
    Work() = default;
    explicit Work(int n);
    Eigen::VectorXd x, d, f, x1;
    Eigen::MatrixXd P, F, Q, FP, T, P1, Ps;
    Eigen::Matrix<double, 2, Eigen::Dynamic> H;
    Eigen::Matrix<double, Eigen::Dynamic, 2> PHt, K, KR, AHt;
    Eigen::LLT<Eigen::MatrixXd> llt;
  };
  Node& push();
  void emit(double t_closed, bool all);
  void smooth(std::size_t i, std::size_t j, SmoothedEstimate& e);
  void prune();
  // The iterated solve (smoother_iterated.cpp).
  void init_node(Node& n, const Node* prev);
  void solve(std::size_t i, std::size_t j, SmoothedEstimate& e);
  void forward(std::size_t i, std::size_t j);
  void backward(std::size_t i, std::size_t j, bool covariances, SmoothedEstimate& e);
  void update(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Measurement& m, const Eigen::VectorXd& xbar);

  double lag_;
  std::vector<Node> nodes_, spare_;
  std::size_t head_ = 0;  // first live node
  bool cut_ = true;
  double emitted_until_;  // time of the newest emitted output
  std::vector<SmoothedEstimate> out_;
  Eigen::VectorXd xs_, d_;
  Eigen::MatrixXd Ps_, T_, CT_;
  Eigen::LLT<Eigen::MatrixXd> llt_;  // of P⁻, for the gain
  // The iterated kind.
  std::unique_ptr<AugmentedEkf> model_;  // f, F, Q (transition) and the state layout; null for RTS
  int iterations_ = 0;
  std::vector<Measurement> meas_;  // entries [meas_base_, mark())
  std::size_t meas_base_ = 0;
  Work work_;
};

}  // namespace safenav
