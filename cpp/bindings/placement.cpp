#include "common.hpp"
#include "safenav/placement.hpp"

using namespace safenav;

namespace {
py::list stretches(const std::vector<Interval>& v) {
  py::list out;
  for (const auto& s : v) out.append(py::make_tuple(s.start, s.end));
  return out;
}

using RowMatrixIv = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;
std::vector<Interval> to_intervals(const Eigen::Ref<const RowMatrixIv>& m) {
  std::vector<Interval> v(m.rows());
  for (Eigen::Index i = 0; i < m.rows(); ++i) v[i] = {m(i, 0), m(i, 1)};
  return v;
}
// Occluders, the sight test and the shadows (occlusion, ours).
void bind_occlusion(py::module_& m) {
  py::class_<Occluders>(m, "Occluders",
                        "Obstacles that hide landmarks (circles as (n, 3) rows x, y, radius; simple polygons).")
      .def(py::init([](const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& circles,
                       std::vector<Points2> polygons) {
             Occluders o;
             for (Eigen::Index i = 0; i < circles.rows(); ++i)
               o.circles.push_back(CircleObstacle{Eigen::Vector2d(circles(i, 0), circles(i, 1)), circles(i, 2)});
             o.polygons = std::move(polygons);
             o.validate();
             return o;
           }),
           py::arg("circles") = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>(0, 3), py::arg("polygons") = std::vector<Points2>{})
      .def_static("from_map", &Occluders::from_map, py::arg("map"))
      .def_property_readonly("circles",
                             [](const Occluders& o) {
                               Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> c(o.circles.size(), 3);
                               for (size_t i = 0; i < o.circles.size(); ++i)
                                 c.row(i) << o.circles[i].center.x(), o.circles[i].center.y(), o.circles[i].radius;
                               return c;
                             })
      .def_readonly("polygons", &Occluders::polygons)
      .def("empty", &Occluders::empty)
      .def("validate", &Occluders::validate);
  m.def("sight_blocked", &sight_blocked, py::arg("occluders"), py::arg("a"), py::arg("b"),
        "Whether the occluders hide b from a: the world's line of sight (ObstacleChecker.line_of_sight), "
        "negated.  Exact and symmetric in a, b.");
  m.def(
      "shadows_on_edge",
      [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c, const Occluders& o) {
        return stretches(shadows_on_edge(a, b, c, o));
      },
      py::arg("a"), py::arg("b"), py::arg("landmark"), py::arg("occluders"));
  m.attr("PLACEMENT_SHADOW_PAD") = kShadowPad;
}

// The camera, edge frames, [Placement Lemma 1, Lemma 2, Cor. 1].
void bind_camera(py::module_& m) {
  py::enum_<FieldOfView>(m, "FieldOfView")
      .value("SECTOR", FieldOfView::Sector)
      .value("CIRCULAR", FieldOfView::Circular);

  py::class_<Camera>(m, "Camera", "Camera range R, viewing angle alpha [rad] and clearance p (placement paper).")
      .def(py::init<>())
      .def_readwrite("range", &Camera::range)
      .def_readwrite("angle", &Camera::angle)
      .def_readwrite("clearance", &Camera::clearance)
      .def_readwrite("fov", &Camera::fov)
      .def("validate", &Camera::validate);

  py::class_<EdgeFrame>(m, "EdgeFrame", "Rigid transform of an edge a -> b to (0, 0) -> (d, 0).")
      .def(py::init<const Eigen::Vector2d&, const Eigen::Vector2d&>(), py::arg("a"), py::arg("b"))
      .def_readonly("origin", &EdgeFrame::origin)
      .def_readonly("heading", &EdgeFrame::heading)
      .def_readonly("length", &EdgeFrame::length)
      .def("to_local", &EdgeFrame::to_local, py::arg("p"))
      .def("to_world", &EdgeFrame::to_world, py::arg("q"));

  m.def("in_region_of_influence", &in_region_of_influence, py::arg("local"), py::arg("length"), py::arg("camera"));
  m.def(
      "visibility_interval",
      [](const Eigen::Vector2d& local, double length, const Camera& cam) -> py::object {
        Interval iv;
        if (!visibility_interval(local, length, cam, &iv)) return py::none();
        return py::make_tuple(iv.start, iv.end);
      },
      py::arg("local"), py::arg("length"), py::arg("camera"));
}

// The greedy cover [Placement Alg. 1] and the placement of a whole route.
void bind_cover(py::module_& m) {
  m.def(
      "greedy_cover",
      [](const Eigen::Ref<const RowMatrixIv>& intervals, double length, int k,
         const Eigen::Ref<const RowMatrixIv>& preplaced) {
        CoverResult r = greedy_cover(to_intervals(intervals), length, k, to_intervals(preplaced));
        return py::make_tuple(r.chosen, stretches(r.uncovered));
      },
      py::arg("intervals"), py::arg("length"), py::arg("k"), py::arg("preplaced"));

  py::class_<PlacementOptions>(m, "PlacementOptions")
      .def(py::init<>())
      .def_readwrite("k", &PlacementOptions::k)
      .def_readwrite("corners", &PlacementOptions::corners)
      .def_readwrite("reuse", &PlacementOptions::reuse)
      .def_readwrite("distinct_bearings", &PlacementOptions::distinct_bearings);

  py::class_<EdgePlacement>(m, "EdgePlacement")
      .def_readonly("landmarks", &EdgePlacement::landmarks)
      .def_property_readonly("uncovered", [](const EdgePlacement& e) { return stretches(e.uncovered); })
      .def_readonly("n_candidates", &EdgePlacement::n_candidates);
  py::class_<CornerPlacement>(m, "CornerPlacement")
      .def_readonly("vertex", &CornerPlacement::vertex)
      .def_readonly("turn", &CornerPlacement::turn)
      .def_readonly("landmarks", &CornerPlacement::landmarks)
      .def_property_readonly("uncovered", [](const CornerPlacement& c) { return stretches(c.uncovered); });
  py::class_<Placement>(m, "Placement")
      .def_readonly("landmarks", &Placement::landmarks)
      .def_readonly("edges", &Placement::edges)
      .def_readonly("corners", &Placement::corners)
      .def_readonly("too_close", &Placement::too_close)
      .def_property_readonly("covered", &Placement::covered);

  m.def("place_landmarks", &place_landmarks, py::arg("route"), py::arg("candidates"), py::arg("camera"),
        py::arg("options"), py::arg("occluders") = Occluders(), release_gil());
}

// The ILP's tables and the exact coverage check.
void bind_tables(py::module_& m) {
  py::class_<VisibilityTable>(m, "VisibilityTable")
      .def_readonly("edge", &VisibilityTable::edge)
      .def_readonly("candidate", &VisibilityTable::candidate)
      .def_readonly("start", &VisibilityTable::start)
      .def_readonly("end", &VisibilityTable::end)
      .def_readonly("x", &VisibilityTable::x)
      .def_readonly("y", &VisibilityTable::y);
  m.def("edge_visibility", &edge_visibility, py::arg("route"), py::arg("candidates"), py::arg("camera"),
        py::arg("occluders") = Occluders(), release_gil());
  m.def("corner_visibility", &corner_visibility, py::arg("route"), py::arg("candidates"), py::arg("camera"),
        py::arg("occluders") = Occluders(), release_gil());
  m.def("turn_angles", &turn_angles, py::arg("route"));

  py::class_<AlignmentTable>(m, "AlignmentTable")
      .def_readonly("edge", &AlignmentTable::edge)
      .def_readonly("first", &AlignmentTable::first)
      .def_readonly("second", &AlignmentTable::second)
      .def_readonly("t", &AlignmentTable::t);
  m.def("alignments", &alignments, py::arg("route"), py::arg("candidates"), py::arg("camera"),
        py::arg("occluders") = Occluders(), release_gil());
  m.def("distance_to_route", &distance_to_route, py::arg("route"), py::arg("points"), release_gil());

  py::class_<CoverageReport>(m, "CoverageReport")
      .def_readonly("min_count", &CoverageReport::min_count)
      .def_readonly("min_distance", &CoverageReport::min_distance)
      .def_readonly("kind", &CoverageReport::kind)
      .def_readonly("index", &CoverageReport::index)
      .def_readonly("start", &CoverageReport::start)
      .def_readonly("end", &CoverageReport::end);
  m.def("check_coverage", &check_coverage, py::arg("route"), py::arg("candidates"), py::arg("camera"), py::arg("k"),
        py::arg("corners") = false, py::arg("occluders") = Occluders(), release_gil());
}
}  // namespace

void pybind_placement(py::module_& m) {
  m.attr("PLACEMENT_MAX_K") = kMaxLandmarksInView;
  bind_occlusion(m);
  bind_camera(m);
  bind_cover(m);
  bind_tables(m);
}
