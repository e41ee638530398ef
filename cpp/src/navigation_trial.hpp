// Private: the simulator's trial (navigation.cpp runs the loop, navigation_sensors.cpp
// holds what its sensors measure: landmarks in view, position fixes and camera frames).
#pragma once

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "rng.hpp"
#include "safenav/filters.hpp"
#include "safenav/metrics.hpp"
#include "safenav/navigation.hpp"
#include "safenav/seed.hpp"
#include "safenav/trilateration.hpp"

namespace safenav::navigation_detail {

// ---------------------------------------------------------------------------
// One trial [SafeNav-ext Alg. 4]: the simulated vehicle and sensors around
// the vehicle's Guidance, and what the trial records.

class Trial {
 public:
  Trial(const Guidance& prototype, const SensorSettings& sensors, const ObstacleChecker& collisions,
        const Eigen::Matrix2d& imu_R, int max_steps, std::uint64_t seed, const PositionCallback& position, bool rec,
        const FrameCallback* frames, std::shared_ptr<const LanBLocFrontEnd> front_end)
      : t0_(std::chrono::steady_clock::now()),
        se_(sensors),
        bp_(prototype.problem().bmm),
        st_(prototype.settings()),
        collisions_(collisions),
        imu_R_(imu_R),
        position_cb_(position),
        frames_(frames),
        rec_(rec),
        N_(max_steps),
        bmm_(bp_),
        motion_rng_(derive_seed(seed, 0)),
        sensor_rng_(derive_seed(seed, 1)),
        // The vehicle's guidance: the same object a vehicle program ticks (guidance.hpp).
        guidance_(prototype.fresh(seed)),
        safe_(guidance_.safe_path().corridor()),
        zones_(guidance_.problem().zones),
        sensor_draws_(sensor_rng_),
        source_noise_(se_.position, sensor_draws_),
        source_R_(se_.position.reported_cov()),
        gate_(st_.filter.gate_probability),
        score_(static_cast<Eigen::Index>(max_steps) + 1) {
    truth_ = guidance_.start_state();  // the first path vertex, at rest, heading along the first edge
    obs_.reserve(static_cast<std::size_t>(se_.landmarks.rows()));
    trilateration_.seed = derive_seed(seed, 3);
    frame_fault_seed_ = derive_seed(seed, 4);
    start_seed_ = derive_seed(seed, 5);
    if (frames_ && front_end) check_front_end_ids(*front_end);
    if (frames_) guidance_.localizer().set_front_end(std::move(front_end));
  }

  TrialResult run();

 private:
  bool range_fix(const State& x, Eigen::Vector2d& z, Eigen::Matrix2d& R);
  bool fix(const State& x, int step, Eigen::Vector2d& z, Eigen::Matrix2d& R);
  bool first_frame(Eigen::Vector2d& z, Eigen::Matrix2d& R);
  void check_front_end_ids(const LanBLocFrontEnd& fe) const;
  bool frame(int step, double t, Eigen::Vector2d& z);
  SightingEdit frame_faults(int step);
  void dispute_start_fix(Eigen::Vector2d& z, Eigen::Matrix2d& R);
  void initialize();
  void start_recording();
  void record(int row, const Eigen::Vector2d& predicted, const Eigen::Vector2d* measured);
  void track_safety(const Eigen::Vector2d& a, const Eigen::Vector2d& b);
  bool command(int step, Command& cmd);
  bool measure(int step, double t, Eigen::Vector2d& z);
  bool ended(int step, const Eigen::Vector2d& before);
  void finish(int step);
  double fit_threshold(int dof) {
    while (static_cast<int>(fit_thresholds_.size()) < dof)
      fit_thresholds_.push_back(chi2_quantile(gate_, static_cast<int>(fit_thresholds_.size()) + 1));
    return fit_thresholds_[static_cast<std::size_t>(dof - 1)];
  }

  const std::chrono::steady_clock::time_point t0_;
  const SensorSettings& se_;
  const BmmParams& bp_;
  const NavigationSettings& st_;
  const ObstacleChecker& collisions_;  // the true obstacles, no clearance
  const Eigen::Matrix2d& imu_R_;
  const PositionCallback& position_cb_;
  const FrameCallback* frames_;  // the camera loop (run_frames), or null
  const bool rec_;
  const int N_;
  const Bmm bmm_;
  detail::Rng motion_rng_;
  detail::Rng sensor_rng_;
  Guidance guidance_;
  const Corridor& safe_;
  const RiskZones& zones_;
  State truth_;
  // Position source: the callback, or the measurement-level profile.
  RandomSourceOf<detail::Rng> sensor_draws_;
  PositionNoise::Trial source_noise_;
  const Eigen::Matrix2d source_R_;
  // FixModel::Ranges: landmark ranges, faults, LanBLoc trilateration.
  std::vector<LandmarkFaults::Observation> obs_;
  LocalizationOptions trilateration_;
  const double gate_;
  std::vector<double> fit_thresholds_;
  int fix_faults_ = 0;  // faulty ranges inside the last fix
  std::uint64_t frame_fault_seed_ = 0;  // the camera frames' landmark faults (frame_faults)
  std::uint64_t start_seed_ = 0;        // the rough start that a start fix is checked against
  TrialResult res_;
  // Metrics accumulate on the fly, so they need no recording.
  TrajectoryScore score_;
  // The true track's clearance: a cached lower bound, as the guard's.
  Eigen::Vector2d clear_p_ = Eigen::Vector2d::Zero();
  double clear_d_ = 0.0;
  TrialOutcome outcome_ = TrialOutcome::StepLimit;
  std::string reason_;
};

}  // namespace safenav::navigation_detail
