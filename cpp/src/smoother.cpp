// The fixed-lag Rauch–Tung–Striebel smoother (safenav/smoother.hpp) and the
// Localizer's feed of it (safenav/localizer.hpp, set_lag).
#include "safenav/smoother.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
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

const char* to_string(SmootherKind kind) { return kind == SmootherKind::Iterated ? "iterated" : "rts"; }

SmootherKind smoother_kind(const std::string& name) {
  if (name == "rts") return SmootherKind::Rts;
  if (name == "iterated") return SmootherKind::Iterated;
  detail::bad("smoother = '" + name + "': the fixed-lag smoother is 'rts' or 'iterated'");
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
  Node& n = push();  // (prev may move)
  n.t = n.t1 = t;
  n.x = x;
  n.P = P;
  n.xp.resize(0);
  n.Pp.resize(0, 0);
  n.linked = n.output_next = false;
  n.output = output;
  n.done = !output || t <= emitted_until_ + kEps;
  if (model_) init_node(n, chained ? &nodes_[nodes_.size() - 2] : nullptr);
  cut_ = false;
  emit(t, false);
}

void FixedLagSmoother::predicted(double t1, const Eigen::Ref<const Eigen::VectorXd>& x,
                                 const Eigen::Ref<const Eigen::MatrixXd>& P,
                                 const Eigen::Ref<const Eigen::MatrixXd>& F, const Control& u, double dt,
                                 bool output) {
  if (window() == 0) return;
  nodes_.back().u = u;
  nodes_.back().dt = dt;
  predicted(t1, x, P, F, output);
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
  if (model_) return;  // the iterated solve computes its own gains
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
    if (model_ && lag_ > 0.0) solve(i, j, e);  // lag 0: the causal filter (no look-ahead to iterate on)
    else smooth(i, j, e);
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
    // Measurements before the first live node's are no longer needed.
    const std::size_t keep = std::max(nodes_.front().m0, meas_base_);
    if (model_ && keep > meas_base_ && keep - meas_base_ <= meas_.size()) {
      meas_.erase(meas_.begin(), meas_.begin() + static_cast<std::ptrdiff_t>(keep - meas_base_));
      meas_base_ = keep;
    }
  }
}

// -- the Localizer's feed ------------------------------------------------------

void Localizer::Impl::smoother_filtered() {
  if (const AugmentedEkf* a = filter->augmented_ekf()) smoother->filtered(t_f, a->augmented(), a->augmented_cov());
  else smoother->filtered(t_f, filter->x(), filter->P());
}

void Localizer::Impl::smoother_predicted(double t1, const Control& u, double dt, bool output) {
  if (const AugmentedEkf* a = filter->augmented_ekf()) {
    a->last_transition(smooth_F, smooth_Q);
    smoother->predicted(t1, a->augmented(), a->augmented_cov(), smooth_F, u, dt, output);
  } else {
    smoother->predicted(t1, filter->x(), filter->P(), filter->ekf()->last_transition().F, u, dt, output);
  }
}

void Localizer::Impl::smoother_measured(const LoggedInput& in) {
  switch (in.kind) {
    case LoggedInput::Kind::Observation: {
      const LandmarkObservation& o = in.obs;
      LandmarkMeasurement m;  // as apply_observation gives it to the filter
      m.row = row_of.at(o.id);
      m.landmark = landmarks.row(m.row).transpose();
      m.range = o.range;
      m.bearing = o.bearing;
      m.range_std = o.range_std;
      m.bearing_std = o.bearing_std;
      return smoother->measured(m);
    }
    case LoggedInput::Kind::Fix: return smoother->measured_position(in.a, in.R);
    case LoggedInput::Kind::SpeedHeading: return smoother->measured_speed_heading(in.a, in.R);
    default: return;
  }
}

void Localizer::set_lag(double lag, SmootherKind kind, int iterations) {
  Impl& I = *impl_;
  if (std::isnan(lag) || !(lag >= 0.0) || !std::isfinite(lag))
    bad("lag = " + num(lag) + " s: the fixed-lag smoother's lag must be finite and >= 0");
  if (I.settings.filter.type != FilterType::Ekf)
    bad("lag = " + num(lag) +
        " s: fixed-lag smoothing needs the EKF (plain or augmented); the particle and information filters "
        "have no Rauch-Tung-Striebel pass here");
  if (kind == SmootherKind::Rts) {
    I.smoother = std::make_unique<FixedLagSmoother>(lag);
    return;
  }
  // The filter's own model: the augmented EKF's, or with no augmented states the plain EKF's f, F, Q.
  const AugmentedStates none;
  const AugmentedEkf model(I.settings.bmm, I.settings.augment.any() ? I.settings.augment : none,
                           static_cast<int>(I.landmarks.rows()), State::Zero(), StateCov::Identity());
  I.smoother = std::make_unique<FixedLagSmoother>(lag, model, iterations);
}

SmootherKind Localizer::smoother() const {
  return impl_->smoother ? impl_->smoother->kind() : SmootherKind::Rts;
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
