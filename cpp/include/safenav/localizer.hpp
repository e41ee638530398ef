// safenav/localizer.hpp — LanBLoc-BMM as an online object: the EKF or
// particle filter of [SafeNav eqs. 10–14] over the Battlefield Motion Model,
// ticked by a vehicle's own loop with timestamped inputs.
//
//   motion input        speed and heading change over the interval since the
//                       previous motion input (IMU, commanded control), or
//                       wheel odometry Δdistance/Δheading: a BMM step whose
//                       length comes from the timestamps (Bmm::with_step);
//   landmark observation  a landmark id with a range, a bearing or both and
//                       their σ, each gated on its own (χ² per observation);
//   position fix        a LanBLoc fix with its covariance;
//   speed and heading   an IMU measurement (v, θ).
//
// Time.  The filter keeps its own time t_f.  A measurement at t > t_f first
// predicts to t with the rates of the last motion input (speed, heading
// change per second).  The next motion input then applies, over the rest of
// its interval, only the distance and heading change that the measurements'
// predictions did not already add ("catch-up": on Plaza1 this beats scaling
// the input by the remaining fraction by 0.03 m RMSE, because the extrapolated
// rates are not what the odometry reported).  A measurement at t < t_f is
// *late*.  One at most settings.max_delay older is applied at its own time:
// the localizer keeps the inputs of the last max_delay seconds and, before
// each motion input, a copy of its filter; it goes back to the newest copy at
// or before the measurement's time and applies the logged inputs again with
// the late one in its place, which gives exactly the estimate of the same
// inputs given in time order (localizer_history.cpp).  A landmark
// observation from before a start from the data, arriving after it within
// max_delay, re-runs that start with the observation in the fit's window
// (status Buffered; Rejected when that fit is refused: the old start stands).
// An older measurement, and any late motion input, is not applied (status
// Late) and never applied at the wrong time.  Equal times are applied in call
// order.
//
// Initialization.  initialize() takes a prior.  Without one the localizer
// starts from the data.  It dead-reckons the motion inputs in their own frame
// (the motion integral: pose q(t) = (q_x, q_y, ψ_q)) and buffers every landmark
// observation (range, bearing or both) and IMU heading.  After each motion
// input it fits the rigid transform (X, Y, φ) from that frame to the world —
// world position T(q) = (X, Y) + R(φ)q, world heading ψ_q + φ — to the buffered
// data of the last init_window seconds (those at or after the first motion
// input's start), once one of these rules holds (the condition for each):
//   (a) range AND bearing of ≥ 2 distinct landmarks: the whole pose, even from
//       one instant (each sighting places the landmark relative to the
//       vehicle; two of them fix the heading too); no motion needed;
//   (b) an IMU heading (speed_heading) AND range and bearing of 1 landmark:
//       the heading row fixes φ, the sighting the position (a heading from
//       before the first motion input counts as taken where the motion
//       integral starts: the vehicle has not moved yet).  One landmark
//       without a heading never suffices: range and bearing are invariant to
//       rotating the whole track about the landmark;
//   (c) bearings alone: of ≥ 3 landmarks (resection, no motion needed), or of
//       2 once the motion integral's path in the window is ≥ init_min_path;
//   (d) ranges of ≥ init_min_beacons landmarks once the path is ≥
//       init_min_path (as before bearings were used: a range-only fit is
//       tried after every motion input and accepted on its range RMS in
//       metres and its position σ alone).
// Position fixes start it as before: with an IMU heading at once, else once
// the vehicle has moved init_baseline metres (the heading from two fixes and
// the motion between them).
// The fit (localizer_fit.hpp) minimises the normalised residuals of every
// buffered range, bearing and heading, with predictions and Jacobians from
// the one landmark model (landmark_geometry, predict_range, predict_bearing in
// measurement.hpp; k fixed at augment.scale_prior when the scale state is on):
// Gauss–Newton from 16 headings × 5 positions (with a range+bearing: × the
// landmarks' centroid and the position the newest range+bearing gives at that
// heading), residuals > 3σ dropped, refitted.  With bearings or headings a fit is tried only when one
// arrived since the last try.  It starts the filter at the newest motion
// input when
//   - ≥ 90 % of the residuals are kept (≤ 3σ),
//   - the inlier RMS ≤ init_max_rms: in metres of range for a range-only fit,
//     in σ (normalised, dimensionless) when bearings or headings are mixed in,
//   - the position σ at that input ≤ init_max_pos_std, and, with bearings or
//     headings, the heading σ ≤ 0.1 rad,
// and the geometry is not degenerate: JᵀJ is invertible (one landmark, no
// motion for bearings, a track along the line of the landmarks fail here) and
// no other start reached a transform > 5σ away with a cost within χ²₃(0.99)
// of the best (a mirror image: ambiguous).  reason() says what the window
// holds, what a start needs and the last fit's verdict.  Until the start
// inputs return Buffered.  It never needs a true pose.
//
// The filter.  The localizer holds one Filter (safenav/filter.hpp): the EKF
// or the particle filter, plain or — with settings.augment on (any of k, β,
// b_j) — augmented (safenav/augmented.hpp; motion through the β-corrected
// predict; with the augmented EKF odometry also owes the next step what the
// BMM's limits kept a catch-up step from applying).
//
// Bad input.  Every input either raises std::invalid_argument naming it and
// leaves the localizer as it was (time, estimate, counts: the prediction to a
// measurement's time and its update are one transaction), or returns with a
// finite estimate and a valid covariance.
//
// After construction a tick allocates nothing with the EKF (the particle
// filter's update allocates its scratch); initialization from data does.
// Only Eigen and std types appear here.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "safenav/augmented.hpp"
#include "safenav/filters.hpp"
#include "safenav/lanbloc.hpp"
#include "safenav/measurement.hpp"
#include "safenav/motion.hpp"
#include "safenav/smoother.hpp"

namespace safenav {

/// What became of one input.
enum class InputStatus {
  Applied,   ///< used by the filter
  Rejected,  ///< failed its χ² gate
  Late,      ///< older than the filter's time: not applied
  Buffered,  ///< kept for initialization from data (not initialized yet)
  Ignored,   ///< not initialized, and of no use to initialization
  /// A position fix that failed its gate after reset_after_rejections
  /// consecutive rejected fixes, or that agrees with the rejected fixes
  /// before it (reset_after_consistent): the filter restarts its position
  /// from it (the estimate had lost the track; without this a gate locks it out).
  Reset,
};
const char* to_string(InputStatus status);

/// The outcome of one input.
struct InputResult {
  InputStatus status = InputStatus::Applied;
  double nis = std::numeric_limits<double>::quiet_NaN();  ///< normalised innovation squared (updates)
  int dim = 0;                                            ///< its degrees of freedom
  double log_det_s = std::numeric_limits<double>::quiet_NaN();  ///< log det S of the NIS's S (UpdateResult)
  bool applied() const { return status == InputStatus::Applied || status == InputStatus::Reset; }
};

/// One landmark observation.  A NaN range or bearing means "not measured";
/// at least one must be given.  The bearing is relative to the heading,
/// counter-clockwise, in radians.
struct LandmarkObservation {
  int id = 0;
  double range = std::numeric_limits<double>::quiet_NaN();    ///< [m]
  double bearing = std::numeric_limits<double>::quiet_NaN();  ///< [rad]
  double range_std = 1.0;                                     ///< σ_r [m]
  double bearing_std = 0.05;                                  ///< σ_b [rad]
};

struct LocalizerSettings {
  BmmParams bmm;  ///< the motion model; bmm.dt is the nominal step its noise refers to
  /// EKF or particle filter.  Its gate_probability gates every update on
  /// its own (χ² at that probability; 0 = off); on (0.99) by default here.
  FilterOptions filter = [] {
    FilterOptions f;
    f.gate_probability = 0.99;
    return f;
  }();
  /// Augmented states (range scale, heading-rate bias, range biases); off by
  /// default.
  AugmentedStates augment;
  double init_window = 30.0;       ///< [s] odometry and ranges this recent are fitted together to start from the data
  double init_min_path = 3.0;      ///< [m] odometry path within the window before a range-only fit (rule d) or a fit to bearings of 2 landmarks (rule c) is tried
  int init_min_beacons = 3;        ///< distinct landmarks ranged within the window before a fit is tried
  /// Accept the fit only if its inlier residual RMS is below this: [m] of
  /// range for a range-only fit; in σ (normalised residuals, dimensionless)
  /// when the fit mixes in bearings or headings.
  double init_max_rms = 1.2;
  double init_max_pos_std = 0.5;   ///< [m] … and its position σ below this
  double init_max_heading_std = 0.1;    ///< [rad] … and, with bearings or headings in the fit, its heading σ below this
  double init_min_inlier_share = 0.9;   ///< … and it keeps at least this share of its residuals (≤ 3σ): a fit that explains the data only by dropping many (a mirror image) is not trusted
  double init_cov_inflation = 4.0; ///< the fit's pose covariance is multiplied by this
  double init_baseline = 5.0;      ///< [m] motion before the heading is taken from two position fixes
  double init_speed_std = 1.0;     ///< [m/s] σ of the initial speed (from the motion inputs)
  /// After this many consecutive position fixes fail the gate, the next fix
  /// that fails it too resets the position (InputStatus::Reset): x_y ← z,
  /// P_xy ← R, the position's cross-covariances 0; augmented states restart
  /// from 0, a particle filter redraws its particles.  0 = never.
  int reset_after_rejections = 10;
  /// A rejected fix that agrees with each of the reset_after_consistent − 1
  /// rejected fixes before it resets the position too (InputStatus::Reset):
  /// they agree when z_j − z_i minus the prediction's displacement between
  /// them passes the gate's χ²₂ test with covariance R_i + R_j + the growth
  /// of P_xy by the predictions between them.  Independent faults rarely
  /// agree; fixes that agree with each other and not with the filter say the
  /// filter has lost the track, even when an occasional fix gets through the
  /// gate between them (which restarts the consecutive count above) and
  /// agrees with them.  A fix through the gate discredits the kept rejected
  /// fixes that it disagrees with (the same test); all are forgotten after
  /// this many fixes in a row pass the gate.  0 = off; at most Localizer's 8
  /// kept rejected fixes.
  int reset_after_consistent = 3;
  /// A rejected fix that contradicts the newest fix through the gate (the
  /// same test as the agreement above, z − z_last minus the predicted
  /// displacement since, on R + R_last + the growth of P_xy since) beyond
  /// the χ²₂ quantile whose tail holds this probability is discredited: it
  /// counts toward no agreement reset (the consecutive count above still
  /// counts it).  A good fix lies beyond it with this probability when the
  /// filter's motion model is honest, so what it discredits are fixes that
  /// the motion since cannot explain: a faulty landmark's fixes repeated
  /// over a few frames, which agree with each other.  A reset clears the
  /// newest fix through the gate.  0 = off.
  double reset_discredit_tail = 1e-6;
  /// [s] A measurement at most this much older than the filter's time is
  /// applied at its own time (the inputs since are applied again after it);
  /// an older one is Late.  0 = every measurement older than the filter is Late.
  double max_delay = 0.5;
  void validate() const;
};

/// How a camera frame's result enters the filter (Localizer::observe_frame).
enum class FrameUpdate {
  Fix,        ///< the trilaterated fix with its covariance, through fix() (one χ² gate)
  Landmarks,  ///< each ranged landmark's range and bearing, through observe() (a gate each)
  /// The fix when the frame gives one (as Fix), else each ranged landmark's
  /// range and bearing (as Landmarks): a frame with too few whole markers for
  /// a fix (fewer ranges than min_landmarks) still informs the filter.
  FixOrLandmarks,
};

/// What became of one camera frame: where the front end searched (windows
/// from the filter's prediction, or the whole frame and why), what it found,
/// and how the filter took it.
struct FrameResult {
  SearchPlan plan;
  LanBLocFix fix;
  /// FrameUpdate::Fix: the fix's update (status Ignored without a fix).
  /// FrameUpdate::Landmarks: Applied when any landmark was applied, else the
  /// first landmark's status (Ignored without a range).  FixOrLandmarks: as
  /// Fix with a fix, else as Landmarks.
  InputResult update;
  /// Per fix.observations entry: its landmark update (Landmarks), or the fix's
  /// (Fix) for a ranged landmark; Ignored for one without a range.
  std::vector<InputResult> landmarks;
};

/// Counts of inputs by outcome.
struct LocalizerCounts {
  int motion = 0;    ///< motion inputs predicted
  int applied = 0;   ///< measurement updates applied
  int rejected = 0;  ///< failed the gate (resets included: their fix failed it too)
  int late = 0;      ///< older than the filter's time
  int buffered = 0;  ///< before initialization
  int ignored = 0;   ///< of no use (InputStatus::Ignored)
  int resets = 0;    ///< position resets after consecutive rejected fixes
};

/// The online filter.  Not thread-safe; one per vehicle.
class Localizer {
 public:
  /// `landmarks` (K×2) are the map; `ids` their ids (default 0 … K−1,
  /// distinct).  The particle filter's seed is settings.filter.seed.
  explicit Localizer(LocalizerSettings settings, Landmarks landmarks = Landmarks(), std::vector<int> ids = {});
  ~Localizer();
  Localizer(Localizer&&) noexcept;
  Localizer& operator=(Localizer&&) noexcept;

  /// Start (or restart) from a prior at time t.
  void initialize(double t, const State& x0, const StateCov& P0);
  bool initialized() const;
  /// The filter's time t_f (NaN before the first input).
  double time() const;

  /// Motion input over (t_prev, t]: desired speed [m/s] and heading change
  /// [rad] — the BMM's control (eqs. 3–9) over a step of t − t_prev.  The
  /// first motion input ever (no prior) covers one nominal step, bmm.dt.
  InputResult motion(double t, const Control& u);
  /// Wheel odometry over (t_prev, t]: the motion input (Δd / (t − t_prev), Δθ).
  InputResult odometry(double t, double distance, double heading_change);
  InputResult observe(double t, const LandmarkObservation& obs);
  InputResult fix(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  /// IMU speed and heading z = (v, θ) with covariance R.
  InputResult speed_heading(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R);

  /// Camera frames (ours).  The front end that observe_frame runs (one
  /// rectified grey pair per call); null turns frames off.  Its fixes come
  /// from its own map; FrameUpdate::Landmarks needs its ids to be this
  /// localizer's map ids.
  void set_front_end(std::shared_ptr<const LanBLocFrontEnd> front_end);
  const LanBLocFrontEnd* front_end() const { return front_end_.get(); }
  /// Where the frame at time t is searched: windows from the filter's own
  /// prediction to t (predict_to, or the estimate itself at t = time()), each
  /// landmark's projection grown by its projected σ (LanBLocFrontEnd::plan);
  /// the whole frame before the start, for a frame older than the filter, or
  /// when the prediction is too uncertain.  A renderer draws these regions.
  /// std::invalid_argument without a front end or for a non-finite t.
  SearchPlan frame_plan(double t) const;
  /// One rectified grey pair taken at time t: the front end searches where
  /// frame_plan(t) says, and its result enters the filter through the normal
  /// measurement path (fix() or observe(), each gated; a late frame as any
  /// late measurement).  std::invalid_argument as frame_plan, for images
  /// that do not fit the front end's rig, and (Landmarks) for a sighted id
  /// not in the map.
  FrameResult observe_frame(double t, const ImageView& left, const ImageView& right,
                            FrameUpdate how = FrameUpdate::Fix);
  /// The same on a pair whose pixels are drawn on demand (StereoPixels):
  /// only the boxes the front end reads are drawn.  `edit` changes the
  /// sightings before trilateration (LanBLocFrontEnd::localize).
  FrameResult observe_frame(double t, const StereoPixels& pixels, FrameUpdate how = FrameUpdate::Fix,
                            const SightingEdit& edit = SightingEdit());
  /// The same with the plan given: `plan` must be frame_plan(t) with no input
  /// given to the localizer since (a camera loop that rendered its regions),
  /// so that it is not computed twice.
  FrameResult observe_frame(double t, const StereoPixels& pixels, const SearchPlan& plan, FrameUpdate how,
                            const SightingEdit& edit = SightingEdit());

  /// The estimate predicted to t > time() as a measurement at t would be
  /// predicted to (eq. 11 at the last motion input's rates), on a copy of the
  /// filter: the localizer is left as it is.  False (x, P untouched) before
  /// the start or when t ≤ time().  The first call allocates the copy.
  bool predict_to(double t, State& x, StateCov& P) const;
  /// The time of the newest motion input (motion, odometry) and of the newest
  /// measurement (observe, fix, speed_heading) that was not late, buffered
  /// ones included; a stream not heard from before the start counts from the
  /// start (NaN: neither yet).  The stale-input watchdog's clock.
  double last_motion_time() const;
  double last_measurement_time() const;

  /// The estimate at time(), and √λ_max of its position covariance [m].
  const State& x() const;
  const StateCov& P() const;
  double position_std() const;
  const LocalizerCounts& counts() const;
  /// Why the localizer has not started ("waiting: …": what the window holds,
  /// what a start needs, and the last fit's verdict), or how it started
  /// ("started at t = … from the data (…)").
  std::string reason() const;
  const LocalizerSettings& settings() const;
  const Bmm& model() const;
  /// Row of landmark `id` in the map, or −1.
  int landmark_index(int id) const;
  const Landmarks& landmarks() const;
  /// The augmented filter when settings.augment is on and initialized, else null
  /// (its augmented() has k, β, b_j).
  const AugmentedEkf* augmented_filter() const;
  /// The full augmented state (x, y, v, θ, [k], [β], [b_j]) — the EKF's mean
  /// or the particles' weighted mean — or empty without augmented states.
  Eigen::VectorXd augmented_state() const;

  /// Fixed-lag smoothing beside the causal estimate (safenav/smoother.hpp):
  /// from now on every prediction feeds a Rauch–Tung–Striebel smoother, and
  /// the estimate at each motion input's time (and the start) becomes final,
  /// with the data up to that time + lag, once the filter passes it.  lag [s]
  /// finite and ≥ 0; the EKF only (plain or augmented: std::invalid_argument
  /// for the particle or information filter).  The causal estimate (x(), P())
  /// is unchanged; without set_lag nothing is recorded.  `kind`: the RTS
  /// pass over the filter's linearisation, or the iterated window solve with
  /// `iterations` Gauss–Newton passes per output (safenav/smoother.hpp).
  void set_lag(double lag, SmootherKind kind = SmootherKind::Rts, int iterations = 1);
  /// The smoother's kind (Rts when off).
  SmootherKind smoother() const;
  /// The smoother's lag [s], NaN when off.
  double lag() const;
  /// The smoothed estimates that became final since the last call, oldest first.
  std::vector<SmoothedEstimate> take_smoothed();
  /// End of the data: every smoothed estimate not yet final is smoothed with
  /// all the data there is (take_smoothed() then returns them).
  void finish_smoothing();

 private:
  InputResult motion_input(double t, const Control& u);
  InputResult odometry_input(double t, double distance, double heading_change);
  InputResult observe_input(double t, const LandmarkObservation& obs);
  InputResult fix_input(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  InputResult speed_heading_input(double t, const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::shared_ptr<const LanBLocFrontEnd> front_end_;  // camera frames (localizer_frame.cpp)
};

/// √ of the largest eigenvalue of P's 2×2 position block [m].
double position_std(const StateCov& P);

}  // namespace safenav
