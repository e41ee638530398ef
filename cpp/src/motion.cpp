#include "safenav/motion.hpp"
#include "declare.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "rng.hpp"

namespace safenav {

template <>
const ParamSet<BmmParams>& param_set<BmmParams>();  // defined below

namespace {
void require(bool ok, const char* field, double value, const char* rule) {
  if (!ok) {
    std::ostringstream os;
    os << "BmmParams." << field << " = " << value << " is invalid: must be " << rule;
    throw std::invalid_argument(os.str());
  }
}
bool finite_nonneg(double v) { return std::isfinite(v) && v >= 0.0; }
bool finite_pos(double v) { return std::isfinite(v) && v > 0.0; }
/// A noise sigma enters as its square (Σ_ε, eq. 6): the square must be finite too.
bool finite_sigma(double v) { return v >= 0.0 && std::isfinite(v * v); }
}  // namespace

void BmmParams::validate() const {
  require(finite_pos(acceleration), "acceleration", acceleration, "finite and > 0");
  require(finite_pos(deceleration), "deceleration", deceleration, "finite and > 0");
  require(finite_pos(max_speed), "max_speed", max_speed, "finite and > 0");
  require(finite_pos(max_heading_rate), "max_heading_rate", max_heading_rate, "finite and > 0");
  require(finite_pos(dt), "dt", dt, "finite and > 0");
  require(finite_nonneg(terrain_effect), "terrain_effect", terrain_effect, "finite and >= 0");
  require(finite_sigma(speed_noise), "speed_noise", speed_noise, ">= 0 with a finite square");
  require(finite_sigma(heading_noise), "heading_noise", heading_noise, ">= 0 with a finite square");
  require(finite_sigma(position_noise), "position_noise", position_noise, ">= 0 with a finite square");
  param_set<BmmParams>().check(*this);
}

void check_finite_state(const State& x, const char* what) {
  static const char* names[4] = {"x", "y", "v", "theta"};
  for (int i = 0; i < 4; ++i) {
    if (!std::isfinite(x[i])) {
      std::ostringstream os;
      os << what << "." << names[i] << " = " << x[i] << " is not finite";
      throw std::invalid_argument(os.str());
    }
  }
}

void check_finite_result(const Eigen::Ref<const Eigen::MatrixXd>& r, const char* what, const std::string& cause) {
  for (Eigen::Index j = 0; j < r.cols(); ++j)
    for (Eigen::Index i = 0; i < r.rows(); ++i)
      if (!std::isfinite(r(i, j))) {
        std::ostringstream os;
        os << what << "[" << i;
        if (r.cols() > 1) os << ", " << j;
        os << "] = " << r(i, j) << " is not finite: it overflows for " << cause;
        throw std::invalid_argument(os.str());
      }
}

namespace {
/// Throws (via check_finite_result) when `r` has a non-finite entry, naming
/// the inputs; the message is built only then.
void check_result(const Eigen::Ref<const Eigen::MatrixXd>& r, const char* what, const State& x, const Control& u,
                  const BmmParams& p) {
  if (r.allFinite()) return;
  std::ostringstream os;
  os << "state (" << x[0] << ", " << x[1] << ", " << x[2] << ", " << x[3] << "), control (" << u[0] << ", " << u[1]
     << "), dt = " << p.dt;
  check_finite_result(r, what, os.str());
}

void check_control(const Control& u) {
  if (!std::isfinite(u[0]) || !std::isfinite(u[1])) {
    std::ostringstream os;
    os << "control (desired_speed, heading_change) = (" << u[0] << ", " << u[1] << ") is not finite";
    throw std::invalid_argument(os.str());
  }
}
}  // namespace

Bmm::Bmm(const BmmParams& params) : params_(params) { params_.validate(); }

State Bmm::predict(const State& x, const Control& u) const { return linearize(x, u, nullptr, nullptr); }

Bmm Bmm::with_step(double dt) const {
  if (!(std::isfinite(dt) && dt > 0.0)) {
    std::ostringstream os;
    os << "step dt = " << dt << " s: must be finite and > 0";
    throw std::invalid_argument(os.str());
  }
  if (is_nominal_step(dt)) return *this;
  BmmParams p = params_;
  const double s = std::sqrt(dt / p.dt);
  p.speed_noise *= s;
  p.heading_noise *= s;
  p.position_noise *= s;
  p.dt = dt;
  return Bmm(p, Unchecked{});
}

State Bmm::transition(const State& x, const Control& u, const Eigen::Vector4d& eps) const {
  check_finite_state(x, "state");
  check_control(u);
  if (!eps.allFinite()) {
    std::ostringstream os;
    os << "noise eps = (" << eps[0] << ", " << eps[1] << ", " << eps[2] << ", " << eps[3] << ") is not finite";
    throw std::invalid_argument(os.str());
  }
  // eqs. 3, 4 and 6: speed and heading with their noise; eq. 7/9: the position
  // moves with the *updated* speed and heading.
  const double v1 = std::clamp(next_speed(x[kV], u[0]) + eps[2], params_.min_speed(), params_.max_speed);
  const double th1 = wrap_angle(x[kTheta] + clipped_heading_change(u[1]) + eps[3]);
  const double k = params_.terrain_factor() * params_.dt;
  State out;
  out << x[kX] + k * v1 * std::cos(th1) + eps[0], x[kY] + k * v1 * std::sin(th1) + eps[1], v1, th1;
  check_result(out, "Bmm.transition x'", x, u, params_);
  return out;
}

State Bmm::linearize(const State& x, const Control& u, Eigen::Matrix4d* F, Eigen::Matrix4d* G) const {
  check_finite_state(x, "state");
  check_control(u);
  const auto& p = params_;
  const double v = x[kV];
  const double desired = u[0];
  const double v1 = next_speed(v, desired);
  const double th1 = wrap_angle(x[kTheta] + clipped_heading_change(u[1]));
  const double k = p.terrain_factor() * p.dt;
  const double c = std::cos(th1), s = std::sin(th1);
  if (F) {
    // ∂v'/∂v: 1 where v' follows v ± a·Δt, 0 where a limit (v_desired, v_max, 0) binds
    // (always, with `unicycle`: the speed comes from the input).
    double dv = 0.0;
    if (p.unicycle) {
      dv = 0.0;
    } else if (desired > v) {
      const double up = v + p.acceleration * p.dt;
      dv = (up <= desired && up <= p.max_speed && up >= 0.0) ? 1.0 : 0.0;
    } else {
      const double down = v - p.deceleration * p.dt;
      dv = (down >= desired && down >= 0.0 && down <= p.max_speed) ? 1.0 : 0.0;
    }
    F->setIdentity();
    (*F)(kX, kV) = k * c * dv;
    (*F)(kX, kTheta) = -k * v1 * s;
    (*F)(kY, kV) = k * s * dv;
    (*F)(kY, kTheta) = k * v1 * c;
    (*F)(kV, kV) = dv;
  }
  if (G) {
    G->setIdentity();
    (*G)(kX, 2) = k * c;
    (*G)(kX, 3) = -k * v1 * s;
    (*G)(kY, 2) = k * s;
    (*G)(kY, 3) = k * v1 * c;
  }
  State out;
  out << x[kX] + k * v1 * c, x[kY] + k * v1 * s, v1, th1;
  check_result(out, "Bmm f(x, u)", x, u, p);
  if (F) check_result(*F, "Bmm Jacobian F", x, u, p);
  if (G) check_result(*G, "Bmm noise Jacobian G", x, u, p);
  return out;
}

Eigen::Matrix4d Bmm::jacobian(const State& x, const Control& u) const {
  Eigen::Matrix4d F;
  linearize(x, u, &F, nullptr);
  return F;
}

Eigen::Matrix4d Bmm::noise_jacobian(const State& x, const Control& u) const {
  Eigen::Matrix4d G;
  linearize(x, u, nullptr, &G);
  return G;
}

Eigen::Matrix4d Bmm::noise_cov() const {
  const auto& p = params_;
  return Eigen::Vector4d(p.position_noise * p.position_noise, p.position_noise * p.position_noise,
                         p.speed_noise * p.speed_noise, p.heading_noise * p.heading_noise)
      .asDiagonal();
}

Eigen::Matrix4d Bmm::process_cov(const State& x, const Control& u) const {
  const Eigen::Matrix4d G = noise_jacobian(x, u);
  const Eigen::Matrix4d Q = G * noise_cov() * G.transpose();
  check_result(Q, "Bmm.process_cov Q", x, u, params_);
  return Q;
}

Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> Bmm::simulate(
    const State& x0, const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& controls,
    std::uint64_t seed) const {
  check_finite_state(x0, "x0");
  detail::Rng rng(seed);
  const auto& p = params_;
  const Eigen::Vector4d sigma(p.position_noise, p.position_noise, p.speed_noise, p.heading_noise);
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> out(controls.rows() + 1, 4);
  State x = x0;
  out.row(0) = x.transpose();
  for (Eigen::Index k = 0; k < controls.rows(); ++k) {
    Eigen::Vector4d eps;
    for (int i = 0; i < 4; ++i) eps[i] = sigma[i] * rng.normal();
    const Control u = controls.row(k).transpose();
    if (!u.allFinite()) {
      std::ostringstream os;
      os << "controls row " << k << " = (" << u[0] << ", " << u[1] << ") is not finite";
      throw std::invalid_argument(os.str());
    }
    x = transition(x, u, eps);
    out.row(k + 1) = x.transpose();
  }
  return out;
}


// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<BmmParams>& param_set<BmmParams>() {
  static const ParamSet<BmmParams> s =
      Declare<BmmParams>{}
          .real("acceleration", SN_REF(BmmParams, acceleration), "m/s^2", above(0, 100), "a, acceleration capability [SafeNav eq. 3]")
          .real("deceleration", SN_REF(BmmParams, deceleration), "m/s^2", above(0, 100), "d, deceleration capability [SafeNav eq. 3]")
          .real("max_speed", SN_REF(BmmParams, max_speed), "m/s", above(0, 100), "v_max [SafeNav eq. 3]")
          .real("max_heading_rate", SN_REF(BmmParams, max_heading_rate), "rad/s", above(0, 100), "m, manoeuvrability: |dtheta| <= m*dt [SafeNav eq. 4]")
          .real("dt", SN_REF(BmmParams, dt), "s", above(0, 10), "the time step dt")
          .real("terrain_effect", SN_REF(BmmParams, terrain_effect), "", closed(0, 100), "tau, terrain effect [SafeNav eq. 8] (see BmmParams)")
          .real("speed_noise", SN_REF(BmmParams, speed_noise), "m/s", closed(0, 10), "sigma of eps_v per step [SafeNav eq. 6]")
          .real("heading_noise", SN_REF(BmmParams, heading_noise), "rad", closed(0, kPi), "sigma of eps_theta per step [SafeNav eq. 6]")
          .real("position_noise", SN_REF(BmmParams, position_noise), "m", closed(0, 10), "sigma of eps_x, eps_y per step [SafeNav eq. 7]")
          .flag("unicycle", SN_REF(BmmParams, unicycle), "speed from the input, signed, no acceleration limit (ours, in place of [SafeNav eq. 3])")
          .set;
  return s;
}

template class ParamSet<BmmParams>;

}  // namespace safenav
