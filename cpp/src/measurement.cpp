#include "safenav/measurement.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace safenav {

const char* to_string(MeasurementKind kind) {
  switch (kind) {
    case MeasurementKind::Position: return "position";
    case MeasurementKind::Range: return "range";
    case MeasurementKind::Bearing: return "bearing";
    case MeasurementKind::RangeBearing: return "range_bearing";
    case MeasurementKind::SpeedHeading: return "speed_heading";
  }
  return "unknown";
}

// ------------------------------- GaussianNoise ------------------------------

GaussianNoise::GaussianNoise(const Eigen::MatrixXd& R, const char* what) : R_(R) {
  std::ostringstream os;
  if (R.rows() != R.cols() || R.rows() == 0) {
    os << what << " must be a non-empty square matrix, got " << R.rows() << "x" << R.cols();
    throw std::invalid_argument(os.str());
  }
  if (!R.allFinite()) {
    os << what << " has non-finite entries:\n" << R;
    throw std::invalid_argument(os.str());
  }
  const double scale = std::max(1.0, R.cwiseAbs().maxCoeff());
  if ((R - R.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    os << what << " is not symmetric:\n" << R;
    throw std::invalid_argument(os.str());
  }
  Eigen::LLT<Eigen::MatrixXd> llt(R);
  if (llt.info() != Eigen::Success) {
    os << what << " is not positive definite:\n" << R;
    throw std::invalid_argument(os.str());
  }
  L_ = llt.matrixL();
}

GaussianNoise GaussianNoise::Sigmas(const Eigen::VectorXd& sigmas, const char* what) {
  for (Eigen::Index i = 0; i < sigmas.size(); ++i) {
    if (!(std::isfinite(sigmas[i]) && sigmas[i] > 0.0)) {
      std::ostringstream os;
      os << what << "[" << i << "] = " << sigmas[i] << " must be finite and > 0";
      throw std::invalid_argument(os.str());
    }
  }
  return GaussianNoise(Eigen::MatrixXd(sigmas.array().square().matrix().asDiagonal()), what);
}

double GaussianNoise::mahalanobis2(const Eigen::Ref<const Eigen::VectorXd>& y) const {
  return L_.triangularView<Eigen::Lower>().solve(y).squaredNorm();
}

// ------------------------------ MeasurementModel ----------------------------

namespace {
bool uses_landmarks(MeasurementKind k) {
  return k == MeasurementKind::Range || k == MeasurementKind::Bearing || k == MeasurementKind::RangeBearing;
}
int dim_of(MeasurementKind k, Eigen::Index n_landmarks) {
  switch (k) {
    case MeasurementKind::Position:
    case MeasurementKind::SpeedHeading: return 2;
    case MeasurementKind::Range:
    case MeasurementKind::Bearing: return static_cast<int>(n_landmarks);
    case MeasurementKind::RangeBearing: return static_cast<int>(2 * n_landmarks);
  }
  return 0;
}
// Below this squared distance a landmark is "at" the vehicle: range and
// bearing Jacobians are undefined there.
constexpr double kMinDist2 = 1e-18;

[[noreturn]] void landmark_at_vehicle(int i, const State& x) {
  std::ostringstream os;
  os << "landmark " << i << " coincides with the vehicle position (" << x[kX] << ", " << x[kY]
     << "): range/bearing undefined";
  throw std::invalid_argument(os.str());
}
}  // namespace

MeasurementModel::MeasurementModel(MeasurementKind kind, GaussianNoise noise, Landmarks landmarks)
    : kind_(kind), noise_(std::move(noise)), landmarks_(std::move(landmarks)) {
  if (uses_landmarks(kind_)) {
    if (landmarks_.rows() == 0) {
      throw std::invalid_argument(std::string(to_string(kind_)) + " model needs at least one landmark");
    }
    for (Eigen::Index i = 0; i < landmarks_.rows(); ++i) {
      if (!landmarks_.row(i).allFinite()) {
        std::ostringstream os;
        os << "landmark " << i << " has non-finite position (" << landmarks_(i, 0) << ", " << landmarks_(i, 1)
           << ")";
        throw std::invalid_argument(os.str());
      }
    }
  } else {
    landmarks_.resize(0, 2);
  }
  dim_ = dim_of(kind_, landmarks_.rows());
  if (noise_.dim() != dim_) {
    std::ostringstream os;
    os << to_string(kind_) << " model has dimension " << dim_ << " but its noise covariance is "
       << noise_.dim() << "x" << noise_.dim();
    throw std::invalid_argument(os.str());
  }
}

MeasurementModel MeasurementModel::position(const Eigen::Matrix2d& R) {
  return MeasurementModel(MeasurementKind::Position, GaussianNoise(R, "position R"));
}
MeasurementModel MeasurementModel::speed_heading(const Eigen::Matrix2d& R) {
  return MeasurementModel(MeasurementKind::SpeedHeading, GaussianNoise(R, "speed_heading R"));
}
MeasurementModel MeasurementModel::range(const Landmarks& lm, double sigma) {
  return MeasurementModel(MeasurementKind::Range,
                          GaussianNoise::Sigmas(Eigen::VectorXd::Constant(lm.rows(), sigma), "range sigma"), lm);
}
MeasurementModel MeasurementModel::bearing(const Landmarks& lm, double sigma) {
  return MeasurementModel(MeasurementKind::Bearing,
                          GaussianNoise::Sigmas(Eigen::VectorXd::Constant(lm.rows(), sigma), "bearing sigma"), lm);
}
MeasurementModel MeasurementModel::range_bearing(const Landmarks& lm, double sr, double sb) {
  Eigen::VectorXd s(2 * lm.rows());
  for (Eigen::Index i = 0; i < lm.rows(); ++i) {
    s[2 * i] = sr;
    s[2 * i + 1] = sb;
  }
  return MeasurementModel(MeasurementKind::RangeBearing, GaussianNoise::Sigmas(s, "range_bearing sigma"), lm);
}

bool MeasurementModel::is_angle(int i) const {
  switch (kind_) {
    case MeasurementKind::Position:
    case MeasurementKind::Range: return false;
    case MeasurementKind::Bearing: return true;
    case MeasurementKind::RangeBearing: return (i % 2) == 1;
    case MeasurementKind::SpeedHeading: return i == 1;
  }
  return false;
}

void MeasurementModel::predict(const State& x, Eigen::Ref<Eigen::VectorXd> zhat) const {
  switch (kind_) {
    case MeasurementKind::Position:
      zhat[0] = x[kX];
      zhat[1] = x[kY];
      return;
    case MeasurementKind::SpeedHeading:
      zhat[0] = x[kV];
      zhat[1] = x[kTheta];
      return;
    default: break;
  }
  for (Eigen::Index i = 0; i < landmarks_.rows(); ++i) {
    const double dx = landmarks_(i, 0) - x[kX], dy = landmarks_(i, 1) - x[kY];
    const double q = dx * dx + dy * dy;
    if (q < kMinDist2) landmark_at_vehicle(static_cast<int>(i), x);
    const double r = std::sqrt(q);
    const double b = wrap_angle(std::atan2(dy, dx) - x[kTheta]);
    if (kind_ == MeasurementKind::Range) zhat[i] = r;
    else if (kind_ == MeasurementKind::Bearing) zhat[i] = b;
    else {
      zhat[2 * i] = r;
      zhat[2 * i + 1] = b;
    }
  }
}

Eigen::VectorXd MeasurementModel::predict(const State& x) const {
  Eigen::VectorXd z(dim_);
  predict(x, z);
  return z;
}

void MeasurementModel::jacobian(const State& x, Eigen::Ref<Eigen::MatrixXd> H) const {
  H.setZero();
  switch (kind_) {
    case MeasurementKind::Position:
      H(0, kX) = 1.0;
      H(1, kY) = 1.0;
      return;
    case MeasurementKind::SpeedHeading:
      H(0, kV) = 1.0;
      H(1, kTheta) = 1.0;
      return;
    default: break;
  }
  for (Eigen::Index i = 0; i < landmarks_.rows(); ++i) {
    const double dx = landmarks_(i, 0) - x[kX], dy = landmarks_(i, 1) - x[kY];
    const double q = dx * dx + dy * dy;
    if (q < kMinDist2) landmark_at_vehicle(static_cast<int>(i), x);
    const double r = std::sqrt(q);
    // ∂r/∂(x,y) = −(dx, dy)/r ; ∂b/∂(x,y) = (dy, −dx)/q ; ∂b/∂θ = −1
    Eigen::Index rr = -1, rb = -1;
    if (kind_ == MeasurementKind::Range) rr = i;
    else if (kind_ == MeasurementKind::Bearing) rb = i;
    else {
      rr = 2 * i;
      rb = 2 * i + 1;
    }
    if (rr >= 0) {
      H(rr, kX) = -dx / r;
      H(rr, kY) = -dy / r;
    }
    if (rb >= 0) {
      H(rb, kX) = dy / q;
      H(rb, kY) = -dx / q;
      H(rb, kTheta) = -1.0;
    }
  }
}

Eigen::MatrixXd MeasurementModel::jacobian(const State& x) const {
  Eigen::MatrixXd H(dim_, 4);
  jacobian(x, H);
  return H;
}

void MeasurementModel::residual(const Eigen::Ref<const Eigen::VectorXd>& z,
                                const Eigen::Ref<const Eigen::VectorXd>& zhat, Eigen::Ref<Eigen::VectorXd> y) const {
  for (int i = 0; i < dim_; ++i) y[i] = is_angle(i) ? wrap_angle(z[i] - zhat[i]) : z[i] - zhat[i];
}

void MeasurementModel::check(const Eigen::Ref<const Eigen::VectorXd>& z) const {
  if (z.size() != dim_) {
    std::ostringstream os;
    os << to_string(kind_) << " measurement must have " << dim_ << " entries, got " << z.size();
    throw std::invalid_argument(os.str());
  }
  for (int i = 0; i < dim_; ++i) {
    if (!std::isfinite(z[i])) {
      std::ostringstream os;
      os << to_string(kind_) << " measurement entry " << i << " = " << z[i] << " is not finite";
      throw std::invalid_argument(os.str());
    }
  }
}

MeasurementModel MeasurementModel::subset(const std::vector<int>& rows) const {
  if (!uses_landmarks(kind_)) return *this;
  const int per = kind_ == MeasurementKind::RangeBearing ? 2 : 1;
  Landmarks lm(static_cast<Eigen::Index>(rows.size()), 2);
  std::vector<int> idx;
  for (size_t j = 0; j < rows.size(); ++j) {
    if (rows[j] < 0 || rows[j] >= landmarks_.rows()) {
      throw std::invalid_argument("landmark subset index " + std::to_string(rows[j]) + " out of range");
    }
    lm.row(static_cast<Eigen::Index>(j)) = landmarks_.row(rows[j]);
    for (int c = 0; c < per; ++c) idx.push_back(per * rows[j] + c);
  }
  const Eigen::Index n = static_cast<Eigen::Index>(idx.size());
  Eigen::MatrixXd R(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b < n; ++b) R(a, b) = noise_.cov()(idx[a], idx[b]);
  return MeasurementModel(kind_, GaussianNoise(R, "subset R"), lm);
}

}  // namespace safenav
