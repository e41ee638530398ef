#include "common.hpp"

void pybind_stereo(py::module_& m) { (void)m; }
