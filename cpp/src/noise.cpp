// Position noise: the error model of a position source, its named profiles
// and its sampler.  See safenav/measurement.hpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "declare.hpp"
#include "errors.hpp"
#include "rng.hpp"
#include "safenav/measurement.hpp"

namespace safenav {

template <>
const ParamSet<PositionNoise>& param_set<PositionNoise>();  // defined below

namespace {

/// A profile from the defaults (LanBLoc's) and the fields that differ.
template <class Edit>
PositionNoise profile(Edit edit) {
  PositionNoise p;
  edit(p);
  return p;
}

/// The named profiles, LanBLoc first.  The three baselines are emulations
/// with error profiles of our choosing: none was tuned to land on a number
/// of the paper's.
const std::vector<PositionNoise>& table() {
  static const std::vector<PositionNoise> t{
      profile([](PositionNoise& p) {
        p.note = "LanBLoc at the measurement level: the paper's RMSE, fixes only with >= min_landmarks in view";
      }),
      profile([](PositionNoise& p) {
        p.name = "deeploc-gps";
        p.label = "DeepLoc-GPS (emulated)";
        p.std << 0.30, 0.30;
        p.bias_std = 0.10;
        p.needs_landmarks = false, p.emulated = true;
        p.note = "emulated: CNN pose regression fused with (degraded) GPS: 0.30 m white noise, 0.10 m constant bias";
      }),
      profile([](PositionNoise& p) {
        p.name = "deeploc-ekf-gps";
        p.label = "DeepLoc-EKF-GPS (emulated)";
        p.std << 0.20, 0.20;
        p.bias_walk_std = 0.005;
        p.needs_landmarks = false, p.emulated = true;
        p.note = "emulated: DeepLoc with an EKF over GPS: 0.20 m white noise, a slowly drifting bias (5 mm/fix walk)";
      }),
      profile([](PositionNoise& p) {
        p.name = "sensor-fusion";
        p.label = "Sensor Fusion (emulated)";
        p.std << 0.25, 0.25;
        p.bias_std = 0.15, p.outlier_probability = 0.02, p.outlier_std = 2.0;
        p.needs_landmarks = false, p.emulated = true;
        p.note = "emulated: multi-source fusion: 0.25 m noise, 0.15 m bias, 2 % outliers of 2 m";
      }),
  };
  return t;
}

/// Two standard normals for X and Y, the second draw in X.  This is the order
/// GCC gave Eigen::Vector2d(rng.normal(), rng.normal()) (it evaluates
/// arguments right to left; the order is unspecified in C++), which the
/// tables were made with; written out, every compiler draws the same.
Eigen::Vector2d normal_pair(RandomSource& rng) {
  const double first = rng.normal();
  return {rng.normal(), first};
}

}  // namespace

PositionNoise PositionNoise::named(const std::string& name) {
  for (const PositionNoise& p : table())
    if (p.name == name) return p;
  std::string have;
  for (const std::string& n : names()) have += (have.empty() ? "" : ", ") + n;
  throw std::invalid_argument("position source '" + name + "' is unknown (have: " + have + ")");
}

std::vector<std::string> PositionNoise::names() {
  std::vector<std::string> out;
  for (const PositionNoise& p : table()) out.push_back(p.name);
  return out;
}

void PositionNoise::validate() const { param_set<PositionNoise>().check(*this, "position."); }

Eigen::Matrix2d PositionNoise::reported_cov() const {
  Eigen::Matrix2d R = std.array().square().matrix().asDiagonal();
  R.diagonal().array() += bias_std * bias_std + outlier_probability * outlier_std * outlier_std;
  return R;
}

PositionNoise::Trial::Trial(const PositionNoise& noise, RandomSource& rng) : noise_(&noise) {
  if (noise.bias_std > 0.0) bias_ << noise.bias_std * rng.normal(), noise.bias_std * rng.normal();
}

bool PositionNoise::Trial::sample(const Eigen::Vector2d& p, RandomSource& rng, Eigen::Vector2d& z) {
  const PositionNoise& n = *noise_;
  if (n.bias_walk_std > 0.0) bias_ += n.bias_walk_std * normal_pair(rng);
  if (n.dropout_probability > 0.0 && rng.uniform() < n.dropout_probability) return false;
  z << p[0] + bias_[0] + n.std[0] * rng.normal(), p[1] + bias_[1] + n.std[1] * rng.normal();
  if (n.outlier_probability > 0.0 && rng.uniform() < n.outlier_probability)
    z += n.outlier_std * normal_pair(rng);
  return true;
}

PositionNoise::Fixes PositionNoise::sample(const Eigen::Ref<const Fixes>& truth, std::uint64_t seed) const {
  validate();
  if (!truth.allFinite()) throw std::invalid_argument("truth: every true position must be finite");
  detail::Rng generator(seed);
  RandomSourceOf<detail::Rng> rng(generator);
  Trial trial(*this, rng);
  Fixes z(truth.rows(), 2);
  Eigen::Vector2d zi;
  for (Eigen::Index i = 0; i < truth.rows(); ++i) {
    if (trial.sample(truth.row(i).transpose(), rng, zi)) z.row(i) = zi.transpose();
    else z.row(i).setConstant(std::numeric_limits<double>::quiet_NaN());
  }
  return z;
}

// ---------------------------------------------------------------------------
// Landmark-level faults

void LandmarkFaults::validate() const {
  auto prob = [](double v, const char* name) {
    if (!(v >= 0.0 && v <= 1.0)) detail::bad(std::string("faults.") + name + " = " + detail::num(v) + ": must be in [0, 1]");
  };
  prob(dropout_probability, "dropout_probability");
  prob(outlier_probability, "outlier_probability");
  prob(misassociation_probability, "misassociation_probability");
  detail::require_finite_positive(outlier_magnitude, "faults.outlier_magnitude");
}

void LandmarkFaults::apply(std::vector<Observation>& obs, const Landmarks& landmarks, const Eigen::Vector2d& p,
                           double confusion_range, RandomSource& rng, int* dropped) const {
  const Eigen::Index K = landmarks.rows();
  if (!p.allFinite()) detail::bad("faults: vehicle position (" + detail::num(p.x()) + ", " + detail::num(p.y()) + ") is not finite");
  detail::require_finite_nonneg(confusion_range, "faults: confusion_range");
  if (!landmarks.allFinite()) detail::bad("faults: every landmark position must be finite");
  for (std::size_t i = 0; i < obs.size(); ++i)
    if (!(std::isfinite(obs[i].range) && obs[i].range >= 0.0))
      detail::bad("faults: observation " + std::to_string(i) + " has range " + detail::num(obs[i].range) +
                  ": must be finite and >= 0");
  std::size_t kept = 0;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    Observation o = obs[i];
    if (o.row < 0 || o.row >= K)
      throw std::invalid_argument("faults: observation " + std::to_string(i) + " has landmark row " +
                                  std::to_string(o.row) + ", the map has " + std::to_string(K));
    if (dropout_probability > 0.0 && rng.uniform() < dropout_probability) {
      if (dropped) ++*dropped;
      continue;
    }
    if (misassociation_probability > 0.0 && K > 1 && rng.uniform() < misassociation_probability) {
      // Another landmark near the vehicle (a plausible wrong match), else any other.
      int near = 0;
      for (Eigen::Index k = 0; k < K; ++k)
        near += k != o.row && (landmarks.row(k).transpose() - p).norm() <= confusion_range;
      const bool any_near = near > 0;
      const int n = any_near ? near : static_cast<int>(K) - 1;
      int pick = std::min(n - 1, static_cast<int>(rng.uniform() * n));
      for (Eigen::Index k = 0; k < K; ++k) {
        if (k == o.row || (any_near && (landmarks.row(k).transpose() - p).norm() > confusion_range)) continue;
        if (pick-- == 0) {
          o.row = static_cast<int>(k);
          break;
        }
      }
      o.faults |= kMisassociated;
    }
    if (outlier_probability > 0.0 && rng.uniform() < outlier_probability) {
      o.range = std::max(0.0, o.range + (rng.uniform() < 0.5 ? -outlier_magnitude : outlier_magnitude));
      o.faults |= kOutlier;
    }
    obs[kept++] = o;
  }
  obs.resize(kept);
}


// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<PositionNoise>& param_set<PositionNoise>() {
  using P = PositionNoise;
  // name, label and note are text, set directly.
  static const ParamSet<P> s =
      Declare<P>{}
          .real("std_x", SN_REF(P, std[0]), "m", closed(1e-6, 100), "sigma of w in X (LanBLoc: its RMSE [SafeNav §IV-A]); the filters need sigma > 0")
          .real("std_y", SN_REF(P, std[1]), "m", closed(1e-6, 100), "sigma of w in Y (LanBLoc: its RMSE [SafeNav §IV-A])")
          .real("bias_std", SN_REF(P, bias_std), "m", closed(0, 1e4), "sigma of the per-trial bias b")
          .real("bias_walk_std", SN_REF(P, bias_walk_std), "m", closed(0, 1e4), "sigma of the bias's random walk per fix")
          .real("outlier_probability", SN_REF(P, outlier_probability), "", closed(0, 1), "a fix gets an outlier's extra error with this probability")
          .real("outlier_std", SN_REF(P, outlier_std), "m", closed(0, 1e4), "sigma of an outlier's extra error")
          .real("dropout_probability", SN_REF(P, dropout_probability), "", closed(0, 1), "a fix is lost at random with this probability")
          .flag("needs_landmarks", SN_REF(P, needs_landmarks), "a fix needs >= min_landmarks landmarks in view (the navigation loop checks)")
          .flag("emulated", SN_REF(P, emulated), "an emulated error profile, not the real method")
          .set;
  return s;
}

template class ParamSet<PositionNoise>;

}  // namespace safenav
