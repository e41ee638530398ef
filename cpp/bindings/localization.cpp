#include "common.hpp"

void pybind_localization(py::module_& m) { (void)m; }
