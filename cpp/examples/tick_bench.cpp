// tick_bench — the C++ cost of one online tick, and its allocations.
//
// A vehicle's tick is one motion input and one landmark range-bearing
// observation to the Localizer (EKF); the full guidance tick adds one
// Guidance::command() (SafeNav-Centroid, no replanning).  The program times N
// ticks of each after a warm-up and counts heap allocations per tick: global
// operator new/delete are replaced here (in this program only) by versions
// that count.  bench/bench_guidance.py builds and runs it.
//
//   tick_bench [ticks] [repeats]   prints one JSON object:
//     localizer_ns_per_tick, guidance_ns_per_tick, command_ns_per_tick (medians
//     over repeats), localizer_allocs_per_tick, guidance_allocs_per_tick,
//     command_checked_* (command() with the obstacle check on, no obstacle
//     ahead), guidance_construction_allocs (proof that the counter sees the
//     library's allocations), events (OR of all command events; 0 expected)
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <vector>

#include <safenav/guidance.hpp>
#include <safenav/localizer.hpp>

// ---------------------------------------------------------------- counting allocator
namespace {
std::atomic<long long> g_allocs{0};
}

void* operator new(std::size_t n) {
  g_allocs.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  g_allocs.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(n ? n : 1);
}
void* operator new[](std::size_t n, const std::nothrow_t& tag) noexcept { return operator new(n, tag); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
// Over-aligned types (Eigen's fixed-size members may use them).
void* operator new(std::size_t n, std::align_val_t al) {
  g_allocs.fetch_add(1, std::memory_order_relaxed);
  const std::size_t a = static_cast<std::size_t>(al);
  if (void* p = std::aligned_alloc(a, (std::max<std::size_t>(n, 1) + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t al) { return operator new(n, al); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kPi = 3.14159265358979323846;

// A vehicle circling a landmark field: (speed, heading change) and the
// range-bearing observation of landmark (k mod 4) from the true pose.
struct World {
  safenav::Landmarks landmarks;
  safenav::BmmParams bmm;
  World() : landmarks(4, 2) { landmarks << 0, 0, 60, 0, 60, 60, 0, 60; }
  double dt() const { return bmm.dt; }
  safenav::Control control(long k) const { return {2.0, 0.01 * std::sin(0.01 * static_cast<double>(k))}; }
};

/// Precomputed noise-free truth along the controls (so the timed loop does no simulation).
struct Script {
  std::vector<safenav::Control> u;
  std::vector<safenav::LandmarkObservation> obs;
};

Script make_script(const World& w, const safenav::State& x0, long n) {
  const safenav::Bmm bmm(w.bmm);
  Script s;
  s.u.resize(static_cast<std::size_t>(n));
  s.obs.resize(static_cast<std::size_t>(n));
  safenav::State x = x0;
  for (long k = 0; k < n; ++k) {
    const safenav::Control u = w.control(k);
    x = bmm.predict(x, u);
    const int id = static_cast<int>(k % 4);
    const Eigen::Vector2d d = w.landmarks.row(id).transpose() - x.head<2>();
    safenav::LandmarkObservation o;
    o.id = id;
    o.range = d.norm();
    o.bearing = std::remainder(std::atan2(d.y(), d.x()) - x[3], 2.0 * kPi);
    o.range_std = 0.3;
    o.bearing_std = 0.02;
    s.u[static_cast<std::size_t>(k)] = u;
    s.obs[static_cast<std::size_t>(k)] = o;
  }
  return s;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

/// One timed quantity over the repeats: ns per tick of each repeat, and the heap allocations.
struct Timing {
  std::vector<double> ns;
  long long allocs = 0;
  double med() const { return median(ns); }
  double min() const { return *std::min_element(ns.begin(), ns.end()); }
  double max() const { return *std::max_element(ns.begin(), ns.end()); }
};

/// Runs body(j) for j = 0 … ticks − 1, timed and with its allocations counted, into `into`.
template <typename Body>
void timed(long ticks, Timing& into, Body&& body) {
  const long long a0 = g_allocs.load();
  const auto t0 = Clock::now();
  for (long j = 0; j < ticks; ++j) body(j);
  const auto t1 = Clock::now();
  into.allocs += g_allocs.load() - a0;
  into.ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / static_cast<double>(ticks));
}

struct Setup {
  World w;
  safenav::State x0{30.0, 10.0, 2.0, 0.0};
  safenav::StateCov P0 = safenav::StateCov::Zero();
  long warm = 1000, ticks = 0;
  int repeats = 0;
  Script script;
};

/// 1. The localizer only: motion + observe.  Returns how many observations it applied.
int time_localizer(const Setup& s, Timing& loc) {
  int applied = 0;
  for (int r = 0; r < s.repeats; ++r) {
    safenav::Localizer l(safenav::LocalizerSettings(), s.w.landmarks);
    l.initialize(0.0, s.x0, s.P0);
    const auto tick = [&](long k) {
      const double t = static_cast<double>(k + 1) * s.w.dt();
      l.motion(t, s.script.u[k]);
      return l.observe(t, s.script.obs[k]).applied();
    };
    for (long k = 0; k < s.warm; ++k) tick(k);
    timed(s.ticks, loc, [&](long j) { applied += tick(s.warm + j); });
  }
  return applied;
}

/// The guidance runs' problem: SafeNav-Centroid along a 170 m path round the
/// landmark field, 10 m segments, no replanning.
safenav::NavigationProblem guidance_problem() {
  safenav::NavigationProblem problem;
  problem.path.resize(5, 2);
  problem.path << 30, 10, 80, 10, 80, 50, 30, 50, 30, 20;
  problem.map.lower = Eigen::Vector2d(-200.0, -200.0);
  problem.map.upper = Eigen::Vector2d(300.0, 300.0);
  return problem;
}

struct GuidanceTimings {
  Timing tick, command, checked;
  long long construction_allocs = 0;
  unsigned events = 0;
  int guiding = 0;
};

/// 2. Guidance: command + motion + observe, command() alone on a fixed
/// estimate at its time (later, guidance would predict the estimate to the
/// command's time, and after input_timeout stop), and command() with the
/// obstacle check on (every 5th command; an obstacle off the path, so no detour).
void time_guidance(const Setup& s, GuidanceTimings& out) {
  const safenav::NavigationProblem problem = guidance_problem();
  safenav::NavigationSettings settings;
  settings.method = safenav::NavigationMethod::Centroid;
  settings.replan = false;
  const long long a_build = g_allocs.load();
  const safenav::Guidance proto(problem, settings, safenav::LocalizerSettings(), s.w.landmarks, {}, 1);
  out.construction_allocs = g_allocs.load() - a_build;  // shows that the counter sees the library's allocations
  safenav::NavigationProblem checked = problem;
  checked.map.circles.push_back({Eigen::Vector2d(150.0, 150.0), 2.0});
  safenav::NavigationSettings check_settings = settings;
  check_settings.replan = true;
  safenav::Guidance g3(checked, check_settings, safenav::LocalizerSettings(), s.w.landmarks, {}, 1);
  g3.localizer().initialize(0.0, s.x0, s.P0);
  for (int r = 0; r < s.repeats; ++r) {
    safenav::Guidance g = proto.fresh(1), g2 = proto.fresh(1);
    g.localizer().initialize(0.0, s.x0, s.P0);
    g2.localizer().initialize(0.0, s.x0, s.P0);
    const auto tick = [&](long k) {
      const double t = static_cast<double>(k + 1) * s.w.dt();
      const safenav::Command c = g.command(static_cast<double>(k) * s.w.dt());
      out.events |= c.events;
      g.motion(t, s.script.u[k]);  // the script's control, so the truth is known
      g.observe(t, s.script.obs[k]);
      return c.status == safenav::GuidanceStatus::Guiding;
    };
    for (long k = 0; k < s.warm; ++k) tick(k);
    timed(s.ticks, out.tick, [&](long j) { out.guiding += tick(s.warm + j); });
    for (long j = 0; j < s.warm; ++j) g2.command(0.0);
    timed(s.ticks, out.command, [&](long) { out.events |= g2.command(0.0).events; });
    for (long j = 0; j < s.warm; ++j) g3.command(0.0);
    timed(s.ticks, out.checked, [&](long) { out.events |= g3.command(0.0).events; });
  }
}

}  // namespace

int main(int argc, char** argv) {
  Setup s;
  s.ticks = argc > 1 ? std::atol(argv[1]) : 100000;
  s.repeats = argc > 2 ? std::atoi(argv[2]) : 5;
  if (s.ticks < 100 || s.repeats < 1) {
    std::fprintf(stderr, "ticks must be >= 100 and repeats >= 1\n");
    return 2;
  }
  s.P0.diagonal() << 0.01, 0.01, 0.01, 0.001;
  s.script = make_script(s.w, s.x0, s.warm + s.ticks);
  Timing loc;
  const int applied = time_localizer(s, loc);
  GuidanceTimings g;
  time_guidance(s, g);
  const double n = static_cast<double>(s.ticks) * s.repeats;
  std::printf(
      "{\"ticks\": %ld, \"repeats\": %d, \"localizer_ns_per_tick\": %.1f, \"localizer_ns_min\": %.1f, "
      "\"localizer_ns_max\": %.1f, \"localizer_allocs_per_tick\": %.6g, \"localizer_applied_fraction\": %.4f, "
      "\"guidance_ns_per_tick\": %.1f, \"guidance_ns_min\": %.1f, \"guidance_ns_max\": %.1f, "
      "\"guidance_allocs_per_tick\": %.6g, \"guidance_guiding_fraction\": %.4f, \"command_ns\": %.1f, "
      "\"command_allocs_per_call\": %.6g, \"command_checked_ns\": %.1f, \"command_checked_allocs_per_call\": %.6g, "
      "\"guidance_construction_allocs\": %lld, \"events\": %u}\n",
      s.ticks, s.repeats, loc.med(), loc.min(), loc.max(), static_cast<double>(loc.allocs) / n, applied / n,
      g.tick.med(), g.tick.min(), g.tick.max(), static_cast<double>(g.tick.allocs) / n, g.guiding / n, g.command.med(),
      static_cast<double>(g.command.allocs) / n, g.checked.med(), static_cast<double>(g.checked.allocs) / n,
      g.construction_allocs, g.events);
  return 0;
}
