#include "common.hpp"

void pybind_navigation(py::module_& m) { (void)m; }
