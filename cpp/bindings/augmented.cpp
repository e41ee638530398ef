// Bindings of safenav/augmented.hpp: AugmentedStates, AugmentedEkf and
// AugmentedParticleFilter (registered before bindings/guidance.cpp, whose
// LocalizerSettings holds an AugmentedStates).
#include "common.hpp"
#include "params.hpp"
#include "safenav/augmented.hpp"

using namespace safenav;

namespace {

void bind_states(py::module_& m) {
  def_params<AugmentedStates>(py::class_<AugmentedStates>(
      m, "AugmentedStates",
      "Optional augmented states of the EKF (ours, not the paper's): range scale k (r = (1+k)|p-a| + b_j),\n"
      "heading-rate (gyro) bias beta (theta' = theta + clip(dtheta) - beta*dt) and per-landmark range biases\n"
      "b_j; each a random walk with sigma per sqrt(s).  All off by default; values tuned on Plaza1."))
      .def(py::init<>())
      .def_readwrite("range_scale", &AugmentedStates::range_scale)
      .def_readwrite("scale_prior", &AugmentedStates::scale_prior)
      .def_readwrite("scale_std", &AugmentedStates::scale_std)
      .def_readwrite("scale_walk", &AugmentedStates::scale_walk)
      .def_readwrite("heading_rate_bias", &AugmentedStates::heading_rate_bias)
      .def_readwrite("heading_rate_bias_prior", &AugmentedStates::heading_rate_bias_prior)
      .def_readwrite("heading_rate_bias_std", &AugmentedStates::heading_rate_bias_std)
      .def_readwrite("heading_rate_bias_walk", &AugmentedStates::heading_rate_bias_walk)
      .def_readwrite("range_bias", &AugmentedStates::range_bias)
      .def_readwrite("range_bias_std", &AugmentedStates::range_bias_std)
      .def_readwrite("range_bias_walk", &AugmentedStates::range_bias_walk)
      .def("any", &AugmentedStates::any)
      .def("validate", &AugmentedStates::validate);
}

void bind_ekf(py::module_& m) {
  py::class_<AugmentedEkf>(m, "AugmentedEkf",
                           "EKF on the BMM (SafeNav eqs. 10-14, Joseph form) over (x, y, v, theta, [k], [beta], [b_j]).")
      .def(py::init<const BmmParams&, const AugmentedStates&, int, const State&, const StateCov&>(), py::arg("params"),
           py::arg("augment"), py::arg("n_landmarks"), py::arg("x0"), py::arg("P0"))
      .def_property_readonly("x", &AugmentedEkf::x, "(x, y, v, theta)")
      .def(
          "last_transition",
          [](const AugmentedEkf& f) {
            Eigen::MatrixXd F, Q;
            f.last_transition(F, Q);
            return py::make_tuple(F, Q);
          },
          "(F, Q) of the last predict, full size (P' = F P F^T + Q); identity and zero before any")
      .def(
          "transition",
          [](const AugmentedEkf& f, const Eigen::VectorXd& x, const Control& u, double dt) {
            const Eigen::Index n = f.size();
            Eigen::VectorXd x1(n);
            Eigen::MatrixXd F(n, n), Q(n, n);
            f.transition(x, u, dt, x1, F, Q);
            return py::make_tuple(x1, F, Q);
          },
          py::arg("x"), py::arg("u"), py::arg("dt"),
          "(x1, F, Q): predict's f(x, u) over dt, its F and Q at the full state x (not the estimate)")
      .def_property_readonly("P", &AugmentedEkf::P, "4x4 covariance of x")
      .def_property_readonly("augmented", &AugmentedEkf::augmented, "The full state (size entries).")
      .def_property_readonly("augmented_cov", &AugmentedEkf::augmented_cov, "The full covariance.")
      .def_property_readonly("size", &AugmentedEkf::size)
      .def_property_readonly("scale_index", &AugmentedEkf::scale_index, "Index of k, or -1.")
      .def_property_readonly("heading_rate_bias_index", &AugmentedEkf::heading_rate_bias_index, "Index of beta, or -1.")
      .def("range_bias_index", &AugmentedEkf::range_bias_index, py::arg("landmark_row"), "Index of b_row, or -1.")
      .def("set_state", &AugmentedEkf::set_state, py::arg("x"), py::arg("P"))
      .def_property("gate", &AugmentedEkf::gate, &AugmentedEkf::set_gate, "chi-square gate probability (0 = off)")
      .def("predict", &AugmentedEkf::predict, py::arg("u"), py::arg("dt"),
           "BMM step of dt seconds with theta' = theta + clip(dtheta) - beta*dt (eq. 11).")
      .def("update_range", &AugmentedEkf::update_range, py::arg("landmark_row"), py::arg("landmark"), py::arg("r"),
           py::arg("variance"), "r = (1+k)|p - a| + b_row (eqs. 12-14).")
      .def("update_bearing", &AugmentedEkf::update_bearing, py::arg("landmark_row"), py::arg("landmark"),
           py::arg("bearing"), py::arg("variance"))
      .def("update_range_bearing", &AugmentedEkf::update_range_bearing, py::arg("landmark_row"), py::arg("landmark"),
           py::arg("z"), py::arg("R"))
      .def("update_position", &AugmentedEkf::update_position, py::arg("z"), py::arg("R"))
      .def("update_speed_heading", &AugmentedEkf::update_speed_heading, py::arg("z"), py::arg("R"));
}

void bind_pf(py::module_& m) {
  py::class_<AugmentedParticleFilter>(
      m, "AugmentedParticleFilter",
      "Particle filter on the BMM over (x, y, v, theta, [k], [beta], [b_j]): the PF counterpart of AugmentedEkf.")
      .def(py::init<const BmmParams&, const AugmentedStates&, int, const State&, const StateCov&, int, std::uint64_t,
                    double, double>(),
           py::arg("params"), py::arg("augment"), py::arg("n_landmarks"), py::arg("x0"), py::arg("P0"),
           py::arg("n_particles") = 1000, py::arg("seed") = 0, py::arg("resample_threshold") = 0.5,
           py::arg("bandwidth_scale") = 1.0)
      .def_property_readonly("size", &AugmentedParticleFilter::size)
      .def_property_readonly("state_size", &AugmentedParticleFilter::state_size)
      .def_property_readonly("scale_index", &AugmentedParticleFilter::scale_index)
      .def_property_readonly("heading_rate_bias_index", &AugmentedParticleFilter::heading_rate_bias_index)
      .def_property("gate", &AugmentedParticleFilter::gate, &AugmentedParticleFilter::set_gate)
      .def_property_readonly("x", &AugmentedParticleFilter::mean)
      .def_property_readonly("P", &AugmentedParticleFilter::covariance)
      .def_property_readonly("sample_covariance", &AugmentedParticleFilter::sample_covariance)
      .def_property_readonly("covariance_floor", &AugmentedParticleFilter::covariance_floor)
      .def_property_readonly("bandwidth", &AugmentedParticleFilter::bandwidth)
      .def_property_readonly("augmented", &AugmentedParticleFilter::augmented)
      .def_property_readonly("particles", &AugmentedParticleFilter::particles)
      .def_property_readonly("weights", &AugmentedParticleFilter::weights)
      .def_property_readonly("ess", &AugmentedParticleFilter::ess)
      .def_property_readonly("resample_count", &AugmentedParticleFilter::resample_count)
      .def("predict", &AugmentedParticleFilter::predict, py::arg("u"), py::arg("dt"))
      .def("update_range", &AugmentedParticleFilter::update_range, py::arg("landmark_row"), py::arg("landmark"),
           py::arg("r"), py::arg("variance"))
      .def("update_bearing", &AugmentedParticleFilter::update_bearing, py::arg("landmark_row"), py::arg("landmark"),
           py::arg("bearing"), py::arg("variance"))
      .def("update_range_bearing", &AugmentedParticleFilter::update_range_bearing, py::arg("landmark_row"),
           py::arg("landmark"), py::arg("z"), py::arg("R"))
      .def("update_position", &AugmentedParticleFilter::update_position, py::arg("z"), py::arg("R"))
      .def("update_speed_heading", &AugmentedParticleFilter::update_speed_heading, py::arg("z"), py::arg("R"));
}

}  // namespace

void pybind_augmented(py::module_& m) {
  bind_states(m);
  bind_ekf(m);
  bind_pf(m);
}
