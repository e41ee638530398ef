#include <sstream>

#include "common.hpp"
#include "params.hpp"
#include "safenav/motion.hpp"
#include "safenav/seed.hpp"

using namespace safenav;

namespace {
// Seeds, angles and the parameter declarations' types.
void bind_basics(py::module_& m) {
  m.def("derive_seed", &derive_seed, py::arg("seed"), py::arg("stream"),
        "The core's one seed rule (safenav/seed.hpp): an independent sub-seed of `seed` for random\n"
        "source `stream` (splitmix64).  Both are unsigned 64-bit integers.");
  m.def("wrap_angle", py::vectorize(&wrap_angle), py::arg("angle"), "Wrap angles to (-pi, pi].");

  py::enum_<ParamKind>(m, "ParamKind")
      .value("REAL", ParamKind::Real)
      .value("INTEGER", ParamKind::Integer)
      .value("REAL_LIST", ParamKind::RealList)
      .value("BOOLEAN", ParamKind::Boolean);
  py::class_<ParamSpec>(m, "ParamSpec", "One declared parameter (safenav/params.hpp).")
      .def_readonly("name", &ParamSpec::name)
      .def_readonly("kind", &ParamSpec::kind)
      .def_readonly("unit", &ParamSpec::unit)
      .def_readonly("lo", &ParamSpec::lo)
      .def_readonly("hi", &ParamSpec::hi)
      .def_readonly("lo_open", &ParamSpec::lo_open)
      .def_readonly("max_size", &ParamSpec::max_size)
      .def_readonly("doc", &ParamSpec::doc)
      .def("range_text", &ParamSpec::range_text)
      .def("__repr__", [](const ParamSpec& s) {
        return "ParamSpec(" + s.name + " in " + s.range_text() + (s.unit.empty() ? "" : " " + s.unit) + ")";
      });
}

// The BMM's parameters and the model (SafeNav eqs. 3-9).
void bind_bmm(py::module_& m) {
  const BmmParams d;
  def_params<BmmParams>(py::class_<BmmParams>(m, "BmmParams", "Parameters of the Battlefield Motion Model (SafeNav eqs. 3-9)."))
      .def(py::init([](double acceleration, double deceleration, double max_speed, double max_heading_rate,
                       double dt, double terrain_effect, double speed_noise, double heading_noise,
                       double position_noise, bool unicycle) {
             BmmParams p{acceleration, deceleration, max_speed,   max_heading_rate, dt,
                         terrain_effect, speed_noise, heading_noise, position_noise, unicycle};
             p.validate();
             return p;
           }),
           py::kw_only(), py::arg("acceleration") = d.acceleration, py::arg("deceleration") = d.deceleration,
           py::arg("max_speed") = d.max_speed, py::arg("max_heading_rate") = d.max_heading_rate,
           py::arg("dt") = d.dt, py::arg("terrain_effect") = d.terrain_effect, py::arg("speed_noise") = d.speed_noise,
           py::arg("heading_noise") = d.heading_noise, py::arg("position_noise") = d.position_noise,
           py::arg("unicycle") = d.unicycle)
      .def_readwrite("acceleration", &BmmParams::acceleration, "a [m/s^2] (eq. 3)")
      .def_readwrite("deceleration", &BmmParams::deceleration, "d [m/s^2] (eq. 3)")
      .def_readwrite("max_speed", &BmmParams::max_speed, "v_max [m/s] (eq. 3)")
      .def_readwrite("max_heading_rate", &BmmParams::max_heading_rate, "m [rad/s] (eq. 4)")
      .def_readwrite("dt", &BmmParams::dt, "time step [s]")
      .def_readwrite("terrain_effect", &BmmParams::terrain_effect, "tau (eq. 8-9); displacement scaled by 1/(1+tau)")
      .def_readwrite("speed_noise", &BmmParams::speed_noise, "sigma of eps_v [m/s]")
      .def_readwrite("heading_noise", &BmmParams::heading_noise, "sigma of eps_theta [rad]")
      .def_readwrite("position_noise", &BmmParams::position_noise, "sigma of eps_x, eps_y [m]")
      .def_readwrite("unicycle", &BmmParams::unicycle,
                     "speed from the input: signed, no acceleration limit (ours, in place of eq. 3)")
      .def("min_speed", &BmmParams::min_speed, "the lowest speed: 0 (eq. 3), or -max_speed with unicycle")
      .def("validate", &BmmParams::validate)
      .def("__repr__", [](const BmmParams& p) {
        std::ostringstream os;
        os << "BmmParams(acceleration=" << p.acceleration << ", deceleration=" << p.deceleration
           << ", max_speed=" << p.max_speed << ", max_heading_rate=" << p.max_heading_rate << ", dt=" << p.dt
           << ", terrain_effect=" << p.terrain_effect << ", speed_noise=" << p.speed_noise
           << ", heading_noise=" << p.heading_noise << ", position_noise=" << p.position_noise
           << (p.unicycle ? ", unicycle=True" : "") << ")";
        return os.str();
      })
      .def(py::pickle(
          [](const BmmParams& p) {
            return py::make_tuple(p.acceleration, p.deceleration, p.max_speed, p.max_heading_rate, p.dt,
                                  p.terrain_effect, p.speed_noise, p.heading_noise, p.position_noise, p.unicycle);
          },
          [](const py::tuple& t) {
            return BmmParams{t[0].cast<double>(), t[1].cast<double>(), t[2].cast<double>(),
                             t[3].cast<double>(), t[4].cast<double>(), t[5].cast<double>(),
                             t[6].cast<double>(), t[7].cast<double>(), t[8].cast<double>(),
                             t.size() > 9 && t[9].cast<bool>()};
          }));

  py::class_<Bmm>(m, "Bmm", "The Battlefield Motion Model f(x, u) (SafeNav eqs. 3-9).")
      .def(py::init<const BmmParams&>(), py::arg("params") = BmmParams())
      .def_property_readonly("params", &Bmm::params)
      .def("next_speed", &Bmm::next_speed, py::arg("v"), py::arg("desired_speed"))
      .def("clipped_heading_change", &Bmm::clipped_heading_change, py::arg("heading_change"))
      .def("predict", &Bmm::predict, py::arg("x"), py::arg("u"))
      .def("jacobian", &Bmm::jacobian, py::arg("x"), py::arg("u"))
      .def("noise_jacobian", &Bmm::noise_jacobian, py::arg("x"), py::arg("u"))
      .def("noise_cov", &Bmm::noise_cov)
      .def("process_cov", &Bmm::process_cov, py::arg("x"), py::arg("u"))
      .def("transition", &Bmm::transition, py::arg("x"), py::arg("u"), py::arg("eps"))
      .def("simulate", &Bmm::simulate, py::arg("x0"), py::arg("controls"), py::arg("seed"), release_gil());
}
}  // namespace

void pybind_motion(py::module_& m) {
  bind_basics(m);
  bind_bmm(m);
}
