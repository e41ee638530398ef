#include "common.hpp"
#include "params.hpp"
#include "safenav/filters.hpp"

using namespace safenav;

namespace {
template <class F>
void common_filter_api(py::class_<F>& c) {
  c.def("predict", py::overload_cast<const Control&>(&F::predict), py::arg("u"), "Predict one step with the BMM.")
      .def("update", &F::update, py::arg("model"), py::arg("z"), "Update with one measurement.");
}

// The step-by-step filters (SafeNav eqs. 10-14; the PF; the EIF of the placement paper).
void bind_step_filters(py::module_& m) {
  m.def("chi2_quantile", &chi2_quantile, py::arg("probability"), py::arg("dof"));
  m.def("check_covariance", [](const Eigen::MatrixXd& P, const std::string& what) { check_covariance(P, what.c_str()); },
        py::arg("P"), py::arg("what") = "P");

  py::class_<UpdateResult>(m, "UpdateResult")
      .def_readonly("accepted", &UpdateResult::accepted)
      .def_readonly("nis", &UpdateResult::nis)
      .def_readonly("log_det_s", &UpdateResult::log_det_s)
      .def_readonly("dim", &UpdateResult::dim)
      .def("__repr__", [](const UpdateResult& r) {
        return "UpdateResult(accepted=" + std::string(r.accepted ? "True" : "False") +
               ", nis=" + std::to_string(r.nis) + ", dim=" + std::to_string(r.dim) + ")";
      });

  py::class_<Ekf> ekf(m, "Ekf", "Extended Kalman filter on the BMM (SafeNav eqs. 10-14, Joseph form).");
  ekf.def(py::init<const BmmParams&, const State&, const StateCov&>(), py::arg("params"), py::arg("x0"),
          py::arg("P0"))
      .def_property_readonly("x", &Ekf::x)
      .def_property_readonly("P", &Ekf::P)
      .def("set_state", &Ekf::set_state, py::arg("x"), py::arg("P"))
      .def_property("gate", &Ekf::gate, &Ekf::set_gate)
      .def(
          "last_transition",
          [](const Ekf& f) {
            const EkfTransition t = f.last_transition();
            return py::make_tuple(t.F, t.Q);
          },
          "(F, Q) of the last predict (eq. 11: P' = F P F^T + Q); identity and zero before any");
  common_filter_api(ekf);

  py::class_<ParticleFilter> pf(
      m, "ParticleFilter",
      "Regularised particle filter on the BMM (log-weights, systematic resampling, the kernel update of the "
      "adaptive Gaussian mixture filter when the weights would degenerate, covariance floored by the kernel's).");
  pf.def(py::init<const BmmParams&, const State&, const StateCov&, int, std::uint64_t, double, double>(),
         py::arg("params"), py::arg("x0"), py::arg("P0"), py::arg("n_particles") = 1000, py::arg("seed") = 0,
         py::arg("resample_threshold") = 0.5, py::arg("bandwidth_scale") = 1.0)
      .def_property_readonly("size", &ParticleFilter::size)
      .def_property_readonly("ess", &ParticleFilter::ess)
      .def_property_readonly("resample_count", &ParticleFilter::resample_count)
      .def_property_readonly("x", &ParticleFilter::mean)
      .def_property_readonly("P", py::overload_cast<>(&ParticleFilter::covariance, py::const_))
      .def_property_readonly("sample_covariance", &ParticleFilter::sample_covariance)
      .def_property_readonly("covariance_floor", &ParticleFilter::covariance_floor)
      .def_property_readonly("bandwidth", &ParticleFilter::bandwidth)
      .def_property_readonly("particles", &ParticleFilter::particles)
      .def_property_readonly("weights", &ParticleFilter::weights);
  common_filter_api(pf);

  py::class_<InformationFilter> eif(m, "InformationFilter", "Extended information filter on the BMM.");
  eif.def(py::init<const BmmParams&, const State&, const StateCov&>(), py::arg("params"), py::arg("x0"),
          py::arg("P0"))
      .def_property_readonly("x", &InformationFilter::x)
      .def_property_readonly("P", &InformationFilter::P)
      .def_property_readonly("information_vector", &InformationFilter::information_vector)
      .def_property_readonly("information_matrix", &InformationFilter::information_matrix);
  common_filter_api(eif);

}

// Batch filtering of a whole trajectory.
void bind_batch(py::module_& m) {
  py::class_<MeasurementStream>(m, "MeasurementStream")
      .def(py::init<>())
      .def_readwrite("position", &MeasurementStream::position)
      .def_readwrite("position_cov", &MeasurementStream::position_cov)
      .def_readwrite("speed_heading", &MeasurementStream::speed_heading)
      .def_readwrite("speed_heading_cov", &MeasurementStream::speed_heading_cov)
      .def_readwrite("ranges", &MeasurementStream::ranges)
      .def_readwrite("range_std", &MeasurementStream::range_std)
      .def_readwrite("bearings", &MeasurementStream::bearings)
      .def_readwrite("bearing_std", &MeasurementStream::bearing_std)
      .def_readwrite("landmarks", &MeasurementStream::landmarks)
      .def("validate", &MeasurementStream::validate, py::arg("n_steps"));

  py::enum_<FilterType>(m, "FilterType")
      .value("EKF", FilterType::Ekf)
      .value("PF", FilterType::ParticleFilter)
      .value("EIF", FilterType::InformationFilter);

  def_params<FilterOptions>(py::class_<FilterOptions>(m, "FilterOptions"))
      .def(py::init<>())
      .def_readwrite("type", &FilterOptions::type)
      .def_readwrite("n_particles", &FilterOptions::n_particles)
      .def_readwrite("resample_threshold", &FilterOptions::resample_threshold)
      .def_readwrite("bandwidth_scale", &FilterOptions::bandwidth_scale)
      .def_readwrite("seed", &FilterOptions::seed)
      .def_readwrite("gate_probability", &FilterOptions::gate_probability)
      .def(
          "validate", [](const FilterOptions& o) { o.validate(); },
          "ValueError naming the first field (filter.<name>) outside its declared range.");

  py::class_<FilterRun>(m, "FilterRun")
      .def_readonly("states", &FilterRun::states)
      .def_readonly("covariances", &FilterRun::covariances)
      .def_readonly("nis", &FilterRun::nis)
      .def_readonly("nis_dof", &FilterRun::nis_dof)
      .def_readonly("n_updates", &FilterRun::n_updates)
      .def_readonly("n_rejected", &FilterRun::n_rejected)
      .def_readonly("n_resampled", &FilterRun::n_resampled)
      .def_readonly("n_gaps", &FilterRun::n_gaps);

  m.def("run_filter", &run_filter, py::arg("params"), py::arg("options"), py::arg("x0"), py::arg("P0"),
        py::arg("controls"), py::arg("stream"), release_gil());
}
}  // namespace

void pybind_filters(py::module_& m) {
  bind_step_filters(m);
  bind_batch(m);
}
