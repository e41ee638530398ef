// Belief along a path and its collision probability (safenav/belief.hpp):
// LQG-MP's a-priori covariances, Patil et al.'s truncated-Gaussian stages.
#include "safenav/belief.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "belief_model.hpp"
#include "declare.hpp"
#include "errors.hpp"
#include "filters/checks.hpp"
#include "rng.hpp"
#include "safenav/localizer.hpp"

namespace safenav {

using detail::bad;
using detail::num;

template <>
const ParamSet<BeliefSettings>& param_set<BeliefSettings>();
template <>
const ParamSet<BeliefPlannerSettings>& param_set<BeliefPlannerSettings>();

void BeliefSettings::validate() const {
  if (!(std::isfinite(speed) && speed > 0.0)) bad("BeliefSettings.speed = " + num(speed) + ": must be finite and > 0");
  param_set<BeliefSettings>().check(*this, "BeliefSettings");
  if (deviation_nodes % 2 == 0)
    bad("BeliefSettings.deviation_nodes = " + std::to_string(deviation_nodes) + ": must be 3, 5 or 7");
  inflation.validate();
}

void BeliefPlannerSettings::validate() const {
  belief.validate();
  param_set<BeliefPlannerSettings>().check(*this, "BeliefPlannerSettings");
}

StateCov start_covariance(const SensorSettings& sensors, const PlanningMap& map, const Eigen::Vector2d& start,
                          double heading, double gate_probability) {
  sensors.validate();
  map.validate();
  if (!start.allFinite() || !std::isfinite(heading))
    bad("start_covariance: start (" + num(start.x()) + ", " + num(start.y()) + ") and heading " + num(heading) +
        " must be finite");
  BeliefSettings settings;
  settings.gate_probability = gate_probability;
  settings.validate();
  return belief::Model(BmmParams{}, sensors, map, settings).start_covariance(start, heading);
}

namespace {

using belief::normal_pdf;
using belief::normal_sf;

void check_path(const Eigen::Ref<const Points2>& path) {
  if (path.rows() < 2) bad("belief path has " + std::to_string(path.rows()) + " waypoints: needs >= 2");
  for (Eigen::Index i = 0; i < path.rows(); ++i)
    if (!path.row(i).allFinite())
      bad("belief path waypoint " + std::to_string(i) + " = (" + num(path(i, 0)) + ", " + num(path(i, 1)) +
          ") is not finite");
}

/// One stage of Patil et al.: the probability that aᵀe > b under N(μ, Σ),
/// then N(μ, Σ) ← the Gaussian with the mean and covariance of e given aᵀe ≤ b.
double truncate_stage(Eigen::Vector4d& mu, StateCov& Sigma, const Eigen::Vector4d& a, double b) {
  const Eigen::Vector4d Sa = Sigma * a;
  const double s2 = a.dot(Sa), m = a.dot(mu);
  if (!(s2 > 1e-300)) return m > b ? 1.0 : 0.0;
  const double s = std::sqrt(s2), alpha = (b - m) / s;
  const double p = normal_sf(alpha);
  if (p >= 1.0 - 1e-15) return 1.0;
  if (p <= 0.0) return 0.0;
  // Upper-truncated normal: E[y | y ≤ b] = m − s·λ, Var = s²(1 − α·λ − λ²), λ = φ(α)/Φ(α).
  const double lambda = normal_pdf(alpha) / (1.0 - p);
  const double mean = m - s * lambda;
  const double var = s2 * std::max(0.0, 1.0 - alpha * lambda - lambda * lambda);
  mu += Sa * ((mean - m) / s2);
  Sigma += Sa * Sa.transpose() * ((var / s2 - 1.0) / s2);
  Sigma = 0.5 * (Sigma + Sigma.transpose());
  return p;
}

/// The stage directions and thresholds, then Patil et al.'s recursion over
/// the closed-loop error dynamics e_{k+1} = A_k e_k + w_k.
void collision_probability(belief::Model& model, std::vector<belief::Step>& steps, const std::vector<StateCov>& P,
                           const std::vector<Eigen::Matrix4d>& A, BeliefProfile& out) {
  const Eigen::Index n = static_cast<Eigen::Index>(P.size());
  out.direction.resize(n, 2);
  out.sigma_toward.resize(n);
  out.stage_probability.resize(n);
  out.marginal_probability.resize(n);
  const double radius = model.settings().inflation.vehicle_radius;
  Eigen::Vector4d mu = Eigen::Vector4d::Zero();
  StateCov Sigma = P[0];
  double survive = 1.0, sum = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    belief::Step& s = steps[static_cast<std::size_t>(k)];
    const StateCov& Pk = P[static_cast<std::size_t>(k)];
    if (k > 0) {  // propagate the truncated Gaussian: Σ ← A Σ Aᵀ + (P_k − A P_{k−1} Aᵀ)
      const Eigen::Matrix4d& Ak = A[static_cast<std::size_t>(k - 1)];
      const StateCov& Pp = P[static_cast<std::size_t>(k - 1)];
      mu = Ak * mu;
      Sigma = Ak * (Sigma - Pp) * Ak.transpose() + Pk;
      Sigma = 0.5 * (Sigma + Sigma.transpose());
    }
    model.direction(s);
    Eigen::Vector2d a2 = s.toward;
    if (a2.squaredNorm() == 0.0) {  // undefined: the axis of the largest σ
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(Pk.topLeftCorner<2, 2>());
      a2 = es.eigenvectors().col(1);
    }
    out.direction.row(k) = a2.transpose();
    out.sigma_toward[k] = std::sqrt(std::max(0.0, a2.dot(Pk.topLeftCorner<2, 2>() * a2)));
    double p = 0.0, marginal = 0.0;
    if (std::isfinite(s.clearance)) {
      const double b = s.clearance - radius;
      const Eigen::Vector4d a(a2.x(), a2.y(), 0.0, 0.0);
      const double sk = out.sigma_toward[k];
      marginal = sk > 0.0 ? normal_sf(b / sk) : (b < 0.0 ? 1.0 : 0.0);
      p = truncate_stage(mu, Sigma, a, b);
    }
    out.stage_probability[k] = p;
    out.marginal_probability[k] = marginal;
    survive *= 1.0 - p;
    sum += marginal;
  }
  out.collision_probability = 1.0 - survive;
  out.union_bound = std::min(1.0, sum);
}

/// The belief over `steps` (stage 0 the start, stage k the end of step k)
/// from P0, and its collision probability.
BeliefProfile profile_of(belief::Model& model, std::vector<belief::Step>& steps, const StateCov& P0, double length) {
  const BeliefSettings& settings = model.settings();
  const std::size_t n = steps.size();
  std::vector<StateCov> P(n);
  std::vector<Eigen::Matrix4d> A(n, Eigen::Matrix4d::Zero());
  P[0] = P0;
  belief::StrataTrace trace;
  if (settings.deviation_mixture) {
    belief::deviation_mixture(model, steps, P, A, trace);
  } else {
    for (std::size_t k = 1; k < n; ++k) {
      belief::StepOutcome o;
      P[k] = P[k - 1];
      model.step(steps[k], P[k], &o);
      // A = (I − K H) F: the product of the update factors is P (P⁻)⁻¹
      // (with a fix that may not arrive, the branches' mean factor).
      A[k - 1] = o.Pm.ldlt().solve(P[k].transpose()).transpose() * o.F;
    }
  }
  BeliefProfile out;
  const Eigen::Index N = static_cast<Eigen::Index>(n);
  out.positions.resize(N, 2);
  out.headings.resize(N);
  out.time.resize(N);
  out.covariance.resize(N, 16);
  out.cov_xy.resize(N, 4);
  out.sigma.resize(N);
  out.landmarks.resize(N);
  out.transition.resize(N, 16);
  out.clearance.resize(N);
  double t = 0.0;
  for (Eigen::Index k = 0; k < N; ++k) {
    const belief::Step& s = steps[static_cast<std::size_t>(k)];
    const StateCov& Pk = P[static_cast<std::size_t>(k)];
    t += k > 0 ? s.dt : 0.0;
    out.positions.row(k) = s.end.transpose();
    out.headings[k] = s.x[kTheta];
    out.time[k] = t;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) {
        out.covariance(k, 4 * r + c) = Pk(r, c);
        out.transition(k, 4 * r + c) = A[static_cast<std::size_t>(k)](r, c);
      }
    out.cov_xy.row(k) << Pk(0, 0), Pk(0, 1), Pk(1, 0), Pk(1, 1);
    out.sigma[k] = position_std(Pk);
    out.landmarks[k] = s.in_view;
    out.clearance[k] = s.clearance;
  }
  out.length = length;
  out.vehicle_radius = settings.inflation.vehicle_radius;
  out.strata_weight = std::move(trace.weight);
  out.strata_positions = std::move(trace.positions);
  out.strata_msq = std::move(trace.msq);
  out.strata_position_cov = std::move(trace.position_cov);
  collision_probability(model, steps, P, A, out);
  return out;
}
}  // namespace

BeliefProfile propagate_belief(const Eigen::Ref<const Points2>& path, const BmmParams& bmm,
                               const SensorSettings& sensors, const PlanningMap& map, const StateCov& P0,
                               const BeliefSettings& settings) {
  check_path(path);
  check_prior(State::Zero(), P0, "x0", "start_cov");
  belief::Model model(bmm, sensors, map, settings);
  // Stage 0 is the start; stage k the end of belief step k.
  std::vector<belief::Step> steps(1);
  steps[0].end = path.row(0).transpose();
  steps[0].x << path(0, 0), path(0, 1), settings.speed, 0.0;
  steps[0].clearance = model.clearance_at(steps[0].end);
  double length = 0.0;
  for (Eigen::Index i = 0; i + 1 < path.rows(); ++i) {
    const Eigen::Vector2d a = path.row(i).transpose(), b = path.row(i + 1).transpose();
    model.leg(a, b, steps);
    length += (b - a).norm();
  }
  if (steps.size() > 1) steps[0].x[kTheta] = steps[1].x[kTheta];
  steps[0].in_view = sensors.landmarks_in_view(steps[0].x, &model.checker());
  return profile_of(model, steps, P0, length);
}

BeliefProfile propagate_belief_along(const Eigen::Ref<const RowMatrixX4>& states, const BmmParams& bmm,
                                     const SensorSettings& sensors, const PlanningMap& map, const StateCov& P0,
                                     const BeliefSettings& settings) {
  if (states.rows() < 2) bad("belief trajectory has " + std::to_string(states.rows()) + " states: needs >= 2");
  for (Eigen::Index i = 0; i < states.rows(); ++i)
    check_finite_state(states.row(i).transpose(), ("belief trajectory state " + std::to_string(i)).c_str());
  check_prior(State::Zero(), P0, "x0", "start_cov");
  belief::Model model(bmm, sensors, map, settings);
  std::vector<belief::Step> steps(1);
  steps[0].x = states.row(0).transpose();
  steps[0].end = steps[0].x.head<2>();
  steps[0].clearance = model.clearance_at(steps[0].end);
  steps[0].in_view = sensors.landmarks_in_view(steps[0].x, &model.checker());
  model.trajectory(states, steps);
  double length = 0.0;
  for (std::size_t k = 1; k < steps.size(); ++k) length += steps[k].length;
  return profile_of(model, steps, P0, length);
}

namespace {
/// The rows of `m` (N×16) as 4×4 matrices, row-major.
StateCov at(const RowMatrixX16& m, Eigen::Index k) {
  StateCov out;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out(r, c) = m(k, 4 * r + c);
  return out;
}
/// A square root L (L Lᵀ = S) of a positive semi-definite S, its negative rounding clamped.
StateCov psd_sqrt(const StateCov& S) {
  Eigen::SelfAdjointEigenSolver<StateCov> es(0.5 * (S + S.transpose()));
  return es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}
}  // namespace

double collision_monte_carlo(const BeliefProfile& prof, int samples, std::uint64_t seed) {
  if (samples < 1) bad("collision_monte_carlo: samples = " + std::to_string(samples) + ": must be >= 1");
  const Eigen::Index n = prof.covariance.rows();
  if (n < 1 || prof.transition.rows() != n || prof.direction.rows() != n || prof.clearance.size() != n)
    bad("collision_monte_carlo: the profile's arrays differ in length (or are empty)");
  std::vector<StateCov> A(static_cast<std::size_t>(n)), L(static_cast<std::size_t>(n));
  L[0] = psd_sqrt(at(prof.covariance, 0));
  for (Eigen::Index k = 1; k < n; ++k) {
    A[static_cast<std::size_t>(k - 1)] = at(prof.transition, k - 1);
    const StateCov& Ak = A[static_cast<std::size_t>(k - 1)];
    L[static_cast<std::size_t>(k)] = psd_sqrt(at(prof.covariance, k) - Ak * at(prof.covariance, k - 1) * Ak.transpose());
  }
  detail::Rng rng(seed);
  auto draw = [&rng] { return Eigen::Vector4d(rng.normal(), rng.normal(), rng.normal(), rng.normal()); };
  std::int64_t hits = 0;
  for (int i = 0; i < samples; ++i) {
    Eigen::Vector4d e = L[0] * draw();
    for (Eigen::Index k = 0; k < n; ++k) {
      if (k > 0) e = A[static_cast<std::size_t>(k - 1)] * e + L[static_cast<std::size_t>(k)] * draw();
      if (!std::isfinite(prof.clearance[k])) continue;
      if (prof.direction.row(k).dot(e.head<2>()) > prof.clearance[k] - prof.vehicle_radius) {
        ++hits;
        break;
      }
    }
  }
  return static_cast<double>(hits) / samples;
}

// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<BeliefSettings>& param_set<BeliefSettings>() {
  static const ParamSet<BeliefSettings> s =
      Declare<BeliefSettings>{}
          .real("speed", SN_REF(BeliefSettings, speed), "m/s", above(0, 1000), "speed along the path (the navigation's cruise speed)")
          .real("step", SN_REF(BeliefSettings, step), "s", closed(0, 1000), "belief step; 0 = the BMM's dt (exact EKF steps)")
          .real("bearing_std", SN_REF(BeliefSettings, bearing_std), "rad", closed(0, 10), "sigma of a bearing to each landmark in view; 0 = none")
          .real("sight_fov_margin", SN_REF(BeliefSettings, sight_fov_margin), "rad", closed(0, 2 * kPi),
                "the belief sees landmarks only inside the field of view less this (at least 10 deg)")
          .real("sight_range_fraction", SN_REF(BeliefSettings, sight_range_fraction), "", above(0, 1),
                "the belief sees landmarks only within this share of the detection range")
          .flag("deviation_mixture", SN_REF(BeliefSettings, deviation_mixture),
                "the expected belief over the vehicle's deviation from the path (Gauss-Hermite strata)")
          .integer("deviation_nodes", SN_REF(BeliefSettings, deviation_nodes), closed(3, 7),
                   "Gauss-Hermite nodes per axis of the deviation mixture: 3, 5 or 7")
          .flag("deviation_along", SN_REF(BeliefSettings, deviation_along),
                "stratify the deviation along the path too (n^3 strata, each reported at its own position)")
          .flag("deviation_split", SN_REF(BeliefSettings, deviation_split),
                "stratify at cells of the deviation, cut where the view changes")
          .integer("deviation_free_strata", SN_REF(BeliefSettings, deviation_free_strata), closed(0, 100000),
                   "with deviation_split: the strata the mixture may hold beyond its rule's (at least twice the rule's)")
          .real("gate_probability", SN_REF(BeliefSettings, gate_probability), "", closed(0, 0.999999),
                "the filter's chi-square gate on position fixes (the navigation's gate_probability); 0 = none")
          .nested("inflation.", param_set<Inflation>(), SN_REF(BeliefSettings, inflation))
          .set;
  return s;
}

template <>
const ParamSet<BeliefPlannerSettings>& param_set<BeliefPlannerSettings>() {
  using S = BeliefPlannerSettings;
  static const ParamSet<S> s =
      Declare<S>{}
          .nested("belief.", param_set<BeliefSettings>(), SN_REF(S, belief))
          .real("k_sigma", SN_REF(S, k_sigma), "", closed(0, 100), "chance constraint: clearance >= k*sigma + vehicle_radius + margin")
          .real("alpha", SN_REF(S, alpha), "1/m", closed(0, 1e6), "weight of the length (SafeNav eq. 16's alpha)")
          .real("sigma_weight", SN_REF(S, sigma_weight), "1/m^2", closed(0, 1e6), "cost += sigma_weight * integral of sigma ds")
          .integer("samples", SN_REF(S, samples), closed(0, 1e6), "roadmap vertices drawn besides start, goal and guide points")
          .integer("neighbours", SN_REF(S, neighbours), closed(1, 1000), "each vertex joins this many nearest ones")
          .real("max_edge", SN_REF(S, max_edge), "m", above(0, 1e6), "longest roadmap edge")
          .real("guide_spacing", SN_REF(S, guide_spacing), "m", above(0, 1e6), "guide paths are cut into pieces of at most this")
          .integer("max_beliefs", SN_REF(S, max_beliefs), closed(1, 1e6), "non-dominated beliefs kept per vertex")
          .real("dominance_tolerance", SN_REF(S, dominance_tolerance), "", closed(0, 1), "relative epsilon of the belief partial order (Bry & Roy)")
          .integer64("max_expansions", SN_REF(S, max_expansions), closed(1, 1e9), "belief expansions before giving up")
          .real("max_time", SN_REF(S, max_time), "s", closed(0, 1e6), "wall-clock budget of the roadmap and the search; 0 = none")
          .flag("shortcut", SN_REF(S, shortcut), "shorten the found path where the chance constraint allows")
          .real("max_turn", SN_REF(S, max_turn), "rad", above(0, kPi), "most the path turns at a vertex and within turn_window")
          .real("turn_window", SN_REF(S, turn_window), "m", closed(0, 1e6), "turns closer together than this add up (the controllers' lookahead)")
          .set;
  return s;
}

template class ParamSet<BeliefSettings>;
template class ParamSet<BeliefPlannerSettings>;

}  // namespace safenav
