// safenav/stereo.hpp — stereo ranging for LanBLoc ([SafeNav §IV-A]:
// "distances between the moving entity and the identified landmark
// anchors are calculated using an efficient stereo-matching technique").
//
//  * rectification from a stereo calibration (OpenCV stereoRectify +
//    initUndistortRectifyMap, maps computed once and cached);
//  * semi-global block matching (OpenCV StereoSGBM), float disparities in
//    pixels with NaN for invalid pixels;
//  * depth Z = f·B / (d + doffs) and the range to a detected landmark: the
//    median depth of the valid pixels inside its box, with
//    σ_Z ≈ Z²·σ_d / (f·B).
//
// OpenCV stays inside cpp/src: images cross this header as raw 8-bit
// buffers (ImageView in, Image out) and disparities as Eigen float matrices.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>
#include <Eigen/Core>

namespace safenav {

/// A stereo calibration as OpenCV's stereoCalibrate returns it: intrinsics
/// K1, K2, distortion D1, D2 (0, 4, 5, 8, 12 or 14 coefficients), and the
/// pose of camera 2 in camera 1's frame, X₂ = R X₁ + T.
struct StereoCalibration {
  Eigen::Matrix3d K1 = Eigen::Matrix3d::Identity();
  Eigen::VectorXd D1;
  Eigen::Matrix3d K2 = Eigen::Matrix3d::Identity();
  Eigen::VectorXd D2;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d T = Eigen::Vector3d::Zero();
  int width = 0;
  int height = 0;

  /// Throws std::invalid_argument naming the field at fault (non-finite
  /// entries, bad distortion length, R not a rotation, zero baseline, a
  /// vertical rig, non-positive image size).
  void validate() const;
};

/// The ideal rectified rig: both cameras have focal length f and principal
/// row cy; the right camera's principal column is cx + doffs; B is the
/// baseline (same unit as the depths).  Z = f·B / (d + doffs).
struct RectifiedCamera {
  double f = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  double baseline = 0.0;
  double doffs = 0.0;
  int width = 0;
  int height = 0;

  void validate() const;
};

/// Every StereoSGBM parameter (OpenCV's names and meanings).  P1 = P2 = 0
/// selects OpenCV's recommended 8·cn·block² and 32·cn·block².
struct SgbmParams {
  enum class Mode { SGBM = 0, HH = 1, SGBM3Way = 2, HH4 = 3 };
  int min_disparity = 0;
  int num_disparities = 64;  ///< > 0, divisible by 16
  int block_size = 5;        ///< odd, >= 1
  int P1 = 0;
  int P2 = 0;
  int disp12_max_diff = 1;
  int pre_filter_cap = 63;
  int uniqueness_ratio = 10;
  int speckle_window_size = 100;
  int speckle_range = 2;
  Mode mode = Mode::SGBM;

  void validate() const;
};

/// SGBM's disparity search for the depths [near_m, far_m] of `camera`
/// (safenav.vision.stereo.disparity_range calls this).  A depth Z is seen at
/// d(Z) = f·B/Z − doffs (d(∞) = −doffs), and SGBM searches the integer
/// disparities min_disparity ≤ d < min_disparity + num_disparities, so
///   min_disparity   = ⌊d(far_m)⌋,
///   num_disparities = 16·⌈(⌈d(near_m)⌉ + margin_px − min_disparity + 1)/16⌉
/// (d(near_m) snapped to an integer within 1e-9 relative of it first, so that a
/// depth on an exact disparity does not open one more).  Only those two fields
/// of `base` change.  Throws std::invalid_argument naming the value when
/// near_m is not finite and > 0, far_m is not > near_m, margin_px < 0,
/// block_size is not odd and >= 1, or the search leaves fewer than block_size
/// of the image's columns to match (SGBM leaves the first min_disparity +
/// num_disparities columns, and the last −min_disparity, without a disparity).
SgbmParams disparity_search(const RectifiedCamera& camera, double near_m, double far_m, const SgbmParams& base,
                            int margin_px = 2);

/// A borrowed 8-bit image (row-major, interleaved channels: 1 or 3).
struct ImageView {
  const std::uint8_t* data = nullptr;
  int rows = 0;
  int cols = 0;
  int channels = 1;
  std::ptrdiff_t row_stride = 0;  ///< bytes per row; 0 = cols·channels
};

/// An owned 8-bit image.
struct Image {
  std::vector<std::uint8_t> data;
  int rows = 0;
  int cols = 0;
  int channels = 1;
  ImageView view() const { return {data.data(), rows, cols, channels, 0}; }
};

using DisparityMap = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// A box in pixels: [x_min, x_max) × [y_min, y_max) (xyxy, as detectors give it).
struct Box {
  double x_min = 0, y_min = 0, x_max = 0, y_max = 0;
};

struct BoxRangeOptions {
  double sigma_d = 0.5;          ///< disparity noise σ_d in pixels
  int min_valid_pixels = 20;     ///< fewer valid pixels → no range
  double min_valid_fraction = 0.1;
  double min_disparity = 1.0;    ///< d + doffs below this (px) → beyond resolvable range
  double max_range = std::numeric_limits<double>::infinity();  ///< Z above this → no range

  void validate() const;
};

/// Range to a landmark from the disparities in its box.
struct BoxRange {
  bool ok = false;
  double range = std::numeric_limits<double>::quiet_NaN();  ///< median Z of valid pixels (along the optical axis)
  double sigma = std::numeric_limits<double>::quiet_NaN();  ///< σ_Z ≈ Z²·σ_d / (f·B)
  double disparity = std::numeric_limits<double>::quiet_NaN();  ///< median disparity d (px)
  int n_valid = 0;
  int n_pixels = 0;
  /// Centre of the box's part inside the image (whose pixels gave the
  /// range) back-projected at depth `range`, in the rectified left camera
  /// frame (x right, y down, z forward).
  Eigen::Vector3d point = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  std::string reason;  ///< why there is no range (empty when ok)
};

/// Rectification and SGBM for one calibrated rig.  Not thread-safe (it
/// reuses the matcher); use one per thread.
class StereoMatcher {
 public:
  /// A rig that needs rectification.
  StereoMatcher(const StereoCalibration& calibration, const SgbmParams& params = SgbmParams(),
                double alpha = 0.0);
  /// An already-rectified rig (renderer output, Middlebury): rectify() copies.
  explicit StereoMatcher(const RectifiedCamera& camera, const SgbmParams& params = SgbmParams());
  ~StereoMatcher();
  StereoMatcher(StereoMatcher&&) noexcept;
  StereoMatcher& operator=(StereoMatcher&&) noexcept;

  const RectifiedCamera& camera() const;
  const SgbmParams& params() const;
  bool needs_rectification() const;
  /// Rectification rotations and projections (identity / ideal for a
  /// rectified rig): R1, R2 (3×3), P1, P2 (3×4), Q (4×4).
  Eigen::Matrix3d R1() const;
  Eigen::Matrix3d R2() const;
  Eigen::Matrix<double, 3, 4> P1() const;
  Eigen::Matrix<double, 3, 4> P2() const;
  Eigen::Matrix4d Q() const;

  /// Remap both images into the rectified frame.  Throws std::invalid_argument
  /// on empty images, mismatched sizes or a size other than the calibration's.
  void rectify(const ImageView& left, const ImageView& right, Image& left_rect, Image& right_rect) const;
  /// Map raw left-image pixels (n×2) to rectified left pixels (n×2).
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> rectify_points_left(
      const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& pts) const;
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> rectify_points_right(
      const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& pts) const;
  /// SGBM disparity of a rectified pair, px, NaN where invalid.
  DisparityMap disparity(const ImageView& left_rect, const ImageView& right_rect) const;
  /// Z = f·B / (d + doffs); NaN where d is NaN or d + doffs <= 0.
  DisparityMap depth(const Eigen::Ref<const DisparityMap>& disparity) const;
  /// Median-depth range inside a box.
  BoxRange box_range(const Eigen::Ref<const DisparityMap>& disparity, const Box& box,
                     const BoxRangeOptions& options = BoxRangeOptions()) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace safenav
