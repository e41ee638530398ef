#include "common.hpp"
#include "params.hpp"
#include "safenav/planning.hpp"

using namespace safenav;

namespace {
// The problem and the planner's settings.
void bind_problem(py::module_& m) {
  py::class_<PlanningProblem>(m, "PlanningProblem", "Map, start, goal and the central path of the risk term.")
      .def(py::init([](PlanningMap map, const Eigen::Vector2d& start, const Eigen::Vector2d& goal,
                       const Points2& central_path, RiskZones zones) {
             PlanningProblem p{std::move(map), start, goal, central_path, std::move(zones)};
             p.validate();
             return p;
           }),
           py::kw_only(), py::arg("map"), py::arg("start"), py::arg("goal"),
           py::arg("central_path") = Points2(0, 2), py::arg("zones") = RiskZones{})
      .def_readwrite("map", &PlanningProblem::map)
      .def_readwrite("start", &PlanningProblem::start)
      .def_readwrite("goal", &PlanningProblem::goal)
      .def_readwrite("central_path", &PlanningProblem::central_path)
      .def_readwrite("zones", &PlanningProblem::zones)
      .def("validate", &PlanningProblem::validate);

  const PlannerSettings ds;
  def_params<PlannerSettings>(py::class_<PlannerSettings>(m, "PlannerSettings", "RAw-RRT* settings (alpha, beta of SafeNav eq. 16)."))
      .def(py::init([](double alpha, double beta, double range, double goal_bias, std::int64_t max_iterations,
                       double max_time, std::uint64_t seed, double resolution, double goal_tolerance, bool smooth,
                       bool stay_in_corridor, bool allow_approximate, double corridor_bias, double hazard_weight,
                       bool informed_sampling) {
             PlannerSettings s{alpha,         beta,   range,           goal_bias,         max_iterations,
                               max_time,      seed,   resolution,      goal_tolerance,    smooth,
                               stay_in_corridor, allow_approximate, corridor_bias, hazard_weight, informed_sampling};
             s.validate();
             return s;
           }),
           py::kw_only(), py::arg("alpha") = ds.alpha, py::arg("beta") = ds.beta, py::arg("range") = ds.range,
           py::arg("goal_bias") = ds.goal_bias, py::arg("max_iterations") = ds.max_iterations,
           py::arg("max_time") = ds.max_time, py::arg("seed") = ds.seed, py::arg("resolution") = ds.resolution,
           py::arg("goal_tolerance") = ds.goal_tolerance, py::arg("smooth") = ds.smooth,
           py::arg("stay_in_corridor") = ds.stay_in_corridor, py::arg("allow_approximate") = ds.allow_approximate,
           py::arg("corridor_bias") = ds.corridor_bias, py::arg("hazard_weight") = ds.hazard_weight,
           py::arg("informed_sampling") = ds.informed_sampling)
      .def_readwrite("alpha", &PlannerSettings::alpha)
      .def_readwrite("beta", &PlannerSettings::beta)
      .def_readwrite("range", &PlannerSettings::range)
      .def_readwrite("goal_bias", &PlannerSettings::goal_bias)
      .def_readwrite("max_iterations", &PlannerSettings::max_iterations)
      .def_readwrite("max_time", &PlannerSettings::max_time)
      .def_readwrite("seed", &PlannerSettings::seed)
      .def_readwrite("resolution", &PlannerSettings::resolution)
      .def_readwrite("goal_tolerance", &PlannerSettings::goal_tolerance)
      .def_readwrite("smooth", &PlannerSettings::smooth)
      .def_readwrite("stay_in_corridor", &PlannerSettings::stay_in_corridor)
      .def_readwrite("allow_approximate", &PlannerSettings::allow_approximate)
      .def_readwrite("corridor_bias", &PlannerSettings::corridor_bias)
      .def_readwrite("hazard_weight", &PlannerSettings::hazard_weight)
      .def_readwrite("informed_sampling", &PlannerSettings::informed_sampling)
      .def("validate", &PlannerSettings::validate);

}

// The result types and the planning calls (RAw-RRT*, eq. 19).
void bind_planner(py::module_& m) {
  py::enum_<PlanStatus>(m, "PlanStatus")
      .value("EXACT", PlanStatus::Exact)
      .value("APPROXIMATE", PlanStatus::Approximate)
      .value("NO_PATH", PlanStatus::NoPath);

  py::class_<PathCost>(m, "PathCost", "Length, risk (integral of WRS) and alpha*length + beta*risk (eq. 19).")
      .def_readonly("length", &PathCost::length)
      .def_readonly("risk", &PathCost::risk)
      .def_readonly("hazard", &PathCost::hazard)
      .def_readonly("total", &PathCost::total);

  py::class_<PlanResult>(m, "PlanResult")
      .def_readonly("status", &PlanResult::status)
      .def_readonly("success", &PlanResult::success)
      .def_readonly("path", &PlanResult::path)
      .def_readonly("cost", &PlanResult::cost)
      .def_readonly("safety", &PlanResult::safety)
      .def_readonly("iterations", &PlanResult::iterations)
      .def_readonly("planning_time", &PlanResult::planning_time)
      .def_readonly("first_solution_iteration", &PlanResult::first_solution_iteration)
      .def_readonly("first_solution_time", &PlanResult::first_solution_time)
      .def_readonly("cost_history", &PlanResult::cost_history);

  m.def("plan", &plan, py::arg("problem"), py::arg("settings") = PlannerSettings{}, release_gil());
  m.def("replan", &replan, py::arg("problem"), py::arg("position"), py::arg("lookahead"),
        py::arg("settings") = PlannerSettings{}, release_gil());
  m.def("replan_to", &replan_to, py::arg("problem"), py::arg("position"), py::arg("goal"),
        py::arg("settings") = PlannerSettings{}, release_gil());
  m.def("point_ahead", &point_ahead, py::arg("path"), py::arg("position"), py::arg("distance"), release_gil());
  m.def("path_cost", &path_cost, py::arg("path"), py::arg("problem"), py::arg("settings") = PlannerSettings{},
        release_gil());
  m.def("cost_lower_bound", &cost_lower_bound, py::arg("points"), py::arg("problem"),
        py::arg("settings") = PlannerSettings{}, release_gil());
}
}  // namespace

void pybind_planning(py::module_& m) {
  bind_problem(m);
  bind_planner(m);
}
