// safenav/metrics.hpp — trajectory metrics of [SafeNav §V-B]: ADE, FDE and
// percent path-length error [SafeNav-ext eqs. 21–23]; plus the filter
// consistency statistics NEES and NIS.  WRS [SafeNav eq. 18] and AWRS
// [SafeNav-ext eq. 20] measure a trajectory against the safe corridor:
// corridor.hpp.  Citations follow docs/paper_map.md.
#pragma once

#include <vector>
#include <Eigen/Core>

#include "safenav/types.hpp"

namespace safenav {

/// Throws std::invalid_argument unless `points` has at least `min_rows` rows,
/// all finite; the message names `what` and the first bad point.
void check_points(const Eigen::Ref<const Points2>& points, const char* what, Eigen::Index min_rows = 1);

/// Power-of-two factor 2^−e that brings coordinates as large as `max_abs`
/// below 1 when they exceed 2^500, else 1.  Distances computed on points
/// scaled by it cannot overflow in their squares, and scaling by a power of
/// two is exact, so results in the ordinary range keep every bit.
double overflow_scale(double max_abs);

/// Mean of finite values without overflow in the sum (values near 1.8e308).
double finite_mean(const Eigen::Ref<const Eigen::VectorXd>& values);

/// ADE = (1/N) Σ ‖Ŷ_t − Y_t‖ [SafeNav-ext eq. 21].  Both trajectories must have the same
/// number of points (the definition pairs them by time).
double ade(const Eigen::Ref<const Points2>& estimate, const Eigen::Ref<const Points2>& truth);
/// FDE = ‖Ŷ_tf − Y_tf‖ [SafeNav-ext eq. 22].  Lengths may differ: only final points are used.
double fde(const Eigen::Ref<const Points2>& estimate, const Eigen::Ref<const Points2>& truth);
/// Polyline length Σ ‖p_{i+1} − p_i‖.
double path_length(const Eigen::Ref<const Points2>& path);
/// |L_est − L_true| / L_true × 100 [SafeNav-ext eq. 23].  Lengths may differ.
double path_length_error_percent(const Eigen::Ref<const Points2>& estimate,
                                 const Eigen::Ref<const Points2>& truth);

/// NEES_k = e_kᵀ P_k⁻¹ e_k per row, e = estimate ⊖ truth (θ residual wrapped
/// when `angle_index` ≥ 0).  errors: N×n, covariances: N×(n·n) row-major.
Eigen::VectorXd nees(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& estimates,
                     const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& truth,
                     const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& covariances,
                     int angle_index = -1);

}  // namespace safenav
