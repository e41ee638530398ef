#include "common.hpp"
#include "params.hpp"
#include "safenav/corridor.hpp"

using namespace safenav;

namespace {
using PtsRef = const Eigen::Ref<const Points2>&;

// The risk zones and the WRS of eq. 18 (free functions over a path).
void bind_risk(py::module_& m) {
  const RiskZones d;
  def_params<RiskZones>(py::class_<RiskZones>(m, "RiskZones", "Safe-buffer risk zones of SafeNav-ext section V-A3(iii), eq. 18."))
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
}

// The small result and option types of the corridor's queries.
void bind_query_types(py::module_& m) {
  py::class_<PathProjection>(m, "PathProjection")
      .def_readonly("arc_length", &PathProjection::arc_length)
      .def_readonly("distance", &PathProjection::distance)
      .def_readonly("side", &PathProjection::side)
      .def_readonly("edge", &PathProjection::edge)
      .def_readonly("foot", &PathProjection::foot)
      .def_property_readonly("signed_offset", &PathProjection::signed_offset)
      .def("__repr__", [](const PathProjection& p) {
        return "PathProjection(arc_length=" + std::to_string(p.arc_length) + ", distance=" +
               std::to_string(p.distance) + ", side=" + std::to_string(p.side) + ")";
      });

  const SegmentOptions so;
  def_params<SegmentOptions>(py::class_<SegmentOptions>(m, "SegmentOptions"))
      .def(py::init([](int count, double length, double spacing, int sub_segments, int disc_sides) {
             SegmentOptions o{count, length, spacing, sub_segments, disc_sides};
             o.validate();
             return o;
           }),
           py::kw_only(), py::arg("count") = so.count, py::arg("length") = so.length, py::arg("spacing") = so.spacing,
           py::arg("sub_segments") = so.sub_segments, py::arg("disc_sides") = so.disc_sides)
      .def_readonly("count", &SegmentOptions::count)
      .def_readonly("length", &SegmentOptions::length)
      .def_readonly("spacing", &SegmentOptions::spacing)
      .def_readonly("sub_segments", &SegmentOptions::sub_segments)
      .def_readonly("disc_sides", &SegmentOptions::disc_sides);

  py::class_<CentroidTarget>(m, "CentroidTarget")
      .def_readonly("index", &CentroidTarget::index)
      .def_readonly("segment", &CentroidTarget::segment)
      .def_readonly("sub_segment", &CentroidTarget::sub_segment)
      .def_readonly("arc_length", &CentroidTarget::arc_length)
      .def_readonly("point", &CentroidTarget::point)
      .def_readonly("ahead", &CentroidTarget::ahead)
      .def("__repr__", [](const CentroidTarget& t) {
        return "CentroidTarget(segment=" + std::to_string(t.segment) + ", sub_segment=" +
               std::to_string(t.sub_segment) + ", arc_length=" + std::to_string(t.arc_length) +
               ", ahead=" + (t.ahead ? "True" : "False") + ")";
      });

}

// Corridor and its segments (Algorithms 1 and 2).
void bind_corridor(py::module_& m) {
  // Registered before Corridor, whose segments() returns one (else its
  // signature would name the C++ type).
  py::class_<PathSegments> path_segments(m, "PathSegments");
  py::class_<Corridor>(m, "Corridor")
      .def(py::init<PtsRef, RiskZones>(), py::arg("path"), py::arg("zones"))
      .def_property_readonly("path", &Corridor::path)
      .def_property_readonly("zones", &Corridor::zones)
      .def_property_readonly("half_width", &Corridor::half_width)
      .def_property_readonly("zone_count", &Corridor::zone_count)
      .def_property_readonly("length", &Corridor::length)
      .def_property_readonly("vertex_arc_lengths", &Corridor::vertex_arc_lengths)
      .def("project", &Corridor::project, py::arg("point"))
      .def("point_at", &Corridor::point_at, py::arg("s"))
      .def("tangent_at", &Corridor::tangent_at, py::arg("s"))
      .def("contains_point", py::overload_cast<const Eigen::Vector2d&>(&Corridor::contains, py::const_),
           py::arg("point"))
      .def("zone_of_point", py::overload_cast<const Eigen::Vector2d&>(&Corridor::zone, py::const_), py::arg("point"))
      .def("distance", &Corridor::distance, py::arg("points"), release_gil())
      .def("arc_length", &Corridor::arc_length, py::arg("points"), release_gil())
      .def("signed_offset", &Corridor::signed_offset, py::arg("points"), release_gil())
      .def("side", &Corridor::side, py::arg("points"), release_gil())
      .def("zone", py::overload_cast<PtsRef>(&Corridor::zone, py::const_), py::arg("points"), release_gil())
      .def("contains", py::overload_cast<PtsRef>(&Corridor::contains, py::const_), py::arg("points"), release_gil())
      .def("wrs", py::overload_cast<PtsRef>(&Corridor::wrs, py::const_), py::arg("points"), release_gil())
      .def("awrs", &Corridor::awrs, py::arg("points"), release_gil())
      .def("points_at", &Corridor::points_at, py::arg("s"), release_gil())
      .def("segments", &Corridor::segments, py::arg("options"), release_gil());

  path_segments.def_property_readonly("size", &PathSegments::size)
      .def("__len__", &PathSegments::size)
      .def_property_readonly("options", &PathSegments::options)
      .def_property_readonly("breaks", &PathSegments::breaks)
      .def("segment_at", &PathSegments::segment_at, py::arg("s"))
      .def("points", &PathSegments::points, py::arg("k"))
      .def("hull_input", &PathSegments::hull_input, py::arg("k"))
      .def("hull", &PathSegments::hull, py::arg("k"))
      .def("hull_contains_point", py::overload_cast<int, const Eigen::Vector2d&>(&PathSegments::hull_contains, py::const_),
           py::arg("k"), py::arg("point"))
      .def("hull_contains", py::overload_cast<int, PtsRef>(&PathSegments::hull_contains, py::const_), py::arg("k"),
           py::arg("points"), release_gil())
      .def("in_current_or_next", &PathSegments::in_current_or_next, py::arg("k"), py::arg("point"))
      .def("segments_containing", &PathSegments::segments_containing, py::arg("point"))
      .def("locate", &PathSegments::locate, py::arg("points"), release_gil())
      .def_property_readonly("centroids", &PathSegments::centroids)
      .def_property_readonly("centroid_arc_lengths", &PathSegments::centroid_arc_lengths)
      .def("segment_centroids", &PathSegments::segment_centroids, py::arg("k"))
      .def("nearest_centroid_ahead", &PathSegments::nearest_centroid_ahead, py::arg("point"));
}
}  // namespace

void pybind_corridor(py::module_& m) {
  bind_risk(m);
  bind_query_types(m);
  bind_corridor(m);
}
