#include "safenav/filters.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <boost/math/distributions/chi_squared.hpp>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <new>
#include <sstream>
#include <stdexcept>

#include "rng.hpp"

namespace safenav {

// --------------------------------------------------------------------------
// helpers
// --------------------------------------------------------------------------

void check_covariance(const Eigen::MatrixXd& P, const char* what) {
  std::ostringstream os;
  if (P.rows() != P.cols()) {
    os << what << " must be square, got " << P.rows() << "x" << P.cols();
    throw std::invalid_argument(os.str());
  }
  if (!P.allFinite()) {
    os << what << " has non-finite entries:\n" << P;
    throw std::invalid_argument(os.str());
  }
  const double scale = std::max(1e-300, P.cwiseAbs().maxCoeff());
  if ((P - P.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    os << what << " is not symmetric:\n" << P;
    throw std::invalid_argument(os.str());
  }
  Eigen::LLT<Eigen::MatrixXd> llt(P);
  if (llt.info() != Eigen::Success) {
    os << what << " is not positive definite:\n" << P;
    throw std::invalid_argument(os.str());
  }
}

double chi2_quantile(double probability, int dof) {
  if (!(probability > 0.0 && probability < 1.0)) {
    std::ostringstream os;
    os << "chi-square probability = " << probability << " must be in (0, 1)";
    throw std::invalid_argument(os.str());
  }
  if (dof < 1) throw std::invalid_argument("chi-square degrees of freedom must be >= 1, got " + std::to_string(dof));
  return boost::math::quantile(boost::math::chi_squared(dof), probability);
}

namespace {
void check_gate(double p) {
  if (!(std::isfinite(p) && p >= 0.0 && p < 1.0)) {
    std::ostringstream os;
    os << "gate probability = " << p << " must be in [0, 1) (0 disables the gate)";
    throw std::invalid_argument(os.str());
  }
}
/// Throws when the NIS yᵀS⁻¹y of an update overflows (a measurement ~1e308 from
/// the prediction): called before any state changes.
void check_nis(double nis, const char* filter, MeasurementKind kind) {
  if (std::isfinite(nis)) return;
  std::ostringstream os;
  os << filter << " " << to_string(kind) << " update: NIS = " << nis
     << " is not finite (the measurement is too far from the prediction for its covariance)";
  throw std::invalid_argument(os.str());
}
void check_prior(const State& x0, const StateCov& P0, const char* xname = "x0", const char* pname = "P0") {
  check_finite_state(x0, xname);
  check_covariance(P0, pname);
}
}  // namespace

// --------------------------------------------------------------------------
// EKF
// --------------------------------------------------------------------------

Ekf::Ekf(const BmmParams& params, const State& x0, const StateCov& P0) : bmm_(params) {
  check_prior(x0, P0);
  x_ = x0;
  x_[kTheta] = wrap_angle(x_[kTheta]);
  P_ = P0;
}

void Ekf::set_state(const State& x, const StateCov& P) {
  check_prior(x, P, "x", "P");
  x_ = x;
  x_[kTheta] = wrap_angle(x_[kTheta]);
  P_ = P;
}

void Ekf::set_gate(double probability) {
  check_gate(probability);
  gate_probability_ = probability;
  gate_thresholds_.clear();
}

bool Ekf::gate_rejects(double nis, int dim) {
  if (gate_probability_ <= 0.0) return false;
  if (static_cast<int>(gate_thresholds_.size()) <= dim) gate_thresholds_.resize(dim + 1, -1.0);
  double& t = gate_thresholds_[dim];
  if (t < 0.0) t = chi2_quantile(gate_probability_, dim);
  return nis > t;
}

void Ekf::predict(const Control& u) {
  // Eq. 11: x̂ = f(x̂, u); P = F P Fᵀ + G Σ_ε Gᵀ.
  Eigen::Matrix4d F, G;
  const State x1 = bmm_.linearize(x_, u, &F, &G);
  const Eigen::Vector4d sigma2 = bmm_.noise_cov().diagonal();
  Eigen::Matrix4d P1 = F * P_ * F.transpose() + G * sigma2.asDiagonal() * G.transpose();
  P1 = 0.5 * (P1 + P1.transpose());
  commit(x1, P1, "EKF predict");
}

void Ekf::commit(const State& x, const StateCov& P, const char* step) {
  // Finite inputs can still overflow (P = 1e308·I, say): refuse the step and keep the old state.
  if (!P.allFinite() || !x.allFinite()) {
    std::ostringstream os;
    os << "P = " << P_(0, 0) << ", " << P_(1, 1) << ", " << P_(2, 2) << ", " << P_(3, 3) << " (diagonal)";
    check_finite_result(x, (std::string(step) + " x").c_str(), os.str());
    check_finite_result(P, (std::string(step) + " P").c_str(), os.str());
  }
  x_ = x;
  P_ = P;
}

template <int M>
UpdateResult Ekf::update_fixed(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  using VecM = Eigen::Matrix<double, M, 1>;
  using MatM4 = Eigen::Matrix<double, M, 4>;
  using MatMM = Eigen::Matrix<double, M, M>;
  const int m = model.dim();
  VecM zhat(m), y(m);
  MatM4 H(m, 4);
  model.predict(x_, zhat);
  model.jacobian(x_, H);
  model.residual(z, zhat, y);  // eq. 12, angle-aware
  const MatMM R = model.noise().cov();
  const Eigen::Matrix<double, 4, M> PHt = P_ * H.transpose();
  const MatMM S = H * PHt + R;  // eq. 12
  const Eigen::LLT<MatMM> llt(S);
  if (llt.info() != Eigen::Success) {
    throw std::runtime_error(std::string("EKF ") + to_string(model.kind()) +
                             " update: innovation covariance S is not positive definite");
  }
  UpdateResult res;
  res.dim = m;
  res.nis = y.dot(llt.solve(y));
  check_nis(res.nis, "EKF", model.kind());
  if (gate_rejects(res.nis, m)) {
    res.accepted = false;
    return res;
  }
  const Eigen::Matrix<double, 4, M> K = llt.solve(PHt.transpose()).transpose();  // eq. 13
  State x1 = x_ + K * y;                                                          // eq. 14
  x1[kTheta] = wrap_angle(x1[kTheta]);
  const Eigen::Matrix4d IKH = Eigen::Matrix4d::Identity() - K * H;
  Eigen::Matrix4d P1 = IKH * P_ * IKH.transpose() + K * R * K.transpose();  // Joseph form of eq. 14
  commit(x1, 0.5 * (P1 + P1.transpose()), "EKF update");
  return res;
}

UpdateResult Ekf::update_position(const Eigen::Ref<const Eigen::VectorXd>& z, const Eigen::Matrix2d& R) {
  // Eqs. 12–14 with H = [I₂ 0] written out: P Hᵀ = P[:, :2], H P Hᵀ = P[:2, :2].
  // Same arithmetic as update_fixed<2>, without the products by zeros.
  const Eigen::Vector2d y(z[0] - x_[kX], z[1] - x_[kY]);
  const Eigen::Matrix<double, 4, 2> PHt = P_.leftCols<2>();
  const Eigen::Matrix2d S = P_.topLeftCorner<2, 2>() + R;
  const Eigen::LLT<Eigen::Matrix2d> llt(S);
  if (llt.info() != Eigen::Success) {
    throw std::runtime_error("EKF position update: innovation covariance S is not positive definite");
  }
  UpdateResult res;
  res.dim = 2;
  res.nis = y.dot(llt.solve(y));
  check_nis(res.nis, "EKF", MeasurementKind::Position);
  if (gate_rejects(res.nis, 2)) {
    res.accepted = false;
    return res;
  }
  const Eigen::Matrix<double, 4, 2> K = llt.solve(PHt.transpose()).transpose();
  State x1 = x_ + K * y;
  x1[kTheta] = wrap_angle(x1[kTheta]);
  // Joseph form: A = (I − KH) P = P − K P[:2, :]; P = A (I − KH)ᵀ + K R Kᵀ = A − A[:, :2] Kᵀ + K R Kᵀ.
  const Eigen::Matrix4d A = P_ - K * P_.topRows<2>();
  const Eigen::Matrix4d P1 = A - A.leftCols<2>() * K.transpose() + K * R * K.transpose();
  commit(x1, 0.5 * (P1 + P1.transpose()), "EKF position update");
  return res;
}

UpdateResult Ekf::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  model.check(z);
  if (model.kind() == MeasurementKind::Position) return update_position(z, model.noise().cov());
  switch (model.dim()) {
    case 1: return update_fixed<1>(model, z);
    case 2: return update_fixed<2>(model, z);
    default: return update_fixed<Eigen::Dynamic>(model, z);
  }
}

// --------------------------------------------------------------------------
// Particle filter
// --------------------------------------------------------------------------
//
// Layout: structure of arrays, one contiguous column per component (x, y, v,
// θ, and cos θ, sin θ kept in step with θ), log-weights and weights in their
// own arrays.  Each per-particle pass below is a branch-free loop over those
// arrays (an always_inline "kernel") that detail::dispatch runs from a copy
// compiled for AVX2 where the CPU has it, and from the baseline x86-64 copy
// elsewhere.  Sums over particles accumulate in four lanes written out in the
// source (D4), so the result, to the last bit, does not depend on which copy
// ran.  No step allocates.

namespace {

/// Taylor coefficients as constants (the core's -frounding-math, from CGAL,
/// stops the compiler folding 1.0/k! itself): 1/k! for exp, and
/// (−1)^k/(2k+1)!, (−1)^k/(2k)! for sin and cos in powers of x².
struct Coefficients {
  double v[14];
  constexpr Coefficients(int first, int step, bool alternate) : v() {
    for (int k = 0; k < 14; ++k) {
      double f = 1.0;
      for (int j = 2; j <= first + step * k; ++j) f *= j;  // exact up to 18! (< 2⁵³); 13! is the most used
      v[k] = (alternate && k % 2 ? -1.0 : 1.0) / f;
    }
  }
  constexpr double operator[](int k) const { return v[k]; }
};
constexpr Coefficients kInvFactorial(0, 1, false), kSin(1, 2, true), kCos(0, 2, true);

/// Four doubles (particles i..i+3) as one 32-byte vector (Bytes = 32, AVX2)
/// or two 16-byte ones (Bytes = 16, SSE2): the same lanes and the same IEEE
/// operations either way.  Sums over particles accumulate in a D4 (lane j
/// takes particles j, j+4, ...) and end in sum(), a fixed order, so reductions
/// give identical bits on both paths.  (Arguments by reference: a 32-byte
/// vector by value has a different ABI without AVX, which GCC remarks on.)
template <int Bytes>
struct D4;
template <>
struct D4<32> {
  typedef double V __attribute__((vector_size(32)));
  V v;
  static D4 load(const double* p) { D4 r; std::memcpy(&r.v, p, 32); return r; }
  static D4 splat(double a) { return {V{a, a, a, a}}; }
  void store(double* p) const { std::memcpy(p, &v, 32); }
  friend D4 operator+(const D4& a, const D4& b) { return {a.v + b.v}; }
  friend D4 operator-(const D4& a, const D4& b) { return {a.v - b.v}; }
  friend D4 operator*(const D4& a, const D4& b) { return {a.v * b.v}; }
  D4& operator+=(const D4& b) { v += b.v; return *this; }
  /// a > b ? a + c : a  (and a <= b ? a + c : a), lane-wise
  static D4 add_if_gt(const D4& a, const D4& b, const D4& c) { return {a.v > b.v ? a.v + c.v : a.v}; }
  static D4 add_if_le(const D4& a, const D4& b, const D4& c) { return {a.v <= b.v ? a.v + c.v : a.v}; }
  double sum() const { return (v[0] + v[1]) + (v[2] + v[3]); }
};
template <>
struct D4<16> {
  typedef double V __attribute__((vector_size(16)));
  V lo, hi;
  static D4 load(const double* p) { D4 r; std::memcpy(&r.lo, p, 16); std::memcpy(&r.hi, p + 2, 16); return r; }
  static D4 splat(double a) { return {V{a, a}, V{a, a}}; }
  void store(double* p) const { std::memcpy(p, &lo, 16); std::memcpy(p + 2, &hi, 16); }
  friend D4 operator+(D4 a, D4 b) { return {a.lo + b.lo, a.hi + b.hi}; }
  friend D4 operator-(D4 a, D4 b) { return {a.lo - b.lo, a.hi - b.hi}; }
  friend D4 operator*(D4 a, D4 b) { return {a.lo * b.lo, a.hi * b.hi}; }
  D4& operator+=(D4 b) { lo += b.lo; hi += b.hi; return *this; }
  static D4 add_if_gt(D4 a, D4 b, D4 c) {
    return {a.lo > b.lo ? a.lo + c.lo : a.lo, a.hi > b.hi ? a.hi + c.hi : a.hi};
  }
  static D4 add_if_le(D4 a, D4 b, D4 c) {
    return {a.lo <= b.lo ? a.lo + c.lo : a.lo, a.hi <= b.hi ? a.hi + c.hi : a.hi};
  }
  double sum() const { return (lo[0] + lo[1]) + (hi[0] + hi[1]); }
};

/// Run body(i, in, n) over the particles in blocks of four: in[c] holds
/// column c of particles i..i+3, n how many of them are real.  The last,
/// partial block is zero-padded, so a weight column is 0 beyond N and the
/// padding adds exactly nothing to any weighted sum (the body stores only n
/// lanes).
template <int Bytes, int K, class Body>
SAFENAV_ALWAYS_INLINE void blocks_of_four(int N, const double* const (&cols)[K], Body&& body) {
  using D = D4<Bytes>;
  int i = 0;
  for (; i + 4 <= N; i += 4) {
    D in[K];
    for (int c = 0; c < K; ++c) in[c] = D::load(cols[c] + i);
    body(i, in, 4);
  }
  if (i < N) {
    double pad[K][4] = {};
    for (int c = 0; c < K; ++c)
      for (int j = 0; i + j < N; ++j) pad[c][j] = cols[c][i + j];
    D in[K];
    for (int c = 0; c < K; ++c) in[c] = D::load(pad[c]);
    body(i, in, N - i);
  }
}

/// Store the first n lanes of a D4 at p.
template <int Bytes>
SAFENAV_ALWAYS_INLINE void store_lanes(const D4<Bytes>& a, double* p, int n) {
  if (n == 4) {
    a.store(p);
  } else {
    double tmp[4];
    a.store(tmp);
    for (int j = 0; j < n; ++j) p[j] = tmp[j];
  }
}

/// One noisy BMM step (eqs. 3, 4, 6, 7/9, as Bmm::transition) for every
/// particle.  θ moves by δ_i; (cos θ, sin θ) is rotated by δ_i with sin δ and
/// cos δ from their Taylor series (truncation error < 1e-17 for |δ| ≤
/// kSmallTurn, rounding within 1.5 eps; larger turns are redone exactly by
/// the caller, which is told how many there were).  Element-wise, so left to the auto-vectoriser;
/// it needs -fno-trapping-math to if-convert the clamps.  (Kernels take their
/// arrays as __restrict parameters: GCC honours restrict there, through
/// inlining, and not on local copies.)
struct StepParams {
  double vdes, heading_step, up_step, down_step, vmax, k, sv, st, sp;
};
constexpr double kSmallTurn = 0.25;
SAFENAV_ALWAYS_INLINE long particles_step(int N, double* __restrict x, double* __restrict y, double* __restrict v,
                                          double* __restrict th, double* __restrict cs, double* __restrict sn,
                                          const double* __restrict ex, const double* __restrict ey,
                                          const double* __restrict ev, const double* __restrict et,
                                          const StepParams* a) {
  constexpr double two_pi = 2.0 * kPi;
  const double vdes = a->vdes, heading_step = a->heading_step, up_step = a->up_step, down_step = a->down_step,
               vmax = a->vmax, k = a->k, sv = a->sv, st = a->st, sp = a->sp;
  long n_big = 0;  // turns with |δ| > kSmallTurn (64-bit, like the doubles, so that the loop vectorises)
  for (int i = 0; i < N; ++i) {
    // eq. 3 (Bmm::next_speed) + ε_v, clamped to [0, v_max]
    const double vi = v[i];
    double up = vi + up_step;
    up = up < vdes ? up : vdes;
    up = up < vmax ? up : vmax;
    double down = vi - down_step;
    down = down > vdes ? down : vdes;
    down = down > 0.0 ? down : 0.0;
    down = down < vmax ? down : vmax;
    double v1 = (vdes > vi ? up : down) + sv * ev[i];
    v1 = v1 > 0.0 ? v1 : 0.0;
    v1 = v1 < vmax ? v1 : vmax;
    v[i] = v1;
    // eq. 4 + ε_θ: θ moves by δ; rotate (cos θ, sin θ) by δ.
    const double d = heading_step + st * et[i];
    n_big += (d > kSmallTurn) | (d < -kSmallTurn);
    // sin δ = δ Σ_k s_k u^k, cos δ = Σ_k c_k u^k (u = δ²) in Estrin's form: a
    // short dependency chain, which is what bounds this loop
    const double u = d * d, u2 = u * u, u4 = u2 * u2;
    const double sd = d * (((1 + kSin[1] * u) + (kSin[2] + kSin[3] * u) * u2) + (kSin[4] + kSin[5] * u) * u4);
    const double cd =
        ((1 + kCos[1] * u) + (kCos[2] + kCos[3] * u) * u2) + ((kCos[4] + kCos[5] * u) + kCos[6] * u2) * u4;
    const double c1 = cs[i] * cd - sn[i] * sd;
    const double s1 = sn[i] * cd + cs[i] * sd;
    const double r = 1.5 - 0.5 * (c1 * c1 + s1 * s1);  // keep (c, s) on the unit circle
    const double c2 = c1 * r, s2 = s1 * r;
    cs[i] = c2;
    sn[i] = s2;
    double t = th[i] + d;  // wrap to (−π, π]; exact for |δ| < π
    t = t > kPi ? t - two_pi : t;
    t = t <= -kPi ? t + two_pi : t;
    th[i] = t;
    // eq. 7/9 + (ε_x, ε_y): position moves with the updated v and θ
    x[i] += k * v1 * c2 + sp * ex[i];
    y[i] += k * v1 * s2 + sp * ey[i];
  }
  return n_big;
}

/// Position update: logw_i −= ½ d_iᵀ R⁻¹ d_i with d_i = z − (x_i, y_i), and
/// the prior-weighted moments of d for the NIS: (Σw d0, Σw d1, Σw d0²,
/// Σw d0 d1, Σw d1²).
struct PositionParams {
  double z0, z1, r00, r01, r11;  // r = ½ R⁻¹ (r01 doubled: the cross term appears twice)
};
struct Sums5 {
  double s[5];
};
template <int Bytes>
SAFENAV_ALWAYS_INLINE Sums5 position_loglik(int N, const double* __restrict x, const double* __restrict y,
                                            const double* __restrict w, double* __restrict logw,
                                            const PositionParams* a) {
  using D = D4<Bytes>;
  const D z0 = D::splat(a->z0), z1 = D::splat(a->z1), r00 = D::splat(a->r00), r01 = D::splat(a->r01),
          r11 = D::splat(a->r11);
  D s0 = D::splat(0), s1 = s0, s00 = s0, s01 = s0, s11 = s0;
  const double* const cols[4] = {x, y, w, logw};
  blocks_of_four<Bytes>(N, cols, [&](int i, const D* in, int n) __attribute__((always_inline)) {
    const D d0 = z0 - in[0], d1 = z1 - in[1];
    const D w0 = in[2] * d0, w1 = in[2] * d1;
    s0 += w0;
    s1 += w1;
    s00 += w0 * d0;
    s01 += w0 * d1;
    s11 += w1 * d1;
    store_lanes(in[3] - (r00 * d0 * d0 + r01 * d0 * d1 + r11 * d1 * d1), logw + i, n);
  });
  return {{s0.sum(), s1.sum(), s00.sum(), s01.sum(), s11.sum()}};
}

/// exp(x) for x in [−700, 0], within 2 ulp (exp(0) = 1 exactly), in plain
/// arithmetic that vectorises: x = n·ln2 + r with |r| ≤ ½ln2, exp(r) by its
/// Taylor series to r¹³ (remainder < 5e-18), 2ⁿ put into the exponent bits.
SAFENAV_ALWAYS_INLINE double exp_nonpositive(double x) {
  constexpr double kInvLn2 = 1.4426950408889634, kLn2Hi = 0x1.62e42fee00000p-1, kLn2Lo = 0x1.a39ef35793c76p-33;
  constexpr double kShift = 0x1.8p52;  // adding it rounds to an integer held in the low mantissa bits
  const double kd = x * kInvLn2 + kShift;
  const double n = kd - kShift;
  const double r = (x - n * kLn2Hi) - n * kLn2Lo;  // n·kLn2Hi is exact
  // Estrin's scheme: a short dependency chain (Horner's 13 steps made this
  // loop latency-bound)
  const auto& c = kInvFactorial;
  const double r2 = r * r, r4 = r2 * r2, r8 = r4 * r4;
  const double q0 = c[0] + c[1] * r, q1 = c[2] + c[3] * r, q2 = c[4] + c[5] * r, q3 = c[6] + c[7] * r,
               q4 = c[8] + c[9] * r, q5 = c[10] + c[11] * r, q6 = c[12] + c[13] * r;
  const double p = ((q0 + q1 * r2) + (q2 + q3 * r2) * r4) + ((q4 + q5 * r2) + q6 * r4) * r8;
  std::uint64_t bits;
  std::memcpy(&bits, &kd, sizeof bits);
  bits = (bits << 52) + (std::uint64_t{1023} << 52);  // 2ⁿ: n sits in the low bits of kd, n ≥ −1022
  double scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

/// Normalisation, first pass (element-wise): floor the log-weights at
/// mx + floor and set w_i = exp(logw_i − mx).
SAFENAV_ALWAYS_INLINE void exp_weights(int N, double* __restrict logw, double* __restrict w, double mx, double floor) {
  const double lo = mx + floor;
  for (int i = 0; i < N; ++i) {
    double l = logw[i];
    l = l > lo ? l : lo;
    logw[i] = l;
    w[i] = exp_nonpositive(l - mx);
  }
}

/// Σ w_i.
template <int Bytes>
SAFENAV_ALWAYS_INLINE double sum_weights(int N, const double* __restrict w) {
  using D = D4<Bytes>;
  D s = D::splat(0);
  const double* const cols[1] = {w};
  blocks_of_four<Bytes>(N, cols, [&](int, const D* in, int) __attribute__((always_inline)) { s += in[0]; });
  return s.sum();
}

/// Normalisation, second pass: w_i ·= 1/Σw, logw_i −= log Σ (the
/// log-sum-exp); returns Σ w_i² (for the ESS).
template <int Bytes>
SAFENAV_ALWAYS_INLINE double scale_weights(int N, double* __restrict logw, double* __restrict w, double inv,
                                           double lse) {
  using D = D4<Bytes>;
  const D dinv = D::splat(inv), dlse = D::splat(lse);
  D s = D::splat(0);
  const double* const cols[2] = {w, logw};
  blocks_of_four<Bytes>(N, cols, [&](int i, const D* in, int n) __attribute__((always_inline)) {
    const D wi = in[0] * dinv;  // zero in padding lanes
    s += wi * wi;
    store_lanes(wi, w + i, n);
    store_lanes(in[1] - dlse, logw + i, n);
  });
  return s.sum();
}

/// Weighted sums for the mean: Σw x, Σw y, Σw v, Σw cos θ, Σw sin θ.
template <int Bytes>
SAFENAV_ALWAYS_INLINE Sums5 mean_sums(int N, const double* __restrict x, const double* __restrict y,
                                      const double* __restrict v, const double* __restrict cs,
                                      const double* __restrict sn, const double* __restrict w) {
  using D = D4<Bytes>;
  D s0 = D::splat(0), s1 = s0, s2 = s0, s3 = s0, s4 = s0;
  const double* const cols[6] = {x, y, v, cs, sn, w};
  blocks_of_four<Bytes>(N, cols, [&](int, const D* in, int) __attribute__((always_inline)) {
    const D wi = in[5];
    s0 += wi * in[0];
    s1 += wi * in[1];
    s2 += wi * in[2];
    s3 += wi * in[3];
    s4 += wi * in[4];
  });
  return {{s0.sum(), s1.sum(), s2.sum(), s3.sum(), s4.sum()}};
}

/// Weighted second moments Σ w_i d_i d_iᵀ about m, θ deviations wrapped (θ_i
/// and m[3] are both in (−π, π]: one wrap suffices); the upper triangle, row
/// by row.
struct Sums10 {
  double s[10];
};
template <int Bytes>
SAFENAV_ALWAYS_INLINE Sums10 covariance_sums(int N, const double* __restrict x, const double* __restrict y,
                                             const double* __restrict v, const double* __restrict th,
                                             const double* __restrict w, const State* m) {
  using D = D4<Bytes>;
  const D m0 = D::splat((*m)[0]), m1 = D::splat((*m)[1]), m2 = D::splat((*m)[2]), m3 = D::splat((*m)[3]);
  const D pi = D::splat(kPi), minus_pi = D::splat(-kPi), two_pi = D::splat(2.0 * kPi),
          minus_two_pi = D::splat(-2.0 * kPi);
  D a0 = D::splat(0), a1 = a0, a2 = a0, a3 = a0, a4 = a0, a5 = a0, a6 = a0, a7 = a0, a8 = a0, a9 = a0;
  const double* const cols[5] = {x, y, v, th, w};
  blocks_of_four<Bytes>(N, cols, [&](int, const D* in, int) __attribute__((always_inline)) {
    D d3 = in[3] - m3;
    d3 = D::add_if_gt(d3, pi, minus_two_pi);
    d3 = D::add_if_le(d3, minus_pi, two_pi);
    const D d0 = in[0] - m0, d1 = in[1] - m1, d2 = in[2] - m2;
    const D wi = in[4];
    const D w0 = wi * d0, w1 = wi * d1, w2 = wi * d2, w3 = wi * d3;
    a0 += w0 * d0;
    a1 += w0 * d1;
    a2 += w0 * d2;
    a3 += w0 * d3;
    a4 += w1 * d1;
    a5 += w1 * d2;
    a6 += w1 * d3;
    a7 += w2 * d2;
    a8 += w2 * d3;
    a9 += w3 * d3;
  });
  return {{a0.sum(), a1.sum(), a2.sum(), a3.sum(), a4.sum(), a5.sum(), a6.sum(), a7.sum(), a8.sum(), a9.sum()}};
}

/// Resampling copy: pointer j takes particle src_j = max(start_0..start_j)
/// (see ParticleFilter::Impl::resample); all six columns of a particle are
/// copied together, which keeps the loop at the stores' pace.
inline void copy_selected(int N, const int* __restrict start, const double* __restrict f0,
                          const double* __restrict f1, const double* __restrict f2, const double* __restrict f3,
                          const double* __restrict f4, const double* __restrict f5, double* __restrict t0,
                          double* __restrict t1, double* __restrict t2, double* __restrict t3, double* __restrict t4,
                          double* __restrict t5) {
  int src = 0;
  for (int j = 0; j < N; ++j) {
    src = std::max(src, start[j]);
    t0[j] = f0[src];
    t1[j] = f1[src];
    t2[j] = f2[src];
    t3[j] = f3[src];
    t4[j] = f4[src];
    t5[j] = f5[src];
  }
}

}  // namespace

/// Columns of doubles for the particle filter, each starting on a 64-byte
/// boundary (the column stride is padded to 8 doubles): vector loads then
/// never split a cache line, whichever allocator the host process uses.
class Columns {
 public:
  void resize(int rows, int cols) {
    stride_ = (rows + 7) / 8 * 8;
    data_.assign(static_cast<std::size_t>(stride_) * cols, 0.0);
  }
  int stride() const { return stride_; }
  double* col(int c) { return data_.data() + static_cast<std::ptrdiff_t>(c) * stride_; }
  const double* col(int c) const { return data_.data() + static_cast<std::ptrdiff_t>(c) * stride_; }
  void swap(Columns& o) noexcept {
    data_.swap(o.data_);
    std::swap(stride_, o.stride_);
  }

 private:
  template <class T>
  struct Allocator {
    using value_type = T;
    Allocator() = default;
    template <class U>
    Allocator(const Allocator<U>&) noexcept {}
    T* allocate(std::size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t{64})); }
    void deallocate(T* p, std::size_t) noexcept { ::operator delete(p, std::align_val_t{64}); }
    friend bool operator==(const Allocator&, const Allocator&) { return true; }
    friend bool operator!=(const Allocator&, const Allocator&) { return false; }
  };
  std::vector<double, Allocator<double>> data_;
  int stride_ = 0;
};

struct ParticleFilter::Impl {
  // Particle columns: x, y, v, θ, cos θ, sin θ; weight columns: log w, w.
  enum Column : int { kCos = 4, kSin = 5, kParticleColumns = 6 };
  enum WeightColumn : int { kLogW = 0, kW = 1 };
  Bmm bmm;
  detail::BatchRng rng;
  double resample_threshold;
  int N = 0;
  Columns S, S_next;          // particles; S_next receives a resampled set
  Columns W;                  // log-weights and normalised weights
  double ess = 0.0;           // 1/Σw², kept with w
  int n_resampled = 0;
  // scratch
  Columns noise;              // ε_x, ε_y, ε_v, ε_θ of every particle
  std::vector<int> start;     // resampling: the particle of each pointer
  Eigen::MatrixXd Y;          // residuals of a general measurement model
  Eigen::VectorXd zhat, resid;

  Impl(const BmmParams& p, std::uint64_t seed, double thr, int n)
      : bmm(p), rng(seed), resample_threshold(thr), N(n) {
    S.resize(N, kParticleColumns);
    S_next.resize(N, kParticleColumns);
    W.resize(N, 2);
    noise.resize(N, 4);
    start.resize(static_cast<std::size_t>(N) + 1);
  }

  int n() const { return N; }
  double* col(int c) { return S.col(c); }
  const double* col(int c) const { return S.col(c); }
  double* logw() { return W.col(kLogW); }
  double* w() { return W.col(kW); }
  const double* w() const { return W.col(kW); }
  State particle(int i) const { return State(S.col(kX)[i], S.col(kY)[i], S.col(kV)[i], S.col(kTheta)[i]); }
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
    reset_weights();
    ++n_resampled;
  }

  State mean() const {
    const Sums5 s = detail::dispatch<mean_sums<32>, mean_sums<16>>(N, col(kX), col(kY), col(kV), col(kCos),
                                                                    col(kSin), w());
    return State(s.s[0], s.s[1], s.s[2], std::atan2(s.s[4], s.s[3]));  // circular mean for θ
  }

  /// Weighted covariance Σ w_i d_i d_iᵀ about m, θ deviations wrapped.
  StateCov covariance(const State& m) const {
    const Sums10 t = detail::dispatch<covariance_sums<32>, covariance_sums<16>>(N, col(kX), col(kY), col(kV),
                                                                                col(kTheta), w(), &m);
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

  /// Noisy BMM for every particle (eqs. 6–9, the body of Bmm::transition).
  /// θ moves by a small δ_i per step, so cos/sin of the new heading come from
  /// rotating the cached (cos θ, sin θ) by δ_i (particles_step); turns larger
  /// than kSmallTurn are redone with std::cos/std::sin.
  void predict(double desired_speed, double heading_step) {
    const auto& p = bmm.params();
    const double k = p.terrain_factor() * p.dt;
    rng.fill_normal(noise.col(0), 4L * noise.stride());  // all four columns (and their padding)
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
    const StepParams a{desired_speed, heading_step, p.acceleration * p.dt, p.deceleration * p.dt,
                       p.max_speed,   k,            p.speed_noise,         p.heading_noise,
                       p.position_noise};
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

ParticleFilter::ParticleFilter(const BmmParams& params, const State& x0, const StateCov& P0, int n_particles,
                               std::uint64_t seed, double resample_threshold) {
  if (n_particles < 1) {
    throw std::invalid_argument("n_particles = " + std::to_string(n_particles) + " must be >= 1");
  }
  if (!(std::isfinite(resample_threshold) && resample_threshold >= 0.0 && resample_threshold <= 1.0)) {
    std::ostringstream os;
    os << "resample_threshold = " << resample_threshold << " must be in [0, 1]";
    throw std::invalid_argument(os.str());
  }
  check_prior(x0, P0);
  impl_ = std::make_unique<Impl>(params, seed, resample_threshold, n_particles);
  auto& I = *impl_;
  const int N = n_particles;
  const Eigen::Matrix4d L = P0.llt().matrixL();
  I.rng.fill_normal(I.noise.col(0), 4L * I.noise.stride());
  for (int i = 0; i < N; ++i) {
    const Eigen::Vector4d e(I.noise.col(0)[i], I.noise.col(1)[i], I.noise.col(2)[i], I.noise.col(3)[i]);
    State p = x0 + L * e;
    p[kV] = std::max(0.0, p[kV]);
    p[kTheta] = wrap_angle(p[kTheta]);
    for (int c = 0; c < 4; ++c) I.col(c)[i] = p[c];
    I.col(Impl::kCos)[i] = std::cos(p[kTheta]);
    I.col(Impl::kSin)[i] = std::sin(p[kTheta]);
  }
  I.reset_weights();
}

ParticleFilter::~ParticleFilter() = default;
ParticleFilter::ParticleFilter(ParticleFilter&&) noexcept = default;
ParticleFilter& ParticleFilter::operator=(ParticleFilter&&) noexcept = default;

int ParticleFilter::size() const { return impl_->n(); }
double ParticleFilter::ess() const { return impl_->ess; }
int ParticleFilter::resample_count() const { return impl_->n_resampled; }
State ParticleFilter::mean() const { return impl_->mean(); }
StateCov ParticleFilter::covariance() const { return impl_->covariance(impl_->mean()); }
StateCov ParticleFilter::covariance(const State& about) const { return impl_->covariance(about); }
Eigen::VectorXd ParticleFilter::weights() const { return Eigen::Map<const Eigen::VectorXd>(impl_->w(), size()); }

Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> ParticleFilter::particles() const {
  const auto& I = *impl_;
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> X(I.N, 4);
  for (int c = 0; c < 4; ++c) X.col(c) = Eigen::Map<const Eigen::VectorXd>(I.col(c), I.N);
  return X;
}

void ParticleFilter::predict(const Control& u) {
  if (!u.allFinite()) {
    std::ostringstream os;
    os << "control (desired_speed, heading_change) = (" << u[0] << ", " << u[1] << ") is not finite";
    throw std::invalid_argument(os.str());
  }
  impl_->predict(u[0], impl_->bmm.clipped_heading_change(u[1]));
  // Finite inputs can still overflow (positions near 1e308, a huge dt·v_max); v and θ stay bounded.
  for (int c : {kX, kY}) {
    const Eigen::Map<const Eigen::ArrayXd> col(impl_->col(c), impl_->n());
    if (!col.allFinite()) {
      std::ostringstream os;
      os << "particle filter predict: particle " << (c == kX ? "x" : "y") << " overflows (control (" << u[0]
         << ", " << u[1] << "), dt = " << impl_->bmm.params().dt << ", max_speed = "
         << impl_->bmm.params().max_speed << ")";
      throw std::invalid_argument(os.str());
    }
  }
}

UpdateResult ParticleFilter::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  model.check(z);
  auto& I = *impl_;
  const int m = model.dim();
  const int N = I.n();
  const Eigen::MatrixXd R = model.noise().cov();
  UpdateResult res;
  res.dim = m;
  const Eigen::ArrayXd prior_logw = Eigen::Map<const Eigen::ArrayXd>(I.logw(), N);
  if (model.kind() == MeasurementKind::Position) {
    // Fast path: 2-D residuals, log-likelihood and NIS moments in one pass.
    const Eigen::Matrix2d Ri = R.inverse();
    const PositionParams a{z[0], z[1], 0.5 * Ri(0, 0), Ri(0, 1), 0.5 * Ri(1, 1)};
    const Sums5 t =
        detail::dispatch<position_loglik<32>, position_loglik<16>>(N, I.col(kX), I.col(kY), I.w(), I.logw(), &a);
    const double* ps = t.s;
    const double s0 = ps[0], s1 = ps[1];
    const Eigen::Vector2d ybar(s0, s1);
    Eigen::Matrix2d S;
    S << ps[2] - s0 * s0, ps[3] - s0 * s1, ps[3] - s0 * s1, ps[4] - s1 * s1;
    S += R;
    res.nis = ybar.dot(S.ldlt().solve(ybar));
  } else {
    // Residual of every particle, y_i = z ⊖ h(x_i), one per column.
    I.Y.resize(m, N);
    I.zhat.resize(m);
    I.resid.resize(m);
    for (int i = 0; i < N; ++i) {
      model.predict(I.particle(i), I.zhat);
      model.residual(z, I.zhat, I.resid);
      I.Y.col(i) = I.resid;
    }
    // NIS (diagnostic) of the prior predictive: mean residual ȳ, S = Cov_w(y) + R.
    const Eigen::Map<const Eigen::VectorXd> w(I.w(), N);
    const Eigen::VectorXd ybar = I.Y * w;
    const Eigen::MatrixXd D = I.Y.colwise() - ybar;
    const Eigen::MatrixXd S = D * w.asDiagonal() * D.transpose() + R;
    res.nis = ybar.dot(S.ldlt().solve(ybar));
    // log-likelihood −½ yᵀR⁻¹y = −½‖L⁻¹y‖², added to the log-weights.
    model.noise().whiten(I.Y);
    Eigen::Map<Eigen::ArrayXd>(I.logw(), N) -= 0.5 * I.Y.colwise().squaredNorm().transpose().array();
  }
  const double mx = Eigen::Map<const Eigen::ArrayXd>(I.logw(), N).maxCoeff();  // exact in any order
  if (!std::isfinite(mx) || !std::isfinite(res.nis)) {  // keep the prior weights, then say why
    Eigen::Map<Eigen::ArrayXd>(I.logw(), N) = prior_logw;
    check_nis(res.nis, "particle filter", model.kind());
    // every likelihood underflowed (residuals beyond ~1e154 σ)
    std::ostringstream os;
    os << "particle filter " << to_string(model.kind()) << " update: the measurement has zero likelihood under "
       << "every particle (log-likelihood " << mx << ")";
    throw std::invalid_argument(os.str());
  }
  I.normalise(mx);
  if (I.ess < I.resample_threshold * N) I.resample();
  return res;
}

// --------------------------------------------------------------------------
// Extended information filter
// --------------------------------------------------------------------------

InformationFilter::InformationFilter(const BmmParams& params, const State& x0, const StateCov& P0) : bmm_(params) {
  check_prior(x0, P0);
  Y_ = P0.inverse();
  Y_ = 0.5 * (Y_ + Y_.transpose());
  y_ = Y_ * x0;
}

State InformationFilter::x() const { return Y_.ldlt().solve(y_); }
StateCov InformationFilter::P() const { return Y_.inverse(); }

void InformationFilter::predict(const Control& u) {
  Eigen::Matrix4d F, G;
  const State x1 = bmm_.linearize(x(), u, &F, &G);
  const Eigen::Vector4d sigma2 = bmm_.noise_cov().diagonal();
  Eigen::Matrix4d Pp = F * P() * F.transpose() + G * sigma2.asDiagonal() * G.transpose();
  Pp = 0.5 * (Pp + Pp.transpose());
  if (!Pp.allFinite()) {
    std::ostringstream os;
    os << "dt = " << bmm_.params().dt << " and the prior P (diagonal " << P().diagonal().transpose() << ")";
    check_finite_result(Pp, "information filter predict P", os.str());
  }
  const Eigen::LLT<Eigen::Matrix4d> llt(Pp);
  if (llt.info() != Eigen::Success || !(llt.matrixL().toDenseMatrix().diagonal().minCoeff() > 1e-12)) {
    // Zero uncertainty in some direction: infinite information, which the
    // information form cannot hold.  Happens when a noise sigma is 0 and a
    // BMM limit binds (∂v'/∂v = 0 with speed_noise = 0, for instance).
    throw std::runtime_error(
        "information filter predict: the predicted covariance F P Fᵀ + Q is singular (a state "
        "component became exactly known, e.g. speed_noise = 0 while a speed limit binds); "
        "the information form needs a positive-definite covariance: use process noise > 0");
  }
  Y_ = llt.solve(Eigen::Matrix4d::Identity());
  Y_ = 0.5 * (Y_ + Y_.transpose());
  y_ = Y_ * x1;
}

UpdateResult InformationFilter::update(const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
  model.check(z);
  const State xb = x();
  const Eigen::MatrixXd H = model.jacobian(xb);
  Eigen::VectorXd zhat = model.predict(xb), nu(model.dim());
  model.residual(z, zhat, nu);
  const Eigen::MatrixXd R = model.noise().cov();
  const Eigen::MatrixXd RinvH = R.ldlt().solve(H);  // R⁻¹ H
  UpdateResult res;
  res.dim = model.dim();
  const Eigen::MatrixXd S = H * P() * H.transpose() + R;
  res.nis = nu.dot(S.ldlt().solve(nu));
  check_nis(res.nis, "information filter", model.kind());
  Eigen::Matrix4d Y1 = Y_ + H.transpose() * RinvH;
  Y1 = 0.5 * (Y1 + Y1.transpose());
  const State y1 = y_ + RinvH.transpose() * (nu + H * xb);
  if (!Y1.allFinite() || !y1.allFinite()) {
    throw std::invalid_argument(std::string("information filter ") + to_string(model.kind()) +
                                " update: the information overflows (measurement noise too small for its scale)");
  }
  Y_ = Y1;
  y_ = y1;
  return res;
}

// --------------------------------------------------------------------------
// Batch filtering
// --------------------------------------------------------------------------

void MeasurementStream::validate(int n_steps) const {
  auto bad_rows = [&](const char* name, Eigen::Index rows) {
    if (rows != 0 && rows != n_steps) {
      std::ostringstream os;
      os << "measurement stream '" << name << "' has " << rows << " rows, expected " << n_steps
         << " (one per control step) or 0";
      throw std::invalid_argument(os.str());
    }
  };
  bad_rows("position", position.rows());
  bad_rows("speed_heading", speed_heading.rows());
  bad_rows("ranges", ranges.rows());
  bad_rows("bearings", bearings.rows());
  auto check_rows = [](const char* name, const RowMatrixX2& m) {
    for (Eigen::Index k = 0; k < m.rows(); ++k) {
      const bool nan0 = std::isnan(m(k, 0)), nan1 = std::isnan(m(k, 1));
      if (nan0 && nan1) continue;  // a gap
      if (nan0 || nan1 || !std::isfinite(m(k, 0)) || !std::isfinite(m(k, 1))) {
        std::ostringstream os;
        os << "measurement stream '" << name << "' row " << k << " = (" << m(k, 0) << ", " << m(k, 1)
           << ") is invalid: use a full NaN row for a gap, finite values otherwise";
        throw std::invalid_argument(os.str());
      }
    }
  };
  check_rows("position", position);
  check_rows("speed_heading", speed_heading);
  auto check_lm = [&](const char* name, const RowMatrixXd& m) {
    if (m.rows() == 0) return;
    if (m.cols() != landmarks.rows()) {
      std::ostringstream os;
      os << "measurement stream '" << name << "' has " << m.cols() << " columns but there are "
         << landmarks.rows() << " landmarks";
      throw std::invalid_argument(os.str());
    }
    for (Eigen::Index k = 0; k < m.rows(); ++k)
      for (Eigen::Index j = 0; j < m.cols(); ++j)
        if (std::isinf(m(k, j))) {
          std::ostringstream os;
          os << "measurement stream '" << name << "' row " << k << " landmark " << j << " = " << m(k, j)
             << " is not finite (use NaN for 'not observed')";
          throw std::invalid_argument(os.str());
        }
  };
  check_lm("ranges", ranges);
  check_lm("bearings", bearings);
}

namespace {

template <class Filter>
State estimate(const Filter& f);
template <>
State estimate(const Ekf& f) { return f.x(); }
template <>
State estimate(const InformationFilter& f) { return f.x(); }
template <>
State estimate(const ParticleFilter& f) { return f.mean(); }

template <class Filter>
StateCov estimate_cov(const Filter& f, const State&);
template <>
StateCov estimate_cov(const Ekf& f, const State&) { return f.P(); }
template <>
StateCov estimate_cov(const InformationFilter& f, const State&) { return f.P(); }
template <>
StateCov estimate_cov(const ParticleFilter& f, const State& mean) { return f.covariance(mean); }

/// Landmark model restricted to the landmarks seen in row k (NaN = unseen).
struct LandmarkStream {
  const RowMatrixXd* data = nullptr;
  std::unique_ptr<MeasurementModel> full;
  std::vector<int> seen;
  Eigen::VectorXd z;

  bool step(Eigen::Index k, std::unique_ptr<MeasurementModel>& subset_out, const MeasurementModel*& model) {
    if (!data || data->rows() == 0) return false;
    seen.clear();
    for (Eigen::Index j = 0; j < data->cols(); ++j)
      if (!std::isnan((*data)(k, j))) seen.push_back(static_cast<int>(j));
    if (seen.empty()) return false;
    z.resize(static_cast<Eigen::Index>(seen.size()));
    for (size_t j = 0; j < seen.size(); ++j) z[static_cast<Eigen::Index>(j)] = (*data)(k, seen[j]);
    if (static_cast<Eigen::Index>(seen.size()) == data->cols()) {
      model = full.get();
    } else {
      subset_out = std::make_unique<MeasurementModel>(full->subset(seen));
      model = subset_out.get();
    }
    return true;
  }
};

template <class Filter>
FilterRun run_impl(Filter& f, const Eigen::Ref<const RowMatrixX2>& controls, const MeasurementStream& st,
                   const std::function<int()>& resampled) {
  const Eigen::Index N = controls.rows();
  FilterRun out;
  out.states.resize(N + 1, 4);
  out.covariances.resize(N + 1, 16);
  out.nis = Eigen::VectorXd::Constant(N, std::numeric_limits<double>::quiet_NaN());
  out.nis_dof = Eigen::VectorXi::Zero(N);

  std::unique_ptr<MeasurementModel> pos, imu;
  if (st.position.rows()) pos = std::make_unique<MeasurementModel>(MeasurementModel::position(st.position_cov));
  if (st.speed_heading.rows())
    imu = std::make_unique<MeasurementModel>(MeasurementModel::speed_heading(st.speed_heading_cov));
  LandmarkStream rng_s, brg_s;
  if (st.ranges.rows()) {
    rng_s.data = &st.ranges;
    rng_s.full = std::make_unique<MeasurementModel>(MeasurementModel::range(st.landmarks, st.range_std));
  }
  if (st.bearings.rows()) {
    brg_s.data = &st.bearings;
    brg_s.full = std::make_unique<MeasurementModel>(MeasurementModel::bearing(st.landmarks, st.bearing_std));
  }

  auto record = [&](Eigen::Index row) {
    const State m = estimate(f);
    const StateCov P = estimate_cov(f, m);
    out.states.row(row) = m.transpose();
    out.covariances.row(row) = Eigen::Map<const Eigen::Matrix<double, 1, 16>>(P.data());  // symmetric
  };
  record(0);
  for (Eigen::Index k = 0; k < N; ++k) {
    const Control u = controls.row(k).transpose();
    if (!u.allFinite()) {
      std::ostringstream os;
      os << "controls row " << k << " = (" << u[0] << ", " << u[1] << ") is not finite";
      throw std::invalid_argument(os.str());
    }
    f.predict(u);
    double nis = 0.0;
    int dof = 0, n_meas = 0;
    auto apply = [&](const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
      const UpdateResult r = f.update(model, z);
      ++n_meas;
      if (r.accepted) {
        ++out.n_updates;
        nis += r.nis;
        dof += r.dim;
      } else {
        ++out.n_rejected;
      }
    };
    if (pos && !std::isnan(st.position(k, 0))) apply(*pos, st.position.row(k).transpose());
    if (imu && !std::isnan(st.speed_heading(k, 0))) apply(*imu, st.speed_heading.row(k).transpose());
    std::unique_ptr<MeasurementModel> sub;
    const MeasurementModel* lm_model = nullptr;
    if (rng_s.step(k, sub, lm_model)) apply(*lm_model, rng_s.z);
    if (brg_s.step(k, sub, lm_model)) apply(*lm_model, brg_s.z);
    if (n_meas == 0) ++out.n_gaps;
    if (dof > 0) {
      out.nis[k] = nis;
      out.nis_dof[k] = dof;
    }
    record(k + 1);
  }
  out.n_resampled = resampled();
  return out;
}

}  // namespace

FilterRun run_filter(const BmmParams& params, const FilterOptions& options, const State& x0, const StateCov& P0,
                     const Eigen::Ref<const RowMatrixX2>& controls, const MeasurementStream& stream) {
  stream.validate(static_cast<int>(controls.rows()));
  switch (options.type) {
    case FilterType::Ekf: {
      Ekf f(params, x0, P0);
      f.set_gate(options.gate_probability);
      return run_impl(f, controls, stream, [] { return 0; });
    }
    case FilterType::ParticleFilter: {
      ParticleFilter f(params, x0, P0, options.n_particles, options.seed, options.resample_threshold);
      return run_impl(f, controls, stream, [&f] { return f.resample_count(); });
    }
    case FilterType::InformationFilter: {
      InformationFilter f(params, x0, P0);
      return run_impl(f, controls, stream, [] { return 0; });
    }
  }
  throw std::invalid_argument("unknown filter type");
}

}  // namespace safenav
