#include <sstream>

#include "common.hpp"
#include "params.hpp"
#include "safenav/measurement.hpp"

using namespace safenav;

namespace {

/// PositionNoise's fields in order: the pickle state.
py::tuple noise_state(const PositionNoise& p) {
  return py::make_tuple(p.name, p.label, p.std, p.bias_std, p.bias_walk_std, p.outlier_probability, p.outlier_std,
                        p.dropout_probability, p.needs_landmarks, p.emulated, p.note);
}

PositionNoise noise_from_state(const py::tuple& t) {
  if (t.size() != 11) throw std::invalid_argument("PositionNoise: a pickle state of 11 fields expected");
  PositionNoise p;
  p.name = t[0].cast<std::string>();
  p.label = t[1].cast<std::string>();
  p.std = t[2].cast<Eigen::Vector2d>();
  p.bias_std = t[3].cast<double>();
  p.bias_walk_std = t[4].cast<double>();
  p.outlier_probability = t[5].cast<double>();
  p.outlier_std = t[6].cast<double>();
  p.dropout_probability = t[7].cast<double>();
  p.needs_landmarks = t[8].cast<bool>();
  p.emulated = t[9].cast<bool>();
  p.note = t[10].cast<std::string>();
  p.validate();
  return p;
}

// The measurement models z = h(x) + v (SafeNav eq. 10 and ours).
void bind_models(py::module_& m) {
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
          py::arg("z"), py::arg("zhat"))
      .def(
          "residuals",
          [](const MeasurementModel& mm, const Eigen::VectorXd& z,
             const Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>& states) {
            mm.check(z);
            if (!states.allFinite()) throw std::invalid_argument("residuals: states must be finite");
            Eigen::MatrixXd Y(mm.dim(), states.rows());
            // row-major n × 4: state i is contiguous, so the 4 × n view has inner stride 1, outer 4
            mm.residuals(z, StatesView(states.data(), 4, states.rows(), Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>(4, 1)),
                         Y);
            return Eigen::MatrixXd(Y.transpose());
          },
          py::arg("z"), py::arg("states"),
          "z ⊖ h(x_i) for each row x_i = (x, y, v, θ) of states (n × 4): an n × dim array, the values of "
          "predict and residual per state, the direct kinds (position, speed and heading) in one pass.");

}

// The error model of a position source (LanBLoc's RMSE, the emulated baselines).
void bind_position_noise(py::module_& m) {
  const PositionNoise d;
  def_params<PositionNoise>(py::class_<PositionNoise>(m, "PositionNoise",
                            "The error model of a position source (LanBLoc, or an emulated baseline's profile):\n"
                            "a per-trial bias N(0, bias_std^2 I) that walks by N(0, bias_walk_std^2 I) per fix,\n"
                            "dropouts, white noise N(0, diag(std^2)) and outliers N(0, outlier_std^2 I).  Named\n"
                            "profiles: PositionNoise.named(name), PositionNoise.names()."))
      .def(py::init([](std::string name, std::string label, const Eigen::Vector2d& std, double bias_std,
                       double bias_walk_std, double outlier_probability, double outlier_std,
                       double dropout_probability, bool needs_landmarks, bool emulated, std::string note) {
             PositionNoise p;
             p.name = std::move(name);
             p.label = std::move(label);
             p.std = std;
             p.bias_std = bias_std;
             p.bias_walk_std = bias_walk_std;
             p.outlier_probability = outlier_probability;
             p.outlier_std = outlier_std;
             p.dropout_probability = dropout_probability;
             p.needs_landmarks = needs_landmarks;
             p.emulated = emulated;
             p.note = std::move(note);
             p.validate();
             return p;
           }),
           py::kw_only(), py::arg("name") = d.name, py::arg("label") = d.label, py::arg("std") = d.std,
           py::arg("bias_std") = d.bias_std, py::arg("bias_walk_std") = d.bias_walk_std,
           py::arg("outlier_probability") = d.outlier_probability, py::arg("outlier_std") = d.outlier_std,
           py::arg("dropout_probability") = d.dropout_probability, py::arg("needs_landmarks") = d.needs_landmarks,
           py::arg("emulated") = d.emulated, py::arg("note") = d.note)
      .def_static("named", &PositionNoise::named, py::arg("name"))
      .def_static("names", &PositionNoise::names)
      .def_readwrite("name", &PositionNoise::name)
      .def_readwrite("label", &PositionNoise::label, "table label")
      .def_readwrite("std", &PositionNoise::std, "sigma of the white noise in X and Y [m]")
      .def_readwrite("bias_std", &PositionNoise::bias_std, "sigma of the per-trial bias [m]")
      .def_readwrite("bias_walk_std", &PositionNoise::bias_walk_std, "sigma of the bias's walk per fix [m]")
      .def_readwrite("outlier_probability", &PositionNoise::outlier_probability)
      .def_readwrite("outlier_std", &PositionNoise::outlier_std, "sigma of an outlier's extra error [m]")
      .def_readwrite("dropout_probability", &PositionNoise::dropout_probability)
      .def_readwrite("needs_landmarks", &PositionNoise::needs_landmarks,
                     "a fix needs min_landmarks landmarks in view (navigation loop)")
      .def_readwrite("emulated", &PositionNoise::emulated, "an emulated error profile, not the real method")
      .def_readwrite("note", &PositionNoise::note)
      .def("validate", &PositionNoise::validate)
      .def("reported_cov", &PositionNoise::reported_cov,
           "The R filters are told: diag(std^2) + (bias_std^2 + outlier_probability * outlier_std^2) I.")
      .def("sample", &PositionNoise::sample, py::arg("truth"), py::arg("seed"), release_gil(),
           "The fixes of one trial at the true positions `truth` (n x 2), from the core's generator seeded\n"
           "with `seed` (the navigation loop's sensors use derive_seed(trial_seed, 1)); NaN rows are lost fixes.")
      .def(py::pickle(&noise_state, &noise_from_state))
      .def("__repr__", [](const PositionNoise& p) {
        std::ostringstream os;
        os << "PositionNoise(name='" << p.name << "', std=(" << p.std[0] << ", " << p.std[1]
           << "), bias_std=" << p.bias_std << ", bias_walk_std=" << p.bias_walk_std
           << ", outlier_probability=" << p.outlier_probability << ", outlier_std=" << p.outlier_std
           << ", dropout_probability=" << p.dropout_probability
           << ", needs_landmarks=" << (p.needs_landmarks ? "True" : "False")
           << ", emulated=" << (p.emulated ? "True" : "False") << ")";
        return os.str();
      });
}
}  // namespace

void pybind_measurement(py::module_& m) {
  bind_models(m);
  bind_position_noise(m);
}
