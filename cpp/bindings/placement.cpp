#include "common.hpp"

void pybind_placement(py::module_& m) { (void)m; }
