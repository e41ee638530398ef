// Ranging a fiducial from its corners (safenav/lanbloc.hpp: marker_centre,
// corner_disparity_sigma, corner_disparity, with the row, square and plane
// checks); LandmarkRanging.observe_corners calls these too.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <string>

#include <Eigen/QR>

#include "errors.hpp"
#include "safenav/lanbloc.hpp"

namespace safenav {

Eigen::Vector2d marker_centre(const MarkerCorners& c) {
  const Eigen::Vector2d p = c.row(0), r = c.row(2) - c.row(0), q = c.row(1), s = c.row(3) - c.row(1);
  const double den = r.x() * s.y() - r.y() * s.x();
  if (!(std::abs(den) > 1e-12)) return c.colwise().mean().transpose();
  return p + r * (((q - p).x() * s.y() - (q - p).y() * s.x()) / den);
}

double corner_disparity_sigma(const LanBLocSettings& settings, int corners_used, double scale, double side_px) {
  if (corners_used != 3 && corners_used != 4)
    detail::bad("corners_used = " + std::to_string(corners_used) + ": must be 3 or 4");
  if (!(scale > 0.0) || !std::isfinite(scale)) detail::bad("scale = " + detail::num(scale) + ": must be > 0");
  if (!(side_px > 0.0)) detail::bad("side_px = " + detail::num(side_px) + ": must be > 0");
  const double rho = settings.corner_edge_correlation;
  const double small = side_px < kSmallMarkerSidePx ? kSmallMarkerSigmaFactor : 1.0;
  return small * scale * settings.corner_sigma_d * (corners_used == 3 ? std::sqrt(2.0 / (1.0 + rho)) : 1.0);
}

namespace {

std::string fixed2(double v) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(2) << v;
  return os.str();
}

/// The two-corner midpoint of corner_disparity (one corner k dropped): the marker's centre in 3-D
/// from corners k+1 and k+3, both triangulated.
bool midpoint_centre(const MarkerCorners& l, const MarkerCorners& r, const RectifiedCamera& cam, int k,
                     CornerDisparity& out) {
  Eigen::Vector3d M = Eigen::Vector3d::Zero();
  for (int j : {(k + 1) % 4, (k + 3) % 4}) {
    const double w = l(j, 0) - r(j, 0) + cam.doffs;
    if (!(w >= 1.0)) {
      out.reason = "beyond resolvable range (corner " + std::to_string(j) + " disparity " + fixed2(w) + " px < 1 px)";
      return false;
    }
    const double Z = cam.f * cam.baseline / w;
    M += 0.5 * Z * Eigen::Vector3d((l(j, 0) - cam.cx) / cam.f, (l(j, 1) - cam.cy) / cam.f, 1.0);
  }
  out.centre = Eigen::Vector2d(cam.f * M.x() / M.z() + cam.cx, cam.f * M.y() / M.z() + cam.cy);
  out.disparity = cam.f * cam.baseline / M.z() - cam.doffs;
  return true;
}

/// The marker's edges in 3-D (corners triangulated, P_i = Z_i·ray_i): their lengths and, from each
/// corner's depth σ_Z = Z²·σ_c/(f·B) along its ray (σ_c the per-corner disparity σ), their σ.
struct MarkerEdges {
  Eigen::Vector4d length = Eigen::Vector4d::Zero(), sigma = Eigen::Vector4d::Zero();  // edge i: corner i → i+1
  bool finite = true;

  MarkerEdges(const MarkerCorners& l, const MarkerCorners& r, const RectifiedCamera& cam, double sigma_c) {
    Eigen::Matrix<double, 4, 3> ray, P;
    Eigen::Vector4d sz;
    for (int i = 0; i < 4; ++i) {
      const double w = l(i, 0) - r(i, 0) + cam.doffs, Z = cam.f * cam.baseline / w;
      ray.row(i) << (l(i, 0) - cam.cx) / cam.f, (l(i, 1) - cam.cy) / cam.f, 1.0;
      P.row(i) = Z * ray.row(i);
      sz[i] = Z * Z * sigma_c / (cam.f * cam.baseline);
      finite = finite && w > 0.0 && std::isfinite(Z);
    }
    for (int i = 0; i < 4; ++i) {
      const int j = (i + 1) % 4;
      const Eigen::RowVector3d e = P.row(j) - P.row(i);
      length[i] = e.norm();
      const Eigen::RowVector3d u = e / std::max(length[i], 1e-300);
      sigma[i] = std::hypot(u.dot(ray.row(i)) * sz[i], u.dot(ray.row(j)) * sz[j]);
    }
  }
  /// Whether edges a and b have the same length within n σ of their difference (and rounding).
  bool agree(int a, int b, double n) const {
    return std::abs(length[a] - length[b]) <= n * std::hypot(sigma[a], sigma[b]) + 1e-9 * (length[a] + length[b]);
  }
};

/// The plane check of corner_disparity (four corners): |r| / σ_r of the least-squares disparity
/// plane's residual.  Four points leave one residual direction n (Aᵀn = 0, A = [u v 1]); r = n·d,
/// σ_r² = nᵀ Σ n with Σ = σ_c²·(I + ρ on the two vertical edges' corner pairs, 0–3 and 1–2).  A
/// corner moved along its row by δ moves r by ~δ/2, also where the edges' lengths barely change
/// (a board facing the camera on its axis, the corner moved along its own ray).
double plane_residual_sigmas(const MarkerCorners& l, const Eigen::Vector4d& disp, double sigma_c, double rho) {
  Eigen::Matrix<double, 4, 3> A;
  A << l, Eigen::Vector4d::Ones();
  const Eigen::Matrix4d Q = Eigen::HouseholderQR<Eigen::Matrix<double, 4, 3>>(A).householderQ();
  const Eigen::Vector4d n = Q.col(3);
  Eigen::Matrix4d S = Eigen::Matrix4d::Identity();
  S(0, 3) = S(3, 0) = S(1, 2) = S(2, 1) = rho;
  return std::abs(n.dot(disp)) / (sigma_c * std::sqrt(std::max(n.dot(S * n), 1e-12)));
}

/// The square check of corner_disparity: with every corner (skip < 0), whether all four edges agree
/// (−1), else the one corner whose two edges disagree with the two that agree (0..3), else −2 (none,
/// or not one); with corner `skip` dropped, −1 when the two edges away from it agree, else −2.
int square_check(const MarkerEdges& e, double n, int skip) {
  if (!e.finite) return -1;  // a corner beyond range: the range check below says so
  if (skip >= 0) return e.agree((skip + 1) % 4, (skip + 2) % 4, n) ? -1 : -2;
  bool all = true;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) all = all && e.agree(a, b, n);
  if (all) return -1;
  int found = -2, count = 0;
  for (int k = 0; k < 4; ++k) {
    const int g1 = (k + 1) % 4, g2 = (k + 2) % 4, b1 = (k + 3) % 4, b2 = k;  // edges away from / at k
    if (e.agree(g1, g2, n) && !(e.agree(b1, g1, n) && e.agree(b1, g2, n) && e.agree(b2, g1, n) && e.agree(b2, g2, n)))
      found = k, ++count;
  }
  return count == 1 ? found : -2;
}

}  // namespace

CornerDisparity corner_disparity(const MarkerCorners& l, const MarkerCorners& r, const RectifiedCamera& cam,
                                 const LanBLocSettings& settings, double scale) {
  if (!l.allFinite() || !r.allFinite()) detail::bad("corner_disparity: the corners must be finite");
  CornerDisparity out;
  double side = 0.0;
  for (int i = 0; i < 4; ++i) side += 0.25 * (l.row((i + 1) % 4) - l.row(i)).norm();
  out.side_px = side;
  const Eigen::Vector4d dv = (l.col(1) - r.col(1)).cwiseAbs();
  int bad = 0, k = -1;
  for (int i = 0; i < 4; ++i)
    if (!(dv[i] <= settings.max_row_error_px)) ++bad, k = i;
  if (bad >= 2) {
    out.reason = "corners " + fixed2(dv.maxCoeff()) + " px off their epipolar lines (max_row_error_px = " +
                 detail::num(settings.max_row_error_px) + "; " + std::to_string(bad) + " corners)";
    return out;
  }
  out.centre = marker_centre(l);
  if (settings.corner_square_sigmas > 0.0) {
    // The marker is a square on a plane: its corners, triangulated, must give four edges of one
    // length and a disparity plane through all four. A corner hidden behind a nearer board in one
    // image moves along its row and breaks them (the row check above cannot see that).
    const double sigma_c = corner_disparity_sigma(settings, 4, scale, side) * 2.0 /
                           std::sqrt(1.0 + settings.corner_edge_correlation);
    const double n = settings.corner_square_sigmas;
    const MarkerEdges edges(l, r, cam, sigma_c);
    const int sq = square_check(edges, n, bad == 1 ? k : -1);
    const double plane =
        sq == -1 && bad == 0 ? plane_residual_sigmas(l, l.col(0) - r.col(0), sigma_c, settings.corner_edge_correlation)
                             : 0.0;
    if (sq == -2 || plane > n) {
      std::ostringstream os;
      os << std::fixed << std::setprecision(3);
      if (sq == -2)
        os << "corners do not form a square in 3-D (edges " << edges.length[0] << ", " << edges.length[1] << ", "
           << edges.length[2] << ", " << edges.length[3] << " m";
      else
        os << "corners not on one plane in 3-D (disparity plane residual " << std::setprecision(1) << plane << " sigma";
      os << "; corner_square_sigmas = " << detail::num(n) << ")";
      out.reason = os.str();
      return out;
    }
    if (sq >= 0) bad = 1, k = sq;
  }
  if (bad == 1) {
    out.dropped_corner = k;
    if (!midpoint_centre(l, r, cam, k, out)) return out;
    out.corners_used = 3;
  } else {
    // The least-squares disparity plane through the four corners, at the centre.
    Eigen::Matrix<double, 4, 3> A;
    A << l, Eigen::Vector4d::Ones();
    const Eigen::Vector4d disp = l.col(0) - r.col(0);
    const Eigen::Vector3d coef = A.colPivHouseholderQr().solve(disp);
    out.disparity = coef.x() * out.centre.x() + coef.y() * out.centre.y() + coef.z();
    out.corners_used = 4;
  }
  const double w = out.disparity + cam.doffs;
  if (!(w >= 1.0)) {
    out.reason = "beyond resolvable range (disparity " + fixed2(w) + " px < 1 px)";
    return out;
  }
  out.sigma = corner_disparity_sigma(settings, out.corners_used, scale, side);
  out.ok = true;
  return out;
}

}  // namespace safenav
