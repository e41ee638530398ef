// LanBLoc front end: settings, search plans, localization and trilateration
// (safenav/lanbloc.hpp; the steps of safenav.vision.full_frame with
// ranging="corners" and safenav.vision.ranging.LandmarkRanging); ranging from
// the refined corners is in lanbloc_ranging.cpp, detection in lanbloc_detect.cpp.
#include "safenav/lanbloc.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <map>
#include <sstream>

#include <boost/math/distributions/chi_squared.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "declare.hpp"
#include "errors.hpp"
#include "lanbloc_internal.hpp"
#include "safenav/types.hpp"

namespace safenav {

using lanbloc_detail::Marker;

const char* to_string(LanBLocStatus s) {
  switch (s) {
    case LanBLocStatus::Ok: return "ok";
    case LanBLocStatus::NoLandmarks: return "no_landmarks";
    case LanBLocStatus::TooFewRanges: return "too_few_ranges";
    case LanBLocStatus::Degenerate: return "degenerate";
    case LanBLocStatus::DidNotConverge: return "did_not_converge";
  }
  return "?";
}

const char* to_string(LanBLocRanging r) { return r == LanBLocRanging::Sgbm ? "sgbm" : "corners"; }

double ranging_near_depth(const RectifiedCamera& c, double min_range_m) {
  return min_range_m * std::cos(std::atan2(std::max(c.cx, c.width - 1 - c.cx), c.f));
}

SgbmParams pipeline_sgbm() {
  SgbmParams p;  // block 5, uniqueness 10, speckle window 100 and range 2: OpenCV's names, our defaults
  p.mode = SgbmParams::Mode::SGBM3Way;
  p.num_disparities = 0;
  return p;
}

const char* to_string(SearchMode m) { return m == SearchMode::Windows ? "windows" : "whole_frame"; }

int LanBLocFix::n_ranges() const {
  return static_cast<int>(std::count_if(observations.begin(), observations.end(), [](const auto& o) { return o.ok; }));
}

void LanBLocRig::validate() const {
  camera.validate();
  detail::require_finite_nonneg(camera_height_m, "rig.camera_height_m");
  if (!(std::abs(pitch_rad) < 0.5))
    detail::bad("rig.pitch_rad = " + detail::num(pitch_rad) + ": must be a finite angle with |pitch| < 0.5 rad");
}

template <>
const ParamSet<LanBLocSettings>& param_set<LanBLocSettings>() {
  using S = LanBLocSettings;
  constexpr double kNone = std::numeric_limits<double>::infinity();
  static const ParamSet<S> s =
      Declare<S>{}
          .real("min_perimeter_rate", SN_REF(S, min_perimeter_rate), "", above(0, 4), "ArUco minMarkerPerimeterRate: smallest marker perimeter as a share of the image's larger side")
          .real("error_correction_rate", SN_REF(S, error_correction_rate), "", closed(0, 1), "ArUco errorCorrectionRate")
          .real("max_border_error_rate", SN_REF(S, max_border_error_rate), "", closed(0, 1), "ArUco maxErroneousBitsInBorderRate")
          .flag("subpixel", SN_REF(S, subpixel), "refine the marker corners to sub-pixel accuracy (CORNER_REFINE_SUBPIX)")
          .integer("corner_refinement_win_size", SN_REF(S, corner_refinement_win_size), closed(1, 100), "ArUco cornerRefinementWinSize [px]")
          .real("relative_corner_refinement_win_size", SN_REF(S, relative_corner_refinement_win_size), "", closed(0, 10), "OpenCV >= 4.8's relativeCornerRefinmentWinSize (window = min(round(this * cell px), corner_refinement_win_size)); 0 = the linked ArUco's fixed window")
          .real("detect_side_px", SN_REF(S, detect_side_px), "px", closed(0, 1e4), "search windows: detect at the pyramid level where the smallest predicted board is at least this wide, refine at full resolution; 0 = full resolution")
          .real("corner_sigma_d", SN_REF(S, corner_sigma_d), "px", above(0, 100), "sigma of the marker centre's disparity from its four corners (measured RMS); sigma_Z = Z^2 sigma / (f B)")
          .real("corner_edge_correlation", SN_REF(S, corner_edge_correlation), "", closed(-0.99, 1), "correlation of the disparity errors of the two corners on one vertical edge (three-corner sigma = sigma sqrt(2/(1 + rho)))")
          .real("max_row_error_px", SN_REF(S, max_row_error_px), "px", above(0, 1e4), "largest row difference of a corner between the left and the right image")
          .real("corner_square_sigmas", SN_REF(S, corner_square_sigmas), "", closed(0, 1e3), "the marker's corners in 3-D must form a square on one plane within this many sigma of their disparity noise (one corner off: dropped; otherwise no range); 0 = no check")
          .real("bearing_sigma_px", SN_REF(S, bearing_sigma_px), "px", above(0, 1e4), "sigma of the marker centre; bearing sigma = sigma_px / f")
          .real("max_range_m", SN_REF(S, max_range_m), "m", above(0, kNone), "depths beyond this: no range; inf = none")
          .real("min_range_m", SN_REF(S, min_range_m), "m", above(0, kNone), "SGBM: the nearest landmark to range (the disparity search's near end when sgbm.num_disparities = 0)")
          .real("sgbm_sigma_d", SN_REF(S, sgbm_sigma_d), "px", above(0, 100), "SGBM: sigma of a box's median disparity; sigma_Z = Z^2 sigma / (f B)")
          .real("box_shrink", SN_REF(S, box_shrink), "", closed(0, 0.5), "SGBM: each side of a box moves in by this share of its size before the median depth (< 0.5)")
          .flag("row_band", SN_REF(S, row_band), "SGBM: match only the band of rows that holds the boxes")
          .integer("band_margin_px", SN_REF(S, band_margin_px), closed(0, 1e5), "SGBM: rows above and below the boxes in the band [px]")
          .integer("min_landmarks", SN_REF(S, min_landmarks), closed(3, 1e6), "ranges needed to trilaterate (at least 3) [SafeNav-ext §IV-A]")
          .flag("resolve_ambiguity", SN_REF(S, resolve_ambiguity), "settle a mirror ambiguity of the fix by the bearings")
          .nested("trilateration.", param_set<LocalizationOptions>(), [](S& t) -> auto& { return t.trilateration; })
          .real("marker_size_m", SN_REF(S, marker_size_m), "m", above(0, 1e3), "side of the black-framed marker (search windows)")
          .real("window_sigmas", SN_REF(S, window_sigmas), "", closed(0, 100), "search windows grow by this many projected sigma")
          .real("window_margin_px", SN_REF(S, window_margin_px), "px", closed(0, 1e4), "background around a board's box in its search window")
          .real("max_window_fraction", SN_REF(S, max_window_fraction), "", closed(0, 1), "windows covering more of the frame than this: search the whole frame")
          .set;
  return s;
}

template class ParamSet<LanBLocSettings>;

void LanBLocSettings::validate() const {
  param_set<LanBLocSettings>().check(*this);
  if (detect_side_px > 0.0 && detect_side_px < 16.0)
    detail::bad("detect_side_px = " + detail::num(detect_side_px) + ": must be 0 (full resolution) or >= 16 px");
  trilateration.validate();
  if (!dictionary.empty()) (void)lanbloc_detail::dictionary(dictionary);
  if (!(box_shrink < 0.5)) detail::bad("box_shrink = " + detail::num(box_shrink) + ": must be < 0.5 (a box left)");
  if (ranging != LanBLocRanging::Corners && ranging != LanBLocRanging::Sgbm)
    detail::bad("ranging = " + std::to_string(static_cast<int>(ranging)) + ": must be Corners or Sgbm");
  SgbmParams p = sgbm;
  if (p.num_disparities == 0) p.num_disparities = 16;  // 0: the search from min_range_m
  try {
    p.validate();
  } catch (const std::invalid_argument& e) {
    detail::bad(std::string("sgbm.") + e.what());
  }
}

// ---------------------------------------------------------------------------


LanBLocFrontEnd::Impl::Impl(const LanBLocRig& r, std::vector<LanBLocLandmark> lms, const LanBLocSettings& s)
    : rig(r), settings(s), landmarks(std::move(lms)), matcher(r.camera), sgbm(s.sgbm) {
  if (sgbm.num_disparities == 0)  // LandmarkRanging's search: from min_range_m anywhere in the image to infinity
    sgbm = disparity_search(r.camera, ranging_near_depth(r.camera, s.min_range_m),
                            std::numeric_limits<double>::infinity(), s.sgbm);
}

int LanBLocFrontEnd::Impl::marker_bits() const {
  if (!dict)
    detail::bad("settings.dictionary is empty: this front end detects no markers; range the boxes of a "
                "detector of your own with localize_boxes");
  return dict->markerSize;
}

LanBLocFrontEnd::LanBLocFrontEnd(const LanBLocRig& rig, std::vector<LanBLocLandmark> landmarks,
                                 const LanBLocSettings& settings) {
  rig.validate();
  settings.validate();
  impl_ = std::make_unique<Impl>(rig, std::move(landmarks), settings);
  // An empty dictionary: no fiducial detection, the front end ranges the caller's boxes
  // (localize_boxes), and a landmark id is any integer.
  if (!settings.dictionary.empty()) impl_->dict = lanbloc_detail::dictionary(settings.dictionary);
  const int n_ids = impl_->dict ? impl_->dict->bytesList.rows : 0;
  for (const LanBLocLandmark& lm : impl_->landmarks) {
    if (impl_->dict && (lm.id < 0 || lm.id >= n_ids))
      detail::bad("landmark id " + std::to_string(lm.id) + " is not in dictionary " + settings.dictionary +
                  " (ids 0.." + std::to_string(n_ids - 1) + ")");
    if (!lm.position.allFinite()) detail::bad("landmark " + std::to_string(lm.id) + " has a non-finite position");
    if (!impl_->anchor.emplace(lm.id, lm.position).second)
      detail::bad("landmark id " + std::to_string(lm.id) + " appears twice in the map");
  }
  // FiducialDetector's parameters (safenav.vision.detect).
  auto& p = impl_->params;
  p = cv::aruco::DetectorParameters::create();
  p->minMarkerPerimeterRate = settings.min_perimeter_rate;
  p->errorCorrectionRate = settings.error_correction_rate;
  p->maxErroneousBitsInBorderRate = settings.max_border_error_rate;
  auto& r = impl_->refine;
  r.relative_win_size = 0.0;
  if (settings.subpixel && settings.relative_corner_refinement_win_size > 0.0) {
    // Refined here, with the window rule of OpenCV >= 4.8 (pip's cv2), not by OpenCV 4.6's ArUco.
    r.relative_win_size = settings.relative_corner_refinement_win_size;
    r.max_win_size = settings.corner_refinement_win_size;
    r.max_iterations = p->cornerRefinementMaxIterations;
    r.min_accuracy = p->cornerRefinementMinAccuracy;
  } else if (settings.subpixel) {
    p->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    p->cornerRefinementWinSize = settings.corner_refinement_win_size;
  }
}

LanBLocFrontEnd::~LanBLocFrontEnd() = default;
LanBLocFrontEnd::LanBLocFrontEnd(LanBLocFrontEnd&&) noexcept = default;
LanBLocFrontEnd& LanBLocFrontEnd::operator=(LanBLocFrontEnd&&) noexcept = default;
const LanBLocRig& LanBLocFrontEnd::rig() const { return impl_->rig; }
const LanBLocSettings& LanBLocFrontEnd::settings() const { return impl_->settings; }
const std::vector<LanBLocLandmark>& LanBLocFrontEnd::landmarks() const { return impl_->landmarks; }

std::vector<SearchWindow> LanBLocFrontEnd::search_windows(const PosePrediction& prediction, SearchMode& mode,
                                                          std::string& mode_reason) const {
  const LanBLocRig& r = impl_->rig;
  std::vector<SearchWindow> w = lanbloc_detail::predicted_windows(r, impl_->settings, impl_->landmarks,
                                                                  impl_->marker_bits(), prediction);
  std::vector<Box> left;
  for (const SearchWindow& s : w)
    if (!s.right) left.push_back(s.box);
  const double share = lanbloc_detail::covered_fraction(left, r.camera.width, r.camera.height);
  mode = SearchMode::Windows;
  mode_reason.clear();
  if (share > impl_->settings.max_window_fraction) {
    mode = SearchMode::WholeFrame;
    std::ostringstream os;
    os << std::setprecision(3) << "prediction too uncertain: windows cover " << share
       << " of the frame > max_window_fraction = " << impl_->settings.max_window_fraction;
    mode_reason = os.str();
  } else if (left.empty()) {
    mode_reason = "no mapped landmark predicted in view";
  }
  return w;
}

namespace {

cv::Mat as_gray_mat(const ImageView& v, const char* name) {
  if (v.data == nullptr || v.rows <= 0 || v.cols <= 0)
    detail::bad(std::string(name) + " image is empty (" + std::to_string(v.cols) + "x" + std::to_string(v.rows) + ")");
  if (v.channels != 1)
    detail::bad(std::string(name) + " image has " + std::to_string(v.channels) + " channels, expected 1 (8-bit grey)");
  const std::ptrdiff_t stride = v.row_stride ? v.row_stride : v.cols;
  if (stride < v.cols)
    detail::bad(std::string(name) + " image row_stride = " + std::to_string(stride) + " is below its width " +
                std::to_string(v.cols));
  return cv::Mat(v.rows, v.cols, CV_8UC1, const_cast<std::uint8_t*>(v.data), static_cast<std::size_t>(stride));
}

/// A marker's box: its corners' bounding box (FiducialDetector's Detection.box).
Box corner_box(const MarkerCorners& c) {
  return {c.col(0).minCoeff(), c.col(1).minCoeff(), c.col(0).maxCoeff(), c.col(1).maxCoeff()};
}

void check_size(const ImageView& v, const RectifiedCamera& cam, const char* name) {
  (void)as_gray_mat(v, name);
  if (v.cols != cam.width || v.rows != cam.height)
    detail::bad(std::string(name) + " image is " + std::to_string(v.cols) + "x" + std::to_string(v.rows) +
                " px but the rig is " + std::to_string(cam.width) + "x" + std::to_string(cam.height) + " px");
}

}  // namespace

StereoImages::StereoImages(const ImageView& left, const ImageView& right) : left_(left), right_(right) {
  (void)as_gray_mat(left, "left");
  (void)as_gray_mat(right, "right");
}

void StereoImages::draw(bool right, int level, int x0, int y0, int width, int height, std::uint8_t* out,
                        std::ptrdiff_t stride) const {
  const cv::Mat img = as_gray_mat(right ? right_ : left_, right ? "right" : "left");
  const int k = 1 << level;
  const cv::Rect box(x0, y0, width * k, height * k);
  if (level < 0 || level > 16 || width <= 0 || height <= 0 || (box & cv::Rect(0, 0, img.cols, img.rows)) != box)
    detail::bad("StereoImages::draw: level " + std::to_string(level) + " box of " + std::to_string(width) + "x" +
                std::to_string(height) + " at (" + std::to_string(x0) + ", " + std::to_string(y0) +
                ") is not inside the " + std::to_string(img.cols) + "x" + std::to_string(img.rows) + " image");
  cv::Mat dst(height, width, CV_8UC1, out, static_cast<std::size_t>(stride));
  if (level == 0)
    img(box).copyTo(dst);
  else
    cv::resize(img(box), dst, dst.size(), 0, 0, cv::INTER_AREA);
}

std::vector<Marker> LanBLocFrontEnd::Impl::detect(const StereoPixels& px, const SearchPlan& plan, bool right) const {
  const bool whole = plan.mode == SearchMode::WholeFrame;
  if (!whole && (right ? plan.right_regions : plan.left_regions).empty()) return {};
  // Each region at its pyramid level (lanbloc_detect.cpp: detection_regions); the whole frame at the
  // level of the farthest board that gives a range (whole_frame_region).
  return lanbloc_detail::detect_markers(
      px, right, cv::Size(rig.camera.width, rig.camera.height),
      whole ? std::vector<lanbloc_detail::Region>{lanbloc_detail::whole_frame_region(rig, settings,
                                                                                     marker_bits())}
            : lanbloc_detail::detection_regions(rig, settings, landmarks, marker_bits(), plan, right),
      dict, params, settings.min_perimeter_rate, refine);
}

std::vector<Marker> LanBLocFrontEnd::Impl::detect_along_rows(const StereoPixels& px,
                                                             const std::vector<Marker>& left) const {
  // The whole frame's right image: only where the left image's landmarks can be (epipolar_regions).
  const std::vector<lanbloc_detail::Region> bands =
      lanbloc_detail::epipolar_regions(rig, settings, marker_bits(), left);
  if (bands.empty()) return {};  // (detect_markers would search the whole image)
  return lanbloc_detail::detect_markers(px, true, cv::Size(rig.camera.width, rig.camera.height), bands, dict,
                                        params, settings.min_perimeter_rate, refine);
}

SearchPlan LanBLocFrontEnd::plan(const std::optional<PosePrediction>& prediction) const {
  SearchPlan p;
  if (!prediction) return p;
  p.prediction = prediction;
  p.windows = search_windows(*prediction, p.mode, p.reason);
  if (p.mode == SearchMode::WholeFrame) {
    p.windows.clear();
    return p;
  }
  for (const SearchWindow& w : p.windows) (w.right ? p.right_regions : p.left_regions).push_back(w.box);
  p.left_regions = lanbloc_detail::merge_boxes(std::move(p.left_regions));
  p.right_regions = lanbloc_detail::merge_boxes(std::move(p.right_regions));
  return p;
}

LanBLocFix LanBLocFrontEnd::localize(const ImageView& left, const ImageView& right,
                                     const std::optional<PosePrediction>& prediction) const {
  return localize(left, right, plan(prediction));
}

LanBLocFix LanBLocFrontEnd::localize(const ImageView& left, const ImageView& right, const SearchPlan& plan) const {
  check_size(left, impl_->rig.camera, "left");
  check_size(right, impl_->rig.camera, "right");  // bad input fails before any work
  return localize(StereoImages(left, right), plan);
}

LanBLocFix LanBLocFrontEnd::localize_boxes(const ImageView& left, const ImageView& right,
                                           const std::vector<LandmarkBox>& boxes) const {
  check_size(left, impl_->rig.camera, "left");
  check_size(right, impl_->rig.camera, "right");
  return localize_boxes(StereoImages(left, right), boxes);
}

LanBLocFix LanBLocFrontEnd::localize(const StereoPixels& pixels, const SearchPlan& plan) const {
  return localize(pixels, plan, SightingEdit());
}

LanBLocFix LanBLocFrontEnd::localize(const StereoPixels& pixels, const SearchPlan& plan,
                                     const SightingEdit& edit) const {
  const Impl& I = *impl_;
  LanBLocFix fix;
  fix.search = plan.mode;
  fix.search_reason = plan.reason;
  const bool whole = plan.mode == SearchMode::WholeFrame;
  if (!whole) {
    fix.windows = plan.windows;
    fix.left_regions = plan.left_regions;
    fix.right_regions = plan.right_regions;
  }
  for (const auto* regions : {&plan.left_regions, &plan.right_regions})
    for (const Box& b : *regions)
      if (!(b.x_min >= 0 && b.y_min >= 0 && b.x_max <= I.rig.camera.width && b.y_max <= I.rig.camera.height &&
            b.x_min <= b.x_max && b.y_min <= b.y_max))
        detail::bad("plan region (" + detail::num(b.x_min) + ", " + detail::num(b.y_min) + ", " +
                    detail::num(b.x_max) + ", " + detail::num(b.y_max) + ") is not inside the " +
                    std::to_string(I.rig.camera.width) + "x" + std::to_string(I.rig.camera.height) + " image");
  std::vector<Marker> dets;
  for (const Marker& m : I.detect(pixels, plan, false)) {
    if (I.anchor.count(m.id))
      dets.push_back(m);
    else
      fix.unmapped.push_back(m.id);  // not a landmark (FiducialDetector.last_unmapped)
  }
  if (dets.empty()) {
    fix.status = LanBLocStatus::NoLandmarks;
    fix.reason = "no landmark recognised in the left image";
    return fix;
  }
  if (I.settings.ranging == LanBLocRanging::Sgbm) {
    std::vector<LandmarkBox> boxes;
    for (const Marker& d : dets) boxes.push_back({d.id, corner_box(d.corners)});
    I.range_boxes(pixels, boxes, fix);
    for (std::size_t i = 0; i < dets.size(); ++i) fix.observations[i].corners_left = dets[i].corners;
  } else {
    std::map<int, Marker> in_right;
    for (const Marker& m : whole ? I.detect_along_rows(pixels, dets) : I.detect(pixels, plan, true))
      in_right.emplace(m.id, m);
    for (const Marker& d : dets) {
      auto it = in_right.find(d.id);
      fix.observations.push_back(I.observe(d, it == in_right.end() ? nullptr : &it->second, ""));
    }
  }
  if (edit) edit(fix.observations);
  I.solve(fix);
  return fix;
}

LandmarkSighting LanBLocFrontEnd::Impl::observe(const Marker& left, const Marker* right,
                                                   const std::string& why) const {
  // LandmarkRanging.observe_corners: the centre and its disparity from the corners
  // (corner_disparity), then Z = f·B/(d + doffs) with σ_Z = Z²·σ_d/(f·B).
  LandmarkSighting o;
  o.landmark_id = left.id;
  o.anchor = anchor.at(left.id);
  o.corners_left = left.corners;
  o.box = corner_box(left.corners);
  o.centre = marker_centre(left.corners);
  const RectifiedCamera& cam = rig.camera;
  o.bearing_sigma = settings.bearing_sigma_px / cam.f;
  if (right == nullptr) {
    sighting(o, std::numeric_limits<double>::quiet_NaN(), 0.0);  // the bearing
    o.reason = why.empty() ? "not found in the right image" : why;
    return o;
  }
  o.corners_right = right->corners;
  const CornerDisparity cd = corner_disparity(left.corners, right->corners, cam, settings);
  if (cd.corners_used == 3) o.centre = cd.centre;  // the centre from the corners that agree
  sighting(o, std::numeric_limits<double>::quiet_NaN(), 0.0);  // the bearing
  if (!cd.ok) {
    o.reason = cd.reason;
    return o;
  }
  o.disparity = cd.disparity;
  o.corners_used = cd.corners_used;
  // The core's depth model Z = f·B/(d + doffs) (StereoMatcher::depth; float disparities, so Z
  // carries a relative rounding of ~1e-7).
  DisparityMap d1(1, 1);
  d1(0, 0) = static_cast<float>(o.disparity);
  const double Z = matcher.depth(d1)(0, 0);
  if (Z > settings.max_range_m) {
    std::ostringstream os;
    os << std::fixed << std::setprecision(1) << "beyond resolvable range (" << Z << " m > max_range_m = "
       << detail::num(settings.max_range_m) << " m)";
    o.reason = os.str();
    return o;
  }
  sighting(o, Z, Z * Z * cd.sigma / (cam.f * cam.baseline));  // σ_Z = Z²·σ_d/(f·B)
  return o;
}

void LanBLocFrontEnd::Impl::sighting(LandmarkSighting& o, double depth, double sigma_z,
                                     const std::optional<Eigen::Vector3d>& point) const {
  // LandmarkRanging.sighting: the centre's ray in the world at heading 0, ray = R₀ᵀ·((u − cx)/f,
  // (v − cy)/f, 1), bearing = atan2(ray_y, ray_x) (counter-clockwise from the heading).
  const RectifiedCamera& cam = rig.camera;
  const Eigen::Vector3d xn((o.centre.x() - cam.cx) / cam.f, (o.centre.y() - cam.cy) / cam.f, 1.0);
  const Eigen::Vector3d ray = lanbloc_detail::camera_rotation(0.0, rig.pitch_rad).transpose() * xn;
  o.bearing = std::atan2(ray.y(), ray.x());
  if (!std::isfinite(depth)) return;
  // Slant range s = ‖P‖ of the centre's point P = Z·xn, σ_s = σ_Z·s/Z; horizontal range
  // ρ = sqrt(s² − (z_ℓ − h)²), σ_ρ = σ_s·s/ρ (safenav.vision.localization.horizontal_range).
  const double s = point ? point->norm() : depth * xn.norm();
  const double sigma_s = sigma_z * s / depth;
  const double dh = o.anchor.z() - rig.camera_height_m;
  const double rho = std::sqrt(std::max(s * s - dh * dh, 0.0));
  o.slant_range = s;
  o.depth = depth;
  if (!(rho > 0.0)) {
    std::ostringstream os;
    os << std::fixed << std::setprecision(3) << "slant range " << s << " m is shorter than the height difference "
       << dh << " m";
    o.reason = os.str();
    return;
  }
  o.ok = true;
  o.range = rho;
  o.sigma = sigma_s * s / rho;
}

bool LanBLocFrontEnd::Impl::bearings_agree(const LocalizationResult& loc,
                                           const std::vector<const LandmarkSighting*>& obs) const {
  // LandmarkRanging.bearings_agree: residuals β_i − b_i of the absolute bearings from the fix about
  // their circular mean (the heading), each with σ² = σ_b² + nᵀPn/ρ², χ² against its 99.9 % quantile.
  const std::size_t n = obs.size();
  Eigen::VectorXd res(n), var(n);
  double sn = 0.0, cs = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d d = obs[i]->anchor.head<2>() - loc.position;
    const double rho = d.norm();
    if (rho < 1e-6) return false;
    const Eigen::Vector2d nrm = Eigen::Vector2d(-d.y(), d.x()) / rho;
    res[i] = std::atan2(d.y(), d.x()) - obs[i]->bearing;
    var[i] = obs[i]->bearing_sigma * obs[i]->bearing_sigma + nrm.dot(loc.covariance * nrm) / (rho * rho);
    sn += std::sin(res[i]);
    cs += std::cos(res[i]);
  }
  const double theta = std::atan2(sn / double(n), cs / double(n));
  double chi2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = wrap_angle(res[i] - theta);
    chi2 += r * r / var[i];
  }
  const double dof = std::max<double>(double(n) - 1.0, 1.0);
  return chi2 <= boost::math::quantile(boost::math::chi_squared(dof), 0.999);
}

void LanBLocFrontEnd::Impl::solve(LanBLocFix& fix) const {
  // LandmarkRanging.solve: trilateration of the usable ranges [SafeNav §IV-A], the mirror
  // ambiguity settled by the bearings.
  std::vector<LandmarkSighting*> usable;
  for (LandmarkSighting& o : fix.observations)
    if (o.ok) usable.push_back(&o);
  const std::vector<char> twice = repeated_landmarks(usable, [](const LandmarkSighting* o) { return o->landmark_id; });
  std::vector<const LandmarkSighting*> ok;
  for (std::size_t i = 0; i < usable.size(); ++i) {
    if (!twice[i]) {
      ok.push_back(usable[i]);
      continue;
    }
    usable[i]->ok = false;  // e.g. another landmark relabelled as this one (a SightingEdit's misassociation)
    usable[i]->range = usable[i]->sigma = LandmarkSighting::kNaN;
    usable[i]->reason = "landmark " + std::to_string(usable[i]->landmark_id) +
                        " seen twice in one frame: neither range is used";
  }
  if (static_cast<int>(ok.size()) < settings.min_landmarks) {
    fix.status = LanBLocStatus::TooFewRanges;
    std::ostringstream os;
    os << ok.size() << " usable range(s), " << settings.min_landmarks << " needed";
    std::string why;
    for (const LandmarkSighting& o : fix.observations)
      if (!o.ok) why += (why.empty() ? "" : "; ") + ("landmark " + std::to_string(o.landmark_id) + ": " + o.reason);
    if (!why.empty()) os << " (" << why << ")";
    fix.reason = os.str();
    return;
  }
  Anchors a(ok.size(), 2);
  Eigen::VectorXd r(ok.size()), s(ok.size());
  for (std::size_t i = 0; i < ok.size(); ++i) {
    a.row(i) = ok[i]->anchor.head<2>().transpose();
    r[i] = ok[i]->range;
    s[i] = ok[i]->sigma;
  }
  LocalizationResult loc = trilaterate(a, r, s, settings.trilateration);
  if (loc.status == LocalizationStatus::Degenerate && settings.resolve_ambiguity) {
    // A forward camera sees every landmark on one side: the mirror image of the fix across them may
    // fit the ranges too; the bearings' left-to-right order tells the two apart.
    LocalizationOptions any = settings.trilateration;
    any.ambiguity_margin = 0.0;
    LocalizationResult best = trilaterate(a, r, s, any);
    if (best.ok() && bearings_agree(best, ok)) {
      loc = std::move(best);
      loc.reason = "mirror ambiguity resolved by the bearings";
    }
  }
  fix.reason = loc.reason;
  fix.gdop = loc.gdop;
  switch (loc.status) {
    case LocalizationStatus::Ok: fix.status = LanBLocStatus::Ok; break;
    case LocalizationStatus::TooFew: fix.status = LanBLocStatus::TooFewRanges; break;
    case LocalizationStatus::Degenerate: fix.status = LanBLocStatus::Degenerate; break;
    case LocalizationStatus::DidNotConverge: fix.status = LanBLocStatus::DidNotConverge; break;
  }
  if (fix.ok()) {
    fix.position = loc.position;
    fix.covariance = loc.covariance;
  }
  fix.localization = std::move(loc);
}

}  // namespace safenav
