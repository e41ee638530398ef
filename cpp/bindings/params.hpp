// Generic parameter access for a bound settings struct (safenav/params.hpp):
// T.params() lists the declarations, obj.get_param(name) / obj.set_param(name,
// value) read and write by name (checked against the declared range).
#pragma once

#include <string>
#include <vector>

#include "common.hpp"
#include "safenav/params.hpp"

template <class T, class Class>
Class def_params(Class cls) {
  using safenav::ParamKind;
  using safenav::param_set;
  cls.def_static(
         "params", [] { return param_set<T>().specs(); },
         "The declared parameters (name, kind, unit, range, doc), in declaration order; the defaults are a "
         "default-constructed object's values.")
      .def(
          "get_param",
          [](const T& t, const std::string& name) -> py::object {
            const auto& set = param_set<T>();
            const std::vector<double> v = set.get(t, name);
            switch (set.entry(name).spec.kind) {
              case ParamKind::Real: return py::float_(v[0]);
              case ParamKind::Integer: return py::int_(static_cast<long long>(v[0]));
              case ParamKind::RealList: return py::cast(v);
              case ParamKind::Boolean: return py::bool_(v[0] != 0.0);
            }
            return py::none();
          },
          py::arg("name"), "The value of parameter `name`.")
      .def(
          "set_param",
          [](T& t, const std::string& name, const py::object& value) {
            const auto& set = param_set<T>();
            const ParamKind kind = set.entry(name).spec.kind;
            const bool list = kind == ParamKind::RealList;
            if (kind == ParamKind::Boolean) {
              if (!py::isinstance<py::bool_>(value) && !py::isinstance(value, py::module_::import("numpy").attr("bool_")))
                throw py::type_error(name + ": " + std::string(py::repr(value)) + " is not a bool");
              set.set(t, name, {value.cast<bool>() ? 1.0 : 0.0});
              return;
            }
            const auto not_a = [&](const char* what) {
              return py::type_error(name + ": " + std::string(py::repr(value)) + " is not " + what);
            };
            if (py::isinstance<py::bool_>(value) || (list ? py::isinstance<py::str>(value) : false))
              throw not_a(list ? "a list of numbers" : "a number");
            std::vector<double> v;
            try {
              v = list ? value.cast<std::vector<double>>() : std::vector<double>{value.cast<double>()};
            } catch (const py::cast_error&) {
              throw not_a(list ? "a list of numbers" : "a number");
            }
            set.set(t, name, v);
          },
          py::arg("name"), py::arg("value"), "Set parameter `name`; ValueError names it when out of range.")
      .def(
          "check_params", [](const T& t) { param_set<T>().check(t); },
          "ValueError naming the first parameter outside its declared range.");
  return cls;
}
