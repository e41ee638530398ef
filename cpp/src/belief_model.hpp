// Private: the belief step shared by propagate_belief (belief.cpp) and the
// belief planner (belief_search.cpp).  See safenav/belief.hpp for the model.
#pragma once

#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "safenav/belief.hpp"
#include "safenav/measurement.hpp"
#include "safenav/motion.hpp"
#include "safenav/world.hpp"
#include "safenav/navigation.hpp"

namespace safenav::belief {

/// One belief step along a leg, prepared once: the nominal state at the
/// step's start (position, speed, the leg's heading), where it ends, how long
/// it lasts, the landmarks in view at its end, and the clearance there.
struct Step {
  State x = State::Zero();
  /// The control over the step (eq. 11's linearization point with x): the
  /// cruise speed and no turn along a leg; the trajectory's own (Model::trajectory).
  Control u = Control(0.0, 0.0);
  Eigen::Vector2d end = Eigen::Vector2d::Zero();
  double dt = 0.0;
  double length = 0.0;     ///< metres covered
  double view_dtheta = 0.0;  ///< the camera's heading less the leg's (Model::offset)
  std::vector<int> seen;   ///< landmark rows in view (ranges or bearings measured)
  int in_view = 0;         ///< landmarks in view
  bool fix = false;        ///< a LanBLoc fix (FixModel::Profile) is expected
  bool ranges = false;     ///< ranges to the landmarks in `seen` (FixModel::Ranges) are expected
  /// With `ranges`: the probability that their trilateration is not refused
  /// (Model::unambiguous_share), asked only when the step is taken (the
  /// mixture's probes compare views alone); < 0 until then.
  mutable double unambiguous = -1.0;
  double clearance = std::numeric_limits<double>::infinity();
  /// Unit direction toward the nearest keep-out area; (NaN, NaN) until asked
  /// (Model::direction), (0, 0) where it is undefined (equidistant walls).
  Eigen::Vector2d toward = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
};

/// What one belief step did (Model::step).  A step whose fix arrives only
/// with probability p_fix < 1 (dropouts, faulty ranges) has two branches,
/// with the fix and without it, and its P is their mean, weighted by p_fix:
/// the expected covariance of a Kalman filter with intermittent observations
/// given the step's prior (Sinopoli et al. 2004, the modified Riccati
/// recursion).  T_fix and T_none are the branches' update factors
/// P_b (P⁻)⁻¹ (set only when 0 < p_fix < 1).
struct StepOutcome {
  StateCov Pm = StateCov::Zero();        ///< P⁻
  Eigen::Matrix4d F = Eigen::Matrix4d::Zero();
  double p_fix = 1.0;                    ///< probability that the step's fix arrives (1: its updates are certain)
  Eigen::Matrix4d T_fix = Eigen::Matrix4d::Identity(), T_none = Eigen::Matrix4d::Identity();
  /// How the filter's gate (BeliefSettings::gate_probability) meets the
  /// step's fix.  None: no fix may arrive, or no gate.  Passes: the filter
  /// trusts the fix more than its prediction (tr P⁻_xy ≤ kGatePersists tr R);
  /// a fix turned away there is one whose noise was large, and the next
  /// passes, so the step is the one without the gate.  Branches: the strata
  /// branch on the gate (belief_gate.hpp); T_fix and T_none are set whatever
  /// p_fix, with the branches' covariances and the fix's noise R (its
  /// position block; FixModel::Ranges: the ranges' information inverted, the
  /// trilateration's linear covariance).
  enum class Gating { None, Passes, Branches } gating = Gating::None;
  StateCov P_fix = StateCov::Zero(), P_none = StateCov::Zero();
  Eigen::Matrix2d R = Eigen::Matrix2d::Identity();
};

/// The gate is stepped where the filter's prediction is this much less
/// certain than the fix (tr P⁻_xy > 10 tr R, StepOutcome::Gating): a vehicle
/// turned away there is turned away by its error, not by the fix's noise,
/// and its next fix is turned away too.
constexpr double kGatePersists = 10.0;

inline double normal_sf(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }  ///< P(N(0,1) > z)
inline double normal_pdf(double z) { return std::exp(-0.5 * z * z) / std::sqrt(2.0 * kPi); }

/// The sensors, the motion model and the map, ready to step beliefs.
class Model {
 public:
  Model(const BmmParams& bmm, const SensorSettings& sensors, const PlanningMap& map, const BeliefSettings& settings);

  /// The steps of the leg a → b, appended to `out` (none when a == b).
  void leg(const Eigen::Vector2d& a, const Eigen::Vector2d& b, std::vector<Step>& out) const;
  /// The steps along a trajectory of states at the BMM's Δt (rows x, y, v,
  /// θ; Guidance::nominal_trajectory), appended to `out`: one step per
  /// BeliefSettings::step (rounded to a whole number of rows, the last step
  /// to the last row), from the state at its start with the control that
  /// takes it to the state at its end (the speed reached, the heading
  /// change; exact for one row per step), seen from the end's pose.
  void trajectory(const Eigen::Ref<const RowMatrixX4>& states, std::vector<Step>& out) const;
  /// P ← one belief step (predict, then the expected updates; StepOutcome
  /// for a fix that may not arrive).  `out`, when given, receives P⁻, F and
  /// the branches; with `gate` (the mixture's strata) also those of a fix
  /// the filter gates (StepOutcome::gated).
  void step(const Step& s, StateCov& P, StepOutcome* out = nullptr, bool gate = false) const;
  /// Q over step s (eq. 11's G Σ_ε Gᵀ): the process noise that the step adds to P.
  StateCov process_noise(const Step& s) const;
  /// `s` seen by a vehicle `lateral` metres to the left of the leg and
  /// turned by `dtheta` (BeliefSettings::deviation_mixture): the landmarks in
  /// view and the measurements from there; the motion (s.x) and the
  /// clearance stay the nominal ones.
  Step offset(const Step& s, double lateral, double dtheta) const;
  /// `motion` (its prediction, clearance and timing) seen from another
  /// step's end and camera, `view`, moved by `shift` [m] and turned by
  /// `dtheta` (BeliefSettings::deviation_along: a vehicle whose estimate
  /// runs ahead of the nominal turns where its estimate is).
  Step seen_from(const Step& motion, const Step& view, const Eigen::Vector2d& shift, double dtheta) const;
  /// The expected prior of a trial that starts at `start` heading `heading`:
  /// the simulator's first fix attempt (navigation.cpp, Trial::initialize)
  /// succeeds with the step's fix probability p, and the localizer then
  /// starts from that fix's R (FixModel::Ranges: trilaterate()'s covariance
  /// of the noise-free ranges in view, each counted as in a fix), else
  /// from SensorSettings::unfixed_start_std(); the mean of the two, weighted
  /// by p (SensorSettings::start_covariance for each).
  StateCov start_covariance(const Eigen::Vector2d& start, double heading) const;
  /// Fills s.toward (central differences of the keep-out distance).
  void direction(Step& s) const;
  /// σ toward s.toward (filled first), or √λ_max where that is undefined.
  double sigma_toward(Step& s, const StateCov& P) const;

  const ObstacleChecker& checker() const { return checker_; }
  const BeliefSettings& settings() const { return settings_; }
  double clearance_at(const Eigen::Vector2d& p) const { return checker_.keep_out_distance(p, p); }

 private:
  void observe(Step& s) const;
  /// The probability that the simulator's trilateration (Trial::range_fix)
  /// of ranges from `p` to the landmarks `seen` is not refused: 0 where the
  /// noise-free ranges fail for their geometry (GDOP), else the share of
  /// noisy ranges whose mirror minimum does not fit within
  /// LocalizationOptions::ambiguity_margin M of the solution.  The noise-free
  /// gap Δ between the two minima's χ² moves with whitened noise ε to
  /// Δ + 2 aᵀε (a the mirror's residuals, ‖a‖² = Δ), so the share is
  /// P(|N(Δ, 4Δ)| > M).
  double unambiguous_share(const Eigen::Vector2d& p, const std::vector<int>& seen) const;
  /// The step's fix: the probability p that one arrives in the step's n
  /// filter steps, and the expected count of each measurement of it given
  /// that one does (R is divided by it).
  struct FixOdds {
    double p = 1.0;
    double count = 0.0;
  };
  FixOdds fix_odds(const Step& s, double n) const;
  /// The information of the step's fix on the position, each measurement
  /// counted `count` times (R⁻¹; FixModel::Ranges: Σ gᵢ gᵢᵀ count / σ_r²).
  Eigen::Matrix2d fix_information(const Step& s, double count) const;
  /// The step's updates on P (after its prediction): the fix's when
  /// `with_fix`, each counted `fix_count` times, then bearings and the IMU.
  void update(const Step& s, double n, double fix_count, bool with_fix, StateCov& P) const;
  Bmm bmm_;
  SensorSettings sensors_;
  // sensors_ with one landmark: the visibility of each in turn (scratch: a
  // Model serves one thread).
  mutable SensorSettings single_;
  ObstacleChecker checker_;
  BeliefSettings settings_;
  double step_;  // belief step [s]
  Eigen::Matrix<double, 2, 4> H_fix_, H_imu_;
  Eigen::Matrix2d R_fix_, R_imu_;
};

/// The deviation mixture's strata per stage (BeliefProfile::strata_*):
/// each one's weight, where its vehicles are (mean and covariance) and its
/// second moment.
struct StrataTrace {
  Eigen::MatrixXd weight, positions, position_cov, msq;
};

/// BeliefSettings::deviation_mixture (belief_mixture.cpp): P[k] for k ≥ 1
/// from P[0] along `steps`, and A[k − 1], the error's transition, for
/// Patil et al.'s recursion.
void deviation_mixture(const Model& model, const std::vector<Step>& steps, std::vector<StateCov>& P,
                       std::vector<Eigen::Matrix4d>& A, StrataTrace& trace);

}  // namespace safenav::belief
