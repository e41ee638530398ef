// safenav/filter.hpp — the one interface of the online filters: the EKF of
// [SafeNav eqs. 10–14] and the particle filter (the LanBLoc-BMM(PF) rows of
// [SafeNav-ext Tables II–III]) over the BMM state (x, y, v, θ) [SafeNav
// eqs. 3–9], each plain or with augmented sensor-error states
// (safenav/augmented.hpp, ours).
//
// Design.  One abstract class, Filter: predict over dt, update with a landmark
// observation (the landmark model of safenav/measurement.hpp), a position fix
// or an IMU speed and heading, the χ² gate, the 4-state estimate and its
// covariance, the full augmented state, and a restart (make_filter).  The EKF
// and the PF are its implementations; "augmented" is a configuration of each
// (AugmentedStates on), served by AugmentedEkf / AugmentedParticleFilter,
// whose state has extra blocks of run-time size.  The plain 4-state EKF keeps
// its fixed-size 4×4 arithmetic (a tick in well under 2 µs, numbers pinned bit
// for bit), which is why the plain and augmented classes stay two storage
// layouts behind the one interface rather than one class with a run-time size.
//
// The checks live here, once (a non-virtual interface): every public call
// refuses bad input with std::invalid_argument naming it, and after the
// implementation ran checks the result — a finite state and a covariance that
// is finite with no negative variance and positive semi-definite within
// rounding (the EKF: Cholesky, else no eigenvalue below −1e-12·max|P_ij|) or
// finite (the particles' weighted covariance, positive semi-definite by
// construction).  A
// call that fails leaves the filter as it was (a Transaction restores a
// snapshot taken before it); the Localizer wraps the prediction to a
// measurement's time and the update in one Transaction.
//
// Only Eigen and std types appear here.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>

#include <Eigen/Core>

#include "safenav/filters.hpp"
#include "safenav/motion.hpp"

namespace safenav {

struct AugmentedStates;
class AugmentedEkf;
class Ekf;

/// One landmark observation as the filters take it: the landmark's row in
/// the map and its position; a range, a bearing or both (NaN = not measured)
/// with their σ.
struct LandmarkMeasurement {
  int row = 0;
  Eigen::Vector2d landmark = Eigen::Vector2d::Zero();
  double range = std::numeric_limits<double>::quiet_NaN();    ///< [m]
  double bearing = std::numeric_limits<double>::quiet_NaN();  ///< relative, counter-clockwise [rad]
  double range_std = 1.0;                                     ///< σ_r [m]
  double bearing_std = 0.05;                                  ///< σ_b [rad]
  bool has_range() const { return !(range != range); }
  bool has_bearing() const { return !(bearing != bearing); }
};

class Filter {
 public:
  virtual ~Filter();
  FilterType type() const { return type_; }
  /// Whether augmented states are on (AugmentedStates::any()).
  bool augmented() const { return augmented_; }

  /// Eq. 11 over dt seconds (Bmm::with_step; the augmented filters correct
  /// the heading by β·dt).  dt finite and > 0, u finite.
  void predict(const Control& u, double dt);
  /// Eqs. 12–14 (the EKF) or the likelihood weights (the PF) of one landmark
  /// observation; throws std::domain_error when the estimate is at the landmark.
  UpdateResult update(const LandmarkMeasurement& m);
  /// A position fix z with its covariance R (h(x) = (x, y)).
  UpdateResult update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  /// IMU z = (v, θ) with covariance R (angle residual wrapped).
  UpdateResult update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R);
  /// χ² gate of every update at this probability, in [0, 1) (0 = off).
  void set_gate(double probability);

  /// The estimate of (x, y, v, θ) (the particles' weighted mean, circular in θ)
  /// and its covariance.  Right after construction: the prior itself.
  const State& x() const;
  const StateCov& P() const;
  /// The full state (x, y, v, θ, [k], [β], [b_j]), or empty without augmented states.
  /// A copy in new storage: the estimate, particles and generator state (a
  /// copy goes on exactly as the original would).  The Localizer's history of
  /// checkpoints for late measurements holds these.
  std::unique_ptr<Filter> clone() const;
  /// Become a copy of `other`, a filter of the same implementation (clone()),
  /// in this filter's storage: no allocation for the same sizes.  Throws
  /// std::logic_error for another implementation or inside a Transaction.
  void assign(const Filter& other);

  virtual Eigen::VectorXd augmented_state() const { return Eigen::VectorXd(); }
  /// The augmented EKF behind this filter, or null.
  virtual const AugmentedEkf* augmented_ekf() const { return nullptr; }
  /// The plain 4-state EKF behind this filter, or null.
  virtual const Ekf* ekf() const { return nullptr; }

  /// Calls inside a Transaction either all stand or, when one throws, the
  /// filter returns to its state at the Transaction's start.  Nested
  /// Transactions join the outermost one, whose commit() checks the result
  /// once (throwing, and so restoring, when it is not finite or not a valid
  /// covariance; `step` names the call in the error).
  class Transaction {
   public:
    explicit Transaction(Filter& f);
    ~Transaction();
    void commit(const char* step);
    Transaction(const Transaction&) = delete;
    Transaction& operator=(const Transaction&) = delete;

   private:
    Filter& f_;
    bool outer_, committed_ = false;
  };

 protected:
  Filter(FilterType type, bool augmented, const State& x0, const StateCov& P0);
  virtual void do_predict(const Control& u, double dt) = 0;
  virtual UpdateResult do_update(const LandmarkMeasurement& m) = 0;
  virtual UpdateResult do_update_position(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) = 0;
  virtual UpdateResult do_update_speed_heading(const Eigen::Vector2d& z, const Eigen::Matrix2d& R) = 0;
  virtual void do_set_gate(double probability) = 0;
  /// The estimate and its covariance now (called when the cache is stale).
  virtual void estimate(State& x, StateCov& P) const = 0;
  /// Throws when the implementation's own state (e.g. the full augmented
  /// covariance) is not finite or not a valid covariance; `step` names the call.
  virtual void check_state(const char* step) const = 0;
  virtual void save() = 0;
  virtual void restore() = 0;
  virtual std::unique_ptr<Filter> do_clone() const = 0;
  virtual void do_assign(const Filter& other) = 0;
  Filter(const Filter&) = default;
  Filter& operator=(const Filter&) = default;

 private:
  template <class F>
  UpdateResult checked(const char* step, F&& f);
  void check_result(const char* step) const;
  FilterType type_;
  bool augmented_;
  int depth_ = 0;
  mutable bool dirty_ = false;
  mutable State x_;
  mutable StateCov P_;
  State saved_x_;
  StateCov saved_P_;
  bool saved_dirty_ = false;
};

/// The filter `options.type` (the EKF or the PF; InformationFilter is refused)
/// over `params`, augmented as `augment` says for a map of `n_landmarks`, started
/// at (x0, P0) with the gate of options.gate_probability; a PF draws with `seed`.
std::unique_ptr<Filter> make_filter(const FilterOptions& options, const BmmParams& params,
                                    const AugmentedStates& augment, int n_landmarks, const State& x0,
                                    const StateCov& P0, std::uint64_t seed);

}  // namespace safenav
