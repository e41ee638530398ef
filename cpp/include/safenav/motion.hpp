// safenav/motion.hpp — the Battlefield Motion Model [SafeNav eqs. 3–9].
// Citations follow docs/paper_map.md; a bare "eq. 3" below means [SafeNav eq. 3].
//
// State x = (x, y, v, θ): position [m], speed [m/s], heading [rad, wrapped to (−π, π]].
// Control u = (desired speed v_desired [m/s], heading change Δθ [rad]).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <Eigen/Core>

#include "safenav/types.hpp"

namespace safenav {

/// Parameters of the BMM (named in [SafeNav-ext Table I]). Defaults are ours
/// (the paper gives no values) and are chosen to cover the synthetic data set
/// of [SafeNav-ext §V-A3(i)] (= [SafeNav-conf §V-A.2(i)]).
struct BmmParams {
  double acceleration = 3.0;       ///< a   [m/s²] acceleration capability (eq. 3)
  double deceleration = 3.0;       ///< d   [m/s²] deceleration capability (eq. 3)
  double max_speed = 10.0;         ///< v_max [m/s] (eq. 3)
  double max_heading_rate = 1.5;   ///< m   [rad/s] maneuverability (eq. 4)
  double dt = 0.05;                ///< Δt  [s] time step
  /// τ  terrain effect, read as metres of extra equivalent travel per metre of
  /// ground (dimensionless, ≥ 0).  Eq. 8 gives the time to cover a leg of
  /// length L at cruise speed v_c as t_τ = L/v_c + λ with λ = τ·L/v_c (the
  /// paper's λ = τ/v_c per metre).  Within one step of Δt the vehicle therefore
  /// covers v·Δt/(1+τ): eq. 9 is applied with the effective travel time
  /// Δt·Δt/t_τ = Δt/(1+τ).  τ = 0 gives eq. 7 exactly.
  double terrain_effect = 0.0;
  // Process noise (eq. 6–7), standard deviations per step.
  double speed_noise = 0.05;       ///< σ of ε_v [m/s]
  double heading_noise = 0.01;     ///< σ of ε_θ [rad]
  double position_noise = 0.01;    ///< σ of ε_x and ε_y [m]
  /// Speed from the input (ours, not the paper's): v' = clamp(v_desired,
  /// −v_max, v_max) at once, with no acceleration limit and a signed speed
  /// (reversing), in place of eq. 3; eq. 4's heading clip and eqs. 6–9 stay.
  /// This is the unicycle model of a vehicle that *reports* its speed (wheel
  /// odometry, commanded speed) rather than one that is asked for a speed it
  /// reaches at a and d: eq. 3 keeps such a vehicle's speed ≥ 0 and lags its
  /// speed changes by (Δv/a), which a unicycle does not (docs/replay.md).
  bool unicycle = false;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
  /// Multiplier on v·Δt in the position update: 1/(1+τ).
  double terrain_factor() const { return 1.0 / (1.0 + terrain_effect); }
  /// The lowest speed: 0 (eq. 3), or −v_max with `unicycle`.
  double min_speed() const { return unicycle ? -max_speed : 0.0; }
};

/// The BMM as a transition function f(x, u) with its Jacobians.
class Bmm {
 public:
  explicit Bmm(const BmmParams& params = BmmParams());
  const BmmParams& params() const { return params_; }

  /// The same model over a step of `dt` seconds instead of params().dt (the
  /// nominal step), for timestamped inputs: Δt becomes dt in eqs. 3, 4, 7 and
  /// 9, and the process-noise variances, which are per nominal step, scale
  /// by dt / params().dt (each σ by its square root: noise accumulates as a
  /// random walk).  A dt within 1e-6 relative of the nominal step (timestamp
  /// rounding) returns the model unchanged.  Throws unless dt is finite and
  /// > 0.  No allocation.
  Bmm with_step(double dt) const;
  /// Whether `dt` counts as the nominal step (|dt − Δt| ≤ 1e-6·Δt).
  bool is_nominal_step(double dt) const { return std::abs(dt - params_.dt) <= 1e-6 * params_.dt; }

  /// Eq. 3: speed update with acceleration/deceleration limits and [0, v_max];
  /// with `unicycle`, the desired speed clamped to [−v_max, v_max].
  double next_speed(double v, double desired) const {
    const auto& p = params_;
    if (p.unicycle) return std::clamp(desired, -p.max_speed, p.max_speed);
    if (desired > v) return std::max(0.0, std::min({v + p.acceleration * p.dt, desired, p.max_speed}));
    return std::min(p.max_speed, std::max({v - p.deceleration * p.dt, desired, 0.0}));
  }
  /// Eq. 4: heading change clipped to ±m·Δt.
  double clipped_heading_change(double dtheta) const {
    const double lim = params_.max_heading_rate * params_.dt;
    return std::clamp(dtheta, -lim, lim);
  }

  /// Deterministic transition f(x, u): eqs. 3, 4 and 7/9 (position uses the
  /// *updated* v and θ, eq. 7).  Throws on non-finite input.
  State predict(const State& x, const Control& u) const;
  /// F = ∂f/∂x, analytic, evaluated at (x, u).
  Eigen::Matrix4d jacobian(const State& x, const Control& u) const;
  /// G = ∂f/∂ε for the noise vector ε = (ε_x, ε_y, ε_v, ε_θ) (eqs. 6–7), at (x, u).
  Eigen::Matrix4d noise_jacobian(const State& x, const Control& u) const;
  /// f(x, u) together with F = ∂f/∂x and G = ∂f/∂ε (either may be null),
  /// computed once — the EKF's predict step uses this.
  State linearize(const State& x, const Control& u, Eigen::Matrix4d* F, Eigen::Matrix4d* G) const;
  /// Σ_ε = diag(σ_x², σ_y², σ_v², σ_θ²).
  Eigen::Matrix4d noise_cov() const;
  /// Q = G Σ_ε Gᵀ, the process-noise covariance of the state (eq. 11's Q_k).
  Eigen::Matrix4d process_cov(const State& x, const Control& u) const;

  /// Noisy transition with the given noise ε = (ε_x, ε_y, ε_v, ε_θ):
  /// v' = clamp(f_v(v,u) + ε_v, 0, v_max); θ' = wrap(θ + clip(Δθ) + ε_θ);
  /// p' = p + κ·v'·Δt·(cos θ', sin θ') + (ε_x, ε_y).   (eqs. 6, 7, 9)
  State transition(const State& x, const Control& u, const Eigen::Vector4d& eps) const;

  /// Simulate a trajectory of the true vehicle: returns (N+1)×4 states
  /// starting at x0, with process noise drawn from a seeded generator.
  Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> simulate(
      const State& x0, const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& controls,
      std::uint64_t seed) const;

 private:
  struct Unchecked {};
  Bmm(const BmmParams& params, Unchecked) : params_(params) {}
  BmmParams params_;
};

/// Throws std::invalid_argument if any entry of x is not finite, naming `what`.
void check_finite_state(const State& x, const char* what);

/// Throws std::invalid_argument if an entry of a computed result is not
/// finite (finite inputs whose result overflows), naming `what`, the entry
/// and its value; `cause` says which inputs produced it.
void check_finite_result(const Eigen::Ref<const Eigen::MatrixXd>& result, const char* what,
                         const std::string& cause);

}  // namespace safenav
