// Private: the filter's χ² gate in the expected belief
// (BeliefSettings::gate_probability; docs/belief_planning.md, "A fix the
// gate turns away").  Used by the deviation mixture (belief_mixture.cpp).
#pragma once

#include <array>

#include <Eigen/Core>

#include "belief_model.hpp"

namespace safenav::belief {

/// The gate of the loop's filter: its χ² threshold on a position fix and
/// the fix turned away in a row that restarts the position from it (the
/// localizer's reset_after_consistent, or the one after
/// reset_after_rejections, whichever comes first, as LocalizerSettings'
/// defaults give them: the loop's; 0 = never; at most kMaxCount + 1).
struct Gate {
  double gamma = 0.0;
  int reset_after = 0;
  explicit Gate(double probability);
};

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

/// The most fixes turned away in a row that a stratum counts (the loop's
/// localizer resets at the third).
constexpr int kMaxCount = 8;
/// A turned-away stratum's vehicles by the fixes turned away in a row:
/// element c − 1 holds the share with c (c < the reset count).
using Counts = std::array<double, kMaxCount>;

/// One branch of a stratum's step under the gate: its share of the
/// stratum, its filter covariance, its error's mean and second moment
/// E[e eᵀ] after the step, the factor T that carries the error's mean from
/// the prediction (m ← T m⁻: how B moves), and whether its vehicles' last
/// fix was turned away (with `counts`).
struct GateBranch {
  double share = 0.0;
  StateCov P = StateCov::Zero(), M = StateCov::Zero();
  Eigen::Vector4d m = Eigen::Vector4d::Zero();
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  bool turned_away = false;
  Counts counts{};
};

/// A stratum's step with a position fix the filter gates (StepOutcome with
/// `gated`): its error after the prediction has mean `mu` and second moment
/// o.Pm + Nm.  Its branches: [0] no fix arrives (1 − p_fix); [1] the fix
/// arrives and passes the gate; [2 …] it arrives and is turned away, one
/// branch per sector of GateParts: the filter takes the step's other
/// updates only (or, with `reset_after` 1, restarts its position from the
/// fix: restart_from_fix).  The innovation ν = v − H e of a vehicle of the
/// stratum is Gaussian with mean −H μ and covariance H Σ Hᵀ + R (Σ its
/// error's covariance), the gate's S the filter's H P⁻ Hᵀ + R; given ν the
/// error is Gaussian (its regression on ν), so each branch's moments follow
/// from the gate's parts of ν (gate_parts).  With the gate open (γ = ∞) the
/// branches are the intermittent fix's (Model::step), exactly.
std::array<GateBranch, 2 + kGateSectors> gate_branches(const StepOutcome& o, const Eigen::Vector4d& mu,
                                                       const StateCov& Nm, int reset_after, double gamma);

/// The step of a stratum whose last fix was turned away: its error lay
/// outside the gate, and where the filter trusts its prediction more than
/// the fix (the caller's condition) the fix's noise moves it by little, so
/// each fix that arrives (p_fix) is turned away too and moves its vehicles'
/// count on; at `reset_after` the localizer restarts the position from it.
/// [0] the vehicles still turned away (the step's other updates only; their
/// counts moved on), [1] those whose position restarts (restart_from_fix).
std::array<GateBranch, 2> turned_away_branches(const StepOutcome& o, const Eigen::Vector4d& mu, const StateCov& Nm,
                                               const Counts& counts, int reset_after);

}  // namespace safenav::belief
