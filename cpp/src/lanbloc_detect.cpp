// LanBLoc front end: fiducial detection (OpenCV ArUco) and the search windows
// from a predicted pose (safenav/lanbloc.hpp).
#include <algorithm>
#include <cctype>
#include <cmath>
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

/// The window of one landmark in one image, or false when its board is not
/// predicted in front of the camera, within range and overlapping the image.
bool window_of(const LanBLocRig& rig, const LanBLocSettings& s, const LanBLocLandmark& lm, double board_radius,
               const PosePrediction& pred, bool right, SearchWindow& out) {
  const Eigen::Vector3d uvz = project(rig, pred.pose, lm.position, right);
  const double near = board_radius + 0.2;
  if (!(uvz.z() > near)) return false;
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
  // The board (any orientation) lies within a sphere of board_radius: f·r/(Z − r) px around its centre.
  const double half = rig.camera.f * board_radius / (uvz.z() - board_radius) + s.window_margin_px;
  const double W = rig.camera.width, H = rig.camera.height;
  Box b{std::max(std::floor(uvz.x() - half - s.window_sigmas * sigma.x()), 0.0),
        std::max(std::floor(uvz.y() - half - s.window_sigmas * sigma.y()), 0.0),
        std::min(std::ceil(uvz.x() + half + s.window_sigmas * sigma.x()) + 1.0, W),
        std::min(std::ceil(uvz.y() + half + s.window_sigmas * sigma.y()) + 1.0, H)};
  if (!(b.x_max > b.x_min && b.y_max > b.y_min)) return false;
  out.landmark_id = lm.id;
  out.right = right;
  out.box = b;
  out.predicted_centre = uvz.head<2>();
  out.sigma_px = sigma;
  return true;
}

/// OpenCV >= 4.8's CORNER_REFINE_SUBPIX (the one pip's cv2 runs): cornerSubPix in a window of
/// min(max(1, round(relative·m)), max_win) px, m the marker's average module (cell) size in px.
void refine_corners(const cv::Mat& grey, std::vector<cv::Point2f>& c, int marker_bits, int border_bits,
                    const CornerRefinement& r) {
  double perimeter = 0.0;
  for (int k = 0; k < 4; ++k) perimeter += cv::norm(c[k] - c[(k + 1) % 4]);
  const double module = perimeter / (4.0 * (marker_bits + 2 * border_bits));
  const int win = std::min(std::max(1, cvRound(r.relative_win_size * module)), r.max_win_size);
  cv::cornerSubPix(grey, c, cv::Size(win, win), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::MAX_ITER | cv::TermCriteria::EPS, r.max_iterations,
                                    r.min_accuracy));
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

std::vector<Marker> detect_markers(const cv::Mat& image, const std::vector<Box>& boxes,
                                   const cv::Ptr<cv::aruco::Dictionary>& dict,
                                   const cv::Ptr<cv::aruco::DetectorParameters>& params,
                                   double min_perimeter_rate, const CornerRefinement& refine) {
  std::vector<Box> search = boxes;
  if (search.empty()) search.push_back({0.0, 0.0, double(image.cols), double(image.rows)});
  const double full_side = std::max(image.cols, image.rows);
  std::vector<Marker> out;
  for (const Box& b : search) {
    const cv::Rect roi(int(b.x_min), int(b.y_min), int(b.x_max - b.x_min), int(b.y_max - b.y_min));
    if (roi.width < 8 || roi.height < 8) continue;
    // The same smallest perimeter in pixels as on the whole image (a rate of the searched side);
    // a copy of the parameters, so that concurrent calls share nothing they write.
    const cv::Ptr<cv::aruco::DetectorParameters> p = cv::makePtr<cv::aruco::DetectorParameters>(*params);
    p->minMarkerPerimeterRate = std::min(min_perimeter_rate * full_side / std::max(roi.width, roi.height), 3.9);
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    cv::aruco::detectMarkers(image(roi), dict, corners, ids, p);
    if (refine.relative_win_size > 0.0)
      for (auto& c : corners) refine_corners(image(roi), c, dict->markerSize, p->markerBorderBits, refine);
    for (std::size_t i = 0; i < ids.size(); ++i) {
      Marker m;
      m.id = ids[i];
      for (int k = 0; k < 4; ++k) m.corners.row(k) << corners[i][k].x + roi.x, corners[i][k].y + roi.y;
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
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(width) * height, 0);
  for (const Box& b : boxes)
    for (int y = int(b.y_min); y < int(b.y_max); ++y)
      std::fill(mask.begin() + std::ptrdiff_t(y) * width + int(b.x_min),
                mask.begin() + std::ptrdiff_t(y) * width + int(b.x_max), std::uint8_t(1));
  return double(std::count(mask.begin(), mask.end(), std::uint8_t(1))) / double(mask.size());
}

std::vector<SearchWindow> predicted_windows(const LanBLocRig& rig, const LanBLocSettings& settings,
                                            const std::vector<LanBLocLandmark>& landmarks, int marker_bits,
                                            const PosePrediction& prediction) {
  check_prediction(prediction);
  // The board: the black-framed marker of markerSize + 2 cells plus a one-cell quiet zone per side
  // (safenav.vision.render: board half-side = marker_size·(cells + 2)/(2·cells)); a sphere holds it.
  const double cells = marker_bits + 2.0;
  const double board_radius = std::sqrt(2.0) * 0.5 * settings.marker_size_m * (cells + 2.0) / cells;
  std::vector<SearchWindow> out;
  for (const LanBLocLandmark& lm : landmarks) {
    // Each image on its own: a marker seen only in the left image is still detected there (and
    // reported as not found in the right one), as in the whole frame.
    SearchWindow w;
    if (window_of(rig, settings, lm, board_radius, prediction, false, w)) out.push_back(w);
    if (window_of(rig, settings, lm, board_radius, prediction, true, w)) out.push_back(w);
  }
  return out;
}

}  // namespace safenav::lanbloc_detail
