// The localizer's start from data: the rigid-transform fit (localizer_fit.hpp).
#include "localizer_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <utility>

#include "safenav/measurement.hpp"
#include "safenav/types.hpp"

namespace safenav::detail {

namespace {

/// χ²₃ at 0.99: a local minimum this close in cost to the best one is as good.
constexpr double kAmbiguousCost = 11.34;
/// (5σ)²: a minimum this far from the fit in its own metric is another pose.
constexpr double kAmbiguousDistance2 = 25.0;

/// The residual rows of a fit and their Jacobian ∂e/∂(X, Y, φ), over the rows
/// that the mask keeps.  Row order: each observation's range, then its
/// bearing; then the headings.
struct Rows {
  const std::vector<FitObs>& obs;
  const std::vector<FitHeading>& headings;
  double k0;
  std::vector<char> mask;
  Eigen::VectorXd e;
  Eigen::MatrixXd J;
  std::vector<double> sigma;  // σ of each row (all rows)
  std::vector<char> is_range;
  int undefined = 0;  // rows of the last eval with T(q) at their landmark (no model there)

  Rows(const std::vector<FitObs>& o, const std::vector<FitHeading>& h, double k) : obs(o), headings(h), k0(k) {
    for (const FitObs& x : obs) {
      if (!std::isnan(x.range)) sigma.push_back(x.range_std), is_range.push_back(1);
      if (!std::isnan(x.bearing)) sigma.push_back(x.bearing_std), is_range.push_back(0);
    }
    for (const FitHeading& x : headings) sigma.push_back(x.std), is_range.push_back(0);
    mask.assign(sigma.size(), 1);
    e.resize(static_cast<Eigen::Index>(sigma.size()));
    J.resize(e.size(), 3);
  }

  /// Fills e and J for th; returns the number of rows kept.
  Eigen::Index eval(const Eigen::Vector3d& th) {
    const double c = std::cos(th[2]), s = std::sin(th[2]);
    Eigen::Index m = 0;
    std::size_t i = 0;
    undefined = 0;
    auto put = [&](double res, double jx, double jy, double jphi) {
      if (mask[i]) {
        e[m] = res / sigma[i];
        J(m, 0) = -jx / sigma[i];  // e = (z − h)/σ: ∂e = −∂h/σ
        J(m, 1) = -jy / sigma[i];
        J(m, 2) = -jphi / sigma[i];
        ++m;
      }
      ++i;
    };
    for (const FitObs& o : obs) {
      // p = T(q); ∂p/∂φ = R'(φ) q.
      const double px = th[0] + c * o.qx - s * o.qy, py = th[1] + s * o.qx + c * o.qy;
      const double dpx = -s * o.qx - c * o.qy, dpy = c * o.qx - s * o.qy;
      const LandmarkGeometry g = landmark_geometry(px, py, o.ax, o.ay);
      const bool ok = g.defined() && g.finite();  // at the landmark h has no Jacobian: the row counts 0
      undefined += !ok;
      LandmarkJacobian H;
      if (!std::isnan(o.range)) {
        if (ok) {
          const double h = predict_range(g, k0, 0.0, &H);
          put(o.range - h, H.x, H.y, H.x * dpx + H.y * dpy);
        } else {
          put(0.0, 0.0, 0.0, 0.0);
        }
      }
      if (!std::isnan(o.bearing)) {
        if (ok) {
          const double h = predict_bearing(g, o.qth + th[2], &H);  // world heading = qθ + φ
          put(wrap_angle(o.bearing - h), H.x, H.y, H.x * dpx + H.y * dpy + H.theta);
        } else {
          put(0.0, 0.0, 0.0, 0.0);
        }
      }
    }
    for (const FitHeading& hd : headings) put(wrap_angle(hd.theta - hd.qth - th[2]), 0.0, 0.0, 1.0);
    return m;
  }

  Eigen::Vector3d gauss_newton(Eigen::Vector3d th, int iters) {
    for (int it = 0; it < iters; ++it) {
      const Eigen::Index m = eval(th);
      const Eigen::Vector3d step = J.topRows(m).completeOrthogonalDecomposition().solve(-e.head(m));
      th += step;
      if (step.cwiseAbs().maxCoeff() < 1e-6) break;
    }
    return th;
  }
};

/// Starting points: 16 headings × 5 positions around the landmarks' centroid;
/// with a range+bearing, at each heading instead the centroid and the
/// transform that puts the newest range+bearing's landmark where it was seen;
/// with headings, the newest heading's φ too.
std::vector<Eigen::Vector3d> seeds(const std::vector<FitObs>& obs, const std::vector<FitHeading>& headings) {
  double ax = 0.0, ay = 0.0;
  for (const FitObs& o : obs) ax += o.ax, ay += o.ay;
  ax /= static_cast<double>(obs.size());
  ay /= static_cast<double>(obs.size());
  const double around[5][2] = {{ax, ay}, {ax + 30, ay}, {ax - 30, ay}, {ax, ay + 30}, {ax, ay - 30}};
  std::vector<double> phis;
  for (int h = 0; h < 16; ++h) phis.push_back(-kPi + 2.0 * kPi * h / 16.0);
  if (!headings.empty()) phis.push_back(wrap_angle(headings.back().theta - headings.back().qth));
  const FitObs* rb = nullptr;
  for (const FitObs& o : obs)
    if (!std::isnan(o.range) && !std::isnan(o.bearing)) rb = &o;
  std::vector<Eigen::Vector3d> out;
  for (const double phi : phis) {
    if (!rb) {
      for (const auto& sd : around) out.emplace_back(sd[0], sd[1], phi);
      continue;
    }
    // With a range+bearing the position at each heading is known: the centroid
    // seed stays as a fallback, the ±30 m ones are dropped (a third of the work).
    // The landmark at range r and bearing β from T(q): T(q) = a − r·(cos, sin)(qθ + φ + β).
    const double c = std::cos(phi), s = std::sin(phi), b = rb->qth + phi + rb->bearing;
    const double px = rb->ax - rb->range * std::cos(b), py = rb->ay - rb->range * std::sin(b);
    out.emplace_back(around[0][0], around[0][1], phi);
    out.emplace_back(px - (c * rb->qx - s * rb->qy), py - (s * rb->qx + c * rb->qy), phi);
  }
  return out;
}

}  // namespace

Eigen::Vector3d odo_at(const std::vector<Eigen::Vector4d>& track, double t) {
  auto hi = std::lower_bound(track.begin(), track.end(), t, [](const Eigen::Vector4d& q, double s) { return q[0] < s; });
  if (hi == track.end()) return track.back().tail<3>();
  if (hi == track.begin() || (*hi)[0] == t) return hi->tail<3>();
  const Eigen::Vector4d& lo = *(hi - 1);
  const double w = (t - lo[0]) / ((*hi)[0] - lo[0]);
  const Eigen::Vector2d q = lo.segment<2>(1) + w * (hi->segment<2>(1) - lo.segment<2>(1));
  return Eigen::Vector3d(q.x(), q.y(), wrap_angle(lo[3] + w * wrap_angle((*hi)[3] - lo[3])));
}

StartWindow start_window(const std::vector<Eigen::Vector4d>& track, const std::vector<BufferedObs>& obs,
                         const std::vector<BufferedHeading>& headings, double t_now) {
  StartWindow w;
  for (std::size_t i = 1; i < track.size(); ++i)
    w.path += std::hypot(track[i][1] - track[i - 1][1], track[i][2] - track[i - 1][2]);
  auto add = [](std::vector<int>& v, int row) {
    if (std::find(v.begin(), v.end(), row) == v.end()) v.push_back(row);
  };
  for (const BufferedObs& o : obs) {
    if (o.t > t_now) continue;  // not interpolable yet
    if (!std::isnan(o.range)) add(w.ranged, o.row);
    if (!std::isnan(o.bearing)) add(w.beared, o.row), w.angles = true;
    if (!std::isnan(o.range) && !std::isnan(o.bearing)) add(w.both, o.row);
  }
  for (const BufferedHeading& h : headings) w.headings += h.t <= t_now;
  w.angles = w.angles || w.headings > 0;
  return w;
}

bool start_rules(const StartWindow& w, double window, double min_path, int min_beacons, StartWindow::Most& most,
                 std::string& why) {
  const int nr = static_cast<int>(w.ranged.size()), nb = static_cast<int>(w.beared.size());
  const int n2 = static_cast<int>(w.both.size());
  const bool moved = w.path >= min_path;
  most.ranged = std::max(most.ranged, nr);
  most.beared = std::max(most.beared, nb);
  most.both = std::max(most.both, n2);
  const bool ok = (n2 >= 2) || (w.headings > 0 && n2 >= 1) || nb >= 3 || (nb >= 2 && moved) ||
                  (nr >= min_beacons && moved);
  std::ostringstream os;
  os << "waiting: in the last " << window << " s ranges of " << nr << " landmark(s), bearings of " << nb << " ("
     << n2 << " with both), " << w.headings << " heading(s), " << std::setprecision(3) << w.path
     << " m of motion; need range+bearing of 2 landmarks, or a heading and range+bearing of 1, or bearings of 3 "
     << "(2 after " << min_path << " m), or ranges of " << min_beacons << " after " << min_path
     << " m (so far at most " << most.ranged << " ranged, " << most.beared << " with bearings, " << most.both
     << " with both in one window)";
  why = os.str();
  return ok;
}

bool fit_transform(const std::vector<FitObs>& obs, const std::vector<FitHeading>& headings, double k0,
                   FitResult& out) {
  if (obs.empty()) return false;
  Rows rows(obs, headings, k0);
  const auto n = static_cast<Eigen::Index>(rows.sigma.size());
  double best_cost = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  std::vector<std::pair<double, Eigen::Vector3d>> minima;  // (cost, th) from each start
  for (const Eigen::Vector3d& seed : seeds(obs, headings)) {
    const Eigen::Vector3d th = rows.gauss_newton(seed, 15);
    const Eigen::Index m = rows.eval(th);
    // A transform that puts the vehicle on a landmark explains nothing there.
    const double cost = rows.undefined ? std::numeric_limits<double>::infinity() : rows.e.head(m).squaredNorm();
    minima.emplace_back(cost, th);
    if (cost < best_cost) best_cost = cost, best = th;
  }
  if (!std::isfinite(best_cost)) return false;
  // Drop residuals over 3σ and refit once.
  rows.eval(best);
  int inliers = 0;
  for (Eigen::Index i = 0; i < n; ++i) inliers += (rows.mask[i] = std::abs(rows.e[i]) < 3.0);
  if (inliers < 3) return false;
  out.th = rows.gauss_newton(best, 20);
  const Eigen::Index m = rows.eval(out.th);
  double ss_range = 0.0, ss = 0.0;
  int n_range = 0;
  out.angle_rows = 0;
  for (Eigen::Index i = 0, r = 0; i < n; ++i) {
    if (!rows.mask[i]) continue;
    ss += rows.e[r] * rows.e[r];
    if (rows.is_range[i]) {
      ss_range += (rows.e[r] * rows.sigma[i]) * (rows.e[r] * rows.sigma[i]);
      ++n_range;
    } else {
      ++out.angle_rows;
    }
    ++r;
  }
  out.rows = static_cast<int>(m);
  out.all_rows = static_cast<int>(n);
  out.range_rms = n_range ? std::sqrt(ss_range / n_range) : std::numeric_limits<double>::quiet_NaN();
  out.normalised_rms = std::sqrt(ss / static_cast<double>(m));
  const Eigen::Matrix3d JtJ = rows.J.topRows(m).transpose() * rows.J.topRows(m);
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(JtJ);
  if (!lu.isInvertible()) return false;
  out.C = lu.inverse();
  if (!out.C.allFinite()) return false;
  // Ambiguity: another local minimum nearly as good, far away in the fit's own metric.
  for (const auto& [cost, th] : minima) {
    if (!(cost <= best_cost + kAmbiguousCost)) continue;
    Eigen::Vector3d d = th - out.th;
    d[2] = wrap_angle(d[2]);
    if (d.dot(JtJ * d) > kAmbiguousDistance2) {
      out.ambiguous = true;
      return false;
    }
  }
  return true;
}

}  // namespace safenav::detail
