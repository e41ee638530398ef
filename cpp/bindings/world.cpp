#include "common.hpp"
#include "params.hpp"
#include "safenav/world.hpp"

using namespace safenav;

namespace {
// The obstacles' and hazards' shapes.
void bind_shapes(py::module_& m) {
  py::class_<CircleObstacle>(m, "CircleObstacle", "A disc obstacle (center [m], radius [m]).")
      .def(py::init([](const Eigen::Vector2d& center, double radius) { return CircleObstacle{center, radius}; }),
           py::arg("center"), py::arg("radius"))
      .def_readwrite("center", &CircleObstacle::center)
      .def_readwrite("radius", &CircleObstacle::radius)
      .def("__repr__", [](const CircleObstacle& c) {
        return "CircleObstacle(center=(" + std::to_string(c.center.x()) + ", " + std::to_string(c.center.y()) +
               "), radius=" + std::to_string(c.radius) + ")";
      });

  py::class_<HazardZone>(m, "HazardZone", "A hazard zone: a disc or a simple polygon, with a risk level in (0, 1].")
      .def_static(
          "from_circle",
          [](const Eigen::Vector2d& center, double radius, double risk) {
            return HazardZone{Points2(0, 2), CircleObstacle{center, radius}, risk};
          },
          py::arg("center"), py::arg("radius"), py::arg("risk") = 1.0)
      .def_static(
          "from_polygon",
          [](const Points2& vertices, double risk) { return HazardZone{vertices, CircleObstacle{}, risk}; },
          py::arg("vertices"), py::arg("risk") = 1.0)
      .def_readonly("polygon", &HazardZone::polygon)
      .def_readonly("disc", &HazardZone::disc)
      .def_readonly("risk", &HazardZone::risk);
}

// The map and the obstacles' inflation.
void bind_map(py::module_& m) {
  const PlanningMap dm;
  def_params<PlanningMap>(py::class_<PlanningMap>(m, "PlanningMap", "The field (rectangle), its circle and polygon obstacles and its hazards."))
      .def(py::init([](const Eigen::Vector2d& lower, const Eigen::Vector2d& upper, std::vector<CircleObstacle> circles,
                       std::vector<Points2> polygons, double clearance, std::vector<HazardZone> hazards,
                       double forbidden_risk) {
             PlanningMap map{lower, upper, std::move(circles), std::move(polygons), clearance, std::move(hazards),
                             forbidden_risk};
             map.validate();
             return map;
           }),
           py::kw_only(), py::arg("lower") = dm.lower, py::arg("upper") = dm.upper,
           py::arg("circles") = std::vector<CircleObstacle>{}, py::arg("polygons") = std::vector<Points2>{},
           py::arg("clearance") = dm.clearance, py::arg("hazards") = std::vector<HazardZone>{},
           py::arg("forbidden_risk") = dm.forbidden_risk)
      .def_readwrite("lower", &PlanningMap::lower)
      .def_readwrite("upper", &PlanningMap::upper)
      .def_readwrite("circles", &PlanningMap::circles)
      .def_readwrite("polygons", &PlanningMap::polygons)
      .def_readwrite("clearance", &PlanningMap::clearance)
      .def_readwrite("hazards", &PlanningMap::hazards)
      .def_readwrite("forbidden_risk", &PlanningMap::forbidden_risk)
      .def("validate", &PlanningMap::validate);

  const Inflation di;
  def_params<Inflation>(py::class_<Inflation>(m, "Inflation", "Obstacle inflation: clearance = vehicle_radius + margin [m]."))
      .def(py::init([](double vehicle_radius, double margin) {
             Inflation f{vehicle_radius, margin};
             f.validate();
             return f;
           }),
           py::kw_only(), py::arg("vehicle_radius") = di.vehicle_radius, py::arg("margin") = di.margin)
      .def_readwrite("vehicle_radius", &Inflation::vehicle_radius)
      .def_readwrite("margin", &Inflation::margin)
      .def_property_readonly("clearance", &Inflation::clearance)
      .def("validate", &Inflation::validate);
}

// The collision checker, line of sight included, and the path queries.
void bind_checker(py::module_& m) {
  py::class_<ObstacleChecker>(m, "ObstacleChecker", "Repeated collision queries against one PlanningMap.")
      .def(py::init<const PlanningMap&>(), py::arg("map"))
      .def("point_free", &ObstacleChecker::point_free, py::arg("point"))
      .def("segment_free", &ObstacleChecker::segment_free, py::arg("a"), py::arg("b"))
      .def_property_readonly("obstacle_count", &ObstacleChecker::obstacle_count)
      .def("obstacles_at", &ObstacleChecker::obstacles_at, py::arg("points"), py::arg("margin") = 0.0, release_gil(),
           "(N, M) bool: point i lies in obstacle j (circles, then polygons) grown by clearance + margin.")
      .def("obstacles_hit", &ObstacleChecker::obstacles_hit, py::arg("a"), py::arg("b"), py::arg("margin") = 0.0,
           release_gil(), "(N, M) bool: segment a[i]-b[i] touches obstacle j grown by clearance + margin.")
      .def("hazard_risk", &ObstacleChecker::hazard_risk, py::arg("points"), release_gil(),
           "(N,): the highest risk of the hazards containing each point, 0 outside every hazard.")
      .def_property_readonly("hazard_count", &ObstacleChecker::hazard_count)
      .def("hazard_lengths", &ObstacleChecker::hazard_lengths, py::arg("a"), py::arg("b"),
           "(H,): exact length [m] of segment a-b inside each hazard (boundary included).")
      .def("hazard_integral", &ObstacleChecker::hazard_integral, py::arg("a"), py::arg("b"),
           "Integral of risk along a-b: sum over hazards of risk * length inside (overlaps add).")
      .def("line_of_sight", &ObstacleChecker::line_of_sight, py::arg("a"), py::arg("b"),
           "Whether segment a-b meets no obstacle (not grown by the clearance; touching blocks), an obstacle "
           "containing a or b excepted.  Hazards never occlude.  Exact and symmetric in a, b.")
      .def("visible_from", &ObstacleChecker::visible_from, py::arg("from_"), py::arg("targets"), release_gil(),
           "(N,) bool: line_of_sight(from_, targets[i]) for each row of the (N, 2) targets.")
      .def("obstacle_distance", &ObstacleChecker::obstacle_distance, py::arg("a"), py::arg("b"),
           "Distance [m] from segment a-b to the nearest obstacle, not grown by the clearance (0 on contact, inf with none).");

  py::class_<PathSafety>(m, "PathSafety", "What a path meets: minimum clearance to obstacles, length inside each hazard, "
                                          "risk-weighted exposure sum(risk * length).")
      .def_readonly("length", &PathSafety::length)
      .def_readonly("min_clearance", &PathSafety::min_clearance)
      .def_readonly("hazard_length", &PathSafety::hazard_length)
      .def_readonly("exposure", &PathSafety::exposure)
      .def("__repr__", [](const PathSafety& s) {
        return "PathSafety(length=" + std::to_string(s.length) + ", min_clearance=" + std::to_string(s.min_clearance) +
               ", exposure=" + std::to_string(s.exposure) + ")";
      });
  m.def("path_safety", &path_safety, py::arg("path"), py::arg("map"), release_gil());

  m.def("point_is_free", &point_is_free, py::arg("map"), py::arg("point"));
  m.def("segment_is_free", &segment_is_free, py::arg("map"), py::arg("a"), py::arg("b"));
  m.def("path_is_free", &path_is_free, py::arg("map"), py::arg("path"), release_gil());
}
}  // namespace

void pybind_world(py::module_& m) {
  bind_shapes(m);
  bind_map(m);
  bind_checker(m);
}
