// The simulator's stereo camera (safenav/render.hpp, SimulatedCamera): which
// boards each camera sees at a pose, in camera coordinates and painter's
// order, for RenderedFrame to draw (safenav.vision.render.StereoRenderer's
// geometry: culled, _board, hidden, centres_in_view).
#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "errors.hpp"
#include "lanbloc_internal.hpp"
#include "safenav/render.hpp"

namespace safenav {

namespace {

using Quad = Eigen::Matrix<double, 4, 3, Eigen::RowMajor>;

/// The left and right camera centres at pose (x, y, θ) and height h.
std::array<Eigen::Vector3d, 2> centres(const Eigen::Vector3d& pose, double h, double baseline) {
  const Eigen::Vector3d left(pose.x(), pose.y(), h);
  return {left, left + baseline * Eigen::Vector3d(std::sin(pose.z()), -std::cos(pose.z()), 0.0)};
}

}  // namespace

void SimulatedCameraSettings::validate() const {
  detail::require_finite_nonneg(baseline_m, "camera.baseline_m");
  if (!(max_range_m > 0.0)) detail::bad("camera.max_range_m = " + detail::num(max_range_m) + ": must be > 0");
  detail::require_finite_positive(near_m, "camera.near_m");
  detail::require_finite_positive(board_half_m, "camera.board_half_m");
  detail::require_finite_positive(pole_width_m, "camera.pole_width_m");
}

SimulatedCamera::SimulatedCamera(std::shared_ptr<const PixelRenderer> renderer, std::vector<CameraBoard> boards,
                                 const SimulatedCameraSettings& settings, std::optional<ObstacleChecker> occlusion)
    : renderer_(std::move(renderer)),
      boards_(std::move(boards)),
      settings_(settings),
      occlusion_(std::move(occlusion)) {
  if (!renderer_) detail::bad("SimulatedCamera: renderer is null");
  settings_.validate();
  for (const CameraBoard& b : boards_) {
    if (!b.centre.allFinite())
      detail::bad("SimulatedCamera: board " + std::to_string(b.id) + " centre is not finite");
    if (!renderer_->scene().boards.count(b.id))
      detail::bad("SimulatedCamera: board " + std::to_string(b.id) + " has no mip pyramid in the scene");
  }
}

std::vector<int> SimulatedCamera::culled(const Eigen::Vector3d& pose) const {
  // Within range and the horizontal field of view, widened by the board's and the baseline's angle.
  const RenderScene& s = renderer_->scene();
  const Eigen::Vector3d C(pose.x(), pose.y(), s.camera_height_m);
  const double c = std::cos(pose.z()), sn = std::sin(pose.z());
  const double half = std::atan2(s.width / 2.0, s.f);
  std::vector<int> out;
  for (std::size_t i = 0; i < boards_.size(); ++i) {
    const Eigen::Vector3d d = boards_[i].centre - C;
    const double fwd = d.x() * c + d.y() * sn, lat = d.x() * sn - d.y() * c;
    const double ang = std::abs(std::atan2(lat, fwd));
    const double slack =
        std::atan2(settings_.board_half_m + settings_.baseline_m, std::max(std::hypot(fwd, lat), 1e-9));
    if (d.norm() <= settings_.max_range_m && fwd > settings_.near_m && ang <= half + slack) out.push_back(int(i));
  }
  return out;
}

std::array<RenderView, 2> SimulatedCamera::views(const Eigen::Vector3d& pose) const {
  if (!pose.allFinite()) detail::bad("camera pose is not finite");
  const RenderScene& s = renderer_->scene();
  const double th = pose.z(), hb = settings_.board_half_m, pw = 0.5 * settings_.pole_width_m;
  const std::array<Eigen::Vector3d, 2> C = centres(pose, s.camera_height_m, settings_.baseline_m);
  const Eigen::Matrix3d R = lanbloc_detail::camera_rotation(th, s.pitch_rad);
  const std::vector<int> idx = culled(pose);
  std::array<RenderView, 2> out;
  for (int cam = 0; cam < 2; ++cam) {
    RenderView& v = out[std::size_t(cam)];
    v.theta = th, v.R = R, v.centre = C[std::size_t(cam)];
    Points2 targets(idx.size(), 2);
    for (std::size_t k = 0; k < idx.size(); ++k)
      targets.row(Eigen::Index(k)) = boards_[std::size_t(idx[k])].centre.head<2>();
    const Eigen::Matrix<bool, Eigen::Dynamic, 1> seen =
        occlusion_ && !idx.empty() ? occlusion_->visible_from(v.centre.head<2>(), targets)
                                   : Eigen::Matrix<bool, Eigen::Dynamic, 1>::Constant(Eigen::Index(idx.size()), true);
    std::vector<std::pair<double, RenderBoard>> items;
    for (std::size_t k = 0; k < idx.size(); ++k) {
      if (!seen(Eigen::Index(k))) continue;
      const CameraBoard& b = boards_[std::size_t(idx[k])];
      const Eigen::Vector3d& c = b.centre;
      // The face's normal: toward the cameras' midpoint, or the board's yaw.
      Eigen::Vector2d n;
      if (std::isnan(b.yaw)) {
        const Eigen::Vector2d mid =
            pose.head<2>() + 0.5 * settings_.baseline_m * Eigen::Vector2d(std::sin(th), -std::cos(th));
        n = mid - c.head<2>();
        const double nn = n.norm();
        n = nn > 1e-9 ? Eigen::Vector2d(n / nn) : Eigen::Vector2d(-std::cos(th), -std::sin(th));
      } else {
        n = Eigen::Vector2d(std::cos(b.yaw), std::sin(b.yaw));
      }
      if (!(n.dot(pose.head<2>() - c.head<2>()) > 0.0)) continue;  // seen from behind
      const Eigen::Vector3d a(-n.y(), n.x(), 0.0), up(0.0, 0.0, 1.0);
      Quad corners;
      corners.row(0) = c - a * hb + up * hb;
      corners.row(1) = c + a * hb + up * hb;
      corners.row(2) = c + a * hb - up * hb;
      corners.row(3) = c - a * hb - up * hb;
      RenderBoard rb;
      rb.id = b.id;
      for (int r = 0; r < 4; ++r) rb.corners.row(r) = (R * (corners.row(r).transpose() - v.centre)).transpose();
      if ((rb.corners.col(2).array() <= settings_.near_m).any()) continue;
      const double bottom = c.z() - hb;
      if (bottom > 0.0) {
        Quad pole;
        pole.row(0) = c - a * pw + up * (bottom - c.z());
        pole.row(1) = c + a * pw + up * (bottom - c.z());
        pole.row(2) = c + a * pw - up * c.z();
        pole.row(3) = c - a * pw - up * c.z();
        for (int r = 0; r < 4; ++r) rb.pole.row(r) = (R * (pole.row(r).transpose() - v.centre)).transpose();
        rb.has_pole = (rb.pole.col(2).array() > settings_.near_m).all();
      }
      // The full-resolution pixels drawing the board and its pole can touch.
      double u0 = 1e300, v0 = 1e300, u1 = -1e300, v1 = -1e300;
      for (const Quad* q : {&rb.corners, &rb.pole}) {
        if (q == &rb.pole && !rb.has_pole) continue;
        for (int r = 0; r < 4; ++r) {
          const double u = s.f * (*q)(r, 0) / (*q)(r, 2) + s.cx, w = s.f * (*q)(r, 1) / (*q)(r, 2) + s.cy;
          u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, w), v1 = std::max(v1, w);
        }
      }
      const double lim = 1e9;  // far outside any image, and inside int
      rb.box = {int(std::clamp(std::floor(u0) - 2, -lim, lim)), int(std::clamp(std::floor(v0) - 2, -lim, lim)),
                int(std::clamp(std::ceil(u1) + 3, -lim, lim)), int(std::clamp(std::ceil(v1) + 3, -lim, lim))};
      items.emplace_back(rb.corners.col(2).mean(), rb);
    }
    std::stable_sort(items.begin(), items.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
    for (auto& it : items) v.boards.push_back(std::move(it.second));  // far first
  }
  return out;
}

int SimulatedCamera::centres_in_view(const Eigen::Vector3d& pose) const {
  if (!pose.allFinite()) detail::bad("camera pose is not finite");
  const RenderScene& s = renderer_->scene();
  const std::vector<int> idx = culled(pose);
  const Eigen::Vector3d C = centres(pose, s.camera_height_m, settings_.baseline_m)[0];
  const Eigen::Matrix3d R = lanbloc_detail::camera_rotation(pose.z(), s.pitch_rad);
  std::vector<int> inside;
  for (int i : idx) {
    const Eigen::Vector3d pc = R * (boards_[std::size_t(i)].centre - C);
    const double u = s.f * pc.x() / pc.z() + s.cx, v = s.f * pc.y() / pc.z() + s.cy;
    if (pc.z() > settings_.near_m && u >= 0 && u <= s.width - 1 && v >= 0 && v <= s.height - 1) inside.push_back(i);
  }
  if (!occlusion_ || inside.empty()) return int(inside.size());
  Points2 targets(inside.size(), 2);
  for (std::size_t k = 0; k < inside.size(); ++k)
    targets.row(Eigen::Index(k)) = boards_[std::size_t(inside[k])].centre.head<2>();
  return int(occlusion_->visible_from(C.head<2>(), targets).count());
}

std::shared_ptr<RenderedFrame> SimulatedCamera::frame(const Eigen::Vector3d& pose,
                                                      std::shared_ptr<const RenderNoise> noise,
                                                      std::uint64_t noise_seed) const {
  std::array<RenderView, 2> v = views(pose);
  return std::make_shared<RenderedFrame>(renderer_, std::move(noise), std::move(v[0]), std::move(v[1]), noise_seed);
}

}  // namespace safenav
