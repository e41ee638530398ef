#include "common.hpp"
#include "params.hpp"
#include "safenav/belief.hpp"

using namespace safenav;

namespace {
void bind_settings(py::module_& m) {
  def_params<BeliefSettings>(py::class_<BeliefSettings>(
      m, "BeliefSettings", "How the belief is stepped along a path (speed, belief step, bearings, inflation)."))
      .def(py::init<>())
      .def_readwrite("speed", &BeliefSettings::speed)
      .def_readwrite("step", &BeliefSettings::step)
      .def_readwrite("bearing_std", &BeliefSettings::bearing_std)
      .def_readwrite("sight_fov_margin", &BeliefSettings::sight_fov_margin)
      .def_readwrite("sight_range_fraction", &BeliefSettings::sight_range_fraction)
      .def_readwrite("deviation_mixture", &BeliefSettings::deviation_mixture)
      .def_readwrite("deviation_nodes", &BeliefSettings::deviation_nodes)
      .def_readwrite("deviation_along", &BeliefSettings::deviation_along)
      .def_readwrite("deviation_split", &BeliefSettings::deviation_split)
      .def_readwrite("deviation_free_strata", &BeliefSettings::deviation_free_strata)
      .def_readwrite("gate_probability", &BeliefSettings::gate_probability)
      .def_readwrite("inflation", &BeliefSettings::inflation)
      .def("validate", &BeliefSettings::validate);

  using S = BeliefPlannerSettings;
  def_params<S>(py::class_<S>(m, "BeliefPlannerSettings", "Belief-aware roadmap planner settings (RRBT-style)."))
      .def(py::init<>())
      .def_readwrite("belief", &S::belief)
      .def_readwrite("k_sigma", &S::k_sigma)
      .def_readwrite("alpha", &S::alpha)
      .def_readwrite("sigma_weight", &S::sigma_weight)
      .def_readwrite("samples", &S::samples)
      .def_readwrite("neighbours", &S::neighbours)
      .def_readwrite("max_edge", &S::max_edge)
      .def_readwrite("guide_spacing", &S::guide_spacing)
      .def_readwrite("seed", &S::seed)
      .def_readwrite("max_beliefs", &S::max_beliefs)
      .def_readwrite("dominance_tolerance", &S::dominance_tolerance)
      .def_readwrite("max_expansions", &S::max_expansions)
      .def_readwrite("shortcut", &S::shortcut)
      .def_readwrite("max_turn", &S::max_turn)
      .def_readwrite("turn_window", &S::turn_window)
      .def("validate", &S::validate);

  py::class_<BeliefProblem>(m, "BeliefProblem", "Map, start, goal, motion model, sensors, start covariance, guide paths.")
      .def(py::init<>())
      .def_readwrite("map", &BeliefProblem::map)
      .def_readwrite("start", &BeliefProblem::start)
      .def_readwrite("goal", &BeliefProblem::goal)
      .def_readwrite("bmm", &BeliefProblem::bmm)
      .def_readwrite("sensors", &BeliefProblem::sensors)
      .def_readwrite("start_cov", &BeliefProblem::start_cov)
      .def_readwrite("guide_paths", &BeliefProblem::guide_paths)
      .def("validate", &BeliefProblem::validate);
}

void bind_results(py::module_& m) {
  using P = BeliefProfile;
  py::class_<P>(m, "BeliefProfile", "Belief along a path, one row per stage (row 0 = the start).")
      .def_readonly("positions", &P::positions)
      .def_readonly("headings", &P::headings)
      .def_readonly("time", &P::time)
      .def_readonly("covariance", &P::covariance)
      .def_readonly("cov_xy", &P::cov_xy)
      .def_readonly("sigma", &P::sigma)
      .def_readonly("landmarks", &P::landmarks)
      .def_readonly("transition", &P::transition)
      .def_readonly("clearance", &P::clearance)
      .def_readonly("direction", &P::direction)
      .def_readonly("sigma_toward", &P::sigma_toward)
      .def_readonly("stage_probability", &P::stage_probability)
      .def_readonly("marginal_probability", &P::marginal_probability)
      .def_readonly("collision_probability", &P::collision_probability)
      .def_readonly("union_bound", &P::union_bound)
      .def_readonly("length", &P::length)
      .def_readonly("vehicle_radius", &P::vehicle_radius)
      .def_readonly("strata_weight", &P::strata_weight)
      .def_readonly("strata_positions", &P::strata_positions)
      .def_readonly("strata_msq", &P::strata_msq)
      .def_readonly("strata_position_cov", &P::strata_position_cov);

  py::enum_<BeliefPlanStatus>(m, "BeliefPlanStatus")
      .value("EXACT", BeliefPlanStatus::Exact)
      .value("INFEASIBLE", BeliefPlanStatus::Infeasible)
      .value("NO_PATH", BeliefPlanStatus::NoPath)
      .value("BUDGET", BeliefPlanStatus::Budget);

  using R = BeliefPlanResult;
  py::class_<R>(m, "BeliefPlanResult")
      .def_readonly("status", &R::status)
      .def_readonly("success", &R::success)
      .def_readonly("detail", &R::detail)
      .def_readonly("path", &R::path)
      .def_readonly("cost", &R::cost)
      .def_readonly("profile", &R::profile)
      .def_readonly("vertices", &R::vertices)
      .def_readonly("edges", &R::edges)
      .def_readonly("expansions", &R::expansions)
      .def_readonly("beliefs", &R::beliefs)
      .def_readonly("capped", &R::capped)
      .def_readonly("planning_time", &R::planning_time);
}
}  // namespace

void pybind_belief(py::module_& m) {
  bind_settings(m);
  bind_results(m);
  m.def("start_covariance", &start_covariance, py::arg("sensors"), py::arg("map"), py::arg("start"),
        py::arg("heading"), py::arg("gate_probability") = 0.0);
  m.def("propagate_belief", &propagate_belief, py::arg("path"), py::arg("bmm"), py::arg("sensors"), py::arg("map"),
        py::arg("start_cov"), py::arg("settings") = BeliefSettings{}, release_gil());
  m.def("propagate_belief_along", &propagate_belief_along, py::arg("states"), py::arg("bmm"), py::arg("sensors"),
        py::arg("map"), py::arg("start_cov"), py::arg("settings") = BeliefSettings{}, release_gil());
  m.def("collision_monte_carlo", &collision_monte_carlo, py::arg("profile"), py::arg("samples") = 10000,
        py::arg("seed") = 0, release_gil());
  m.def("plan_belief", &plan_belief, py::arg("problem"), py::arg("settings") = BeliefPlannerSettings{},
        release_gil());
}
