#include "common.hpp"
#include "safenav/geometry.hpp"

using namespace safenav;

void pybind_geometry(py::module_& m) {
  m.def("convex_hull", &convex_hull, py::arg("points"), release_gil());
  m.def("points_in_polygon", &points_in_polygon, py::arg("points"), py::arg("polygon"), release_gil());
}

void pybind_geometry_simple_polygon(py::module_& m) {
  m.def("is_simple_polygon", &is_simple_polygon, py::arg("polygon"), release_gil(),
        "Whether the (M, 2) polygon is simple (CGAL::is_simple_2, O(M log M)).");
}
