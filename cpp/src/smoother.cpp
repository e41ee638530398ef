// The fixed-lag Rauch–Tung–Striebel smoother (safenav/smoother.hpp) and the
// Localizer's feed of it (safenav/localizer.hpp, set_lag).
#include "safenav/smoother.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "errors.hpp"
#include "localizer_impl.hpp"
#include "safenav/types.hpp"

namespace safenav {

namespace {
constexpr double kEps = 1e-9;  // timestamps this close are the same instant [s]
}  // namespace

FixedLagSmoother::FixedLagSmoother(double lag) : lag_(lag), emitted_until_(-std::numeric_limits<double>::infinity()) {
  if (!(std::isfinite(lag) && lag >= 0.0))
    detail::bad("lag = " + detail::num(lag, 12) + " s: the smoother's lag must be finite and >= 0");
}

FixedLagSmoother::Node& FixedLagSmoother::push() {
  if (spare_.empty()) {
    nodes_.emplace_back();
  } else {
    nodes_.push_back(std::move(spare_.back()));
    spare_.pop_back();
  }
  return nodes_.back();
}

void FixedLagSmoother::filtered(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                                const Eigen::Ref<const Eigen::MatrixXd>& P) {
  // A re-run from an older time (late measurement, or an input that failed
  // after its prediction) replaces the nodes from t on.
  while (window() > 0 && nodes_.back().t >= t - kEps) {
    spare_.push_back(std::move(nodes_.back()));
    nodes_.pop_back();
  }
  Node* prev = window() > 0 ? &nodes_.back() : nullptr;
  bool chained = false;
  if (prev) {
    prev->linked = !cut_ && std::abs(prev->t1 - t) <= kEps && prev->Pp.size() > 0;
    chained = prev->linked;
  }
  const bool output = chained ? prev->output_next : true;  // a chain's first node is an output (the start)
  Node& n = push();
  n.t = n.t1 = t;
  n.x = x;
  n.P = P;
  n.xp.resize(0);
  n.Pp.resize(0, 0);
  n.linked = n.output_next = false;
  n.output = output;
  n.done = !output || t <= emitted_until_ + kEps;
  cut_ = false;
  emit(t, false);
}

void FixedLagSmoother::predicted(double t1, const Eigen::Ref<const Eigen::VectorXd>& x,
                                 const Eigen::Ref<const Eigen::MatrixXd>& P,
                                 const Eigen::Ref<const Eigen::MatrixXd>& F, bool output) {
  if (window() == 0) return;
  Node& n = nodes_.back();
  n.t1 = t1;
  n.xp = x;
  n.Pp = P;
  n.output_next = output;
  // RTS gain C = P Fᵀ (P⁻)⁻¹, i.e. Cᵀ = (P⁻)⁻¹ F P (P, P⁻ symmetric).
  T_.noalias() = F * n.P;
  llt_.compute(n.Pp);
  if (llt_.info() != Eigen::Success) {
    n.Pp.resize(0, 0);  // not positive definite: no smoothing across this step
    return;
  }
  llt_.solveInPlace(T_);
  n.C = T_.transpose();
}

void FixedLagSmoother::finish(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                              const Eigen::Ref<const Eigen::MatrixXd>& P) {
  filtered(t, x, P);
  emit(t, true);
}

void FixedLagSmoother::emit(double t_closed, bool all) {
  for (std::size_t i = head_; i < nodes_.size(); ++i) {
    Node& n = nodes_[i];
    if (n.done) continue;
    if (!all && n.t + lag_ > t_closed + kEps) break;  // nodes are in time order
    // j: the newest node of i's chain at or before t_i + lag.
    std::size_t j = i;
    while (j + 1 < nodes_.size() && nodes_[j].linked && nodes_[j + 1].t <= n.t + lag_ + kEps) ++j;
    SmoothedEstimate e;
    smooth(i, j, e);
    out_.push_back(e);
    emitted_until_ = n.t;
    n.done = true;
  }
  prune();
}

void FixedLagSmoother::smooth(std::size_t i, std::size_t j, SmoothedEstimate& e) {
  // The RTS backward recursion (header) from node j down to node i.
  xs_ = nodes_[j].x;
  Ps_ = nodes_[j].P;
  for (std::size_t k = j; k-- > i;) {
    const Node& n = nodes_[k];
    d_ = xs_ - n.xp;
    d_[kTheta] = wrap_angle(d_[kTheta]);
    xs_ = n.x;
    xs_.noalias() += n.C * d_;
    T_ = Ps_ - n.Pp;
    CT_.noalias() = n.C * T_;
    Ps_ = n.P;
    Ps_.noalias() += CT_ * n.C.transpose();
  }
  e.t = nodes_[i].t;
  e.x = xs_.head<4>();
  e.x[kTheta] = wrap_angle(e.x[kTheta]);
  const StateCov P4 = Ps_.topLeftCorner<4, 4>();
  e.P = 0.5 * (P4 + P4.transpose());
}

void FixedLagSmoother::prune() {
  // Nodes before the oldest output still to emit are no longer needed.
  while (head_ < nodes_.size() && nodes_[head_].done && head_ + 1 < nodes_.size()) ++head_;
  if (head_ >= 64 && head_ * 2 >= nodes_.size()) {
    for (std::size_t k = 0; k < head_; ++k) spare_.push_back(std::move(nodes_[k]));
    nodes_.erase(nodes_.begin(), nodes_.begin() + static_cast<std::ptrdiff_t>(head_));
    head_ = 0;
  }
}

// -- the Localizer's feed ------------------------------------------------------

void Localizer::Impl::smoother_filtered() {
  if (const AugmentedEkf* a = filter->augmented_ekf()) smoother->filtered(t_f, a->augmented(), a->augmented_cov());
  else smoother->filtered(t_f, filter->x(), filter->P());
}

void Localizer::Impl::smoother_predicted(double t1, bool output) {
  if (const AugmentedEkf* a = filter->augmented_ekf()) {
    a->last_transition(smooth_F, smooth_Q);
    smoother->predicted(t1, a->augmented(), a->augmented_cov(), smooth_F, output);
  } else {
    smoother->predicted(t1, filter->x(), filter->P(), filter->ekf()->last_transition().F, output);
  }
}

void Localizer::set_lag(double lag) {
  Impl& I = *impl_;
  if (std::isnan(lag) || !(lag >= 0.0) || !std::isfinite(lag))
    bad("lag = " + num(lag) + " s: the fixed-lag smoother's lag must be finite and >= 0");
  if (I.settings.filter.type != FilterType::Ekf)
    bad("lag = " + num(lag) +
        " s: fixed-lag smoothing needs the EKF (plain or augmented); the particle and information filters "
        "have no Rauch-Tung-Striebel pass here");
  I.smoother = std::make_unique<FixedLagSmoother>(lag);
}

double Localizer::lag() const { return impl_->smoother ? impl_->smoother->lag() : kNaN; }

std::vector<SmoothedEstimate> Localizer::take_smoothed() {
  std::vector<SmoothedEstimate> out;
  if (impl_->smoother) std::swap(out, impl_->smoother->outputs());
  return out;
}

void Localizer::finish_smoothing() {
  Impl& I = *impl_;
  if (!I.smoother || !I.initialized()) return;
  if (const AugmentedEkf* a = I.filter->augmented_ekf()) I.smoother->finish(I.t_f, a->augmented(), a->augmented_cov());
  else I.smoother->finish(I.t_f, I.filter->x(), I.filter->P());
}

}  // namespace safenav
