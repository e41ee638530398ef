// Private: the filter's χ² gate in the expected belief
// (BeliefSettings::gate_probability; docs/belief_planning.md, "A fix the
// gate turns away").  Used by the deviation mixture (belief_mixture.cpp).
#pragma once

#include <array>

#include <Eigen/Core>

#include "belief_model.hpp"

namespace safenav::belief {

/// The parts of w ~ N(0, I₂) split by a χ² gate on ν = c + C w: part 0
/// passes it (νᵀ S⁻¹ ν ≤ γ); parts 1 … kGateSectors fail it, each in its
/// quarter of directions of w (the vehicles turned away lie on a ring about
/// the gate: one Gaussian for the ring would put them at its middle, where
/// the fix passes and the view is the nominal's).  Each part's mass,
/// E[w | part] and E[w wᵀ | part].
constexpr int kGateSectors = 4;
struct GateParts {
  std::array<double, 1 + kGateSectors> mass{};
  std::array<Eigen::Vector2d, 1 + kGateSectors> mean;
  std::array<Eigen::Matrix2d, 1 + kGateSectors> second;
  GateParts() {
    mean.fill(Eigen::Vector2d::Zero());
    second.fill(Eigen::Matrix2d::Identity());
  }
};

/// The gate's parts of N(0, I₂), integrated along rays from w = 0: along a
/// direction d the gate's test is a quadratic in the radius r, its passing
/// stretch [r₁, r₂] is closed form, and so are the radial integrals of
/// r e^{−r²/2} times 1, r and r² over it and over the rest; the angle is
/// integrated by the trapezoidal rule (`angles` directions, periodic, a
/// multiple of kGateSectors).  No part is found as 1 minus the others, so a
/// tail of 10⁻⁹ keeps its digits.  S must be positive definite, C lower
/// triangular and invertible.
GateParts gate_parts(const Eigen::Vector2d& c, const Eigen::Matrix2d& C, const Eigen::Matrix2d& S, double gamma,
                     int angles = 64);

/// One branch of a stratum's step under the gate: its share of the
/// stratum, its filter covariance, its error's mean and second moment
/// E[e eᵀ] after the step, the factor T that carries the error's mean from
/// the prediction (m ← T m⁻: how B moves), and the fixes it has had turned
/// away in a row since (the localizer's reset count).
struct GateBranch {
  double share = 0.0;
  StateCov P = StateCov::Zero(), M = StateCov::Zero();
  Eigen::Vector4d m = Eigen::Vector4d::Zero();
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  int rejections = 0;
};

/// A stratum's step with a position fix the filter gates (StepOutcome with
/// `gated`): its error after the prediction has mean `mu` and second moment
/// o.Pm + Nm.  Its branches: [0] no fix arrives (1 − p_fix); [1] the fix
/// arrives and passes the gate; [2 …] it arrives and is turned away, one
/// branch per sector of GateParts (a stratum turned away before: one, all
/// of it; its error stays outside the gate while the filter trusts its
/// prediction more than the fix, the caller's condition): the
/// filter takes the step's other updates only, or, when this is the
/// `reset_after`-th fix turned away in a row, restarts its position from
/// the fix (Localizer's reset: P_xy ← R, the cross-covariances 0, the
/// position error the fix's).  The innovation ν = v − H e of a vehicle of
/// the stratum is Gaussian with mean −H μ and covariance H Σ Hᵀ + R (Σ its
/// error's covariance), the gate's S the filter's H P⁻ Hᵀ + R; given ν the
/// error is Gaussian (its regression on ν), so each branch's moments follow
/// from the gate's parts of ν (gate_parts).  With the gate open (γ = ∞) the
/// branches are the intermittent fix's (Model::step), exactly.
std::array<GateBranch, 2 + kGateSectors> gate_branches(const StepOutcome& o, const Eigen::Vector4d& mu, const StateCov& Nm,
                                        int rejections, int reset_after, double gamma);

}  // namespace safenav::belief
