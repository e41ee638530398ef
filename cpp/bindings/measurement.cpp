#include "common.hpp"
#include "safenav/measurement.hpp"

using namespace safenav;

void pybind_measurement(py::module_& m) {
  py::enum_<MeasurementKind>(m, "MeasurementKind")
      .value("POSITION", MeasurementKind::Position)
      .value("RANGE", MeasurementKind::Range)
      .value("BEARING", MeasurementKind::Bearing)
      .value("RANGE_BEARING", MeasurementKind::RangeBearing)
      .value("SPEED_HEADING", MeasurementKind::SpeedHeading);

  py::class_<MeasurementModel>(m, "MeasurementModel", "A measurement model z = h(x) + v, v ~ N(0, R).")
      .def(py::init([](MeasurementKind kind, const Eigen::MatrixXd& R, const Landmarks& landmarks) {
             return MeasurementModel(kind, GaussianNoise(R, "R"), landmarks);
           }),
           py::arg("kind"), py::arg("R"), py::arg("landmarks") = Landmarks())
      .def(py::init([](MeasurementKind kind, const Eigen::VectorXd& sigmas, const Landmarks& landmarks) {
             return MeasurementModel(kind, GaussianNoise::Sigmas(sigmas, "sigmas"), landmarks);
           }),
           py::arg("kind"), py::kw_only(), py::arg("sigmas"), py::arg("landmarks") = Landmarks(),
           "Independent rows: R = diag(sigmas²), stored per row (O(n) for n rows).")
      .def_static("position", &MeasurementModel::position, py::arg("R"))
      .def_static("speed_heading", &MeasurementModel::speed_heading, py::arg("R"))
      .def_static("range", &MeasurementModel::range, py::arg("landmarks"), py::arg("sigma"))
      .def_static("bearing", &MeasurementModel::bearing, py::arg("landmarks"), py::arg("sigma"))
      .def_static("range_bearing", &MeasurementModel::range_bearing, py::arg("landmarks"), py::arg("sigma_range"),
                  py::arg("sigma_bearing"))
      .def_property_readonly("kind", &MeasurementModel::kind)
      .def_property_readonly("dim", &MeasurementModel::dim)
      .def_property_readonly("R", [](const MeasurementModel& mm) { return mm.noise().cov(); },
                             "The dense noise covariance (built on each access).")
      .def_property_readonly("landmarks", &MeasurementModel::landmarks)
      .def("is_angle", &MeasurementModel::is_angle, py::arg("i"))
      .def("predict", py::overload_cast<const State&>(&MeasurementModel::predict, py::const_), py::arg("x"))
      .def("jacobian", py::overload_cast<const State&>(&MeasurementModel::jacobian, py::const_), py::arg("x"))
      .def(
          "residual",
          [](const MeasurementModel& mm, const Eigen::VectorXd& z, const Eigen::VectorXd& zhat) {
            mm.check(z);
            mm.check(zhat);
            Eigen::VectorXd y(mm.dim());
            mm.residual(z, zhat, y);
            return y;
          },
          py::arg("z"), py::arg("zhat"));
}
