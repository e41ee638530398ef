#include "common.hpp"
#include "params.hpp"
#include "safenav/metrics.hpp"

using namespace safenav;

void pybind_metrics(py::module_& m) {
  m.def("ade", &ade, py::arg("estimate"), py::arg("truth"), release_gil());
  m.def("fde", &fde, py::arg("estimate"), py::arg("truth"), release_gil());
  m.def("path_length", &path_length, py::arg("path"), release_gil());
  m.def("path_length_error_percent", &path_length_error_percent, py::arg("estimate"), py::arg("truth"),
        release_gil());

  m.def("nees", &nees, py::arg("estimates"), py::arg("truth"), py::arg("covariances"), py::arg("angle_index") = -1,
        release_gil());
}
