#include "common.hpp"
#include "params.hpp"
#include "safenav/trilateration.hpp"

using namespace safenav;

void pybind_trilateration(py::module_& m) {
  py::enum_<LocalizationStatus>(m, "LocalizationStatus")
      .value("OK", LocalizationStatus::Ok)
      .value("TOO_FEW", LocalizationStatus::TooFew)
      .value("DEGENERATE", LocalizationStatus::Degenerate)
      .value("DID_NOT_CONVERGE", LocalizationStatus::DidNotConverge)
      .def("__str__", [](LocalizationStatus s) { return std::string(to_string(s)); });

  def_params<LocalizationOptions>(py::class_<LocalizationOptions>(m, "LocalizationOptions"))
      .def(py::init<>())
      .def_readwrite("outlier_threshold", &LocalizationOptions::outlier_threshold)
      .def_readwrite("reject_outliers", &LocalizationOptions::reject_outliers)
      .def_readwrite("max_iterations", &LocalizationOptions::max_iterations)
      .def_readwrite("tolerance", &LocalizationOptions::tolerance)
      .def_readwrite("max_gdop", &LocalizationOptions::max_gdop)
      .def_readwrite("ambiguity_margin", &LocalizationOptions::ambiguity_margin)
      .def_readwrite("profile_probability", &LocalizationOptions::profile_probability)
      .def_readwrite("min_crossing_angle", &LocalizationOptions::min_crossing_angle)
      .def_readwrite("max_subsets", &LocalizationOptions::max_subsets)
      .def_readwrite("seed", &LocalizationOptions::seed)
      .def("validate", &LocalizationOptions::validate);

  py::class_<LocalizationResult>(m, "LocalizationResult")
      .def_readonly("status", &LocalizationResult::status)
      .def_readonly("position", &LocalizationResult::position)
      .def_readonly("covariance", &LocalizationResult::covariance)
      .def_readonly("gdop", &LocalizationResult::gdop)
      .def_readonly("chi2", &LocalizationResult::chi2)
      .def_readonly("ambiguity_gap", &LocalizationResult::ambiguity_gap)
      .def_readonly("inliers", &LocalizationResult::inliers)
      .def_readonly("iterations", &LocalizationResult::iterations)
      .def_readonly("reason", &LocalizationResult::reason)
      .def_property_readonly("ok", &LocalizationResult::ok);

  m.def("trilaterate", &trilaterate, py::arg("anchors"), py::arg("ranges"), py::arg("sigmas"),
        py::arg("options") = LocalizationOptions(), release_gil());
  m.def("triangulate_bearings", &triangulate_bearings, py::arg("anchors"), py::arg("bearings"), py::arg("sigmas"),
        py::arg("options") = LocalizationOptions(), release_gil());
  m.def(
      "repeated_landmarks",
      [](const std::vector<long long>& ids) {
        const std::vector<char> twice = repeated_landmarks(ids, [](long long id) { return id; });
        return std::vector<bool>(twice.begin(), twice.end());
      },
      py::arg("landmark_ids"),
      "Per range, whether its landmark id is another range's too (a landmark seen twice in one frame: "
      "neither range may be used; safenav::repeated_landmarks).");
}
