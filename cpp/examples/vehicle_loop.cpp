// vehicle_loop — embed SafeNav guidance in a vehicle program.
//
// A simulated vehicle follows a safe path across a 100 m × 60 m field.  A
// boulder (a circular obstacle) sits ON the path, so guidance must see it
// ahead and splice a RAw-RRT* detour round it ([SafeNav-ext Alg. 4]).  The
// vehicle sees eight landmarks along the way: range and bearing to each one
// within its sensing range, with noise.
//
// The loop is the one a real vehicle runs (Navigator::run in
// cpp/src/navigation.cpp drives the same Guidance object):
//
//   guidance.localizer().initialize(0, prior)        start from a prior
//   every tick t_k = k·Δt:
//     cmd = guidance.command(t_k)                    control, status, events
//     the vehicle drives cmd.control for Δt          here: Bmm::transition + seeded noise
//     guidance.motion(t_k+1, cmd.control)            its commanded motion
//     guidance.observe(t_k+1, {id, range, bearing})  each landmark in range
//     stop on Arrived (or NoPath / LostLocalization)
//
// Guidance never sees the truth: it steers by the localizer's estimate.  The
// program checks the true path against the obstacle with ObstacleChecker (the obstacle itself;
// guidance plans with the map's clearance, 0.5 m here).
//
//   vehicle_loop [max_steps] [seed]   prints the steps, events and final error;
//                                     exits 0 when the vehicle arrived with no
//                                     collision after planning a detour
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <safenav/guidance.hpp>
#include <safenav/localizer.hpp>
#include <safenav/motion.hpp>
#include <safenav/world.hpp>

namespace {

std::string event_names(unsigned events) {
  static const std::pair<unsigned, const char*> kNames[] = {
      {safenav::kDetourPlanned, "detour_planned"}, {safenav::kPathSpliced, "path_spliced"},
      {safenav::kNoPath, "no_path"},               {safenav::kLostLocalization, "lost_localization"},
      {safenav::kArrived, "arrived"}};
  std::string out;
  for (const auto& [bit, name] : kNames)
    if (events & bit) out += (out.empty() ? "" : ",") + std::string(name);
  return out;
}

constexpr double kPi = 3.14159265358979323846;
double wrap(double a) { return std::remainder(a, 2.0 * kPi); }

/// The world: a straight safe path with a boulder on it.
safenav::NavigationProblem make_problem() {
  safenav::NavigationProblem problem;
  problem.path.resize(3, 2);
  problem.path << 10.0, 30.0, 50.0, 30.0, 90.0, 30.0;
  problem.map.lower = Eigen::Vector2d(0.0, 0.0);
  problem.map.upper = Eigen::Vector2d(100.0, 60.0);
  problem.map.clearance = 0.5;  // the vehicle's radius
  problem.map.circles.push_back(safenav::CircleObstacle{Eigen::Vector2d(50.0, 30.0), 2.5});
  // problem.zones: the default 8 m safe buffer; problem.bmm: the default BMM (Δt = 0.05 s).
  return problem;
}

/// The vehicle's camera: range and bearing to each landmark within range of the true pose.
void sense(safenav::Guidance& guidance, double t, const safenav::State& truth, const safenav::Landmarks& landmarks,
           std::mt19937_64& gen, std::normal_distribution<double>& n01, int& observations, int& rejected) {
  constexpr double sensing_range = 25.0;  // [m]
  constexpr double range_std = 0.2, bearing_std = 0.02;
  for (Eigen::Index k = 0; k < landmarks.rows(); ++k) {
    const Eigen::Vector2d d = landmarks.row(k).transpose() - truth.head<2>();
    const double r = d.norm();
    if (r > sensing_range) continue;
    safenav::LandmarkObservation obs;
    obs.id = static_cast<int>(k);  // default ids: the landmark rows
    obs.range = r + range_std * n01(gen);
    obs.bearing = wrap(std::atan2(d.y(), d.x()) - truth[3] + bearing_std * n01(gen));
    obs.range_std = range_std;
    obs.bearing_std = bearing_std;
    ++observations;
    if (!guidance.observe(t, obs).applied()) ++rejected;
  }
}

/// The localizer starts from a prior 0.5 m and a few degrees off the truth.
void start_localizer(safenav::Guidance& guidance, const safenav::State& truth, std::mt19937_64& gen,
                     std::normal_distribution<double>& n01) {
  safenav::StateCov P0 = safenav::StateCov::Zero();
  P0.diagonal() << 0.5 * 0.5, 0.5 * 0.5, 0.2 * 0.2, 0.05 * 0.05;
  const safenav::State x0 = truth + P0.diagonal().cwiseSqrt().cwiseProduct(
                                        safenav::State(n01(gen), n01(gen), n01(gen), n01(gen)));
  guidance.localizer().initialize(0.0, safenav::State(x0[0], x0[1], std::max(0.0, x0[2]), x0[3]), P0);
}

}  // namespace

int main(int argc, char** argv) {
  const int max_steps = argc > 1 ? std::atoi(argv[1]) : 2000;
  const std::uint64_t seed = argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 7;
  if (max_steps <= 0) {
    std::fprintf(stderr, "steps must be > 0\n");
    return 2;
  }

  const safenav::NavigationProblem problem = make_problem();
  const safenav::CircleObstacle boulder = problem.map.circles.front();
  safenav::Landmarks landmarks(8, 2);
  landmarks << 20, 18, 20, 42, 40, 18, 40, 42, 60, 18, 60, 42, 80, 18, 80, 42;

  safenav::NavigationSettings settings;  // SafeNav-Centroid, 2 m/s, detours on
  safenav::Guidance guidance(problem, settings, safenav::LocalizerSettings(), landmarks, {}, seed);
  const safenav::BmmParams& bp = guidance.problem().bmm;
  const safenav::Bmm vehicle(bp);
  // The collision check: the true obstacle itself (no clearance), as the simulator's.
  safenav::PlanningMap true_map = problem.map;
  true_map.clearance = 0.0;
  const safenav::ObstacleChecker obstacles(true_map);

  // The true vehicle starts at rest at the path's start, heading east.
  std::mt19937_64 gen(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  safenav::State truth(10.0, 30.0, 0.0, 0.0);
  start_localizer(guidance, truth, gen, n01);

  const Eigen::Vector4d sigma(bp.position_noise, bp.position_noise, bp.speed_noise, bp.heading_noise);
  bool detour = false, collided = false, arrived = false;
  int step = 0, observations = 0, rejected = 0;
  double min_gap = std::numeric_limits<double>::infinity();  // closest approach to the boulder's edge [m]
  safenav::GuidanceStatus last = safenav::GuidanceStatus::Initializing;
  while (step < max_steps) {
    // 1. Ask guidance for the control of the next step.
    const double t = step * bp.dt;
    const safenav::Command cmd = guidance.command(t);
    last = cmd.status;
    if (cmd.events || step % 200 == 0) {
      std::printf("step %d t=%.2f s: %s events=%s segment=%d sigma=%.3f m estimate=(%.2f, %.2f)\n", step, t,
                  safenav::to_string(cmd.status).c_str(), event_names(cmd.events).c_str(), cmd.segment, cmd.position_std, guidance.localizer().x()[0],
                  guidance.localizer().x()[1]);
    }
    if (cmd.events & safenav::kDetourPlanned) detour = true;
    if (cmd.status == safenav::GuidanceStatus::Arrived) {
      arrived = true;
      break;
    }
    if (cmd.status != safenav::GuidanceStatus::Guiding) {
      std::printf("guidance stopped: %s (%s)\n", safenav::to_string(cmd.status).c_str(), guidance.detail().c_str());
      break;
    }
    // 2. The vehicle drives the control for one step (the simulated truth).
    ++step;
    const double t1 = step * bp.dt;
    const Eigen::Vector2d before = truth.head<2>();
    Eigen::Vector4d eps;
    for (int i = 0; i < 4; ++i) eps[i] = sigma[i] * n01(gen);
    truth = vehicle.transition(truth, cmd.control, eps);
    if (!obstacles.segment_free(before, truth.head<2>())) collided = true;
    min_gap = std::min(min_gap, (truth.head<2>() - boulder.center).norm() - boulder.radius);
    // 3. Its inputs: the commanded motion, then each landmark within range.
    guidance.motion(t1, cmd.control);
    sense(guidance, t1, truth, landmarks, gen, n01, observations, rejected);
  }

  const safenav::Localizer& loc = guidance.localizer();
  const double err = (loc.x().head<2>() - truth.head<2>()).norm();
  const Eigen::Vector2d goal = problem.path.bottomRows<1>().transpose();
  std::printf(
      "steps=%d status=%s replans=%d detour=%s collision=%s min_gap=%.3fm observations=%d rejected=%d truth=(%.3f, %.3f) "
      "estimate=(%.3f, %.3f) error=%.4f m sigma=%.4f m goal_distance=%.3f m\n",
      step, safenav::to_string(last).c_str(), guidance.replans(), detour ? "yes" : "no", collided ? "yes" : "no",
      min_gap, observations, rejected, truth.x(), truth.y(), loc.x().x(), loc.x().y(), err, loc.position_std(),
      (truth.head<2>() - goal).norm());
  return arrived && detour && !collided ? 0 : 1;
}
