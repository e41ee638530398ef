// safenav/lanbloc.hpp — LanBLoc's stereo front end in the core
// ([SafeNav §IV-A]: landmarks recognised in the left image, their distances
// from stereo, trilateration with the landmarks as anchors).
//
// One rectified 8-bit grey stereo pair in (plain buffers: ImageView), the
// landmark map, the rig's calibration and optionally a predicted pose with its
// covariance; per-landmark observations (id, range, bearing, σ, status with a
// reason) and the trilaterated fix with its covariance out.  The steps are
// those of the Python whole-frame pipeline with corner ranging
// (safenav.vision.full_frame with ranging="corners"):
//
//  1. fiducial detection (OpenCV ArUco) in the left image, and in the right
//     image for the same ids; corners refined by cv::cornerSubPix with
//     OpenCV >= 4.8's window rule (as pip's cv2 refines for the Python side);
//  2. per marker found in both: its centre (the diagonals' intersection of
//     the left corners), the least-squares disparity plane d = a·u + b·v + c
//     through the four corner disparities evaluated there, Z = f·B/(d + doffs)
//     (StereoMatcher::depth) with σ_Z = Z²·σ_c/(f·B);
//  3. slant range s = ‖P‖ of the centre's 3D point, horizontal range
//     ρ = sqrt(s² − (z_ℓ − h)²) with σ_ρ = σ_s·s/ρ, and the bearing of the
//     centre relative to the heading (counter-clockwise);
//  4. trilateration (safenav::trilaterate) and the mirror ambiguity settled
//     by the bearings (a χ² test, 99.9 %).
//
// With ranging = Sgbm (the paper's dense stereo) step 2 is instead: SGBM
// (StereoMatcher) over the band of rows that holds the markers' boxes, and
// the median depth inside each box shrunk by box_shrink per side
// (StereoMatcher::box_range; safenav.vision.full_frame with ranging="sgbm").
// localize_boxes() ranges boxes that the caller's own detector found (a YOLO
// model for natural landmarks) the same way.
//
// Where to search (ours): with a predicted pose, each mapped landmark's board
// is projected from the prediction into both images and its box grown by the
// projection's 3σ (the pose covariance propagated to pixels through the
// projection's Jacobian); detection runs in those windows only.  Without a
// prediction, or when the windows would cover too large a share of the frame,
// the whole frame is searched.  The result says which.
//
// OpenCV stays inside cpp/src: only Eigen and std types cross this header.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>
#include <Eigen/Core>

#include "safenav/stereo.hpp"
#include "safenav/trilateration.hpp"

namespace safenav {

/// A mapped landmark: its id (= its marker id in the dictionary) and the
/// position of its marker's centre (x, y east/north, z height above the
/// ground) [m].
struct LanBLocLandmark {
  int id = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
};

/// The rectified rig (safenav.vision.rig.StereoRig): the camera (f, cx, cy,
/// baseline B, doffs, image size; Z = f·B/(d + doffs)), the camera centres'
/// height h above the ground and the pitch (positive looks up).  The vehicle's
/// position is the left camera's centre.
struct LanBLocRig {
  RectifiedCamera camera;
  double camera_height_m = 1.5;
  double pitch_rad = 0.0;

  void validate() const;  ///< std::invalid_argument naming the field at fault
};

/// How the front end measures a landmark's range.
enum class LanBLocRanging {
  Corners,  ///< ours: the fiducial's refined corners found in both images (corner_disparity)
  Sgbm,     ///< the paper's: the median SGBM depth inside the landmark's box in the left image
};
const char* to_string(LanBLocRanging ranging);  ///< "corners", "sgbm", as LanBLoc's ranging=

/// The pipeline's SGBM parameters (safenav.vision.ranging.PIPELINE_SGBM: 3-way, block 5,
/// uniqueness 10, speckle window 100 and range 2) with num_disparities = 0: the search then
/// covers the depths from min_range_m to infinity (LanBLocSettings::sgbm).
SgbmParams pipeline_sgbm();

/// The nearest depth SGBM must search to range a landmark min_range_m away
/// anywhere in the image: the depth of a point at that distance on the
/// image's farther side edge, min_range_m·cos(atan(max(cx, W − 1 − cx)/f))
/// (LandmarkRanging's matcher in Python calls this too).
double ranging_near_depth(const RectifiedCamera& camera, double min_range_m);

/// The front end's settings; the defaults are the Python pipeline's
/// (LanBLoc(..., ranging="corners") with FiducialDetector's defaults).
struct LanBLocSettings {
  /// OpenCV ArUco dictionary name ("DICT_4X4_100", "DICT_6X6_250",
  /// "APRILTAG_36h11", …); empty: no fiducial detection (the front end ranges
  /// the boxes of the caller's detector, localize_boxes; a landmark id is then any integer).
  std::string dictionary = "DICT_4X4_100";
  // --- detection (FiducialDetector)
  double min_perimeter_rate = 0.02;     ///< ArUco minMarkerPerimeterRate (of the larger side of the searched image)
  double error_correction_rate = 0.3;   ///< ArUco errorCorrectionRate
  double max_border_error_rate = 0.1;   ///< ArUco maxErroneousBitsInBorderRate
  bool subpixel = true;                 ///< CORNER_REFINE_SUBPIX
  int corner_refinement_win_size = 3;   ///< [px] cornerRefinementWinSize (the largest window)
  /// OpenCV >= 4.8's relativeCornerRefinmentWinSize: the window is
  /// min(round(this · cell size), corner_refinement_win_size) px, as pip's cv2
  /// (which the Python pipeline runs) refines; 0 = the linked ArUco's own
  /// refinement (OpenCV 4.6: always corner_refinement_win_size).
  double relative_corner_refinement_win_size = 0.3;
  /// Pyramid detection (ours, as the Python region pipeline's detect_side_px): each merged
  /// search window is searched at the pyramid level (2^L px averaged) where the smallest board
  /// predicted in it is at least this many pixels on a side (3 px per cell at 24), the whole
  /// frame at the level where a board at max_range_m is (full resolution when max_range_m is
  /// unbounded), and the corners found are refined back to full resolution; 0 = detect at full
  /// resolution.  At least 16.
  double detect_side_px = 24.0;
  // --- ranging (LandmarkRanging.observe_corners / sighting)
  /// [px] σ_d of the marker centre's disparity from its four corners: the
  /// measured RMS error of the refined corners' centre disparity, 0.0290 ±
  /// 0.0009 px over 502 markers rendered with pixel noise σ = 1 and the
  /// optics' blur σ = 0.8 px (bench/bench_corner_noise.py; Gaussian, kurtosis
  /// 3.0; no dependence on the marker's size in pixels was found).
  double corner_sigma_d = 0.029;
  /// Correlation of the disparity errors of the two corners on one vertical
  /// edge of a marker (measured 0.80–0.82; corners on different edges: −0.06).  A
  /// centre from three corners (the midpoint of one diagonal, one corner per
  /// edge) has σ = σ_d·sqrt(2/(1 + ρ)) (corner_disparity_sigma).
  double corner_edge_correlation = 0.8;
  double max_row_error_px = 1.0;        ///< [px] largest left/right row difference of a corner
  /// The square check of corner_disparity: the four edges of the marker
  /// triangulated in 3-D must agree in length, and the four corner
  /// disparities lie on one plane, within this many σ (σ from the corners'
  /// disparity noise); 0 turns it off.
  double corner_square_sigmas = 6.0;
  double bearing_sigma_px = 1.0;        ///< [px] σ of the centre, bearing σ = σ_px / f
  double max_range_m = std::numeric_limits<double>::infinity();  ///< [m] depths beyond: no range
  LanBLocRanging ranging = LanBLocRanging::Corners;  ///< corners (ours) or SGBM (the paper's)
  // --- SGBM ranging (ranging = Sgbm, and localize_boxes; LandmarkRanging.observe)
  /// SGBM's parameters; num_disparities = 0: min_disparity and num_disparities from
  /// disparity_search for the depths from min_range_m (at the image's edge: min_range_m·cos of
  /// the half field of view) to infinity, with a 2 px margin.
  SgbmParams sgbm = pipeline_sgbm();
  double min_range_m = 2.5;     ///< [m] the nearest landmark SGBM must range (num_disparities = 0)
  double sgbm_sigma_d = 0.5;    ///< [px] σ_d of a box's median disparity, σ_Z = Z²·σ_d/(f·B)
  double box_shrink = 0.1;      ///< each side of a box moves in by this share of its size before the median
  bool row_band = true;         ///< match only the rows that hold the boxes (16-row grid), not the whole image
  int band_margin_px = 24;      ///< [px] rows above and below the boxes in that band
  // --- trilateration (LandmarkRanging.solve)
  int min_landmarks = 3;                ///< ranges needed to trilaterate (the paper: at least 3)
  bool resolve_ambiguity = true;        ///< settle a mirror ambiguity by the bearings
  LocalizationOptions trilateration;    ///< safenav::trilaterate's options
  // --- search windows from the prediction (ours)
  double marker_size_m = 1.5;           ///< [m] side of the black-framed marker (the board adds one cell per side)
  double window_sigmas = 3.0;           ///< windows grow by this many projected σ
  double window_margin_px = 12.0;       ///< [px] quiet background around a board's box for the detector
  double max_window_fraction = 0.5;     ///< windows covering more of the frame than this: whole frame

  void validate() const;  ///< std::invalid_argument naming the field at fault
};

using MarkerCorners = Eigen::Matrix<double, 4, 2, Eigen::RowMajor>;  ///< TL, TR, BR, BL (u, v) [px]

/// A marker's centre and its disparity from its refined corners in both
/// rectified images (ours; LandmarkRanging.observe_corners in Python calls
/// the same function).  corner_disparity() fills it.
struct CornerDisparity {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  bool ok = false;              ///< whether disparity and sigma are valid
  std::string reason;           ///< why not (empty when ok)
  Eigen::Vector2d centre = Eigen::Vector2d::Constant(kNaN);  ///< the centre's image, left [px]
  double disparity = kNaN;      ///< d at the centre [px]
  double sigma = kNaN;          ///< σ_d of d [px] (corner_disparity_sigma)
  double side_px = kNaN;        ///< the marker's mean side in the left image [px]
  int corners_used = 0;         ///< 4, or 3 when one corner's rows disagree
  int dropped_corner = -1;      ///< that corner (0..3: TL, TR, BR, BL), else −1
};

/// The image of a marker's centre: the intersection of the diagonals 0–2 and
/// 1–3 of its corners (the centre under the homography; the corners' mean
/// when the diagonals are parallel).
Eigen::Vector2d marker_centre(const MarkerCorners& corners);

/// σ_d [px] of a marker centre's disparity from its corners: the corner-noise
/// model fitted to the refined corners' measured errors
/// (bench/bench_corner_noise.py, docs/lanbloc_cpp.md).  Four corners: the
/// plane at the centre is the mean of the four corner disparities (exact for
/// a parallelogram), σ = corner_sigma_d.  Three: the mean of two corners on
/// different edges, whose variance is 2/(1 + ρ) times the four's, ρ =
/// corner_edge_correlation (the four's is σ_c²·(1 + ρ)/4 for per-corner σ_c,
/// the two's σ_c²/2).  Times `scale` (2^L for corners refined at pyramid
/// level L).
/// Markers under kSmallMarkerSidePx a side (mean, left image, px at full
/// resolution) have kSmallMarkerSigmaFactor times that σ: OpenCV's refinement
/// window (0.3 cell, rounded) is 1 px there, and under the optics' blur the
/// centre's disparity RMS was 0.15 px for 20–30 px against 0.029–0.037 px
/// from 30 px up (bench/bench_corner_noise.py at 640 px wide).
inline constexpr double kSmallMarkerSidePx = 30.0, kSmallMarkerSigmaFactor = 5.0;
double corner_disparity_sigma(const LanBLocSettings& settings, int corners_used, double scale = 1.0,
                              double side_px = std::numeric_limits<double>::infinity());

/// A marker's centre and disparity from its corners (ours):
///  * every corner's rows agree within settings.max_row_error_px: the least-squares
///    disparity plane d = a·u + b·v + c through the four corner disparities
///    (the marker is a plane, so its disparity is affine in (u, v)), evaluated
///    at marker_centre(left);
///  * exactly one corner k disagrees (hidden differently in the two images,
///    e.g. behind another board's edge): corners k+1 and k+3 triangulated,
///    P_i = Z_i·((u_i − cx)/f, (v_i − cy)/f, 1) with Z_i = f·B/(d_i + doffs),
///    and the centre is the image of their midpoint, the marker's centre (exact
///    for exact corners); its disparity d = f·B/M_z − doffs; the three
///    corners that agree must do so;
///  * two or more disagree: no disparity, with the reason.
/// Then the square check (settings.corner_square_sigmas > 0): the corners
/// triangulated must give four edges of one length, each within n σ of the
/// others (σ from the corners' depth noise, σ_Z = Z²·σ_c/(f·B) along their
/// rays, σ_c the per-corner disparity σ).  A corner hidden behind a nearer
/// board in one image moves along its row, which the row check cannot see:
/// when exactly one corner's two edges disagree with the two edges away from
/// it, that corner is dropped as above; otherwise no disparity, with the
/// reason.  With a corner already dropped, the two edges away from it must
/// agree.  With four edges that agree, the residual of the disparity plane
/// must be within n σ too (one residual direction for four corners; σ from
/// corner_edge_correlation): a corner moved along its own ray barely changes
/// the edges of a board facing the camera, but moves the residual by about
/// half its shift; such a corner cannot be told from the others, so no
/// disparity.
/// σ_d = corner_disparity_sigma(settings, corners used, scale, the left
/// marker's mean side).
CornerDisparity corner_disparity(const MarkerCorners& left, const MarkerCorners& right, const RectifiedCamera& camera,
                                 const LanBLocSettings& settings, double scale = 1.0);

/// A predicted pose (x, y, θ) and its 3×3 covariance, e.g. the filter's
/// prediction for the frame's time.
struct PosePrediction {
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

enum class LanBLocStatus { Ok, NoLandmarks, TooFewRanges, Degenerate, DidNotConverge };
const char* to_string(LanBLocStatus status);  ///< "ok", "no_landmarks", …, as safenav.vision's STATUSES

enum class SearchMode { WholeFrame, Windows };
const char* to_string(SearchMode mode);  ///< "whole_frame", "windows"

/// A search window of one landmark in one image: [x_min, x_max) × [y_min, y_max)
/// in pixels, clipped to the image.
struct SearchWindow {
  int landmark_id = 0;
  bool right = false;  ///< in the right image
  Box box;
  Eigen::Vector2d predicted_centre = Eigen::Vector2d::Zero();  ///< projected marker centre [px]
  Eigen::Vector2d sigma_px = Eigen::Vector2d::Zero();          ///< its projected σ (u, v) [px]
};

/// Where a frame is searched: the mode and its reason, the prediction the
/// windows came from (none: whole frame), each landmark's windows, and the
/// regions of each image that detection runs in (the windows, those that
/// overlap merged into their bounding box; empty in WholeFrame mode).  A
/// renderer that draws only part of the image draws these regions
/// (LanBLocFrontEnd::plan).
struct SearchPlan {
  SearchMode mode = SearchMode::WholeFrame;
  std::string reason = "no prediction given";
  std::optional<PosePrediction> prediction;
  std::vector<SearchWindow> windows;  ///< when mode == Windows
  std::vector<Box> left_regions, right_regions;
};

/// One mapped landmark detected in the left image: what stereo made of it
/// (safenav.vision.sighting.LandmarkSighting; not the Localizer's timestamped
/// LandmarkObservation, localizer.hpp).
struct LandmarkSighting {
  int landmark_id = 0;
  bool ok = false;  ///< whether range and σ are valid
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double range = kNaN;          ///< horizontal range ρ [m]
  double sigma = kNaN;          ///< σ_ρ [m]
  double bearing = kNaN;        ///< relative to the heading, counter-clockwise [rad]
  double bearing_sigma = kNaN;  ///< [rad]
  double slant_range = kNaN;    ///< s [m]
  double depth = kNaN;          ///< Z [m]
  double disparity = kNaN;      ///< d at the centre [px]
  Eigen::Vector2d centre = Eigen::Vector2d::Constant(kNaN);  ///< left image [px]
  Eigen::Vector3d anchor = Eigen::Vector3d::Constant(kNaN);  ///< the landmark's map position
  MarkerCorners corners_left = MarkerCorners::Constant(kNaN);
  MarkerCorners corners_right = MarkerCorners::Constant(kNaN);  ///< NaN when not found
  int corners_used = 0;  ///< corners the disparity came from (corner_disparity): 4, 3, or 0 without
  Box box;               ///< the landmark's box in the left image (the corners' bounding box for a marker)
  int n_valid = 0;       ///< SGBM: valid disparities in the shrunk box (StereoMatcher::box_range)
  std::string reason;  ///< why there is no range (empty when ok)
  /// Landmark faults applied to this sighting (LandmarkFaults::Fault flags;
  /// 0 without a SightingEdit that applies them, e.g. the simulator's).
  unsigned faults = 0;
  /// The landmark actually seen when a fault relabelled the sighting
  /// (misassociation: landmark_id and anchor are then the wrong landmark's);
  /// −1 otherwise.
  int true_landmark_id = -1;
};

/// Changes a frame's sightings before trilateration: it may drop, relabel or
/// change the ranged ones (ok), e.g. the simulator's landmark faults
/// (Navigator's camera loop), or a vehicle's exclusion of landmarks it knows
/// to be moved.  An empty function changes nothing.
using SightingEdit = std::function<void(std::vector<LandmarkSighting>&)>;

/// A landmark that the caller's own detector recognised in the rectified
/// left image (e.g. a YOLO model for natural landmarks): its id in the map
/// and its box [px].
struct LandmarkBox {
  int landmark_id = 0;
  Box box;
};

/// A frame's result: status and reason, the fix (NaN unless ok), every
/// detected landmark's observation (by id), the search mode and windows.
struct LanBLocFix {
  LanBLocStatus status = LanBLocStatus::NoLandmarks;
  std::string reason;
  Eigen::Vector2d position = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Constant(std::numeric_limits<double>::quiet_NaN());
  double gdop = std::numeric_limits<double>::quiet_NaN();
  LocalizationResult localization;  ///< the trilateration's (empty when it did not run)
  std::vector<LandmarkSighting> observations;
  SearchMode search = SearchMode::WholeFrame;
  std::string search_reason;  ///< why this mode
  std::vector<SearchWindow> windows;  ///< when search == Windows
  /// The regions searched when search == Windows: each image's windows, those
  /// that overlap merged into their bounding box (a marker is found when it
  /// lies whole inside one).
  std::vector<Box> left_regions, right_regions;
  std::vector<int> unmapped;          ///< marker ids detected in the left image but not in the map

  bool ok() const { return status == LanBLocStatus::Ok; }
  int n_ranges() const;
};

/// A rectified grey stereo pair whose pixels are read on demand (ours): the
/// front end asks for the boxes it reads, at the pyramid level it reads them,
/// so a simulator draws only those (the camera loop) while a camera hands over
/// whole images (StereoImages).  draw() writes the level-`level` pixels of a
/// box of `width` × `height` level pixels whose top-left full-resolution pixel
/// is (x0, y0): level pixel (i, j) is the mean of the 2^level × 2^level
/// full-resolution pixels from (x0 + i·2^level, y0 + j·2^level), and the box
/// lies inside the rig's image.  Calls for one frame come from one thread, in
/// an order that depends only on the pixels drawn before.
class StereoPixels {
 public:
  virtual ~StereoPixels() = default;
  /// Writes the box of the left (right = false) or right image into `out`:
  /// `height` rows of `width` bytes, `stride` bytes apart.
  virtual void draw(bool right, int level, int x0, int y0, int width, int height, std::uint8_t* out,
                    std::ptrdiff_t stride) const = 0;
};

/// Two whole images as StereoPixels: level 0 copied, a level L > 0 averaged
/// over whole 2^L × 2^L blocks (OpenCV's INTER_AREA).  The views must outlive
/// it; std::invalid_argument on an empty view or one that is not 8-bit grey.
class StereoImages final : public StereoPixels {
 public:
  StereoImages(const ImageView& left, const ImageView& right);
  void draw(bool right, int level, int x0, int y0, int width, int height, std::uint8_t* out,
            std::ptrdiff_t stride) const override;
  const ImageView& left() const { return left_; }
  const ImageView& right() const { return right_; }

 private:
  ImageView left_, right_;
};

/// LanBLoc's front end for one rig, landmark map and settings.  localize()
/// and search_windows() are const and write no shared state: one front end
/// may serve several threads.
class LanBLocFrontEnd {
 public:
  /// Throws std::invalid_argument on a bad rig or settings, an unknown
  /// dictionary, duplicate or out-of-dictionary landmark ids, non-finite
  /// positions.
  LanBLocFrontEnd(const LanBLocRig& rig, std::vector<LanBLocLandmark> landmarks,
                  const LanBLocSettings& settings = LanBLocSettings());
  ~LanBLocFrontEnd();
  LanBLocFrontEnd(LanBLocFrontEnd&&) noexcept;
  LanBLocFrontEnd& operator=(LanBLocFrontEnd&&) noexcept;

  const LanBLocRig& rig() const;
  const LanBLocSettings& settings() const;
  const std::vector<LanBLocLandmark>& landmarks() const;

  /// One rectified grey pair (1 channel, the rig's size) → observations and
  /// fix.  With a prediction the search is in windows around the landmarks'
  /// predicted projections (see search_windows); without, the left image is
  /// searched whole and the right one along the rows of the landmarks found
  /// in the left, over the disparities their marker size allows.  Throws
  /// std::invalid_argument on images of the wrong size or channels, or a
  /// non-finite or non-symmetric-PSD prediction.
  LanBLocFix localize(const ImageView& left, const ImageView& right,
                      const std::optional<PosePrediction>& prediction = std::nullopt) const;
  /// The same with the search planned beforehand (plan(prediction)): a
  /// camera loop asks for the plan, renders or reads the regions it names,
  /// then localizes in exactly those regions.
  LanBLocFix localize(const ImageView& left, const ImageView& right, const SearchPlan& plan) const;
  /// The same on pixels read on demand: only the boxes that detection and
  /// corner refinement read are drawn (each region at its pyramid level, and
  /// full-resolution patches around the corners found there).  Equal to
  /// localize(left, right, plan) on StereoImages(left, right).
  LanBLocFix localize(const StereoPixels& pixels, const SearchPlan& plan) const;
  /// The same with `edit` applied to the sightings before trilateration.
  LanBLocFix localize(const StereoPixels& pixels, const SearchPlan& plan, const SightingEdit& edit) const;

  /// The paper's SGBM ranging of landmarks that the caller's detector found
  /// (ranging = Sgbm whatever settings.ranging says): SGBM over the band of
  /// rows that holds the boxes, each box's median depth (box_shrink, sgbm_sigma_d,
  /// max_range_m), the bearing of its centre, then trilateration as localize().
  /// Ids not in the map are listed in LanBLocFix::unmapped and skipped; the
  /// first box of an id is kept.  Throws std::invalid_argument on images of
  /// the wrong size or channels, or a box that is not finite or is empty.
  LanBLocFix localize_boxes(const ImageView& left, const ImageView& right,
                            const std::vector<LandmarkBox>& boxes) const;
  /// The same on pixels read on demand (the band's rows of both images at
  /// full resolution), with `edit` applied to the sightings before trilateration.
  LanBLocFix localize_boxes(const StereoPixels& pixels, const std::vector<LandmarkBox>& boxes,
                            const SightingEdit& edit = SightingEdit()) const;

  /// Where localize(…, prediction) searches: search_windows for a prediction
  /// (WholeFrame with the reason when too uncertain), merged into each
  /// image's regions; WholeFrame ("no prediction given") without one.
  SearchPlan plan(const std::optional<PosePrediction>& prediction) const;

  /// The windows for `prediction`: per mapped landmark whose board projects
  /// in front of both cameras within max_range_m and into the image, the
  /// board's box in each image (the bounding box of the upright board at any
  /// yaw about its vertical axis: the 16-sided prism around it, projected)
  /// grown by window_sigmas·σ (Jacobian of the
  /// centre's projection with respect to (x, y, θ) times the covariance) plus
  /// window_margin_px.  Empty `mode_reason` and mode Windows, or mode
  /// WholeFrame with the reason (too uncertain).
  std::vector<SearchWindow> search_windows(const PosePrediction& prediction, SearchMode& mode,
                                           std::string& mode_reason) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace safenav
