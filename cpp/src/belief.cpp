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
                          double heading) {
  sensors.validate();
  map.validate();
  if (!start.allFinite() || !std::isfinite(heading))
    bad("start_covariance: start (" + num(start.x()) + ", " + num(start.y()) + ") and heading " + num(heading) +
        " must be finite");
  return belief::Model(BmmParams{}, sensors, map, BeliefSettings{}).start_covariance(start, heading);
}

namespace {

double normal_sf(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }  // P(N(0,1) > z)
double normal_pdf(double z) { return std::exp(-0.5 * z * z) / std::sqrt(2.0 * kPi); }

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

/// The Gauss–Hermite rule of N(0, 1) with n = 3, 5 or 7 nodes
/// (numpy.polynomial.hermite_e.hermegauss, weights over √(2π)).
struct Quadrature {
  std::vector<double> node, weight;
  explicit Quadrature(int n) {
    if (n == 3) {
      node = {-std::sqrt(3.0), 0.0, std::sqrt(3.0)};
      weight = {1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0};
    } else if (n == 5) {
      node = {-2.8569700138728056, -1.355626179974266, 0.0, 1.355626179974266, 2.8569700138728056};
      weight = {0.011257411327720677, 0.22207592200561257, 8.0 / 15.0, 0.22207592200561257, 0.011257411327720677};
    } else if (n == 7) {
      node = {-3.7504397177257425, -2.366759410734541, -1.1544053947399682, 0.0,
              1.1544053947399682,  2.366759410734541,  3.7504397177257425};
      weight = {0.0005482688559722169, 0.030757123967586515, 0.24012317860501264, 16.0 / 35.0,
                0.24012317860501264,   0.030757123967586515, 0.0005482688559722169};
    } else {
      bad("deviation_nodes = " + std::to_string(n) + ": must be 3, 5 or 7");
    }
  }
};

/// The strata of deviation_mixture (below): the product rule of `axes`
/// copies of the n-node rule, stratum i's node z_i (axes × S) and weight.
struct Strata {
  Eigen::MatrixXd z;
  std::vector<double> w;
  Strata(const Quadrature& q, int axes) {
    const std::size_t n = q.node.size();
    std::size_t count = 1;
    for (int a = 0; a < axes; ++a) count *= n;
    z.resize(axes, static_cast<Eigen::Index>(count));
    w.assign(count, 1.0);
    for (std::size_t i = 0; i < count; ++i) {
      std::size_t rest = i;  // the last axis varies fastest
      for (int a = axes - 1; a >= 0; --a) {
        z(a, static_cast<Eigen::Index>(i)) = q.node[rest % n];
        w[i] *= q.weight[rest % n];
        rest /= n;
      }
    }
  }
  std::size_t size() const { return w.size(); }
};

/// The strata anew from the mixture's error covariance
/// M = Σ w_i (P_i + N_i): stratum i's mean error m_i and its N_i (its
/// error's second moment less its filter covariance P_i, which stays).
/// K = 2 or 3 axes (H's rows).
template <int K>
void stratify(const Eigen::Matrix<double, K, 4>& H, const Strata& st, const std::vector<StateCov>& Pi,
              std::vector<StateCov>& N, std::vector<Eigen::Vector4d>& m) {
  using MatK = Eigen::Matrix<double, K, K>;
  StateCov M = StateCov::Zero();
  for (std::size_t i = 0; i < Pi.size(); ++i) M += st.w[i] * (Pi[i] + N[i]);
  M = 0.5 * (M + M.transpose());
  const Eigen::Matrix<double, 4, K> G = M * H.transpose();
  const MatK S = H * G;
  const Eigen::LLT<MatK> llt(S);
  double floor = 1e-12;  // 1e-12 tr(S)^K: the determinant's units
  for (int a = 0; a < K; ++a) floor *= S.trace();
  const bool ok = llt.info() == Eigen::Success && S.determinant() > floor;
  // The error given u: mean G S⁻¹ L z_i = G L⁻ᵀ z_i, covariance M − G S⁻¹ Gᵀ.
  const StateCov C = ok ? StateCov(M - G * llt.solve(G.transpose())) : M;
  for (std::size_t i = 0; i < Pi.size(); ++i) {
    const Eigen::Matrix<double, K, 1> z = st.z.col(static_cast<Eigen::Index>(i));
    m[i] = ok ? Eigen::Vector4d(G * llt.matrixU().solve(z)) : Eigen::Vector4d::Zero();
    N[i] = C - Pi[i] + m[i] * m[i].transpose();
  }
}

/// u = H e at heading h: across the leg (its left normal) and the heading.
Eigen::Matrix<double, 2, 4> lateral_axes(double h) {
  Eigen::Matrix<double, 2, 4> H;
  H << -std::sin(h), std::cos(h), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0;
  return H;
}

/// u = H e at heading h: along the leg, across it and the heading.
Eigen::Matrix<double, 3, 4> full_axes(double h) {
  Eigen::Matrix<double, 3, 4> H;
  H << std::cos(h), std::sin(h), 0.0, 0.0, -std::sin(h), std::cos(h), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0;
  return H;
}

/// Whether the strata are one Gaussian again: every one took the same
/// updates (landmarks in view, fix) and their filter covariances agree to
/// within 1 % of their norm (Frobenius).  Mid-transition, when some have
/// seen a landmark and some not, the mixture is far from Gaussian, and
/// stratifying it anew would move the late strata's error toward the rest.
bool one_gaussian(const std::vector<belief::Step>& seen, const std::vector<StateCov>& Pi) {
  constexpr double tol = 1e-2;
  for (std::size_t i = 1; i < seen.size(); ++i) {
    if (seen[i].seen != seen[0].seen || seen[i].fix != seen[0].fix || seen[i].ranges != seen[0].ranges) return false;
    if ((Pi[i] - Pi[0]).norm() > tol * Pi[0].norm()) return false;
  }
  return true;
}

/// A, scaled down where needed so that A P_prev Aᵀ ⪯ P_next: Patil's
/// recursion needs Cov w = P_next − A P_prev Aᵀ ⪰ 0.  A stratum's update
/// can raise its error (its filter trusts a fix more than its own, smaller
/// error warrants), so the mixture's update need not shrink it in every
/// direction.  The scale keeps the marginals and lowers only the correlation
/// of the errors between stages: toward independent stages, whose product
/// of survivals is close to the union bound for small probabilities.
Eigen::Matrix4d within_marginals(const Eigen::Matrix4d& A, const StateCov& P_prev, const StateCov& P_next) {
  const StateCov X = A * P_prev * A.transpose();
  const Eigen::GeneralizedSelfAdjointEigenSolver<StateCov> ges(0.5 * (X + X.transpose()), P_next,
                                                               Eigen::EigenvaluesOnly);
  if (ges.info() != Eigen::Success) return Eigen::Matrix4d::Zero();
  const double lambda = ges.eigenvalues().maxCoeff();
  return lambda > 1.0 ? Eigen::Matrix4d(A / std::sqrt(lambda * (1.0 + 1e-12))) : A;
}

/// What a vehicle with mean error e (estimate − truth) sees at step k with
/// the along-track axis (BeliefSettings::deviation_along).  Its speed
/// follows the command, so its true progress along the path keeps to the
/// nominal's, and it is its estimate that runs e_along = t·e ahead; the
/// controller turns where the estimate is.  So it sees from the nominal
/// pose e_along further along the steps (`arc`: metres at each stage),
/// moved by −e in position and turned by −e_θ: on a straight leg that is
/// the nominal's arc, at a turn it turns early or late.
belief::Step ahead_view(const belief::Model& model, const std::vector<belief::Step>& steps,
                        const std::vector<double>& arc, std::size_t k, const Eigen::Vector4d& e) {
  const double h = steps[k].x[kTheta];
  const double target = arc[k] + std::cos(h) * e[0] + std::sin(h) * e[1];
  const auto it = std::lower_bound(arc.begin() + 1, arc.end(), target);
  std::size_t j = static_cast<std::size_t>(it - arc.begin());
  if (j >= arc.size()) j = arc.size() - 1;
  if (j > 1 && target - arc[j - 1] < arc[j] - target) --j;  // the nearest stage
  // The rest of the way along stage j's own step.
  const belief::Step& v = steps[j];
  const Eigen::Vector2d dir = v.length > 0.0 ? Eigen::Vector2d((v.end - v.x.head<2>()) / v.length)
                                             : Eigen::Vector2d(std::cos(v.x[kTheta]), std::sin(v.x[kTheta]));
  const double rest = std::clamp(target - arc[j], -v.length, j + 1 < arc.size() ? steps[j + 1].length : 0.0);
  return model.seen_from(steps[k], v, rest * dir - e.head<2>(), -e[kTheta]);
}

/// Each stratum's true position and second moment per stage
/// (BeliefProfile::strata_*).
struct StrataTrace {
  Eigen::MatrixXd positions, msq;
};

/// BeliefSettings::deviation_mixture: the vehicle's error, stratified on its
/// part across the leg and in heading, u = H e (H's rows: the leg's left
/// normal n and the heading; K = 3 with deviation_along: the leg's direction
/// first), at the n^K Gauss–Hermite nodes z_i of N(0, I_K)
/// (n = BeliefSettings::deviation_nodes; with 3, per axis −√3, 0, √3 with
/// weights 1/6, 2/3, 1/6).  Stratum i is the
/// error given u = L z_i (L Lᵀ = H M Hᵀ, M the error's covariance): mean
/// m_i = M Hᵀ L⁻ᵀ z_i and covariance M − M Hᵀ (H M Hᵀ)⁻¹ H M.  The vehicle
/// drives its estimate along the path, so stratum i's vehicles are off it by
/// −m_i: they see from the nominal pose moved by −n·m_i across the leg (and
/// by −t·m_i along it, K = 3) and turned by −m_i,θ, and their filter takes
/// the updates of what is in view from there.  Each stratum's filter covariance P_i follows the filter's
/// recursion; its error's second moment is P_i + N_i, where N_i, the part
/// the stratum's selection adds, moves with the filter's error dynamics:
/// N_i ← T_i F N_i Fᵀ T_iᵀ, m_i ← T_i F m_i, T_i = P_i (P_i⁻)⁻¹ = I − K_i H_i
/// (the optimal gain's); a step whose fix may not arrive (belief::StepOutcome)
/// moves N_i by each branch's factor, weighted by the branch's probability,
/// and m_i by their mean.  So the strata that see a landmark late are the
/// ones whose error lies on that side, and the reported covariance
/// Σ w_i (P_i + N_i) keeps their larger error until they see it.  While the
/// strata are one Gaussian (one_gaussian), they are stratified anew from its
/// covariance each step, so the deviation follows the current error.
/// A[k−1] = M[k] (M⁻)⁻¹ F as in the single recursion, M⁻ the mixture's prior,
/// within_marginals.  `trace` receives where each stratum saw from and its
/// second moment.
template <int K>
void mixture_recursion(const belief::Model& model, const std::vector<belief::Step>& steps, std::vector<StateCov>& P,
                       std::vector<Eigen::Matrix4d>& A, const Strata& st, StrataTrace& trace) {
  const std::size_t S = st.size();
  std::vector<StateCov> Pi(S, P[0]), N(S, StateCov::Zero());
  std::vector<Eigen::Vector4d> m(S, Eigen::Vector4d::Zero());
  std::vector<belief::Step> seen(S);
  const auto S_ = static_cast<Eigen::Index>(S);
  trace.positions.resize(static_cast<Eigen::Index>(steps.size()), 2 * S_);
  trace.msq.resize(static_cast<Eigen::Index>(steps.size()), S_);
  for (Eigen::Index i = 0; i < S_; ++i) {
    trace.positions.block<1, 2>(0, 2 * i) = (steps.empty() ? Eigen::Vector2d::Zero() : steps[0].end).transpose();
    trace.msq(0, i) = P[0](0, 0) + P[0](1, 1);
  }
  std::vector<double> arc(steps.size(), 0.0);  // metres along the steps
  for (std::size_t k = 1; k < steps.size(); ++k) arc[k] = arc[k - 1] + steps[k].length;
  bool merged = true;
  for (std::size_t k = 1; k < steps.size(); ++k) {
    const double h = steps[k].x[kTheta];
    Eigen::Matrix<double, K, 4> H;
    if constexpr (K == 2) H = lateral_axes(h); else H = full_axes(h);
    if (merged) stratify<K>(H, st, Pi, N, m);
    StateCov mix = StateCov::Zero(), mix_m = StateCov::Zero();
    Eigen::Matrix4d F;
    for (std::size_t i = 0; i < S; ++i) {
      const double w = st.w[i];
      // The vehicle is off the path by minus its error.
      const Eigen::Matrix<double, K, 1> d = -(H * m[i]);
      if (!(d.squaredNorm() > 0.0))
        seen[i] = steps[k];
      else if constexpr (K == 3)
        seen[i] = ahead_view(model, steps, arc, k, m[i]);
      else
        seen[i] = model.offset(steps[k], d[0], d[K - 1]);
      belief::StepOutcome o;
      model.step(seen[i], Pi[i], &o);
      F = o.F;
      N[i] = F * N[i] * F.transpose();
      mix_m += w * (o.Pm + N[i]);
      if (o.p_fix < 1.0) {  // a fix that may not arrive: each branch moves the error by its own factor
        const StateCov X = N[i];
        N[i] = o.p_fix * o.T_fix * X * o.T_fix.transpose() + (1.0 - o.p_fix) * o.T_none * X * o.T_none.transpose();
        m[i] = (o.p_fix * o.T_fix + (1.0 - o.p_fix) * o.T_none) * (F * m[i]);
      } else {
        const Eigen::Matrix4d T = o.Pm.ldlt().solve(Pi[i].transpose()).transpose();  // P_i (P_i⁻)⁻¹ = I − K_i H_i
        N[i] = T * N[i] * T.transpose();
        m[i] = T * (F * m[i]);
      }
      N[i] = 0.5 * (N[i] + N[i].transpose());
      mix += w * (Pi[i] + N[i]);
      const auto row = static_cast<Eigen::Index>(k), col = static_cast<Eigen::Index>(i);
      trace.positions.block<1, 2>(row, 2 * col) = seen[i].end.transpose();
      trace.msq(row, col) = Pi[i](0, 0) + N[i](0, 0) + Pi[i](1, 1) + N[i](1, 1);
    }
    P[k] = 0.5 * (mix + mix.transpose());
    A[k - 1] = within_marginals(mix_m.ldlt().solve(P[k].transpose()).transpose() * F, P[k - 1], P[k]);
    merged = one_gaussian(seen, Pi);
  }
}

}  // namespace

namespace {
/// The belief over `steps` (stage 0 the start, stage k the end of step k)
/// from P0, and its collision probability.
BeliefProfile profile_of(belief::Model& model, std::vector<belief::Step>& steps, const StateCov& P0, double length) {
  const BeliefSettings& settings = model.settings();
  const std::size_t n = steps.size();
  std::vector<StateCov> P(n);
  std::vector<Eigen::Matrix4d> A(n, Eigen::Matrix4d::Zero());
  P[0] = P0;
  StrataTrace trace;
  std::vector<double> strata_weight;
  if (settings.deviation_mixture) {
    const Quadrature q(settings.deviation_nodes);
    const Strata st(q, settings.deviation_along ? 3 : 2);
    if (settings.deviation_along)
      mixture_recursion<3>(model, steps, P, A, st, trace);
    else
      mixture_recursion<2>(model, steps, P, A, st, trace);
    strata_weight = st.w;
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
  out.strata_weight = Eigen::Map<const Eigen::VectorXd>(strata_weight.data(),
                                                        static_cast<Eigen::Index>(strata_weight.size()));
  out.strata_positions = std::move(trace.positions);
  out.strata_msq = std::move(trace.msq);
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
          .flag("shortcut", SN_REF(S, shortcut), "shorten the found path where the chance constraint allows")
          .real("max_turn", SN_REF(S, max_turn), "rad", above(0, kPi), "most the path turns at a vertex and within turn_window")
          .real("turn_window", SN_REF(S, turn_window), "m", closed(0, 1e6), "turns closer together than this add up (the controllers' lookahead)")
          .set;
  return s;
}

template class ParamSet<BeliefSettings>;
template class ParamSet<BeliefPlannerSettings>;

}  // namespace safenav
