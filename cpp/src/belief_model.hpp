// Private: the belief step shared by propagate_belief (belief.cpp) and the
// belief planner (belief_search.cpp).  See safenav/belief.hpp for the model.
#pragma once

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
  Eigen::Vector2d end = Eigen::Vector2d::Zero();
  double dt = 0.0;
  double length = 0.0;     ///< metres covered
  double view_dtheta = 0.0;  ///< the camera's heading less the leg's (Model::offset)
  std::vector<int> seen;   ///< landmark rows in view (ranges or bearings measured)
  int in_view = 0;         ///< landmarks in view
  bool fix = false;        ///< a LanBLoc fix (FixModel::Profile) is expected
  bool ranges = false;     ///< ranges to the landmarks in `seen` (FixModel::Ranges) are expected
  double clearance = std::numeric_limits<double>::infinity();
  /// Unit direction toward the nearest keep-out area; (NaN, NaN) until asked
  /// (Model::direction), (0, 0) where it is undefined (equidistant walls).
  Eigen::Vector2d toward = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
};

/// The sensors, the motion model and the map, ready to step beliefs.
class Model {
 public:
  Model(const BmmParams& bmm, const SensorSettings& sensors, const PlanningMap& map, const BeliefSettings& settings);

  /// The steps of the leg a → b, appended to `out` (none when a == b).
  void leg(const Eigen::Vector2d& a, const Eigen::Vector2d& b, std::vector<Step>& out) const;
  /// P ← one belief step (predict, then the expected updates).  Pm and F,
  /// when given, receive P⁻ and the step's F.
  void step(const Step& s, StateCov& P, StateCov* Pm = nullptr, Eigen::Matrix4d* F = nullptr) const;
  /// `s` seen by a vehicle `lateral` metres to the left of the leg and
  /// turned by `dtheta` (BeliefSettings::deviation_mixture): the landmarks in
  /// view and the measurements from there; the motion (s.x) and the
  /// clearance stay the nominal ones.
  Step offset(const Step& s, double lateral, double dtheta) const;
  /// Fills s.toward (central differences of the keep-out distance).
  void direction(Step& s) const;
  /// σ toward s.toward (filled first), or √λ_max where that is undefined.
  double sigma_toward(Step& s, const StateCov& P) const;

  const ObstacleChecker& checker() const { return checker_; }
  const BeliefSettings& settings() const { return settings_; }
  double clearance_at(const Eigen::Vector2d& p) const { return checker_.keep_out_distance(p, p); }

 private:
  void observe(Step& s) const;
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

}  // namespace safenav::belief
