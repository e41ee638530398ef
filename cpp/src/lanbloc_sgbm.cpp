// The paper's SGBM ranging in the LanBLoc front end (safenav/lanbloc.hpp:
// ranging = Sgbm, localize_boxes): SGBM over the band of rows that holds the
// landmarks' boxes, and the median depth inside each box shrunk by box_shrink
// per side ([SafeNav §IV-A]; safenav.vision.full_frame.FullFramePipeline.disparity
// and safenav.vision.ranging.LandmarkRanging.observe, step for step).
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <vector>

#include "errors.hpp"
#include "lanbloc_internal.hpp"

namespace safenav {

namespace {

/// ⌊a / b⌋ for b > 0 (Python's //; C++'s / truncates towards zero).
long long floor_div(long long a, long long b) { return a / b - ((a % b != 0) && (a < 0)); }

/// The rows [y0, y1) that SGBM matches for `boxes`: the boxes' rows grown by `margin` and
/// rounded out to a 16-row grid (so that a camera's band repeats from frame to frame), or the
/// whole image when that band would cover 80 % of it or more, or without row_band.
std::pair<int, int> band_rows(const std::vector<Box>& boxes, int height, bool row_band, int margin) {
  if (!row_band || boxes.empty()) return {0, height};
  double top = std::numeric_limits<double>::infinity(), bottom = -top;
  for (const Box& b : boxes) top = std::min(top, b.y_min), bottom = std::max(bottom, b.y_max);
  // Clamped in doubles first: the boxes are finite, but may lie far outside the image.
  const auto row = [height](double v) { return static_cast<long long>(std::clamp(v, -4.0 * height, 4.0 * height)); };
  constexpr long long q = 16;
  const long long y0 = std::max(floor_div(row(std::floor(top)) - margin, q) * q, 0LL);
  const long long y1 = std::min(-floor_div(-(row(std::ceil(bottom)) + 1 + margin), q) * q, (long long)height);
  if (y1 - y0 >= 0.8 * height || y1 <= y0) return {0, height};
  return {static_cast<int>(y0), static_cast<int>(y1)};
}

}  // namespace

void LanBLocFrontEnd::Impl::range_boxes(const StereoPixels& px, const std::vector<LandmarkBox>& boxes,
                                        LanBLocFix& fix) const {
  const RectifiedCamera& cam = rig.camera;
  std::vector<LandmarkBox> mapped;
  std::set<int> seen;
  for (const LandmarkBox& b : boxes) {
    const Box& x = b.box;
    if (!(std::isfinite(x.x_min) && std::isfinite(x.y_min) && std::isfinite(x.x_max) && std::isfinite(x.y_max)) ||
        !(x.x_max > x.x_min && x.y_max > x.y_min))
      detail::bad("box of landmark " + std::to_string(b.landmark_id) + " (" + detail::num(x.x_min) + ", " +
                  detail::num(x.y_min) + ", " + detail::num(x.x_max) + ", " + detail::num(x.y_max) +
                  ") must be finite with x_min < x_max and y_min < y_max");
    if (!anchor.count(b.landmark_id))
      fix.unmapped.push_back(b.landmark_id);
    else if (seen.insert(b.landmark_id).second)
      mapped.push_back(b);
  }
  if (mapped.empty()) return;
  // FullFramePipeline.disparity: SGBM on the band of rows that holds the boxes (a camera with its
  // principal row moved into the band), NaN elsewhere.
  std::vector<Box> row_boxes;
  for (const LandmarkBox& b : mapped) row_boxes.push_back(b.box);
  const auto [y0, y1] = band_rows(row_boxes, cam.height, settings.row_band, settings.band_margin_px);
  RectifiedCamera band = cam;
  band.cy = cam.cy - y0;
  band.height = y1 - y0;
  std::vector<std::uint8_t> left(static_cast<std::size_t>(cam.width) * band.height), right(left.size());
  px.draw(false, 0, 0, y0, cam.width, band.height, left.data(), cam.width);
  px.draw(true, 0, 0, y0, cam.width, band.height, right.data(), cam.width);
  const StereoMatcher band_matcher(band, sgbm);  // one per call: a matcher is not thread-safe
  DisparityMap disparity = DisparityMap::Constant(cam.height, cam.width, std::numeric_limits<float>::quiet_NaN());
  disparity.middleRows(y0, band.height) = band_matcher.disparity({left.data(), band.height, cam.width, 1, 0},
                                                                 {right.data(), band.height, cam.width, 1, 0});
  // LandmarkRanging.observe: the median depth of the box shrunk by box_shrink per side; the
  // bearing of the (whole) box's centre; the slant range from the shrunk box's centre at that depth.
  BoxRangeOptions options;
  options.sigma_d = settings.sgbm_sigma_d;
  options.max_range = settings.max_range_m;
  for (const LandmarkBox& b : mapped) {
    LandmarkSighting o;
    o.landmark_id = b.landmark_id;
    o.anchor = anchor.at(b.landmark_id);
    o.box = b.box;
    o.centre = Eigen::Vector2d(0.5 * (b.box.x_min + b.box.x_max), 0.5 * (b.box.y_min + b.box.y_max));
    o.bearing_sigma = settings.bearing_sigma_px / cam.f;
    const double sx = settings.box_shrink * (b.box.x_max - b.box.x_min);
    const double sy = settings.box_shrink * (b.box.y_max - b.box.y_min);
    const BoxRange r =
        matcher.box_range(disparity, Box{b.box.x_min + sx, b.box.y_min + sy, b.box.x_max - sx, b.box.y_max - sy},
                          options);
    o.disparity = r.disparity;
    o.n_valid = r.n_valid;
    if (r.ok) {
      sighting(o, r.range, r.sigma, r.point);
    } else {
      sighting(o, std::numeric_limits<double>::quiet_NaN(), 0.0);  // the bearing
      o.reason = r.reason;
    }
    fix.observations.push_back(std::move(o));
  }
}

LanBLocFix LanBLocFrontEnd::localize_boxes(const StereoPixels& pixels, const std::vector<LandmarkBox>& boxes,
                                           const SightingEdit& edit) const {
  LanBLocFix fix;
  fix.search_reason = "boxes given";
  impl_->range_boxes(pixels, boxes, fix);
  if (fix.observations.empty()) {
    fix.status = LanBLocStatus::NoLandmarks;
    fix.reason = "no landmark of the map among the boxes";
    return fix;
  }
  if (edit) edit(fix.observations);
  impl_->solve(fix);
  return fix;
}

}  // namespace safenav
