// Private parts of the LanBLoc front end (safenav/lanbloc.hpp), shared by
// lanbloc.cpp (corner ranging, trilateration), lanbloc_sgbm.cpp (SGBM ranging)
// and lanbloc_detect.cpp (ArUco detection, search windows).  OpenCV appears
// only here and in those files.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/aruco.hpp>

#include "safenav/lanbloc.hpp"

namespace safenav::lanbloc_detail {

/// The predefined dictionary named `name` (case-insensitive, "DICT_" optional);
/// std::invalid_argument listing the known names otherwise.
cv::Ptr<cv::aruco::Dictionary> dictionary(const std::string& name);

/// World → camera rotation, rows: camera x = right, y = down, z = forward,
/// for heading θ (counter-clockwise from +x) and pitch (positive up)
/// (safenav.vision.rig.camera_rotation).
Eigen::Matrix3d camera_rotation(double theta, double pitch);

/// A detected marker: its id and four corners (TL, TR, BR, BL) in pixels.
struct Marker {
  int id = 0;
  MarkerCorners corners;
};

/// Sub-pixel corner refinement as OpenCV >= 4.8 does it (relative_win_size > 0), run after a
/// detection without refinement; relative_win_size = 0 leaves it to the linked ArUco (fixed window).
struct CornerRefinement {
  double relative_win_size = 0.3;  ///< OpenCV's relativeCornerRefinmentWinSize
  int max_win_size = 3;            ///< cornerRefinementWinSize
  int max_iterations = 30;         ///< cornerRefinementMaxIterations
  double min_accuracy = 0.1;       ///< cornerRefinementMinAccuracy [px]
};

/// A region of an image searched at pyramid level `level` (2^level × 2^level pixels averaged).
struct Region {
  Box box;
  int level = 0;
};

/// The regions of `plan` in one image (right: the right image's), each with the pyramid level
/// where the smallest board predicted in it (its windows' landmarks, at their farthest depth within
/// window_sigmas·σ of the predicted position) is at least settings.detect_side_px wide (as the
/// Python region pipeline chooses it); level 0 when detect_side_px is 0, without subpixel
/// refinement, without a prediction, or for a region without windows.
std::vector<Region> detection_regions(const LanBLocRig& rig, const LanBLocSettings& settings,
                                      const std::vector<LanBLocLandmark>& landmarks, int marker_bits,
                                      const SearchPlan& plan, bool right);

/// The pyramid level of a region `box` whose smallest board is `side` px: the coarsest (at most 6)
/// where that board is still `detect_side_px` wide and the region at least 16 px.
int pyramid_level(double side, const Box& box, double detect_side_px);

/// `box` as a region at the level where a board at `settings.max_range_m` (the farthest that gives a
/// range) is still `detect_side_px` wide (pyramid_level); level 0 with detect_side_px = 0, no
/// sub-pixel refinement or an unbounded range.
Region far_board_region(const LanBLocRig& rig, const LanBLocSettings& settings, int marker_bits, const Box& box);

/// The whole frame as one region at its far_board_region level.
Region whole_frame_region(const LanBLocRig& rig, const LanBLocSettings& settings, int marker_bits);

/// The right image's regions when the left was searched whole: each left marker's box carried
/// along its rows (the rig is rectified) over the disparities of depths from half to twice the
/// depth its vertical sides give (f·marker_size_m / side), grown by window_margin_px and a cell,
/// overlaps merged, each at the whole frame's level (far_board_region).
std::vector<Region> epipolar_regions(const LanBLocRig& rig, const LanBLocSettings& settings, int marker_bits,
                                     const std::vector<Marker>& left);

/// ArUco detection (FiducialDetector's parameters) in the regions of one image of `pixels`
/// (`right`: the right one; `image` its size; the whole image at full resolution when `regions` is
/// empty), each region drawn at its level, corners in
/// full-image pixels, sorted by id, the first of each id kept.  The perimeter
/// threshold is scaled per region so that it stays the whole image's in
/// full-resolution pixels.  A region at level L > 0 is averaged down 2^L
/// times, searched there, and its corners are refined back to full
/// resolution (refine_from_level) from patches around them.
std::vector<Marker> detect_markers(const StereoPixels& pixels, bool right, cv::Size image,
                                   const std::vector<Region>& regions, const cv::Ptr<cv::aruco::Dictionary>& dict,
                                   const cv::Ptr<cv::aruco::DetectorParameters>& params,
                                   double min_perimeter_rate, const CornerRefinement& refine);

/// Boxes that overlap merged into their bounding box, until none overlap.
std::vector<Box> merge_boxes(std::vector<Box> boxes);

/// Share of a width×height frame that the union of `boxes` covers.
double covered_fraction(const std::vector<Box>& boxes, int width, int height);

/// Windows of every mapped landmark for `prediction` (LanBLocFrontEnd::search_windows).
std::vector<SearchWindow> predicted_windows(const LanBLocRig& rig, const LanBLocSettings& settings,
                                            const std::vector<LanBLocLandmark>& landmarks, int marker_bits,
                                            const PosePrediction& prediction);

}  // namespace safenav::lanbloc_detail

namespace safenav {

/// The front end's state (LanBLocFrontEnd); const after construction.
struct LanBLocFrontEnd::Impl {
  LanBLocRig rig;
  LanBLocSettings settings;
  std::vector<LanBLocLandmark> landmarks;
  std::map<int, Eigen::Vector3d> anchor;  // id → map position
  cv::Ptr<cv::aruco::Dictionary> dict;
  cv::Ptr<cv::aruco::DetectorParameters> params;
  lanbloc_detail::CornerRefinement refine;  // relative_win_size 0: ArUco refines (or nothing does)
  StereoMatcher matcher;  // the depth model Z = f·B/(d + doffs), and box_range
  SgbmParams sgbm;        // settings.sgbm with its disparity search resolved

  Impl(const LanBLocRig& r, std::vector<LanBLocLandmark> lms, const LanBLocSettings& s);

  /// The dictionary's marker side in bits; std::invalid_argument without a dictionary.
  int marker_bits() const;

  std::vector<lanbloc_detail::Marker> detect(const StereoPixels& px, const SearchPlan& plan, bool right) const;
  std::vector<lanbloc_detail::Marker> detect_along_rows(const StereoPixels& px,
                                                        const std::vector<lanbloc_detail::Marker>& left) const;
  LandmarkSighting observe(const lanbloc_detail::Marker& left, const lanbloc_detail::Marker* right,
                           const std::string& why) const;
  /// Bearing from o.centre; with a finite depth, slant and horizontal ranges from the centre's
  /// point (`point`, or depth·((u − cx)/f, (v − cy)/f, 1) without one).
  void sighting(LandmarkSighting& o, double depth, double sigma_z,
                const std::optional<Eigen::Vector3d>& point = std::nullopt) const;
  /// SGBM ranging (lanbloc_sgbm.cpp): the mapped boxes' sightings into fix.observations, the
  /// others' ids into fix.unmapped.
  void range_boxes(const StereoPixels& px, const std::vector<LandmarkBox>& boxes, LanBLocFix& fix) const;
  void solve(LanBLocFix& fix) const;
  bool bearings_agree(const LocalizationResult& loc, const std::vector<const LandmarkSighting*>& obs) const;
};

}  // namespace safenav
