// Private: the builder of parameter declarations (safenav/params.hpp) and the
// ParamSet<T> member definitions.  Each area's .cpp that implements a
// settings struct T includes this, specialises param_set<T>() beside the
// struct's validate() and instantiates `template class ParamSet<T>;`, so that
// a parameter is declared once, next to the code that uses it (as OMPL's
// planners call declareParam beside each setter).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "safenav/params.hpp"

namespace safenav {

namespace detail {

/// Checks a value of parameter `s` (each entry of a list, named name[i]);
/// throws std::invalid_argument "prefix.name = value: must be …" (params.cpp).
void check_param_value(const ParamSpec& s, const std::vector<double>& v, const std::string& prefix);

template <class... F>
struct Overload : F... {
  using F::operator()...;
};
template <class... F>
Overload(F...) -> Overload<F...>;

}  // namespace detail

// ---------------------------------------------------------------------------
// ParamSet<T>

template <class T>
ParamSet<T>& ParamSet<T>::add(ParamSpec spec, Ref ref) {
  for (const auto& e : entries_)
    if (e.spec.name == spec.name) throw std::logic_error("parameter '" + spec.name + "' is declared twice");
  entries_.push_back({std::move(spec), std::move(ref)});
  return *this;
}

template <class T>
std::vector<ParamSpec> ParamSet<T>::specs() const {
  std::vector<ParamSpec> out;
  for (const auto& e : entries_) out.push_back(e.spec);
  return out;
}

template <class T>
const typename ParamSet<T>::Entry& ParamSet<T>::entry(const std::string& name) const {
  for (const auto& e : entries_)
    if (e.spec.name == name) return e;
  std::string known;
  for (const auto& e : entries_) known += (known.empty() ? "" : ", ") + e.spec.name;
  throw std::invalid_argument("unknown parameter '" + name + "' (known: " + known + ")");
}

template <class T>
std::vector<double> ParamSet<T>::get(const T& t, const std::string& name) const {
  using detail::Overload;
  T& m = const_cast<T&>(t);  // the accessors return references; get only reads
  return std::visit(Overload{[&](const RealRef& r) { return std::vector<double>{r(m)}; },
                             [&](const IntRef& r) { return std::vector<double>{static_cast<double>(r(m))}; },
                             [&](const Int64Ref& r) { return std::vector<double>{static_cast<double>(r(m))}; },
                             [&](const ListRef& r) { return r(m); },
                             [&](const BoolRef& r) { return std::vector<double>{r(m) ? 1.0 : 0.0}; }},
                    entry(name).ref);
}

template <class T>
void ParamSet<T>::set(T& t, const std::string& name, const std::vector<double>& value) const {
  using detail::Overload;
  const Entry& e = entry(name);
  detail::check_param_value(e.spec, value, "");
  std::visit(Overload{[&](const RealRef& r) { r(t) = value[0]; },
                      [&](const IntRef& r) { r(t) = static_cast<int>(value[0]); },
                      [&](const Int64Ref& r) { r(t) = static_cast<std::int64_t>(value[0]); },
                      [&](const ListRef& r) { r(t) = value; },
                      [&](const BoolRef& r) { r(t) = value[0] != 0.0; }},
             e.ref);
}

template <class T>
void ParamSet<T>::check(const T& t, const std::string& prefix) const {
  for (const auto& e : entries_) detail::check_param_value(e.spec, get(t, e.spec.name), prefix);
}

// ---------------------------------------------------------------------------
// The builder

namespace {

struct Range {
  double lo, hi;
  bool lo_open;
};
constexpr Range closed(double lo, double hi) { return {lo, hi, false}; }
constexpr Range above(double lo, double hi) { return {lo, hi, true}; }  ///< (lo, hi]

/// Builds a ParamSet with one line per parameter.
template <class T>
struct Declare {
  ParamSet<T> set;
  using PS = ParamSet<T>;

  static ParamSpec spec(const char* name, ParamKind kind, const char* unit, Range r, const char* doc, int max_size = 0) {
    return ParamSpec{name, kind, unit, r.lo, r.hi, r.lo_open, max_size, doc};
  }
  Declare& real(const char* name, typename PS::RealRef ref, const char* unit, Range r, const char* doc) {
    set.add(spec(name, ParamKind::Real, unit, r, doc), std::move(ref));
    return *this;
  }
  Declare& integer(const char* name, typename PS::IntRef ref, Range r, const char* doc) {
    set.add(spec(name, ParamKind::Integer, "", r, doc), std::move(ref));
    return *this;
  }
  Declare& integer64(const char* name, typename PS::Int64Ref ref, Range r, const char* doc) {
    set.add(spec(name, ParamKind::Integer, "", r, doc), std::move(ref));
    return *this;
  }
  Declare& flag(const char* name, typename PS::BoolRef ref, const char* doc) {
    set.add(spec(name, ParamKind::Boolean, "", closed(0, 1), doc), std::move(ref));
    return *this;
  }
  Declare& list(const char* name, typename PS::ListRef ref, const char* unit, Range r, int max_size, const char* doc) {
    set.add(spec(name, ParamKind::RealList, unit, r, doc, max_size), std::move(ref));
    return *this;
  }

  /// Every parameter of the nested struct U that `member` reaches in T, as
  /// declared by U's own set `inner` (range, unit, doc), under the name
  /// prefix + its name, or rename[its name] where given (an existing
  /// scenario key that differs).  A field added to U's declaration appears
  /// here with no further line.
  template <class U>
  Declare& nested(const std::string& prefix, const ParamSet<U>& inner,
                  typename std::common_type<std::function<U&(T&)>>::type member,  // U deduced from `inner` only
                  const std::map<std::string, std::string>& rename = {}) {
    for (const auto& [from, to] : rename) inner.entry(from);  // a misspelt name fails at the first use
    for (const auto& e : inner.entries()) {
      ParamSpec s = e.spec;
      const auto r = rename.find(s.name);
      s.name = r != rename.end() ? r->second : prefix + s.name;
      set.add(std::move(s), std::visit(
                                [&member](const auto& ref) -> typename PS::Ref {
                                  using V = std::remove_reference_t<decltype(ref(std::declval<U&>()))>;
                                  return std::function<V&(T&)>([ref, member](T& t) -> V& { return ref(member(t)); });
                                },
                                e.ref));
    }
    return *this;
  }
};

// Member accessors: SN_REF(T, member) reaches t.member (nested members too).
#define SN_REF(T, member) [](T& t) -> auto& { return t.member; }

}  // namespace

}  // namespace safenav
