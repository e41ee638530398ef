// LanBLoc front end: fiducial detection (OpenCV ArUco) and the search windows
// from a predicted pose (safenav/lanbloc.hpp).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "errors.hpp"
#include "lanbloc_internal.hpp"

namespace safenav::lanbloc_detail {

namespace {

const std::pair<const char*, int> kDictionaries[] = {
    {"DICT_4X4_50", cv::aruco::DICT_4X4_50},
    {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
    {"DICT_4X4_250", cv::aruco::DICT_4X4_250},
    {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000},
    {"DICT_5X5_50", cv::aruco::DICT_5X5_50},
    {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
    {"DICT_5X5_250", cv::aruco::DICT_5X5_250},
    {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000},
    {"DICT_6X6_50", cv::aruco::DICT_6X6_50},
    {"DICT_6X6_100", cv::aruco::DICT_6X6_100},
    {"DICT_6X6_250", cv::aruco::DICT_6X6_250},
    {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000},
    {"DICT_7X7_50", cv::aruco::DICT_7X7_50},
    {"DICT_7X7_100", cv::aruco::DICT_7X7_100},
    {"DICT_7X7_250", cv::aruco::DICT_7X7_250},
    {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000},
    {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL},
    {"DICT_APRILTAG_16H5", cv::aruco::DICT_APRILTAG_16h5},
    {"DICT_APRILTAG_25H9", cv::aruco::DICT_APRILTAG_25h9},
    {"DICT_APRILTAG_36H10", cv::aruco::DICT_APRILTAG_36h10},
    {"DICT_APRILTAG_36H11", cv::aruco::DICT_APRILTAG_36h11},
};

/// Projection of world point P into the left (or right) camera at pose
/// (x, y, θ): (u, v, Z), u = f·X/Z + cx (+ doffs in the right image),
/// v = f·Y/Z + cy (safenav.vision.render.StereoRenderer.project).
Eigen::Vector3d project(const LanBLocRig& rig, const Eigen::Vector3d& pose, const Eigen::Vector3d& P, bool right) {
  const RectifiedCamera& c = rig.camera;
  const double th = pose.z();
  Eigen::Vector3d C(pose.x(), pose.y(), rig.camera_height_m);
  if (right) C += c.baseline * Eigen::Vector3d(std::sin(th), -std::cos(th), 0.0);
  const Eigen::Vector3d pc = camera_rotation(th, rig.pitch_rad) * (P - C);
  return {c.f * pc.x() / pc.z() + c.cx + (right ? c.doffs : 0.0), c.f * pc.y() / pc.z() + c.cy, pc.z()};
}

void check_prediction(const PosePrediction& p) {
  if (!p.pose.allFinite()) {
    std::ostringstream os;
    os << "prediction.pose = (" << p.pose.transpose() << "): must be finite";
    detail::bad(os.str());
  }
  const Eigen::Matrix3d& P = p.covariance;
  const double scale = std::max(P.cwiseAbs().maxCoeff(), 1e-300);
  if (!P.allFinite() || (P - P.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale ||
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(P).eigenvalues().minCoeff() < -1e-9 * scale) {
    std::ostringstream os;
    os << "prediction.covariance = [" << P.row(0) << "; " << P.row(1) << "; " << P.row(2)
       << "]: must be finite, symmetric and positive semi-definite";
    detail::bad(os.str());
  }
}

/// The board's side [m]: the black-framed marker of marker_bits + 2 cells plus a one-cell quiet
/// zone per side (safenav.vision.render: half-side = marker_size·(cells + 2)/(2·cells)).
double board_side_m(const LanBLocSettings& s, int marker_bits) {
  const double cells = marker_bits + 2.0;
  return s.marker_size_m * (cells + 2.0) / cells;
}

/// The window of one landmark in one image, or false when its board is not
/// predicted in front of the camera, within range and overlapping the image.
bool window_of(const LanBLocRig& rig, const LanBLocSettings& s, const LanBLocLandmark& lm, double board_half,
               const PosePrediction& pred, bool right, SearchWindow& out) {
  const Eigen::Vector3d uvz = project(rig, pred.pose, lm.position, right);
  if (!(uvz.z() > 1.5 * board_half + 0.2)) return false;
  // J = ∂(u, v)/∂(x, y, θ) by central differences; Σ_uv = J P Jᵀ.
  Eigen::Matrix<double, 2, 3> J;
  for (int k = 0; k < 3; ++k) {
    const double h = 1e-6 * std::max(1.0, std::abs(pred.pose[k]));
    Eigen::Vector3d a = pred.pose, b = pred.pose;
    a[k] += h;
    b[k] -= h;
    J.col(k) = (project(rig, a, lm.position, right) - project(rig, b, lm.position, right)).head<2>() / (2 * h);
  }
  const Eigen::Matrix2d S = J * pred.covariance * J.transpose();
  const Eigen::Vector2d sigma(std::sqrt(std::max(S(0, 0), 0.0)), std::sqrt(std::max(S(1, 1), 0.0)));
  // Within range: the nearest the landmark may be, at window_sigmas·σ of the position.
  const double pos_sigma = std::sqrt(std::max(pred.covariance.topLeftCorner<2, 2>().trace(), 0.0));
  const Eigen::Vector3d C(pred.pose.x(), pred.pose.y(), rig.camera_height_m);
  if ((lm.position - C).norm() - s.window_sigmas * pos_sigma > s.max_range_m) return false;
  // The board is upright and turns, if at all, about the vertical through its centre: it lies in
  // the vertical cylinder of radius board_half and height ±board_half about the centre, and so in
  // the 16-sided prism circumscribing that cylinder.  The image of a convex body in front of the
  // camera is the convex hull of its vertices' images: their bounding box bounds the board's.
  constexpr int kSides = 16;
  const double r = board_half / std::cos(kPi / kSides);
  double u0 = uvz.x(), u1 = uvz.x(), v0 = uvz.y(), v1 = uvz.y();
  for (int k = 0; k < 2 * kSides; ++k) {
    const double a = 2.0 * kPi * (k % kSides) / kSides;
    const Eigen::Vector3d q = lm.position + Eigen::Vector3d(r * std::cos(a), r * std::sin(a),
                                                            k < kSides ? board_half : -board_half);
    const Eigen::Vector3d p = project(rig, pred.pose, q, right);
    if (!(p.z() > 0.05)) return false;
    u0 = std::min(u0, p.x()), u1 = std::max(u1, p.x()), v0 = std::min(v0, p.y()), v1 = std::max(v1, p.y());
  }
  const double m = s.window_margin_px, W = rig.camera.width, H = rig.camera.height;
  Box b{std::max(std::floor(u0 - m - s.window_sigmas * sigma.x()), 0.0),
        std::max(std::floor(v0 - m - s.window_sigmas * sigma.y()), 0.0),
        std::min(std::ceil(u1 + m + s.window_sigmas * sigma.x()) + 1.0, W),
        std::min(std::ceil(v1 + m + s.window_sigmas * sigma.y()) + 1.0, H)};
  if (!(b.x_max > b.x_min && b.y_max > b.y_min)) return false;
  out.landmark_id = lm.id;
  out.right = right;
  out.box = b;
  out.predicted_centre = uvz.head<2>();
  out.sigma_px = sigma;
  return true;
}

/// Module (cell) size in px of a marker with corners c, marker_bits + 2·border_bits cells a side.
double module_px(const std::vector<cv::Point2f>& c, int marker_bits, int border_bits) {
  double perimeter = 0.0;
  for (int k = 0; k < 4; ++k) perimeter += cv::norm(c[k] - c[(k + 1) % 4]);
  return perimeter / (4.0 * (marker_bits + 2 * border_bits));
}

/// OpenCV >= 4.8's CORNER_REFINE_SUBPIX window: min(max(1, round(relative·m)), max_win) px, m the
/// marker's average module (cell) size in px.
int refine_window(const std::vector<cv::Point2f>& c, int marker_bits, int border_bits, const CornerRefinement& r) {
  return std::min(std::max(1, cvRound(r.relative_win_size * module_px(c, marker_bits, border_bits))), r.max_win_size);
}

cv::TermCriteria refine_criteria(const CornerRefinement& r) {
  return cv::TermCriteria(cv::TermCriteria::MAX_ITER | cv::TermCriteria::EPS, r.max_iterations, r.min_accuracy);
}

/// OpenCV >= 4.8's CORNER_REFINE_SUBPIX (the one pip's cv2 runs): cornerSubPix in refine_window.
void refine_corners(const cv::Mat& grey, std::vector<cv::Point2f>& c, int marker_bits, int border_bits,
                    const CornerRefinement& r) {
  const int win = refine_window(c, marker_bits, border_bits, r);
  cv::cornerSubPix(grey, c, cv::Size(win, win), cv::Size(-1, -1), refine_criteria(r));
}

/// The level-`level` pixels of full-resolution box `cut` (whole 2^level blocks) of one image.
cv::Mat draw_level(const StereoPixels& px, bool right, const cv::Rect& cut, int level) {
  cv::Mat m(cut.height >> level, cut.width >> level, CV_8UC1);
  px.draw(right, level, cut.x, cut.y, m.cols, m.rows, m.data, static_cast<std::ptrdiff_t>(m.step));
  return m;
}

/// Full-resolution patches around a marker's four corners, drawn on demand: each corner's patch
/// reaches `half` px beyond it (clipped to the image, as cornerSubPix clamps at its edges), and one
/// patch holds all four when their bounding box is no larger than the four together.
struct CornerPatches {
  std::vector<cv::Mat> images;
  std::vector<cv::Point2f> origins;
  int of[4] = {0, 0, 0, 0};  ///< each corner's patch

  CornerPatches(const StereoPixels& px, bool right, cv::Size image, const std::vector<cv::Point2f>& c, int half) {
    const cv::Rect frame(0, 0, image.width, image.height);
    cv::Rect boxes[4], all;
    int area = 0;
    for (int k = 0; k < 4; ++k) {
      // about the corner's pixel, clamped into the image: the patch is at least half + 1 px a side
      const int u = std::clamp(cvRound(c[k].x), 0, image.width - 1);
      const int v = std::clamp(cvRound(c[k].y), 0, image.height - 1);
      boxes[k] = cv::Rect(u - half, v - half, 2 * half + 1, 2 * half + 1) & frame;
      all = k == 0 ? boxes[k] : (all | boxes[k]);
      area += boxes[k].area();
    }
    const bool one = all.area() <= area;
    for (int k = 0; k < (one ? 1 : 4); ++k) {
      const cv::Rect& b = one ? all : boxes[k];
      images.push_back(b.area() > 0 ? draw_level(px, right, b, 0) : cv::Mat());
      origins.emplace_back(float(b.x), float(b.y));
    }
    for (int k = 0; k < 4; ++k) of[k] = one ? 0 : k;
  }

  /// cornerSubPix of corner k in its patch (nothing when the patch is smaller than cornerSubPix's
  /// 2·win + 5, which only an image that small has).
  void refine(cv::Point2f& p, int k, int win, const cv::TermCriteria& criteria) const {
    const cv::Mat& img = images[std::size_t(of[k])];
    if (img.cols < 2 * win + 5 || img.rows < 2 * win + 5) return;
    std::vector<cv::Point2f> q{p - origins[std::size_t(of[k])]};
    cv::cornerSubPix(img, q, cv::Size(win, win), cv::Size(-1, -1), criteria);
    p = q[0] + origins[std::size_t(of[k])];
  }
};

/// Corners found at pyramid level L (in `level_img`, the region averaged 2^L times; `origin` its
/// full-resolution top-left) brought to full resolution: cornerSubPix at the level (window half a
/// cell) so the mapped corners are within ~0.1·2^L px, mapped up (level pixel i is centred on
/// full-resolution (i + 0.5)·2^L − 0.5), cornerSubPix at full resolution in a window of up to 0.4
/// cell (at least 2^L px, at most 16) to the corner's fixed point, then the front end's own final
/// refinement (`final_win` > 0: that fixed window; otherwise the OpenCV >= 4.8 rule of `refine`).
/// A window stays inside the board's quiet zone, so it holds one corner.  Only patches around the
/// corners are read at full resolution (CornerPatches), reaching twice both windows beyond them:
/// cornerSubPix returns its start when it ends farther than its window from it, and reads at most
/// its window plus 2 px around where it stands.
void refine_from_level(const StereoPixels& px, bool right, cv::Size image, const cv::Mat& level_img,
                       cv::Point2f origin, int level, std::vector<cv::Point2f>& c, int marker_bits, int border_bits,
                       const CornerRefinement& refine, int final_win) {
  const int k = 1 << level;
  const cv::TermCriteria fine(cv::TermCriteria::MAX_ITER | cv::TermCriteria::EPS, 30, 0.01);
  const double m_level = module_px(c, marker_bits, border_bits);
  const int w_level = std::min(std::max(2, cvRound(0.5 * m_level)), 12);
  cv::cornerSubPix(level_img, c, cv::Size(w_level, w_level), cv::Size(-1, -1), fine);
  for (auto& p : c) p = cv::Point2f((p.x + 0.5f) * k - 0.5f + origin.x, (p.y + 0.5f) * k - 0.5f + origin.y);
  const int w0 = std::min({std::max(k, 2), std::max(2, cvRound(0.4 * m_level * k)), 16});
  const int w_final_max = final_win > 0 ? final_win : refine.max_win_size;
  const CornerPatches patches(px, right, image, c, 2 * w0 + 2 * w_final_max + 4);
  for (int i = 0; i < 4; ++i) patches.refine(c[std::size_t(i)], i, w0, fine);
  const int w_final = final_win > 0 ? final_win : refine_window(c, marker_bits, border_bits, refine);
  for (int i = 0; i < 4; ++i) patches.refine(c[std::size_t(i)], i, w_final, refine_criteria(refine));
}

/// One region searched at level L > 0: drawn at the level (whole 2^L blocks; the region is trimmed
/// to a multiple of 2^L), detected there with refinement off, corners refined back to full
/// resolution (refine_from_level); corners in full-image pixels.  ArUco drops a contour within
/// minDistanceToBorder px of the searched image's edge; at the level that would be 2^L times as
/// far, so the level image is padded (edge pixels repeated) and the rule is applied to the refined
/// corners at full resolution instead, as a full-resolution search would.
void detect_at_level(const StereoPixels& px, bool right, cv::Size image, const cv::Rect& roi, int level,
                     const cv::Ptr<cv::aruco::Dictionary>& dict, const cv::aruco::DetectorParameters& base,
                     double min_perimeter_px, const CornerRefinement& refine,
                     std::vector<std::vector<cv::Point2f>>& corners, std::vector<int>& ids) {
  const int k = 1 << level;
  const cv::Rect cut(roi.x, roi.y, roi.width / k * k, roi.height / k * k);
  const cv::Mat small = draw_level(px, right, cut, level);
  cv::Mat padded;
  const int pad = base.minDistanceToBorder + 1;
  cv::copyMakeBorder(small, padded, pad, pad, pad, pad, cv::BORDER_REPLICATE);
  const cv::Ptr<cv::aruco::DetectorParameters> p = cv::makePtr<cv::aruco::DetectorParameters>(base);
  p->minMarkerPerimeterRate = std::min(min_perimeter_px / k / std::max(padded.cols, padded.rows), 3.9);
  p->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;
  // At the level a cell is detect_side_px/8 to detect_side_px/4 px (a board of 8 cells, 3-6 px at
  // the default 24): one adaptive threshold window of ArUco's scales, the first of at least 13 px
  // (2-4 cells; the 3 px window is about a cell and finds texture, and one scale fits all the
  // cell sizes a level holds).
  int win = p->adaptiveThreshWinSizeMin;
  while (win < 13 && win + p->adaptiveThreshWinSizeStep <= p->adaptiveThreshWinSizeMax)
    win += p->adaptiveThreshWinSizeStep;
  p->adaptiveThreshWinSizeMin = p->adaptiveThreshWinSizeMax = win;
  std::vector<std::vector<cv::Point2f>> found;
  std::vector<int> found_ids;
  cv::aruco::detectMarkers(padded, dict, found, found_ids, p);
  // ArUco's own refinement (OpenCV 4.6: a fixed window) when the rule of >= 4.8 is not selected.
  const bool aruco_rule = refine.relative_win_size <= 0.0;
  const CornerRefinement final_rule = aruco_rule ? CornerRefinement{0.0, base.cornerRefinementWinSize,
                                                                    base.cornerRefinementMaxIterations,
                                                                    base.cornerRefinementMinAccuracy}
                                                 : refine;
  const float d = float(base.minDistanceToBorder);
  for (std::size_t i = 0; i < found.size(); ++i) {
    auto& c = found[i];
    for (auto& q : c) q -= cv::Point2f(float(pad), float(pad));
    refine_from_level(px, right, image, small, cv::Point2f(float(cut.x), float(cut.y)), level, c, dict->markerSize,
                      base.markerBorderBits, final_rule, aruco_rule ? base.cornerRefinementWinSize : 0);
    const bool inside = std::all_of(c.begin(), c.end(), [&](const cv::Point2f& q) {
      return q.x >= roi.x + d && q.y >= roi.y + d && q.x <= roi.x + roi.width - 1 - d &&
             q.y <= roi.y + roi.height - 1 - d;
    });
    if (!inside) continue;
    corners.push_back(c);
    ids.push_back(found_ids[i]);
  }
}

}  // namespace

cv::Ptr<cv::aruco::Dictionary> dictionary(const std::string& name) {
  std::string key;
  for (char ch : name) key += static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  if (key.rfind("DICT_", 0) != 0) key = "DICT_" + key;
  for (const auto& [n, id] : kDictionaries)
    if (key == n) return cv::aruco::getPredefinedDictionary(id);
  std::string known;
  for (const auto& d : kDictionaries) known += (known.empty() ? "" : ", ") + std::string(d.first + 5);
  detail::bad("dictionary = '" + name + "': unknown; known: " + known);
}

Eigen::Matrix3d camera_rotation(double theta, double pitch) {
  const double c = std::cos(theta), s = std::sin(theta), cp = std::cos(pitch), sp = std::sin(pitch);
  const Eigen::Vector3d fwd(c * cp, s * cp, sp), right(s, -c, 0.0);
  Eigen::Matrix3d R;
  R.row(0) = right;
  R.row(1) = fwd.cross(right);
  R.row(2) = fwd;
  return R;
}

std::vector<Marker> detect_markers(const StereoPixels& px, bool right, cv::Size image,
                                   const std::vector<Region>& regions, const cv::Ptr<cv::aruco::Dictionary>& dict,
                                   const cv::Ptr<cv::aruco::DetectorParameters>& params,
                                   double min_perimeter_rate, const CornerRefinement& refine) {
  std::vector<Region> search = regions;
  if (search.empty()) search.push_back({{0.0, 0.0, double(image.width), double(image.height)}, 0});
  // The whole image's smallest perimeter in full-resolution pixels, kept in every region.
  const double min_perimeter_px = min_perimeter_rate * std::max(image.width, image.height);
  std::vector<Marker> out;
  for (const Region& r : search) {
    const Box& b = r.box;
    const cv::Rect roi(int(b.x_min), int(b.y_min), int(b.x_max - b.x_min), int(b.y_max - b.y_min));
    if (roi.width < 8 || roi.height < 8) continue;
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    if (r.level > 0) {
      detect_at_level(px, right, image, roi, r.level, dict, *params, min_perimeter_px, refine, corners, ids);
    } else {
      // A copy of the parameters, so that concurrent calls share nothing they write.
      const cv::Ptr<cv::aruco::DetectorParameters> p = cv::makePtr<cv::aruco::DetectorParameters>(*params);
      p->minMarkerPerimeterRate = std::min(min_perimeter_px / std::max(roi.width, roi.height), 3.9);
      const cv::Mat grey = draw_level(px, right, roi, 0);
      cv::aruco::detectMarkers(grey, dict, corners, ids, p);
      if (refine.relative_win_size > 0.0)
        for (auto& c : corners) refine_corners(grey, c, dict->markerSize, p->markerBorderBits, refine);
      for (auto& c : corners)
        for (auto& q : c) q += cv::Point2f(float(roi.x), float(roi.y));
    }
    for (std::size_t i = 0; i < ids.size(); ++i) {
      Marker m;
      m.id = ids[i];
      for (int k = 0; k < 4; ++k) m.corners.row(k) << corners[i][k].x, corners[i][k].y;
      out.push_back(m);
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const Marker& a, const Marker& b) { return a.id < b.id; });
  out.erase(std::unique(out.begin(), out.end(), [](const Marker& a, const Marker& b) { return a.id == b.id; }),
            out.end());
  return out;
}

std::vector<Box> merge_boxes(std::vector<Box> boxes) {
  bool merged = true;
  while (merged) {
    merged = false;
    for (std::size_t i = 0; i < boxes.size() && !merged; ++i)
      for (std::size_t j = i + 1; j < boxes.size() && !merged; ++j) {
        Box& a = boxes[i];
        const Box& b = boxes[j];
        if (a.x_min < b.x_max && b.x_min < a.x_max && a.y_min < b.y_max && b.y_min < a.y_max) {
          a = {std::min(a.x_min, b.x_min), std::min(a.y_min, b.y_min), std::max(a.x_max, b.x_max),
               std::max(a.y_max, b.y_max)};
          boxes.erase(boxes.begin() + static_cast<std::ptrdiff_t>(j));
          merged = true;
        }
      }
  }
  return boxes;
}

double covered_fraction(const std::vector<Box>& boxes, int width, int height) {
  // The union's area in whole pixels (pixel columns int(x_min)..int(x_max) − 1, as a mask would
  // count them), swept over the boxes' column edges: O(n² log n) for n boxes, not O(width·height).
  std::vector<int> xs;
  for (const Box& b : boxes) xs.insert(xs.end(), {int(b.x_min), int(b.x_max)});
  std::sort(xs.begin(), xs.end());
  xs.erase(std::unique(xs.begin(), xs.end()), xs.end());
  long long area = 0;
  std::vector<std::pair<int, int>> rows;
  for (std::size_t i = 0; i + 1 < xs.size(); ++i) {
    rows.clear();
    for (const Box& b : boxes)
      if (int(b.x_min) <= xs[i] && int(b.x_max) >= xs[i + 1] && int(b.y_max) > int(b.y_min))
        rows.emplace_back(int(b.y_min), int(b.y_max));
    std::sort(rows.begin(), rows.end());
    long long covered = 0;
    int end = std::numeric_limits<int>::min();
    for (const auto& [y0, y1] : rows) {
      if (y1 <= end) continue;
      covered += y1 - std::max(y0, end);
      end = y1;
    }
    area += covered * (xs[i + 1] - xs[i]);
  }
  return double(area) / (double(width) * double(height));
}

std::vector<SearchWindow> predicted_windows(const LanBLocRig& rig, const LanBLocSettings& settings,
                                            const std::vector<LanBLocLandmark>& landmarks, int marker_bits,
                                            const PosePrediction& prediction) {
  check_prediction(prediction);
  const double board_half = 0.5 * board_side_m(settings, marker_bits);
  std::vector<SearchWindow> out;
  for (const LanBLocLandmark& lm : landmarks) {
    // Each image on its own: a marker seen only in the left image is still detected there (and
    // reported as not found in the right one), as in the whole frame.
    SearchWindow w;
    if (window_of(rig, settings, lm, board_half, prediction, false, w)) out.push_back(w);
    if (window_of(rig, settings, lm, board_half, prediction, true, w)) out.push_back(w);
  }
  return out;
}

std::vector<Region> detection_regions(const LanBLocRig& rig, const LanBLocSettings& settings,
                                      const std::vector<LanBLocLandmark>& landmarks, int marker_bits,
                                      const SearchPlan& plan, bool right) {
  const std::vector<Box>& boxes = right ? plan.right_regions : plan.left_regions;
  std::vector<Region> out;
  for (const Box& b : boxes) out.push_back({b, 0});
  if (!(settings.detect_side_px > 0.0) || !settings.subpixel || !plan.prediction) return out;
  const PosePrediction& pred = *plan.prediction;
  const double board_side = board_side_m(settings, marker_bits);
  const double pos_sigma = std::sqrt(std::max(pred.covariance.topLeftCorner<2, 2>().trace(), 0.0));
  for (Region& r : out) {
    // The smallest board in the region: each window's landmark at its predicted depth plus
    // window_sigmas·σ of the position (the farthest, so the smallest, it can be).
    double side = std::numeric_limits<double>::infinity();
    for (const SearchWindow& w : plan.windows) {
      const Box& wb = w.box;
      if (w.right != right || wb.x_min < r.box.x_min || wb.y_min < r.box.y_min || wb.x_max > r.box.x_max ||
          wb.y_max > r.box.y_max)
        continue;
      const auto lm = std::find_if(landmarks.begin(), landmarks.end(),
                                   [&](const LanBLocLandmark& l) { return l.id == w.landmark_id; });
      if (lm == landmarks.end()) continue;
      const double z_far = project(rig, pred.pose, lm->position, right).z() + settings.window_sigmas * pos_sigma;
      side = std::min(side, rig.camera.f * board_side / z_far);
    }
    if (!std::isfinite(side)) continue;  // no window of a mapped landmark: full resolution
    r.level = pyramid_level(side, r.box, settings.detect_side_px);
  }
  return out;
}

int pyramid_level(double side, const Box& box, double detect_side_px) {
  // The coarsest level (at most 6) where that board is still detect_side_px wide and the region
  // at least 16 px.
  int level = 0;
  const double extent = std::min(box.x_max - box.x_min, box.y_max - box.y_min);
  while (level < 6 && side / double(2 << level) >= detect_side_px) ++level;
  while (level > 0 && extent / double(1 << level) < 16.0) --level;
  return level;
}

Region far_board_region(const LanBLocRig& rig, const LanBLocSettings& settings, int marker_bits, const Box& box) {
  Region r{box, 0};
  if (!(settings.detect_side_px > 0.0) || !settings.subpixel || !std::isfinite(settings.max_range_m)) return r;
  // The smallest board a range is taken of: at max_range_m (a board beyond gives no range).
  r.level = pyramid_level(rig.camera.f * board_side_m(settings, marker_bits) / settings.max_range_m, r.box,
                          settings.detect_side_px);
  return r;
}

Region whole_frame_region(const LanBLocRig& rig, const LanBLocSettings& settings, int marker_bits) {
  return far_board_region(rig, settings, marker_bits, {0.0, 0.0, double(rig.camera.width), double(rig.camera.height)});
}

std::vector<Region> epipolar_regions(const LanBLocRig& rig, const LanBLocSettings& settings, int marker_bits,
                                     const std::vector<Marker>& left) {
  const RectifiedCamera& cam = rig.camera;
  const double W = cam.width, H = cam.height, cells = marker_bits + 2.0;
  std::vector<Box> boxes;
  for (const Marker& mk : left) {
    const Eigen::Matrix<double, 4, 2>& c = mk.corners;  // TL, TR, BR, BL
    // An upright board turns about the vertical: its marker's vertical sides stay f·size/Z tall.
    const double side = 0.5 * ((c.row(3) - c.row(0)).norm() + (c.row(2) - c.row(1)).norm());
    if (!(side > 0.0)) continue;
    const double z = cam.f * settings.marker_size_m / side, fb = cam.f * cam.baseline;
    const double d_lo = fb / (2.0 * z) - cam.doffs, d_hi = 2.0 * fb / z - cam.doffs;  // depths z/2 … 2z
    const double m = settings.window_margin_px + side / cells;  // the detector's margin and the quiet zone
    const Box b{std::max(std::floor(c.col(0).minCoeff() - d_hi - m), 0.0),
                std::max(std::floor(c.col(1).minCoeff() - m), 0.0),
                std::min(std::ceil(c.col(0).maxCoeff() - d_lo + m) + 1.0, W),
                std::min(std::ceil(c.col(1).maxCoeff() + m) + 1.0, H)};
    if (b.x_max > b.x_min && b.y_max > b.y_min) boxes.push_back(b);
  }
  // Each band at the whole frame's level (its board size rule), so that it finds what a whole
  // right image searched at that level would.
  std::vector<Region> out;
  for (const Box& b : merge_boxes(std::move(boxes))) out.push_back(far_board_region(rig, settings, marker_bits, b));
  return out;
}

}  // namespace safenav::lanbloc_detail
