// safenav/navigation.hpp — SafeNav safe-path navigation: SafeNav-CHull
// [SafeNav Alg. 1], SafeNav-Centroid [SafeNav Alg. 2] and the safe path
// navigation loop with RAw-RRT* replanning [SafeNav-ext Alg. 4] (= [SafeNav-conf
// Alg. 3]), with LanBLoc-BMM (EKF or PF) in the loop.  Citations follow
// docs/paper_map.md: algorithm line numbers differ between the versions.
//
// One trial: a true vehicle (the BMM with process noise and terrain) follows a
// safe path from its first to its last vertex.  Each step the navigator
//   1. chooses a control from the filter's estimate with the selected method,
//      which the uncertainty-aware guard may slow, steer or hold (ours,
//      guard.hpp; off in the papers' loop);
//   2. checks the path ahead for obstacles and replans with RAw-RRT* when it
//      is blocked (the detour is spliced into the path it follows);
//   3. moves the true vehicle;
//   4. measures — a LanBLoc position fix when enough landmarks are in the
//      camera's view, not hidden by an obstacle (SensorSettings::occlusion,
//      ours) (the measurement-level noise profile; or, ours, single
//      landmark ranges with landmark faults through LanBLoc's trilateration,
//      FixModel::Ranges; or a user callback such as the camera-in-the-loop
//      pipeline), plus IMU speed and heading — and updates the filter, each
//      update through its χ² gate (ours; off in the papers' loop);
//   5. records the true, predicted, measured and estimated trajectories, and
//      feeds the trial's TrajectoryScore (metrics.hpp): the estimate against
//      the truth, the risk and the safety of the true track (TrialMetrics).
// It ends at the destination or with an explicit failure (TrialOutcome).
//
// Only Eigen and std types appear here.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "safenav/corridor.hpp"
#include "safenav/filters.hpp"
#include "safenav/guidance.hpp"
#include "safenav/measurement.hpp"
#include "safenav/metrics.hpp"
#include "safenav/motion.hpp"
#include "safenav/params.hpp"
#include "safenav/planning.hpp"
#include "safenav/world.hpp"

namespace safenav {


/// How a trial ended.
enum class TrialOutcome {
  Arrived,           ///< the estimate reached the destination (within arrival_radius)
  Collision,         ///< the true vehicle's step crossed an obstacle
  LeftCorridor,      ///< the true vehicle left the safe buffer of the path it follows
  StepLimit,         ///< max_steps ran out
  LostLocalization,  ///< the position standard deviation exceeded lost_position_std
  NoPath,            ///< the path ahead was blocked and RAw-RRT* found no way round
  /// The guard gave up: a hold that could not end (σ could not halve), after
  /// its recoveries (GuidanceStatus::Blocked; the reason says why).
  Blocked,
};
std::string to_string(TrialOutcome outcome);

/// A position fix from a user callback (e.g. the camera-in-the-loop LanBLoc
/// pipeline): given the true state and the step, fill z and its covariance R
/// and return true, or return false when localization failed (a dropout).
using PositionCallback = std::function<bool(const State& truth, int step, Eigen::Vector2d& z, Eigen::Matrix2d& R)>;

/// Camera frames for the camera loop (ours): given the true state, the step
/// and the plan of where the vehicle's front end will search (windows from
/// its own prediction, or the whole frame), the rectified grey pair as
/// StereoPixels — whole images (StereoImages), or a renderer that draws the
/// boxes the front end asks for — or null when there is no frame.
using FrameCallback =
    std::function<std::shared_ptr<const StereoPixels>(const State& truth, int step, const SearchPlan& plan)>;

/// Where the simulator's position fixes come from.
enum class FixModel {
  /// The measurement-level error profile `position` (the paper's): a fix is
  /// the true position plus PositionNoise when >= min_landmarks are in view.
  Profile,
  /// LanBLoc from single landmark ranges (ours): each landmark in view gives
  /// a range with σ = range_std, landmark faults apply, and LanBLoc's
  /// trilateration (with its outlier rejection, trilateration.hpp) turns them
  /// into a fix with its own covariance.
  Ranges,
};
std::string to_string(FixModel model);

/// Observations after LandmarkFaults::apply (landmark rows, ranges, fault
/// flags) and how many were dropped.
struct FaultedObservations {
  std::vector<int> rows;
  std::vector<double> ranges;
  std::vector<unsigned> faults;  ///< LandmarkFaults flags of each observation
  int dropped = 0;
};
/// `faults` applied to observations (landmark `rows` of `landmarks`, their
/// `ranges`) of a vehicle at `position`, drawing from the core's generator
/// seeded with `seed` (as the simulator's sensors draw).  Throws
/// std::invalid_argument when rows and ranges differ in length, a row is not
/// a landmark of the map, or the faults are invalid.
FaultedObservations apply_faults(const LandmarkFaults& faults, const std::vector<int>& rows,
                                 const std::vector<double>& ranges, const Landmarks& landmarks,
                                 const Eigen::Vector2d& position, double confusion_range, std::uint64_t seed);

/// What the faults did to a camera frame's sightings (apply_sighting_faults).
struct SightingFaults {
  int observations = 0;   ///< ranged sightings before the faults
  int dropped = 0;
  int outliers = 0;
  int misassociated = 0;
};
/// `faults` on a camera frame's ranged sightings (the simulator's camera loop;
/// LanBLoc.apply_faults in Python does the same), with the vehicle at
/// `position` (a misassociation draws another landmark within
/// `confusion_range`): each ranged sighting goes through LandmarkFaults::apply
/// alone, drawing from derive_seed(seed, its landmark id), so what happens to
/// one does not depend on which others were found.  Dropped sightings are
/// removed; an outlier's range is changed; a misassociated one takes the other
/// landmark's id and `anchors` position (true_landmark_id says which it was).
/// `landmarks` and `ids` are the map (rows, one id per row; empty ids: the
/// rows); every ranged sighting's id must be in it.  Sightings without a range
/// pass unchanged.
SightingFaults apply_sighting_faults(const LandmarkFaults& faults, std::vector<LandmarkSighting>& sightings,
                                     const Landmarks& landmarks, const std::vector<int>& ids,
                                     const std::vector<LanBLocLandmark>& anchors, const Eigen::Vector2d& position,
                                     double confusion_range, std::uint64_t seed);

/// What the vehicle senses.
struct SensorSettings {
  PositionNoise position;              ///< the measurement-level source (LanBLoc by default)
  FixModel fix_model = FixModel::Profile;  ///< where fixes come from (Ranges: required by landmark faults)
  double range_std = 0.05;             ///< σ of one landmark range in FixModel::Ranges [m]
  LandmarkFaults faults;               ///< landmark-level faults (FixModel::Ranges, or a camera-loop callback)
  Landmarks landmarks;                 ///< K×2 landmark positions (map)
  /// The landmarks' ids (the world's), one per row of `landmarks`, distinct;
  /// empty: 0 … K−1.  The vehicle's localizer carries them, and the camera
  /// loop's front end must name its landmarks by them.
  std::vector<int> landmark_ids;
  double max_range = 30.0;             ///< landmark detection range [m]
  double field_of_view = 85.0 * kPi / 180.0;  ///< full horizontal FOV [rad], centred on the heading; ≥ 2π = all round
  int min_landmarks = 3;               ///< trilateration needs ≥ 3 ([SafeNav-ext §V-A3(ii)]: clusters of ≥ 3)
  /// Obstacles hide landmarks from the camera (ours; ObstacleChecker::line_of_sight:
  /// obstacles as tall as any landmark, hazards hide nothing).  Off in the papers' loop.
  bool occlusion = true;
  int position_every = 1;              ///< a fix every n steps
  bool imu = true;                     ///< IMU speed and heading every step
  double imu_speed_std = 0.05;         ///< [m/s]
  double imu_heading_std = 0.02;       ///< [rad]
  void validate() const;
  /// Landmarks in view of a vehicle at (x, y, θ): within max_range, inside
  /// the field of view and, when `occlusion` is on and the map's `obstacles`
  /// are given (true obstacles, no clearance), not hidden by one
  /// (ObstacleChecker::line_of_sight).  Without `obstacles` nothing is hidden.
  int landmarks_in_view(const State& x, const ObstacleChecker* obstacles = nullptr) const;
  /// The σ of a start position known without a fix: max(1, position σ) in each axis [m].
  double unfixed_start_std() const { return std::max(1.0, position.std.maxCoeff()); }
  /// The covariance a trial's localizer starts from (the simulator's one
  /// rule, which the belief planner predicts with): the start fix's R when
  /// there is one (`fix_R`), else unfixed_start_std() in each axis; the
  /// IMU's speed and heading variances.
  StateCov start_covariance(const Eigen::Matrix2d* fix_R) const {
    StateCov P0 = StateCov::Zero();
    const double s0 = unfixed_start_std();
    P0.topLeftCorner<2, 2>() = fix_R ? *fix_R : Eigen::Matrix2d(s0 * s0 * Eigen::Matrix2d::Identity());
    P0(2, 2) = imu_speed_std * imu_speed_std;
    P0(3, 3) = imu_heading_std * imu_heading_std;
    return P0;
  }
  /// f(row, distance) for each landmark in view of a vehicle at x (as
  /// landmarks_in_view), in map order.  The line of sight is asked only for
  /// landmarks in range and inside the field of view.
  template <class F>
  void for_each_in_view(const State& x, const ObstacleChecker* obstacles, F&& f) const;
};



struct TrialResult {
  TrialOutcome outcome = TrialOutcome::StepLimit;
  bool success = false;          ///< outcome == Arrived
  std::string reason;            ///< human-readable detail of the outcome
  int steps = 0;
  int replans = 0;
  int position_fixes = 0;        ///< accepted position updates
  int dropouts = 0;              ///< fix steps without a fix (no landmarks in view, failed callback, random loss)
  int rejected = 0;              ///< updates rejected by the NIS gate
  int resets = 0;                ///< position resets after consecutive rejected fixes (Localizer, InputStatus::Reset)
  int start_disputed = 0;        ///< 1 where the start fix and the rough start failed the gate together (ours): the start is their midpoint, its covariance holds both
  // Landmark observations (FixModel::Ranges): counts over the trial.
  int observations = 0;          ///< landmark observations made (landmarks in view, before faults)
  int dropped = 0;               ///< missed by a dropout fault
  int outliers = 0;              ///< outlier faults injected
  int misassociated = 0;         ///< misassociation faults injected
  int ranges_rejected = 0;       ///< ranges rejected by the trilateration's outlier test, or with a landmark seen twice in one frame (drop_repeated_landmarks)
  int faults_through = 0;        ///< faulty ranges that the filter accepted: inside a fix, or alone (camera loop)
  // Guard (guidance.hpp): steps on which it acted.
  int guard_slow = 0;            ///< slowed down
  int guard_steer = 0;           ///< steered away from the way the method chose
  int guard_hold = 0;            ///< stopped and held for a fix (turning toward landmarks)
  int guard_recover = 0;         ///< recovering from a stuck hold (backing up along the track, spinning)
  int stale_input = 0;           ///< stopped by the watchdog: an input older than input_timeout (kStaleInput)
  int chull_default = 0;         ///< Algorithm 1: steps that kept the default command
  int chull_corrective = 0;      ///< Algorithm 1: corrective controls
  int chull_step_back = 0;       ///< Algorithm 1: step-back controls
  double wall_time = 0.0;        ///< [s]
  TrialMetrics metrics;          ///< metrics.hpp (accumulated by TrajectoryScore)
  // Trajectories (rows 0 … steps), when NavigationSettings::record.
  RowMatrixX4 truth;             ///< true states
  RowMatrixX4 estimate;          ///< filter estimates
  RowMatrixX2 predicted;         ///< BMM prediction from the previous estimate with the chosen control (row 0 = start)
  RowMatrixX2 measured;          ///< position fixes (NaN when none)
  RowMatrixX2 controls;          ///< steps×2 (v_desired, Δθ)
  Eigen::VectorXd position_std;  ///< √λ_max(P_xy) per row
  Points2 followed_path;         ///< the path finally followed (with detours)
};

/// Runs trials of one navigation problem.  Construction builds the corridor,
/// segment hulls and centroids once; run() is const and thread-safe.
class Navigator {
 public:
  Navigator(NavigationProblem problem, NavigationSettings settings, SensorSettings sensors);
  ~Navigator();
  Navigator(Navigator&&) noexcept;
  Navigator& operator=(Navigator&&) noexcept;

  const NavigationProblem& problem() const;
  const NavigationSettings& settings() const;
  const SensorSettings& sensors() const;
  const PathSegments& segments() const;
  int max_steps() const;
  /// Guidance::nominal_trajectory over max_steps(): the trajectory a trial's
  /// vehicle would drive without noise.
  RowMatrixX4 nominal_trajectory() const;

  /// One trial with its own seed (process noise, measurement noise, PF,
  /// planner).  A position callback, when given, replaces the
  /// measurement-level position source.
  TrialResult run(std::uint64_t seed, const PositionCallback& position = nullptr) const;

  /// One trial with the camera in the loop: each fix step the vehicle's
  /// localizer plans where its front end searches (Localizer::frame_plan),
  /// `frames` renders the pair, and Localizer::observe_frame localizes and
  /// updates (the first frame, before any estimate, searches the whole frame
  /// and gives the prior).  Replaces the measurement-level position source.
  TrialResult run_frames(std::uint64_t seed, std::shared_ptr<const LanBLocFrontEnd> front_end,
                         const FrameCallback& frames) const;

  /// Trials for each seed with the measurement-level source, metrics only
  /// (no trajectories), in order.  Results equal run(seed) one by one.
  std::vector<TrialResult> run_many(const std::vector<std::uint64_t>& seeds) const;

 private:
  TrialResult run_trial(std::uint64_t seed, const PositionCallback& position, bool record,
                        const FrameCallback* frames = nullptr,
                        std::shared_ptr<const LanBLocFrontEnd> front_end = nullptr) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};


}  // namespace safenav
