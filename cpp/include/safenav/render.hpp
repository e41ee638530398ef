// safenav/render.hpp — the simulator's stereo pixels (ours;
// safenav.vision.render): a rectified pair drawn box by box, at any pyramid
// level, as the front end asks for it (StereoPixels).
//
// A box of a view is drawn as the whole image has it there: the background at
// infinity (a periodic panorama indexed by azimuth and elevation, zero
// disparity), the textured ground plane through its homography H = K[r₁ r₂ t],
// faded into haze with distance, every board (marker with its white quiet zone)
// warped from its mip pyramid with an alpha edge over a pole, far boards first,
// and pixel noise.  A box at level L is drawn by the pinhole view whose pixel
// centres are the 2^L × 2^L blocks' centres (focal f/2^L), its noise at σ/2^L
// (the mean of 4^L independent pixels).  The geometry (which boards are seen,
// occlusion, facing) is the caller's: each frame gets each camera's boards in
// camera coordinates.
//
// Only Eigen and std types cross this header (OpenCV stays in cpp/src).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "safenav/lanbloc.hpp"
#include "safenav/stereo.hpp"
#include "safenav/world.hpp"

namespace safenav {

/// What stays fixed across a renderer's frames: the rig, the textures and
/// the boards' mip pyramids.  validate() names the field at fault.
struct RenderScene {
  // --- the rig (safenav.vision.rig.StereoRig): pinhole, the pixel centres at integers
  double f = 350.0, cx = 319.5, cy = 239.5;  ///< [px]
  int width = 640, height = 480;              ///< [px]
  double camera_height_m = 1.5;               ///< camera centres above the ground [m]
  double pitch_rad = 0.0;                     ///< positive looks up
  // --- textures
  Image ground;                ///< periodic ground tile (grey), ground_res_m per texel
  double ground_res_m = 0.02;  ///< [m]
  Image panorama;              ///< background at infinity (grey): azimuth over its width, elevation down its height
  double pano_el_min = -0.35, pano_el_max = 0.9;  ///< elevations at its bottom and top rows [rad]
  double haze_m = 80.0;        ///< the ground's contrast falls as exp(−Z / haze_m)
  double pole_grey = 70.0;     ///< grey level of the poles
  /// σ [px] of the optics' point spread, applied to the boards (σ/2^L at
  /// level L; none below 0.25 px): an edge ramps over ~2 px at any size, as
  /// in a camera, so that refined corners do not lock to the pixel grid.
  double psf_sigma_px = 0.8;
  /// landmark id → its board's mip levels, smallest first, each square with
  /// two channels (grey, alpha).
  std::map<int, std::vector<Image>> boards;

  void validate() const;
};

/// One board in a camera's view: its id, its corners (TL, TR, BR, BL of the
/// board, quiet zone included) in camera coordinates (x right, y down, z
/// forward) [m], its pole's quad when wholly in front of the camera, and the
/// full-resolution pixels [x0, x1) × [y0, y1) that drawing both can touch.
struct RenderBoard {
  int id = 0;
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> corners = Eigen::Matrix<double, 4, 3, Eigen::RowMajor>::Zero();
  bool has_pole = false;
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> pole = Eigen::Matrix<double, 4, 3, Eigen::RowMajor>::Zero();
  std::array<int, 4> box{0, 0, 0, 0};
};

/// One camera at one pose: the heading θ, the world → camera rotation R
/// (rows: right, down, forward), the camera centre C [m], and its boards far
/// first (painter's order).
struct RenderView {
  double theta = 0.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  std::vector<RenderBoard> boards;
};

/// Pixel noise of a trial: a tile of side `side` of N(0, σ²) draws from
/// `seed` (the core's generator).  A frame's level-L pixel at full-resolution
/// (X, Y) reads it at ((X mod S)/2^L, (Y mod S)/2^L), S = side·2^L, from the
/// offset of its block (X div S, Y div S), which a hash of the frame's seed,
/// the image, the level and the block gives: a pixel's noise does not depend
/// on what was drawn before it.
struct RenderNoise {
  RenderNoise(double sigma, std::uint64_t seed, int side = 1024);
  double sigma;
  int side;
  std::vector<float> tile;  ///< (2·side)², the tile repeated 2 × 2 (any window up to side is one slice)
};

class RenderedFrame;

/// The renderer of one scene: its textures as images, and the panorama
/// coordinates of the image's pixels (computed once: a renderer serves every
/// trial of its scene).  Immutable; frames share it.
class PixelRenderer {
 public:
  explicit PixelRenderer(RenderScene scene);  ///< std::invalid_argument from scene.validate()
  ~PixelRenderer();
  PixelRenderer(const PixelRenderer&) = delete;
  PixelRenderer& operator=(const PixelRenderer&) = delete;
  const RenderScene& scene() const;

 private:
  friend class RenderedFrame;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The pair of one frame as StereoPixels (draw() as the class says; the
/// pixel noise from `noise_seed`, see RenderNoise).
class RenderedFrame final : public StereoPixels {
 public:
  /// `noise` may be null (no pixel noise).  std::invalid_argument on a null
  /// renderer or a board whose id has no pyramid in the scene.
  RenderedFrame(std::shared_ptr<const PixelRenderer> renderer, std::shared_ptr<const RenderNoise> noise,
                RenderView left, RenderView right, std::uint64_t noise_seed);
  ~RenderedFrame() override;
  void draw(bool right, int level, int x0, int y0, int width, int height, std::uint8_t* out,
            std::ptrdiff_t stride) const override;
  long draws() const;   ///< boxes drawn so far
  long pixels() const;  ///< their pixels

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A landmark's board for the simulated camera: its id (a pyramid of the
/// scene's), its marker's centre (x, y east/north, height) [m], and the yaw
/// its face points to [rad] (NaN: it turns to face the camera).
struct CameraBoard {
  int id = 0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double yaw = std::numeric_limits<double>::quiet_NaN();
};

/// The simulated rig's geometry beyond the scene's camera.
struct SimulatedCameraSettings {
  double baseline_m = 0.3;     ///< the right camera sits this far to the left camera's right
  double max_range_m = 30.0;   ///< boards farther (3D, from the left camera) are not drawn
  double near_m = 0.2;         ///< near clipping depth
  double board_half_m = 1.0;   ///< half the board's side (marker and quiet zone)
  double pole_width_m = 0.08;  ///< the pole under each board

  void validate() const;
};

/// The simulator's stereo camera (ours; safenav.vision.render.StereoRenderer's
/// geometry): at a vehicle pose (x, y, θ) — the left camera's centre, the
/// right one baseline_m to its right, both at the scene's height and pitch —
/// the boards within max_range_m and the horizontal field of view (plus the
/// board's and the baseline's angular slack), each facing the camera's
/// midpoint or at its yaw (seen from behind: not drawn), hidden from a camera
/// whose centre an obstacle blocks (ObstacleChecker::visible_from, the
/// measurement model's and placement's line of sight; per board, not per
/// pixel), in painter's order.  Immutable: one camera serves every trial.
class SimulatedCamera {
 public:
  /// `occlusion`: the world's obstacles (none: nothing is hidden).
  /// std::invalid_argument on a null renderer, bad settings or a board without a pyramid.
  SimulatedCamera(std::shared_ptr<const PixelRenderer> renderer, std::vector<CameraBoard> boards,
                  const SimulatedCameraSettings& settings, std::optional<ObstacleChecker> occlusion);
  /// The cameras' views at `pose` (left, right).
  std::array<RenderView, 2> views(const Eigen::Vector3d& pose) const;
  /// Boards whose centre projects into the left image and that no obstacle
  /// hides: a bound on the whole markers a detector can find there.
  int centres_in_view(const Eigen::Vector3d& pose) const;
  /// The frame at `pose` drawn on demand (noise may be null).
  std::shared_ptr<RenderedFrame> frame(const Eigen::Vector3d& pose, std::shared_ptr<const RenderNoise> noise,
                                       std::uint64_t noise_seed) const;
  const std::shared_ptr<const PixelRenderer>& renderer() const { return renderer_; }

 private:
  std::vector<int> culled(const Eigen::Vector3d& pose) const;
  std::shared_ptr<const PixelRenderer> renderer_;
  std::vector<CameraBoard> boards_;
  SimulatedCameraSettings settings_;
  std::optional<ObstacleChecker> occlusion_;
};

}  // namespace safenav
