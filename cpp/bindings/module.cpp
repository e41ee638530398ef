#include "common.hpp"

void pybind_geometry_simple_polygon(py::module_& m);  // appended to bindings/geometry.cpp
void pybind_lanbloc(py::module_& m);                   // bindings/lanbloc.cpp
void pybind_lanbloc_loop(py::module_& m);              // bindings/lanbloc_loop.cpp
void pybind_render(py::module_& m);                    // bindings/render.cpp

PYBIND11_MODULE(_core, m) {
  m.doc() = "safenav C++ core (use the safenav package, not this module directly)";
  // std::invalid_argument -> ValueError and std::runtime_error -> RuntimeError
  // are pybind11's built-in translations.
  pybind_motion(m);
  pybind_measurement(m);
  pybind_filters(m);
  pybind_augmented(m);
  pybind_metrics(m);
  pybind_geometry(m);
  pybind_geometry_simple_polygon(m);
  pybind_corridor(m);
  pybind_world(m);
  pybind_planning(m);
  pybind_trilateration(m);
  pybind_stereo(m);
  pybind_lanbloc(m);
  pybind_placement(m);
  pybind_navigation(m);
  pybind_guidance(m);
  pybind_render(m);        // before lanbloc_loop: its pixels go to the front end
  pybind_lanbloc_loop(m);  // after lanbloc, navigation and guidance: it extends their classes
  pybind_belief(m);  // after navigation: it takes SensorSettings
}
