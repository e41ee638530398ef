#include "safenav/measurement.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "filters/checks.hpp"

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

GaussianNoise::GaussianNoise(const Eigen::MatrixXd& R, const char* what) { add_block(R, what); }

void GaussianNoise::add_block(const Eigen::MatrixXd& R, const char* what) {
  std::ostringstream os;
  if (R.rows() != R.cols() || R.rows() == 0) {
    os << what << " must be a non-empty square matrix, got " << R.rows() << "x" << R.cols();
    throw std::invalid_argument(os.str());
  }
  for (Eigen::Index j = 0; j < R.cols(); ++j)
    for (Eigen::Index i = 0; i < R.rows(); ++i)
      if (!std::isfinite(R(i, j))) {
        os << what << "[" << dim_ + i << ", " << dim_ + j << "] = " << R(i, j) << " is not finite";
        throw std::invalid_argument(os.str());
      }
  if (!symmetric_to_rounding(R)) {
    Eigen::Index i, j;
    (R - R.transpose()).cwiseAbs().maxCoeff(&i, &j);
    os << what << " is not symmetric: [" << dim_ + i << ", " << dim_ + j << "] = " << R(i, j) << " but ["
       << dim_ + j << ", " << dim_ + i << "] = " << R(j, i);
    throw std::invalid_argument(os.str());
  }
  Eigen::LLT<Eigen::MatrixXd> llt(R);
  if (llt.info() != Eigen::Success) {
    os << what << " (" << R.rows() << "x" << R.cols() << " block at row " << dim_ << ") is not positive definite";
    throw std::invalid_argument(os.str());
  }
  blocks_.push_back(Block{dim_, R, Eigen::MatrixXd(llt.matrixL())});
  dim_ += static_cast<int>(R.rows());
}

GaussianNoise GaussianNoise::Sigmas(const Eigen::VectorXd& sigmas, const char* what) {
  GaussianNoise out;
  out.blocks_.reserve(static_cast<size_t>(sigmas.size()));
  for (Eigen::Index i = 0; i < sigmas.size(); ++i) {
    const double s = sigmas[i], s2 = s * s;
    if (!(std::isfinite(s2) && s > 0.0 && s2 > 0.0)) {
      std::ostringstream os;
      os << what << "[" << i << "] = " << s << " must be > 0 with a finite, non-zero square";
      throw std::invalid_argument(os.str());
    }
    out.blocks_.push_back(Block{out.dim_++, Eigen::MatrixXd::Constant(1, 1, s2), Eigen::MatrixXd::Constant(1, 1, s)});
  }
  if (out.dim_ == 0) throw std::invalid_argument(std::string(what) + " must not be empty");
  return out;
}

Eigen::MatrixXd GaussianNoise::cov() const {
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(dim_, dim_);
  for (const Block& b : blocks_) R.block(b.start, b.start, b.R.rows(), b.R.cols()) = b.R;
  return R;
}

double GaussianNoise::mahalanobis2(const Eigen::Ref<const Eigen::VectorXd>& y) const {
  Eigen::MatrixXd w = y;
  whiten(w);
  return w.squaredNorm();
}

void GaussianNoise::whiten(Eigen::Ref<Eigen::MatrixXd> Y) const {
  for (const Block& b : blocks_)
    b.L.triangularView<Eigen::Lower>().solveInPlace(Y.middleRows(b.start, b.L.rows()));
}

size_t GaussianNoise::block_of(int row) const {
  const auto it = std::upper_bound(blocks_.begin(), blocks_.end(), row,
                                   [](int r, const Block& b) { return r < b.start; });
  return static_cast<size_t>(it - blocks_.begin()) - 1;
}

GaussianNoise GaussianNoise::subset(const std::vector<int>& rows) const {
  GaussianNoise out;
  std::vector<bool> used(blocks_.size(), false);
  for (size_t a = 0; a < rows.size();) {
    const size_t k = block_of(rows[a]);
    size_t b = a + 1;
    while (b < rows.size() && block_of(rows[b]) == k) ++b;
    if (used[k]) {
      throw std::invalid_argument("noise subset: rows of the correlated block at row " +
                                  std::to_string(blocks_[k].start) + " are not consecutive");
    }
    used[k] = true;
    const Block& B = blocks_[k];
    const Eigen::Index n = static_cast<Eigen::Index>(b - a);
    Eigen::MatrixXd R(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j < n; ++j) R(i, j) = B.R(rows[a + i] - B.start, rows[a + j] - B.start);
    out.add_block(R, "subset R");
    a = b;
  }
  return out;
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
[[noreturn]] void landmark_at_vehicle(int i, const State& x) {
  std::ostringstream os;
  os << "landmark " << i << " coincides with the vehicle position (" << x[kX] << ", " << x[kY]
     << "): range/bearing undefined";
  throw std::invalid_argument(os.str());
}

/// Landmark i seen from the vehicle (landmark_geometry), checked: finite and not at the vehicle.
LandmarkGeometry offset(const Landmarks& lm, Eigen::Index i, const State& x) {
  const LandmarkGeometry g = landmark_geometry(x[kX], x[kY], lm(i, 0), lm(i, 1));
  if (!g.finite()) {
    std::ostringstream os;
    os << "landmark " << i << " at (" << lm(i, 0) << ", " << lm(i, 1) << ") is farther than 1.8e308 from the vehicle ("
       << x[kX] << ", " << x[kY] << ")";
    throw std::invalid_argument(os.str());
  }
  if (!g.defined()) landmark_at_vehicle(static_cast<int>(i), x);
  return g;
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

namespace {
/// Whether row i of a kind's z is an angle (its residual wrapped).
bool angle_row(MeasurementKind kind, int i) {
  switch (kind) {
    case MeasurementKind::Position:
    case MeasurementKind::Range: return false;
    case MeasurementKind::Bearing: return true;
    case MeasurementKind::RangeBearing: return (i % 2) == 1;
    case MeasurementKind::SpeedHeading: return i == 1;
  }
  return false;
}
}  // namespace

bool MeasurementModel::is_angle(int i) const { return angle_row(kind_, i); }

namespace {
// The measurement functions (position and speed/heading share one), in
// GTSAM's form (a factor's evaluateError with an optional Jacobian): each
// writes h(x) into its rows of zhat and, when H is given, ∂h/∂x into the same
// rows of *H, whose other entries stay zero.
using Jacobian = Eigen::Ref<Eigen::MatrixXd>;

/// The components that a direct kind observes; false for a landmark kind.
bool direct(MeasurementKind kind, StateIndex& i, StateIndex& j) {
  switch (kind) {
    case MeasurementKind::Position: i = kX, j = kY; return true;
    case MeasurementKind::SpeedHeading: i = kV, j = kTheta; return true;
    default: return false;
  }
}

/// Two state components observed directly: h(x) = (x_i, x_j), H = rows i and
/// j of I₄.  Position is (x, y), speed and heading (v, θ): direct().
void components(const State& x, StateIndex i, StateIndex j, Eigen::Ref<Eigen::VectorXd> zhat, Jacobian* H) {
  zhat[0] = x[i];
  zhat[1] = x[j];
  if (H) {
    (*H)(0, i) = 1.0;
    (*H)(1, j) = 1.0;
  }
}

/// Range to a landmark (predict_range with k = b = 0) in row `row`.
void range(const LandmarkGeometry& g, Eigen::Index row, Eigen::Ref<Eigen::VectorXd> zhat, Jacobian* H) {
  LandmarkJacobian J;
  zhat[row] = predict_range(g, 0.0, 0.0, H ? &J : nullptr);
  if (H) {
    (*H)(row, kX) = J.x;
    (*H)(row, kY) = J.y;
  }
}

/// Relative bearing to a landmark (predict_bearing), wrapped to (−π, π], in row `row`.
void bearing(const LandmarkGeometry& g, const State& x, Eigen::Index row, Eigen::Ref<Eigen::VectorXd> zhat,
             Jacobian* H) {
  LandmarkJacobian J;
  zhat[row] = wrap_angle(predict_bearing(g, x[kTheta], H ? &J : nullptr));
  if (H) {
    (*H)(row, kX) = J.x;
    (*H)(row, kY) = J.y;
    (*H)(row, kTheta) = J.theta;
  }
}

/// h(x) and, when H is given, ∂h/∂x of a model of this kind.
void evaluate(MeasurementKind kind, const Landmarks& lm, const State& x, Eigen::Ref<Eigen::VectorXd> zhat,
              Jacobian* H) {
  if (H) H->setZero();
  const Eigen::Index n = lm.rows();
  switch (kind) {
    case MeasurementKind::Position:
    case MeasurementKind::SpeedHeading: {
      StateIndex i, j;
      direct(kind, i, j);
      return components(x, i, j, zhat, H);
    }
    case MeasurementKind::Range:
      for (Eigen::Index i = 0; i < n; ++i) range(offset(lm, i, x), i, zhat, H);
      return;
    case MeasurementKind::Bearing:
      for (Eigen::Index i = 0; i < n; ++i) bearing(offset(lm, i, x), x, i, zhat, H);
      return;
    case MeasurementKind::RangeBearing:
      for (Eigen::Index i = 0; i < n; ++i) {
        const LandmarkGeometry g = offset(lm, i, x);
        range(g, 2 * i, zhat, H);
        bearing(g, x, 2 * i + 1, zhat, H);
      }
      return;
  }
}
}  // namespace

void MeasurementModel::predict(const State& x, Eigen::Ref<Eigen::VectorXd> zhat) const {
  evaluate(kind_, landmarks_, x, zhat, nullptr);
}

void MeasurementModel::predict(const State& x, Eigen::Ref<Eigen::VectorXd> zhat, Eigen::Ref<Eigen::MatrixXd> H) const {
  evaluate(kind_, landmarks_, x, zhat, &H);
}

Eigen::VectorXd MeasurementModel::predict(const State& x) const {
  Eigen::VectorXd z(dim_);
  predict(x, z);
  return z;
}

void MeasurementModel::jacobian(const State& x, Eigen::Ref<Eigen::MatrixXd> H) const {
  Eigen::VectorXd zhat(dim_);
  evaluate(kind_, landmarks_, x, zhat, &H);
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

void MeasurementModel::direct_residuals(MeasurementKind kind, const Eigen::Ref<const Eigen::VectorXd>& z,
                                        const StatesView& states, Eigen::Ref<Eigen::MatrixXd> Y) {
  StateIndex a, b;
  if (!direct(kind, a, b))
    throw std::invalid_argument(std::string("direct_residuals: a ") + to_string(kind) + " model needs its landmarks");
  const Eigen::Index n = states.cols();
  if (z.size() != 2 || Y.rows() != 2 || Y.cols() != n)
    throw std::invalid_argument("direct_residuals: z must have 2 entries and Y be 2 x " + std::to_string(n));
  // residual(z, components(x)) for each state
  if (angle_row(kind, 1)) {
    for (Eigen::Index i = 0; i < n; ++i) {
      Y(0, i) = z[0] - states(a, i);
      Y(1, i) = wrap_angle(z[1] - states(b, i));
    }
  } else {
    for (Eigen::Index i = 0; i < n; ++i) {
      Y(0, i) = z[0] - states(a, i);
      Y(1, i) = z[1] - states(b, i);
    }
  }
}

Eigen::Vector2d MeasurementModel::direct_residual(MeasurementKind kind, const Eigen::Vector2d& z, const State& x) {
  Eigen::Vector2d y;
  direct_residuals(kind, z, StatesView(x.data(), 4, 1, Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>(4, 1)), y);
  return y;
}

void MeasurementModel::residuals(const Eigen::Ref<const Eigen::VectorXd>& z, const StatesView& states,
                                 Eigen::Ref<Eigen::MatrixXd> Y) const {
  StateIndex a, b;
  if (direct(kind_, a, b)) return direct_residuals(kind_, z, states, Y);
  const Eigen::Index n = states.cols();
  if (Y.rows() != dim_ || Y.cols() != n)
    throw std::invalid_argument("residuals: Y must be " + std::to_string(dim_) + " x " + std::to_string(n));
  Eigen::VectorXd zhat(dim_), y(dim_);
  for (Eigen::Index i = 0; i < n; ++i) {
    predict(State(states.col(i)), zhat);
    residual(z, zhat, y);
    Y.col(i) = y;
  }
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
  return MeasurementModel(kind_, noise_.subset(idx), lm);
}

}  // namespace safenav
