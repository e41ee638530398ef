// Shared declarations of the binding files: one pybind_<area>(m) per area.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

namespace py = pybind11;

void pybind_motion(py::module_& m);
void pybind_measurement(py::module_& m);
void pybind_filters(py::module_& m);
void pybind_metrics(py::module_& m);
void pybind_geometry(py::module_& m);
void pybind_corridor(py::module_& m);
void pybind_world(py::module_& m);
void pybind_planning(py::module_& m);
void pybind_belief(py::module_& m);
void pybind_trilateration(py::module_& m);
void pybind_stereo(py::module_& m);
void pybind_placement(py::module_& m);
void pybind_navigation(py::module_& m);
void pybind_augmented(py::module_& m);
void pybind_guidance(py::module_& m);

/// Release the GIL for a batch call (inputs are already converted).
using release_gil = py::call_guard<py::gil_scoped_release>;
