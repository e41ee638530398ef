// The fixed-lag smoother's iterated window solve (safenav/smoother.hpp,
// SmootherKind::Iterated): the iterated extended Kalman smoother over the
// window, i.e. Gauss–Newton on the window's negative log posterior in its
// Kalman form (Bell 1994, "The iterated Kalman smoother as a Gauss–Newton
// method"), with the filter's own motion model (AugmentedEkf::transition,
// [SafeNav eq. 11]), landmark model (safenav/measurement.hpp, eq. 10) and
// Kalman update (filters/kalman_update.hpp, eqs. 12–14).
#include <Eigen/Cholesky>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "errors.hpp"
#include "filters/kalman_update.hpp"
#include "safenav/measurement.hpp"
#include "safenav/smoother.hpp"
#include "safenav/types.hpp"

namespace safenav {

FixedLagSmoother::Work::Work(int n)
    : x(n), d(n), f(n), x1(n), P(n, n), F(n, n), Q(n, n), FP(n, n), T(n, n), P1(n, n), Ps(n, n), H(2, n),
      PHt(n, 2), K(n, 2), KR(n, 2), AHt(n, 2), llt(n) {}

FixedLagSmoother::FixedLagSmoother(double lag, const AugmentedEkf& model, int iterations) : FixedLagSmoother(lag) {
  if (iterations < 1 || iterations > 100)
    detail::bad("iterations = " + std::to_string(iterations) +
                ": the iterated smoother's Gauss-Newton passes per output must be in [1, 100]");
  model_ = std::make_unique<AugmentedEkf>(model);
  iterations_ = iterations;
  work_ = Work(model.size());
}

void FixedLagSmoother::measured(const LandmarkMeasurement& m) {
  if (!model_) return;
  Measurement& r = meas_.emplace_back();
  r.kind = Measurement::Kind::Landmark;
  r.m = m;
}

void FixedLagSmoother::measured_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  if (!model_) return;
  meas_.push_back(Measurement{Measurement::Kind::Position, LandmarkMeasurement(), z, R});
}

void FixedLagSmoother::measured_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  if (!model_) return;
  meas_.push_back(Measurement{Measurement::Kind::SpeedHeading, LandmarkMeasurement(), z, R});
}

void FixedLagSmoother::rewind(std::size_t mark) {
  if (mark >= this->mark()) return;
  if (mark < meas_base_) {
    meas_.clear();
    meas_base_ = mark;
  } else {
    meas_.resize(mark - meas_base_);
  }
}

void FixedLagSmoother::init_node(Node& n, const Node* prev) {
  // The prior at t before t's updates: the causal prediction from the previous
  // step (a solve that reaches t replaces it by its re-linearised one); a
  // chain's first node starts from its filtered estimate, its updates inside.
  const std::size_t end = mark();
  n.m0 = prev ? prev->m1 : end;
  n.m1 = end;
  n.xq = prev ? prev->xp : n.x;
  n.Pq = prev ? prev->Pp : n.P;
  n.xbar = n.x;
  n.u.setZero();
  n.dt = 0.0;
}

void FixedLagSmoother::solve(std::size_t i, std::size_t j, SmoothedEstimate& e) {
  // `iterations` Gauss–Newton passes; each re-linearises about the last one's
  // smoothed means (the first about those of earlier outputs' solves).
  for (int it = 0; it < iterations_; ++it) {
    forward(i, j);
    backward(i, j, it + 1 == iterations_, e);
  }
}

void FixedLagSmoother::forward(std::size_t i, std::size_t j) {
  Work& w = work_;
  w.x = nodes_[i].xq;
  w.P = nodes_[i].Pq;
  for (std::size_t k = i; k <= j; ++k) {
    Node& n = nodes_[k];
    if (k > i) {
      const Node& p = nodes_[k - 1];
      w.x = p.xpp;
      w.P = p.Ppp;
      n.xq = w.x;  // the re-linearised prior at t_k (the next output's window starts from it)
      n.Pq = w.P;
    }
    const std::size_t m0 = std::max(n.m0, meas_base_), m1 = std::min(n.m1, mark());
    for (std::size_t m = m0; m < m1; ++m) update(w.x, w.P, meas_[m - meas_base_], n.xbar);
    n.xf = w.x;
    n.Pf = w.P;
    if (k == j) break;
    // Eq. 11 linearised at x̄_k: x⁻ = f(x̄) + F (x ⊖ x̄), P⁻ = F P Fᵀ + Q.
    model_->transition(n.xbar, n.u, n.dt, w.f, w.F, w.Q);
    w.d = w.x - n.xbar;
    w.d[kTheta] = wrap_angle(w.d[kTheta]);
    n.xpp = w.f;
    n.xpp.noalias() += w.F * w.d;
    n.xpp[kTheta] = wrap_angle(n.xpp[kTheta]);
    w.FP.noalias() = w.F * w.P;
    n.Ppp = w.Q;
    n.Ppp.noalias() += w.FP * w.F.transpose();
    // RTS gain G = P Fᵀ (P⁻)⁻¹, i.e. Gᵀ = (P⁻)⁻¹ F P.
    // A P⁻ that is not positive definite: no smoothing across this step (as the RTS kind), G = 0.
    w.llt.compute(n.Ppp);
    if (w.llt.info() != Eigen::Success) {
      n.G.setZero(w.x.size(), w.x.size());
      continue;
    }
    w.llt.solveInPlace(w.FP);
    n.G = w.FP.transpose();
  }
}

void FixedLagSmoother::backward(std::size_t i, std::size_t j, bool covariances, SmoothedEstimate& e) {
  // The RTS recursion (header) over the forward pass; the smoothed means are
  // the next pass's (and the next outputs') linearisation points.
  Work& w = work_;
  Node& last = nodes_[j];
  last.xbar = last.xf;
  if (covariances) w.Ps = last.Pf;
  for (std::size_t k = j; k-- > i;) {
    Node& n = nodes_[k];
    w.d = nodes_[k + 1].xbar - n.xpp;
    w.d[kTheta] = wrap_angle(w.d[kTheta]);
    n.xbar = n.xf;
    n.xbar.noalias() += n.G * w.d;
    n.xbar[kTheta] = wrap_angle(n.xbar[kTheta]);
    if (!covariances) continue;
    w.T = w.Ps - n.Ppp;
    w.FP.noalias() = n.G * w.T;
    w.Ps = n.Pf;
    w.Ps.noalias() += w.FP * n.G.transpose();
  }
  if (!covariances) return;
  e.t = nodes_[i].t;
  e.x = nodes_[i].xbar.head<4>();
  const StateCov P4 = w.Ps.topLeftCorner<4, 4>();
  e.P = 0.5 * (P4 + P4.transpose());
}

void FixedLagSmoother::update(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Measurement& meas,
                              const Eigen::VectorXd& xbar) {
  // One accepted update, eqs. 12–14 with h linearised at x̄:
  //   y = z ⊖ h(x̄) − H (x ⊖ x̄)   (the Gauss–Newton residual; at x = x̄ the filter's own y).
  Work& w = work_;
  w.d = x - xbar;
  w.d[kTheta] = wrap_angle(w.d[kTheta]);
  const auto never = [](double, int) { return false; };  // the causal gate already accepted it
  const KalmanWork kw{w.PHt, w.K, w.KR, w.AHt, w.P1, w.x1};
  w.H.setZero();
  if (meas.kind == Measurement::Kind::Position || meas.kind == Measurement::Kind::SpeedHeading) {
    // Linear: h = (x, y) or (v, θ) (the angle residual wrapped).
    const bool pos = meas.kind == Measurement::Kind::Position;
    const int a = pos ? kX : kV, b = pos ? kY : kTheta;
    w.H(0, a) = w.H(1, b) = 1.0;
    const MeasurementKind kind = pos ? MeasurementKind::Position : MeasurementKind::SpeedHeading;
    const Eigen::Vector2d y = MeasurementModel::direct_residual(kind, meas.z, x);
    kalman_update<2>("iterated smoother", kind, x, P, y,
                     w.H.topRows<2>(), meas.R, never, kw);
  } else {
    const LandmarkMeasurement& m = meas.m;
    const LandmarkGeometry g = landmark_geometry(xbar[kX], xbar[kY], m.landmark.x(), m.landmark.y());
    if (!g.finite() || !g.defined()) return;  // h undefined at x̄ (at the landmark): left out of this pass
    const int ik = model_->scale_index(), ib = model_->range_bias_index(m.row);
    Eigen::Vector2d y, sd;
    int rows = 0;
    const auto row = [&](const LandmarkJacobian& J, double residual, double sigma) {
      w.H(rows, kX) = J.x;
      w.H(rows, kY) = J.y;
      w.H(rows, kTheta) = J.theta;
      if (ik >= 0) w.H(rows, ik) = J.k;
      if (ib >= 0) w.H(rows, ib) = J.b;
      y[rows] = residual - w.H.row(rows).dot(w.d);
      sd[rows++] = sigma;
    };
    LandmarkJacobian J;
    if (m.has_range()) {
      const double h = predict_range(g, ik >= 0 ? xbar[ik] : 0.0, ib >= 0 ? xbar[ib] : 0.0, &J);
      row(J, m.range - h, m.range_std);
    }
    if (m.has_bearing()) {
      const double h = predict_bearing(g, xbar[kTheta], &J);
      row(J, wrap_angle(m.bearing - h), m.bearing_std);
    }
    const MeasurementKind kind = rows == 2 ? MeasurementKind::RangeBearing
                                 : m.has_range() ? MeasurementKind::Range
                                                 : MeasurementKind::Bearing;
    if (rows == 2) {
      const Eigen::Matrix2d R = sd.cwiseAbs2().asDiagonal();
      kalman_update<2>("iterated smoother", kind, x, P, y, w.H.topRows<2>(), R, never, kw);
    } else {
      kalman_update<1>("iterated smoother", kind, x, P, y.head<1>(), w.H.topRows<1>(),
                       Eigen::Matrix<double, 1, 1>(sd[0] * sd[0]), never, kw);
    }
  }
  x.swap(w.x1);
  P.swap(w.P1);
}

}  // namespace safenav
