// Python bindings of LanBLoc's C++ front end (safenav/lanbloc.hpp).
#include "common.hpp"
#include "params.hpp"
#include "safenav/lanbloc.hpp"
#include "safenav/yolo.hpp"

#include <array>
#include <map>
#include <optional>

#include <pybind11/numpy.h>

using namespace safenav;

namespace {
using U8Array = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

ImageView gray_view(const U8Array& a, const char* what) {
  if (a.ndim() != 2)
    throw std::invalid_argument(std::string(what) + " image must be (H, W) 8-bit grey, got " +
                                std::to_string(a.ndim()) + " dimensions");
  ImageView v;
  v.data = a.data();
  v.rows = static_cast<int>(a.shape(0));
  v.cols = static_cast<int>(a.shape(1));
  v.channels = 1;
  v.row_stride = static_cast<std::ptrdiff_t>(a.strides(0));
  return v;
}

py::tuple box_tuple(const Box& b) { return py::make_tuple(b.x_min, b.y_min, b.x_max, b.y_max); }

py::list boxes(const std::vector<Box>& bs) {
  py::list out;
  for (const Box& b : bs) out.append(box_tuple(b));
  return out;
}

/// The rig, the ranging modes and the settings.
void bind_settings(py::module_& m) {
  py::class_<LanBLocRig>(m, "LanBLocRig")
      .def(py::init<>())
      .def(py::init([](const RectifiedCamera& c, double h, double pitch) { return LanBLocRig{c, h, pitch}; }),
           py::arg("camera"), py::arg("camera_height_m") = 1.5, py::arg("pitch_rad") = 0.0)
      .def_readwrite("camera", &LanBLocRig::camera)
      .def_readwrite("camera_height_m", &LanBLocRig::camera_height_m)
      .def_readwrite("pitch_rad", &LanBLocRig::pitch_rad)
      .def("validate", &LanBLocRig::validate);

  py::enum_<LanBLocRanging>(m, "LanBLocRanging")
      .value("CORNERS", LanBLocRanging::Corners)
      .value("SGBM", LanBLocRanging::Sgbm)
      .def("__str__", [](LanBLocRanging r) { return std::string(to_string(r)); });
  m.def("ranging_near_depth", &ranging_near_depth, py::arg("camera"), py::arg("min_range_m"),
        "The nearest depth SGBM must search to range a landmark min_range_m away anywhere in the image");
  m.def("pipeline_sgbm", &pipeline_sgbm,
        "The pipeline's SGBM parameters (3-way, block 5, ...) with num_disparities = 0 (the search from min_range_m)");

  def_params<LanBLocSettings>(py::class_<LanBLocSettings>(m, "LanBLocSettings"))
      .def(py::init<>())
      .def(py::init<const LanBLocSettings&>(), py::arg("other"), "a copy")
      .def_readwrite("dictionary", &LanBLocSettings::dictionary)
      .def_readwrite("min_perimeter_rate", &LanBLocSettings::min_perimeter_rate)
      .def_readwrite("error_correction_rate", &LanBLocSettings::error_correction_rate)
      .def_readwrite("max_border_error_rate", &LanBLocSettings::max_border_error_rate)
      .def_readwrite("subpixel", &LanBLocSettings::subpixel)
      .def_readwrite("corner_refinement_win_size", &LanBLocSettings::corner_refinement_win_size)
      .def_readwrite("relative_corner_refinement_win_size", &LanBLocSettings::relative_corner_refinement_win_size)
      .def_readwrite("detect_side_px", &LanBLocSettings::detect_side_px)
      .def_readwrite("corner_sigma_d", &LanBLocSettings::corner_sigma_d)
      .def_readwrite("corner_edge_correlation", &LanBLocSettings::corner_edge_correlation)
      .def_readwrite("max_row_error_px", &LanBLocSettings::max_row_error_px)
      .def_readwrite("corner_square_sigmas", &LanBLocSettings::corner_square_sigmas)
      .def_readwrite("bearing_sigma_px", &LanBLocSettings::bearing_sigma_px)
      .def_readwrite("max_range_m", &LanBLocSettings::max_range_m)
      .def_readwrite("min_landmarks", &LanBLocSettings::min_landmarks)
      .def_readwrite("resolve_ambiguity", &LanBLocSettings::resolve_ambiguity)
      .def_readwrite("trilateration", &LanBLocSettings::trilateration)
      .def_readwrite("marker_size_m", &LanBLocSettings::marker_size_m)
      .def_readwrite("window_sigmas", &LanBLocSettings::window_sigmas)
      .def_readwrite("window_margin_px", &LanBLocSettings::window_margin_px)
      .def_readwrite("max_window_fraction", &LanBLocSettings::max_window_fraction)
      .def_readwrite("ranging", &LanBLocSettings::ranging)
      .def_readwrite("sgbm", &LanBLocSettings::sgbm)
      .def_readwrite("min_range_m", &LanBLocSettings::min_range_m)
      .def_readwrite("sgbm_sigma_d", &LanBLocSettings::sgbm_sigma_d)
      .def_readwrite("box_shrink", &LanBLocSettings::box_shrink)
      .def_readwrite("row_band", &LanBLocSettings::row_band)
      .def_readwrite("band_margin_px", &LanBLocSettings::band_margin_px)
      .def("validate", &LanBLocSettings::validate);
}

/// What a LanBLoc frame gives: statuses, search windows and the fix (bind_sightings: its sightings).
void bind_results(py::module_& m) {
  py::enum_<LanBLocStatus>(m, "LanBLocStatus")
      .value("OK", LanBLocStatus::Ok)
      .value("NO_LANDMARKS", LanBLocStatus::NoLandmarks)
      .value("TOO_FEW_RANGES", LanBLocStatus::TooFewRanges)
      .value("DEGENERATE", LanBLocStatus::Degenerate)
      .value("DID_NOT_CONVERGE", LanBLocStatus::DidNotConverge)
      .def("__str__", [](LanBLocStatus s) { return std::string(to_string(s)); });
  py::enum_<SearchMode>(m, "SearchMode")
      .value("WHOLE_FRAME", SearchMode::WholeFrame)
      .value("WINDOWS", SearchMode::Windows)
      .def("__str__", [](SearchMode s) { return std::string(to_string(s)); });

  py::class_<SearchWindow>(m, "SearchWindow")
      .def_readonly("landmark_id", &SearchWindow::landmark_id)
      .def_readonly("right", &SearchWindow::right)
      .def_property_readonly("box", [](const SearchWindow& w) { return box_tuple(w.box); },
                             "(x_min, y_min, x_max, y_max) [px], x_max and y_max exclusive")
      .def_readonly("predicted_centre", &SearchWindow::predicted_centre)
      .def_readonly("sigma_px", &SearchWindow::sigma_px);
}

/// One landmark's sighting, and the corners' disparity it was ranged from.
void bind_sightings(py::module_& m) {
  py::class_<LandmarkSighting>(m, "LandmarkSighting")
      .def(py::init([](int landmark_id, double range, const Eigen::Vector3d& anchor) {
             LandmarkSighting s;
             s.landmark_id = landmark_id;
             s.ok = std::isfinite(range);
             s.range = range;
             s.anchor = anchor;
             return s;
           }),
           py::arg("landmark_id"), py::arg("range"), py::arg("anchor"),
           "A ranged sighting (ok when the range is finite), e.g. for apply_sighting_faults.")
      .def_readonly("landmark_id", &LandmarkSighting::landmark_id)
      .def_readonly("ok", &LandmarkSighting::ok)
      .def_readonly("range", &LandmarkSighting::range)
      .def_readonly("sigma", &LandmarkSighting::sigma)
      .def_readonly("bearing", &LandmarkSighting::bearing)
      .def_readonly("bearing_sigma", &LandmarkSighting::bearing_sigma)
      .def_readonly("slant_range", &LandmarkSighting::slant_range)
      .def_readonly("depth", &LandmarkSighting::depth)
      .def_readonly("disparity", &LandmarkSighting::disparity)
      .def_readonly("centre", &LandmarkSighting::centre)
      .def_readonly("anchor", &LandmarkSighting::anchor)
      .def_readonly("corners_left", &LandmarkSighting::corners_left)
      .def_readonly("corners_right", &LandmarkSighting::corners_right)
      .def_readonly("corners_used", &LandmarkSighting::corners_used)
      .def_property_readonly("box", [](const LandmarkSighting& o) { return box_tuple(o.box); },
                             "the landmark's box in the left image (x_min, y_min, x_max, y_max) [px]")
      .def_readonly("n_valid", &LandmarkSighting::n_valid, "SGBM: valid disparities in the shrunk box")
      .def_readonly("reason", &LandmarkSighting::reason)
      .def_readonly("faults", &LandmarkSighting::faults, "LandmarkFaults flags applied (the simulator's faults)")
      .def_readonly("true_landmark_id", &LandmarkSighting::true_landmark_id,
                    "the landmark actually seen when a fault relabelled the sighting, else -1");

  py::class_<CornerDisparity>(m, "CornerDisparity")
      .def_readonly("ok", &CornerDisparity::ok)
      .def_readonly("reason", &CornerDisparity::reason)
      .def_readonly("centre", &CornerDisparity::centre)
      .def_readonly("disparity", &CornerDisparity::disparity)
      .def_readonly("sigma", &CornerDisparity::sigma)
      .def_readonly("side_px", &CornerDisparity::side_px)
      .def_readonly("corners_used", &CornerDisparity::corners_used)
      .def_readonly("dropped_corner", &CornerDisparity::dropped_corner);
}

void bind_fix(py::module_& m) {
  py::class_<LanBLocFix>(m, "LanBLocFix")
      .def_readonly("status", &LanBLocFix::status)
      .def_readonly("reason", &LanBLocFix::reason)
      .def_readonly("position", &LanBLocFix::position)
      .def_readonly("covariance", &LanBLocFix::covariance)
      .def_readonly("gdop", &LanBLocFix::gdop)
      .def_readonly("localization", &LanBLocFix::localization)
      .def_readonly("observations", &LanBLocFix::observations)
      .def_readonly("search", &LanBLocFix::search)
      .def_readonly("search_reason", &LanBLocFix::search_reason)
      .def_readonly("windows", &LanBLocFix::windows)
      .def_readonly("unmapped", &LanBLocFix::unmapped)
      .def_property_readonly("left_regions", [](const LanBLocFix& f) { return boxes(f.left_regions); },
                             "the left image's searched regions (x_min, y_min, x_max, y_max) [px] (windows mode)")
      .def_property_readonly("right_regions", [](const LanBLocFix& f) { return boxes(f.right_regions); },
                             "the right image's searched regions (windows mode)")
      .def_property_readonly("ok", &LanBLocFix::ok)
      .def_property_readonly("n_ranges", &LanBLocFix::n_ranges);
}

void bind_types(py::module_& m) {
  bind_settings(m);
  bind_results(m);
  bind_sightings(m);
  bind_fix(m);
}

std::optional<PosePrediction> prediction_of(const std::optional<Eigen::Vector3d>& pose,
                                            const std::optional<Eigen::Matrix3d>& covariance) {
  if (pose.has_value() != covariance.has_value())
    throw std::invalid_argument("predicted_pose and predicted_covariance must be given together (or neither)");
  if (!pose) return std::nullopt;
  return PosePrediction{*pose, *covariance};
}
}  // namespace

void bind_yolo(py::module_& m) {
  py::class_<YoloSettings>(m, "YoloSettings")
      .def(py::init<>())
      .def_readwrite("input_size", &YoloSettings::input_size)
      .def_readwrite("conf_threshold", &YoloSettings::conf_threshold)
      .def_readwrite("iou_threshold", &YoloSettings::iou_threshold)
      .def_readwrite("max_detections", &YoloSettings::max_detections)
      .def("validate", &YoloSettings::validate);
  py::class_<YoloDetection>(m, "YoloDetection")
      .def_readonly("class_id", &YoloDetection::class_id)
      .def_readonly("score", &YoloDetection::score)
      .def_property_readonly("box", [](const YoloDetection& d) { return box_tuple(d.box); });
  m.def(
      "decode_yolo",
      [](const py::array_t<float, py::array::c_style | py::array::forcecast>& out, const YoloSettings& s) {
        if (out.ndim() != 3 || out.shape(0) != 1)
          throw std::invalid_argument("YOLO output must be (1, 4 + nc, N), got " + std::to_string(out.ndim()) +
                                      " dimensions");
        const std::vector<float> v(out.data(), out.data() + out.size());
        return decode_yolo(v, static_cast<int>(out.shape(1)), static_cast<int>(out.shape(2)), s);
      },
      py::arg("output"), py::arg("settings") = YoloSettings(),
      "Decode a YOLOv8/11 output (1, 4 + nc, N) with class-wise NMS: YoloDetections, best score first.");
  py::class_<YoloDetector>(m, "YoloDetector")
      .def(py::init<const std::string&, const YoloSettings&>(), py::arg("model_path"),
           py::arg("settings") = YoloSettings())
      .def_property_readonly("num_classes", &YoloDetector::num_classes)
      .def_property_readonly("settings", &YoloDetector::settings)
      .def(
          "detect",
          [](const YoloDetector& d, const py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>& a) {
            if (a.ndim() != 2 && !(a.ndim() == 3 && a.shape(2) == 3))
              throw std::invalid_argument("image must be (H, W) grey or (H, W, 3) BGR 8-bit");
            const ImageView v{a.data(), static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)),
                              a.ndim() == 3 ? 3 : 1, static_cast<std::ptrdiff_t>(a.strides(0))};
            py::gil_scoped_release nogil;
            return d.detect(v);
          },
          py::arg("image"), "Detections in a grey or BGR image, best score first (boxes in image pixels).");
}

void pybind_lanbloc(py::module_& m) {
  bind_types(m);
  bind_yolo(m);
  m.def("marker_centre", [](const MarkerCorners& c) { return marker_centre(c); }, py::arg("corners"),
        "The image of a marker's centre: the intersection of the diagonals of its (4, 2) corners "
        "(TL, TR, BR, BL).");
  m.def("corner_disparity_sigma", &corner_disparity_sigma, py::arg("settings"), py::arg("corners_used"),
        py::arg("scale") = 1.0, py::arg("side_px") = std::numeric_limits<double>::infinity(),
        "sigma [px] of a marker centre's disparity from its corners: the fitted corner-noise model "
        "(times kSmallMarkerSigmaFactor for a marker under kSmallMarkerSidePx a side).");
  m.def("corner_disparity", &corner_disparity, py::arg("left"), py::arg("right"), py::arg("camera"),
        py::arg("settings"), py::arg("scale") = 1.0,
        "A marker's centre and disparity from its (4, 2) corners in both rectified images: the "
        "least-squares disparity plane through the four, or, when one corner's rows disagree, the "
        "midpoint of the other diagonal's triangulated corners (CornerDisparity).");
  py::class_<LanBLocFrontEnd>(m, "LanBLocFrontEnd")
      .def(py::init([](const LanBLocRig& rig, const std::map<int, Eigen::Vector3d>& landmarks,
                       const LanBLocSettings& settings) {
             std::vector<LanBLocLandmark> lms;
             for (const auto& [id, p] : landmarks) lms.push_back({id, p});
             return LanBLocFrontEnd(rig, std::move(lms), settings);
           }),
           py::arg("rig"), py::arg("landmarks"), py::arg("settings") = LanBLocSettings(),
           "landmarks: {id: (x, y, z)}, the marker centres' map positions [m]")
      .def_property_readonly("rig", &LanBLocFrontEnd::rig)
      .def_property_readonly("settings", &LanBLocFrontEnd::settings)
      .def(
          "localize",
          [](const LanBLocFrontEnd& f, const U8Array& left, const U8Array& right,
             const std::optional<Eigen::Vector3d>& pose, const std::optional<Eigen::Matrix3d>& covariance) {
            const ImageView l = gray_view(left, "left"), r = gray_view(right, "right");
            const std::optional<PosePrediction> p = prediction_of(pose, covariance);
            py::gil_scoped_release nogil;
            return f.localize(l, r, p);
          },
          py::arg("left"), py::arg("right"), py::arg("predicted_pose") = py::none(),
          py::arg("predicted_covariance") = py::none(),
          "Observations and fix of one rectified grey pair; with a predicted pose (x, y, theta) and its 3x3 "
          "covariance the search is in windows around the landmarks' predicted projections.")
      .def(
          "localize_boxes",
          [](const LanBLocFrontEnd& f, const U8Array& left, const U8Array& right,
             const std::vector<std::pair<int, std::array<double, 4>>>& boxes) {
            const ImageView l = gray_view(left, "left"), r = gray_view(right, "right");
            std::vector<LandmarkBox> bs;
            for (const auto& [id, b] : boxes) bs.push_back({id, Box{b[0], b[1], b[2], b[3]}});
            py::gil_scoped_release nogil;
            return f.localize_boxes(l, r, bs);
          },
          py::arg("left"), py::arg("right"), py::arg("boxes"),
          "SGBM ranging of the landmarks a detector of the caller's found: boxes [(landmark id, (x_min, y_min, "
          "x_max, y_max))] in the rectified left image; observations and fix as localize.")
      .def(
          "search_windows",
          [](const LanBLocFrontEnd& f, const Eigen::Vector3d& pose, const Eigen::Matrix3d& covariance) {
            SearchMode mode;
            std::string reason;
            std::vector<SearchWindow> w = f.search_windows(PosePrediction{pose, covariance}, mode, reason);
            return py::make_tuple(w, mode, reason);
          },
          py::arg("predicted_pose"), py::arg("predicted_covariance"),
          "(windows, mode, reason) for a predicted pose and covariance.");
}
