#include "common.hpp"
#include "params.hpp"
#include "safenav/stereo.hpp"

#include <pybind11/numpy.h>

using namespace safenav;

namespace {
using U8Array = py::array_t<std::uint8_t, py::array::c_style>;

ImageView view_of(const U8Array& a, const char* what) {
  if (a.ndim() != 2 && a.ndim() != 3)
    throw std::invalid_argument(std::string(what) + " image must be (H, W) or (H, W, C), got " +
                                std::to_string(a.ndim()) + " dimensions");
  ImageView v;
  v.data = a.data();
  v.rows = static_cast<int>(a.shape(0));
  v.cols = static_cast<int>(a.shape(1));
  v.channels = a.ndim() == 3 ? static_cast<int>(a.shape(2)) : 1;
  return v;
}

py::array to_numpy(Image&& img) {
  auto* heap = new Image(std::move(img));
  py::capsule owner(heap, [](void* p) { delete static_cast<Image*>(p); });
  std::vector<py::ssize_t> shape{heap->rows, heap->cols};
  if (heap->channels > 1) shape.push_back(heap->channels);
  return py::array_t<std::uint8_t>(shape, heap->data.data(), owner);
}

// Calibration, SGBM and box-range settings, and the box range result.
void bind_settings(py::module_& m) {
  py::class_<StereoCalibration>(m, "StereoCalibration")
      .def(py::init<>())
      .def_readwrite("K1", &StereoCalibration::K1)
      .def_readwrite("D1", &StereoCalibration::D1)
      .def_readwrite("K2", &StereoCalibration::K2)
      .def_readwrite("D2", &StereoCalibration::D2)
      .def_readwrite("R", &StereoCalibration::R)
      .def_readwrite("T", &StereoCalibration::T)
      .def_readwrite("width", &StereoCalibration::width)
      .def_readwrite("height", &StereoCalibration::height)
      .def("validate", &StereoCalibration::validate);

  py::class_<RectifiedCamera>(m, "RectifiedCamera")
      .def(py::init<>())
      .def_readwrite("f", &RectifiedCamera::f)
      .def_readwrite("cx", &RectifiedCamera::cx)
      .def_readwrite("cy", &RectifiedCamera::cy)
      .def_readwrite("baseline", &RectifiedCamera::baseline)
      .def_readwrite("doffs", &RectifiedCamera::doffs)
      .def_readwrite("width", &RectifiedCamera::width)
      .def_readwrite("height", &RectifiedCamera::height)
      .def("validate", &RectifiedCamera::validate);

  py::enum_<SgbmParams::Mode>(m, "SgbmMode")
      .value("SGBM", SgbmParams::Mode::SGBM)
      .value("HH", SgbmParams::Mode::HH)
      .value("SGBM_3WAY", SgbmParams::Mode::SGBM3Way)
      .value("HH4", SgbmParams::Mode::HH4);

  py::class_<SgbmParams>(m, "SgbmParams")
      .def(py::init<>())
      .def_readwrite("min_disparity", &SgbmParams::min_disparity)
      .def_readwrite("num_disparities", &SgbmParams::num_disparities)
      .def_readwrite("block_size", &SgbmParams::block_size)
      .def_readwrite("P1", &SgbmParams::P1)
      .def_readwrite("P2", &SgbmParams::P2)
      .def_readwrite("disp12_max_diff", &SgbmParams::disp12_max_diff)
      .def_readwrite("pre_filter_cap", &SgbmParams::pre_filter_cap)
      .def_readwrite("uniqueness_ratio", &SgbmParams::uniqueness_ratio)
      .def_readwrite("speckle_window_size", &SgbmParams::speckle_window_size)
      .def_readwrite("speckle_range", &SgbmParams::speckle_range)
      .def_readwrite("mode", &SgbmParams::mode)
      .def("validate", &SgbmParams::validate);
  m.def("disparity_search", &disparity_search, py::arg("camera"), py::arg("near_m"), py::arg("far_m"),
        py::arg("base"), py::arg("margin_px") = 2,
        "SGBM's disparity search for the depths [near_m, far_m]: base with min_disparity and num_disparities set");


  def_params<BoxRangeOptions>(py::class_<BoxRangeOptions>(m, "BoxRangeOptions"))
      .def(py::init<>())
      .def_readwrite("sigma_d", &BoxRangeOptions::sigma_d)
      .def_readwrite("min_valid_pixels", &BoxRangeOptions::min_valid_pixels)
      .def_readwrite("min_valid_fraction", &BoxRangeOptions::min_valid_fraction)
      .def_readwrite("min_disparity", &BoxRangeOptions::min_disparity)
      .def_readwrite("max_range", &BoxRangeOptions::max_range)
      .def("validate", &BoxRangeOptions::validate);

  py::class_<BoxRange>(m, "BoxRange")
      .def_readonly("ok", &BoxRange::ok)
      .def_readonly("range", &BoxRange::range)
      .def_readonly("sigma", &BoxRange::sigma)
      .def_readonly("disparity", &BoxRange::disparity)
      .def_readonly("n_valid", &BoxRange::n_valid)
      .def_readonly("n_pixels", &BoxRange::n_pixels)
      .def_readonly("point", &BoxRange::point)
      .def_readonly("reason", &BoxRange::reason);
}

// Rectification, SGBM disparity, depth and box ranges.
void bind_matcher(py::module_& m) {
  py::class_<StereoMatcher>(m, "StereoMatcher")
      .def(py::init<const StereoCalibration&, const SgbmParams&, double>(), py::arg("calibration"),
           py::arg("params") = SgbmParams(), py::arg("alpha") = 0.0)
      .def(py::init<const RectifiedCamera&, const SgbmParams&>(), py::arg("camera"), py::arg("params") = SgbmParams())
      .def_property_readonly("camera", &StereoMatcher::camera)
      .def_property_readonly("params", &StereoMatcher::params)
      .def_property_readonly("needs_rectification", &StereoMatcher::needs_rectification)
      .def_property_readonly("R1", &StereoMatcher::R1)
      .def_property_readonly("R2", &StereoMatcher::R2)
      .def_property_readonly("P1", &StereoMatcher::P1)
      .def_property_readonly("P2", &StereoMatcher::P2)
      .def_property_readonly("Q", &StereoMatcher::Q)
      .def(
          "rectify",
          [](const StereoMatcher& s, const U8Array& left, const U8Array& right) {
            const ImageView l = view_of(left, "left"), r = view_of(right, "right");
            Image lo, ro;
            {
              py::gil_scoped_release nogil;
              s.rectify(l, r, lo, ro);
            }
            return py::make_tuple(to_numpy(std::move(lo)), to_numpy(std::move(ro)));
          },
          py::arg("left"), py::arg("right"))
      .def("rectify_points_left", &StereoMatcher::rectify_points_left, py::arg("points"))
      .def("rectify_points_right", &StereoMatcher::rectify_points_right, py::arg("points"))
      .def(
          "disparity",
          [](const StereoMatcher& s, const U8Array& left, const U8Array& right) {
            const ImageView l = view_of(left, "left_rect"), r = view_of(right, "right_rect");
            DisparityMap d;
            {
              py::gil_scoped_release nogil;
              d = s.disparity(l, r);
            }
            return d;
          },
          py::arg("left_rect"), py::arg("right_rect"))
      .def("depth", &StereoMatcher::depth, py::arg("disparity"), release_gil())
      .def(
          "box_range",
          [](const StereoMatcher& s, const Eigen::Ref<const DisparityMap>& d, double x_min, double y_min, double x_max,
             double y_max, const BoxRangeOptions& o) { return s.box_range(d, Box{x_min, y_min, x_max, y_max}, o); },
          py::arg("disparity"), py::arg("x_min"), py::arg("y_min"), py::arg("x_max"), py::arg("y_max"),
          py::arg("options") = BoxRangeOptions());
}
}  // namespace

void pybind_stereo(py::module_& m) {
  bind_settings(m);
  bind_matcher(m);
}
