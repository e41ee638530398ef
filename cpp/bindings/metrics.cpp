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

  const RiskZones d;
  def_params<RiskZones>(py::class_<RiskZones>(m, "RiskZones", "Safe-buffer risk zones of SafeNav section V-A(iii), eq. 18."))
      .def(py::init([](double half_width, std::vector<double> weights) {
             RiskZones z{half_width, std::move(weights)};
             z.validate();
             return z;
           }),
           py::kw_only(), py::arg("half_width") = d.half_width, py::arg("weights") = d.weights)
      .def_readwrite("half_width", &RiskZones::half_width)
      .def_readwrite("weights", &RiskZones::weights)
      .def(py::pickle([](const RiskZones& z) { return py::make_tuple(z.half_width, z.weights); },
                      [](const py::tuple& t) {
                        return RiskZones{t[0].cast<double>(), t[1].cast<std::vector<double>>()};
                      }));

  m.def("distance_to_path", &distance_to_path, py::arg("points"), py::arg("path"), release_gil());
  m.def(
      "wrs_deviation",
      [](const Eigen::VectorXd& d, const RiskZones& z) {
        z.validate();
        Eigen::VectorXd out(d.size());
        for (Eigen::Index i = 0; i < d.size(); ++i) out[i] = wrs(d[i], z);
        return out;
      },
      py::arg("deviation"), py::arg("zones"));
  m.def("wrs", py::overload_cast<const Eigen::Ref<const Points2>&, const Eigen::Ref<const Points2>&,
                                 const RiskZones&>(&wrs),
        py::arg("points"), py::arg("path"), py::arg("zones"), release_gil());
  m.def("awrs", &awrs, py::arg("points"), py::arg("path"), py::arg("zones"), release_gil());
  m.def("nees", &nees, py::arg("estimates"), py::arg("truth"), py::arg("covariances"), py::arg("angle_index") = -1,
        release_gil());
}
