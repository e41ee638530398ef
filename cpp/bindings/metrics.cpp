#include <string>

#include "common.hpp"
#include "params.hpp"
#include "safenav/metrics.hpp"

using namespace safenav;

namespace {

/// One pose of dimension k = 2 (position) or 4 (state): estimate, k×k covariance, truth.
void add_pose(TrajectoryScore& s, const Eigen::Ref<const Eigen::VectorXd>& est,
              const Eigen::Ref<const Eigen::VectorXd>& cov_row_major, const Eigen::Ref<const Eigen::VectorXd>& truth) {
  const Eigen::Index k = est.size();
  if ((k != 2 && k != 4) || truth.size() != k || cov_row_major.size() != k * k)
    throw py::value_error("TrajectoryScore.add: a pose is a position (2) with a 2x2 covariance or a state (4) with "
                          "a 4x4 one, and its truth of the same size; got sizes " + std::to_string(k) + ", " +
                          std::to_string(cov_row_major.size()) + " and " + std::to_string(truth.size()));
  if (k == 2) {
    const Eigen::Matrix2d P = Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>>(cov_row_major.data());
    s.add(Eigen::Vector2d(est), P, Eigen::Vector2d(truth));
  } else {
    const StateCov P = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(cov_row_major.data());
    s.add(State(est), P, State(truth));
  }
}

}  // namespace

void pybind_metrics(py::module_& m) {
  m.def("ade", &ade, py::arg("estimate"), py::arg("truth"), release_gil());
  m.def("fde", &fde, py::arg("estimate"), py::arg("truth"), release_gil());
  m.def("path_length", &path_length, py::arg("path"), release_gil());
  m.def("path_length_error_percent", &path_length_error_percent, py::arg("estimate"), py::arg("truth"),
        release_gil());

  m.def("nees", &nees, py::arg("estimates"), py::arg("truth"), py::arg("covariances"), py::arg("angle_index") = -1,
        release_gil());

  py::class_<TrajectoryScore>(m, "TrajectoryScore",
                              "The one accumulator of an estimated trajectory's scores against the truth (ADE, FDE, "
                              "RMSE, NEES, share outside 3 sigma), fed pose by pose in time order.")
      .def(py::init<Eigen::Index>(), py::arg("capacity") = 0)
      .def(
          "add",
          [](TrajectoryScore& s, const Eigen::VectorXd& est, const RowMatrixXd& cov, const Eigen::VectorXd& truth) {
            if (cov.rows() != est.size() || cov.cols() != est.size())
              throw py::value_error("TrajectoryScore.add: covariance is " + std::to_string(cov.rows()) + "x" +
                                    std::to_string(cov.cols()) + " for an estimate of size " +
                                    std::to_string(est.size()));
            add_pose(s, est, Eigen::Map<const Eigen::VectorXd>(cov.data(), cov.size()), truth);
          },
          py::arg("estimate"), py::arg("covariance"), py::arg("truth"),
          "One pose: a position (2) with its 2x2 covariance, or a state (x, y, v, theta) with its 4x4 one, and the "
          "truth.")
      .def(
          "add_rows",
          [](TrajectoryScore& s, const RowMatrixXd& est, const RowMatrixXd& covs, const RowMatrixXd& truth) {
            const Eigen::Index k = est.cols();
            if (truth.rows() != est.rows() || truth.cols() != k || covs.rows() != est.rows() || covs.cols() != k * k)
              throw py::value_error("TrajectoryScore.add_rows: estimates " + std::to_string(est.rows()) + "x" +
                                    std::to_string(k) + " need truth of the same shape and covariances " +
                                    std::to_string(est.rows()) + "x" + std::to_string(k * k) + " (row-major), got " +
                                    std::to_string(truth.rows()) + "x" + std::to_string(truth.cols()) + " and " +
                                    std::to_string(covs.rows()) + "x" + std::to_string(covs.cols()));
            for (Eigen::Index i = 0; i < est.rows(); ++i)
              add_pose(s, est.row(i).transpose(), covs.row(i).transpose(), truth.row(i).transpose());
          },
          py::arg("estimates"), py::arg("covariances"), py::arg("truth"),
          "Poses in order, one per row: estimates (N, k), covariances (N, k*k) row-major, truth (N, k); k = 2 or 4.")
      .def_property_readonly("size", &TrajectoryScore::size)
      .def_property_readonly("estimates", [](const TrajectoryScore& s) { return Points2(s.estimates()); })
      .def_property_readonly("length", &TrajectoryScore::length)
      .def_property_readonly("truth_ade", &TrajectoryScore::truth_ade)
      .def_property_readonly("truth_fde", &TrajectoryScore::truth_fde)
      .def_property_readonly("truth_rmse", &TrajectoryScore::truth_rmse)
      .def_property_readonly("nees", &TrajectoryScore::nees)
      .def_property_readonly("nees_poses", &TrajectoryScore::nees_poses)
      .def_property_readonly("position_nees", &TrajectoryScore::position_nees)
      .def_property_readonly("position_nees_poses", &TrajectoryScore::position_nees_poses)
      .def_property_readonly("outside_3sigma", &TrajectoryScore::outside_3sigma);
}
