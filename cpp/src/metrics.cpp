#include "safenav/metrics.hpp"

#include "safenav/motion.hpp"  // wrap_angle

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/LU>  // determinant

namespace safenav {

void check_points(const Eigen::Ref<const Points2>& p, const char* what, Eigen::Index min_rows) {
  if (p.rows() < min_rows) {
    std::ostringstream os;
    os << what << " needs at least " << min_rows << " point(s), got " << p.rows();
    throw std::invalid_argument(os.str());
  }
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    if (!p.row(i).allFinite()) {
      std::ostringstream os;
      os << what << " point " << i << " = (" << p(i, 0) << ", " << p(i, 1) << ") is not finite";
      throw std::invalid_argument(os.str());
    }
  }
}

double overflow_scale(double max_abs) {
  int e = 0;
  std::frexp(max_abs, &e);
  return e > 500 ? std::ldexp(1.0, -e) : 1.0;
}

double finite_mean(const Eigen::Ref<const Eigen::VectorXd>& values) {
  const double m = values.mean();  // divide before summing only when the sum overflows
  return std::isfinite(m) ? m : (values / static_cast<double>(values.size())).sum();
}

namespace {
/// ‖a − b‖ without overflow in the squares (std::hypot); throws naming `what`
/// and both points when the distance itself is not representable.
double distance(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const char* what) {
  const double d = std::hypot(a.x() - b.x(), a.y() - b.y());
  if (!std::isfinite(d)) {
    std::ostringstream os;
    os << what << ": the distance from (" << a.x() << ", " << a.y() << ") to (" << b.x() << ", " << b.y()
       << ") overflows";
    throw std::invalid_argument(os.str());
  }
  return d;
}

Eigen::Vector2d row(const Eigen::Ref<const Points2>& p, Eigen::Index i) { return p.row(i).transpose(); }

}  // namespace

double ade(const Eigen::Ref<const Points2>& est, const Eigen::Ref<const Points2>& truth) {
  check_points(est, "estimate");
  check_points(truth, "truth");
  if (est.rows() != truth.rows()) {
    std::ostringstream os;
    os << "ADE pairs points by time: estimate has " << est.rows() << " points but truth has " << truth.rows();
    throw std::invalid_argument(os.str());
  }
  // The plain expression first (its bits are the tables' since the start); the
  // overflow-safe one only when a square overflowed.
  const double m = (est - truth).rowwise().norm().mean();
  if (std::isfinite(m)) return m;
  const Eigen::Index n = est.rows();
  Eigen::VectorXd d(n);
  for (Eigen::Index i = 0; i < n; ++i) d[i] = distance(row(est, i), row(truth, i), "ADE");
  return finite_mean(d);
}

double fde(const Eigen::Ref<const Points2>& est, const Eigen::Ref<const Points2>& truth) {
  check_points(est, "estimate");
  check_points(truth, "truth");
  const double d = (est.row(est.rows() - 1) - truth.row(truth.rows() - 1)).norm();
  return std::isfinite(d) ? d : distance(row(est, est.rows() - 1), row(truth, truth.rows() - 1), "FDE");
}

double path_length(const Eigen::Ref<const Points2>& path) {
  check_points(path, "path");
  if (path.rows() < 2) return 0.0;
  const double plain = (path.bottomRows(path.rows() - 1) - path.topRows(path.rows() - 1)).rowwise().norm().sum();
  if (std::isfinite(plain)) return plain;
  Eigen::VectorXd d(path.rows() - 1);
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i) d[i] = distance(row(path, i + 1), row(path, i), "path length");
  const double L = d.sum();
  if (!std::isfinite(L)) throw std::invalid_argument("path length overflows (sum of edge lengths > 1.8e308)");
  return L;
}

double path_length_error_percent(const Eigen::Ref<const Points2>& est, const Eigen::Ref<const Points2>& truth) {
  const double lt = path_length(truth), le = path_length(est);
  if (!(lt > 0.0)) throw std::invalid_argument("percent path-length error: the true path has zero length");
  const double e = std::abs(le - lt) / lt * 100.0;
  if (!std::isfinite(e)) {
    std::ostringstream os;
    os << "percent path-length error overflows: estimate length " << le << ", true length " << lt;
    throw std::invalid_argument(os.str());
  }
  return e;
}

Eigen::VectorXd nees(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& est,
                     const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& truth,
                     const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& covs,
                     int angle_index) {
  const Eigen::Index N = est.rows(), n = est.cols();
  std::ostringstream os;
  if (truth.rows() != N || truth.cols() != n) {
    os << "NEES: estimates are " << N << "x" << n << " but truth is " << truth.rows() << "x" << truth.cols();
    throw std::invalid_argument(os.str());
  }
  if (covs.rows() != N || covs.cols() != n * n) {
    os << "NEES: covariances must be " << N << "x" << n * n << " (row-major " << n << "x" << n << " per row), got "
       << covs.rows() << "x" << covs.cols();
    throw std::invalid_argument(os.str());
  }
  if (angle_index >= n) {
    os << "NEES: angle_index = " << angle_index << " out of range for state dimension " << n;
    throw std::invalid_argument(os.str());
  }
  Eigen::VectorXd out(N);
  for (Eigen::Index k = 0; k < N; ++k) {
    Eigen::VectorXd e = (est.row(k) - truth.row(k)).transpose();
    if (angle_index >= 0) e[angle_index] = wrap_angle(e[angle_index]);
    const Eigen::MatrixXd P = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
        covs.row(k).data(), n, n);
    if (!e.allFinite() || !P.allFinite()) {
      os << "NEES: row " << k << " has non-finite estimate, truth or covariance";
      throw std::invalid_argument(os.str());
    }
    Eigen::LLT<Eigen::MatrixXd> llt(P);
    if (llt.info() != Eigen::Success) {
      os << "NEES: covariance at row " << k << " is not positive definite";
      throw std::invalid_argument(os.str());
    }
    out[k] = e.dot(llt.solve(e));
    if (!std::isfinite(out[k])) {  // finite inputs, but P near-singular at its scale (1e-310) or e, P near 1e308
      os << "NEES: row " << k << ": e^T P^-1 e = " << out[k] << " is not finite (covariance diagonal "
         << P.diagonal().transpose() << ")";
      throw std::invalid_argument(os.str());
    }
  }
  return out;
}

// ---------------------------------------------------------------------------
// TrajectoryScore

TrajectoryScore::TrajectoryScore(Eigen::Index capacity) : points_(std::max<Eigen::Index>(capacity, 0), 2) {}

void TrajectoryScore::add(const State& estimate, const StateCov& P, const State& truth) {
  State e = truth - estimate;
  e[kTheta] = wrap_angle(e[kTheta]);
  // A P that is not positive definite (a particle cloud collapsed onto a few
  // particles) has no NEES: left out of the mean.
  const Eigen::LLT<Eigen::Matrix4d> llt(P);
  const double n4 = llt.info() == Eigen::Success ? e.dot(llt.solve(e)) : std::numeric_limits<double>::quiet_NaN();
  if (std::isfinite(n4)) {
    nees_sum_ += n4;
    ++nees_n_;
  }
  add_position(estimate.head<2>(), P.topLeftCorner<2, 2>(), truth.head<2>());
}

void TrajectoryScore::add(const Eigen::Vector2d& estimate, const Eigen::Matrix2d& P_xy, const Eigen::Vector2d& truth) {
  add_position(estimate, P_xy, truth);
}

void TrajectoryScore::add_position(const Eigen::Vector2d& estimate, const Eigen::Matrix2d& Pxy,
                                   const Eigen::Vector2d& truth) {
  if (!estimate.allFinite() || !truth.allFinite()) {
    std::ostringstream os;
    os << "TrajectoryScore: pose " << n_ << ": estimate (" << estimate.x() << ", " << estimate.y() << ") or truth ("
       << truth.x() << ", " << truth.y() << ") is not finite";
    throw std::invalid_argument(os.str());
  }
  // Position NEES, 2 degrees of freedom: eᵀP_xy⁻¹e by the 2×2 inverse; a
  // singular or indefinite P_xy puts the pose outside 3σ.
  const Eigen::Vector2d ep = truth - estimate;
  const double det = Pxy.determinant();
  const double d2 = det > 0.0 ? (Pxy(1, 1) * ep.x() * ep.x() - 2.0 * Pxy(0, 1) * ep.x() * ep.y() + Pxy(0, 0) * ep.y() * ep.y()) / det
                              : std::numeric_limits<double>::infinity();
  if (!(d2 <= 9.0)) ++outside_;
  if (det > 0.0 && Pxy(0, 0) > 0.0) {
    pos_nees_sum_ += d2;
    ++pos_nees_n_;
  }
  const double sq = (estimate - truth).squaredNorm();
  const double d = std::sqrt(sq);  // = ‖p̂ − p‖ (Eigen's norm())
  error_sum_ += d;
  error2_sum_ += sq;
  last_error_ = d;
  if (n_ > 0) {
    const Eigen::Vector2d prev = points_.row(n_ - 1).transpose();
    length_ += (estimate - prev).norm();
  }
  if (n_ == points_.rows()) points_.conservativeResize(std::max<Eigen::Index>(16, 2 * n_), 2);
  points_.row(n_) = estimate.transpose();
  ++n_;
}

void TrajectoryScore::add_risk(double truth_deviation, double truth_wrs, double estimate_wrs) {
  max_deviation_ = std::max(max_deviation_, truth_deviation);
  wrs_truth_ += truth_wrs;
  wrs_estimate_ += estimate_wrs;
}

void TrajectoryScore::add_clearance(double clearance) { min_clearance_ = std::min(min_clearance_, clearance); }

void TrajectoryScore::add_hazard(double length, double exposure, bool inside, double dt) {
  hazard_length_ += length;
  exposure_ += exposure;
  if (inside) hazard_time_ += dt;
}

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

double TrajectoryScore::truth_ade() const { return n_ > 0 ? error_sum_ / double(n_) : kNaN; }
double TrajectoryScore::truth_fde() const { return n_ > 0 ? last_error_ : kNaN; }
double TrajectoryScore::truth_rmse() const { return n_ > 0 ? std::sqrt(error2_sum_ / double(n_)) : kNaN; }
double TrajectoryScore::nees() const { return nees_n_ > 0 ? nees_sum_ / double(nees_n_) : kNaN; }
double TrajectoryScore::position_nees() const { return pos_nees_n_ > 0 ? pos_nees_sum_ / double(pos_nees_n_) : kNaN; }
double TrajectoryScore::outside_3sigma() const { return n_ > 0 ? double(outside_) / double(n_) : kNaN; }

void TrajectoryScore::fill(TrialMetrics& m) const {
  const double rows = double(n_);
  m.awrs = wrs_estimate_ / rows;
  m.awrs_true = wrs_truth_ / rows;
  m.truth_ade = truth_ade();
  m.truth_fde = truth_fde();
  m.max_deviation = max_deviation_;
  m.min_clearance = min_clearance_;
  m.hazard_time = hazard_time_;
  m.hazard_length = hazard_length_;
  m.exposure = exposure_;
  m.nees = nees();
  m.outside_3sigma = outside_3sigma();
}

}  // namespace safenav
