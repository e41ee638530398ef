// The simulator's stereo pixels (safenav/render.hpp; safenav.vision.render
// draws through it): background, ground, boards and noise of any box of a
// view at any pyramid level.
#include "safenav/render.hpp"
#include "safenav/seed.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "errors.hpp"
#include "render_kernels.hpp"
#include "rng.hpp"
#include "safenav/types.hpp"

namespace safenav {

namespace {

using Quad = Eigen::Matrix<double, 4, 3, Eigen::RowMajor>;

cv::Mat as_mat(const Image& im) {
  return cv::Mat(im.rows, im.cols, CV_8UC(im.channels), const_cast<std::uint8_t*>(im.data.data()));
}

/// A pinhole view of a box: focal f and principal point (cx, cy) in the box's own pixels, and the
/// full-resolution pixels [x0, x1) × [y0, y1) it covers at 2^level pixels per side.
struct View {
  double f, cx, cy;
  int level, x0, y0, x1, y1;
};

/// World-up component of row v's ray (camera z = 1) at the scene's pitch.
double ray_up(const RenderScene& s, const View& v, double row) {
  return -std::cos(s.pitch_rad) * (row - v.cy) / v.f + std::sin(s.pitch_rad);
}

}  // namespace

void RenderScene::validate() const {
  detail::require_finite_positive(f, "scene.f");
  if (!std::isfinite(cx) || !std::isfinite(cy)) detail::bad("scene.cx, cy = " + detail::num(cx) + ", " +
                                                            detail::num(cy) + ": must be finite");
  if (width < 1 || height < 1)
    detail::bad("scene image " + std::to_string(width) + "x" + std::to_string(height) + ": must not be empty");
  detail::require_finite_positive(camera_height_m, "scene.camera_height_m");
  if (!(std::abs(pitch_rad) < 0.5)) detail::bad("scene.pitch_rad = " + detail::num(pitch_rad) + ": |pitch| < 0.5");
  detail::require_finite_positive(ground_res_m, "scene.ground_res_m");
  detail::require_finite_positive(haze_m, "scene.haze_m");
  if (!(pano_el_max > pano_el_min)) detail::bad("scene.pano_el_max must exceed pano_el_min");
  for (const auto& [name, im] : {std::pair<const char*, const Image*>{"ground", &ground}, {"panorama", &panorama}})
    if (im->rows < 2 || im->cols < 2 || im->channels != 1 ||
        im->data.size() != std::size_t(im->rows) * std::size_t(im->cols))
      detail::bad(std::string("scene.") + name + ": must be a grey image of at least 2x2 px");
  for (const auto& [id, pyr] : boards) {
    if (pyr.empty()) detail::bad("scene.boards[" + std::to_string(id) + "]: no mip levels");
    for (const Image& im : pyr)
      if (im.rows < 1 || im.rows != im.cols || im.channels != 2 ||
          im.data.size() != std::size_t(im.rows) * std::size_t(im.cols) * 2)
        detail::bad("scene.boards[" + std::to_string(id) + "]: each level must be square with 2 channels");
  }
}

RenderNoise::RenderNoise(double sigma_, std::uint64_t seed, int side_) : sigma(sigma_), side(side_) {
  detail::require_finite_nonneg(sigma, "noise sigma");
  if (side < 1 || side > 8192) detail::bad("noise tile side = " + std::to_string(side) + ": must be in [1, 8192]");
  detail::Rng rng(seed);
  const std::size_t n = std::size_t(side), m = 2 * n;
  tile.resize(m * m);
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = 0; c < n; ++c) {
      const float v = static_cast<float>(rng.normal() * sigma);
      for (std::size_t a : {r, r + n})
        for (std::size_t b : {c, c + n}) tile[a * m + b] = v;
    }
}

/// The renderer of one scene: its textures and boards as OpenCV images, and the panorama
/// coordinates (at heading 0) of the image's rows down to the lowest any view's background needs.
struct PixelRenderer::Impl {
  RenderScene scene;
  cv::Mat ground;
  // Per pyramid level L (up to kLevels − 1): the ground tile and the panorama averaged 2^L times
  // (INTER_AREA), so that a view at level L samples textures prefiltered to its pixel size, as
  // the average of the full-resolution pixels would be; the ground tile repeated 3 × 3.
  static constexpr int kLevels = 7;
  std::vector<cv::Mat> ground3, pano;
  float ground_mean = 0.0f;
  std::map<int, std::vector<cv::Mat>> boards;
  cv::Mat map_x, map_y;  // CV_32F, rows [0, map rows) × the image's columns
  cv::Mat map_xy;        // the two as one CV_32FC2 (one remap samples both at the same weights)
  // The maps at the centres of the level-L pixels of boxes on the 2^L grid (index L, 1 ≤ L < 5):
  // what background() would sample from map_x and map_y for such a box, computed once.
  static constexpr int kMapLevels = 5;
  std::vector<cv::Mat> level_map_x, level_map_y;

  explicit Impl(RenderScene s) : scene(std::move(s)) {
    scene.validate();
    ground = as_mat(scene.ground);
    cv::Mat g = ground, p = as_mat(scene.panorama);
    for (int L = 0; L < kLevels; ++L) {
      ground3.emplace_back();
      cv::repeat(g, 3, 3, ground3.back());
      pano.push_back(p);
      if (g.cols < 4 || p.cols < 4 || p.rows < 4) break;
      cv::Mat gs, ps;
      cv::resize(g, gs, cv::Size(g.cols / 2, g.rows / 2), 0, 0, cv::INTER_AREA);
      cv::resize(p, ps, cv::Size(p.cols / 2, p.rows / 2), 0, 0, cv::INTER_AREA);
      g = gs, p = ps;
    }
    ground_mean = static_cast<float>(cv::mean(ground)[0]);
    for (const auto& [id, pyr] : scene.boards)
      for (const Image& im : pyr) boards[id].push_back(as_mat(im));
    maps();
  }

  /// Panorama x (azimuth) and y (elevation) of pixel (u, v), for the rows above the ground and the
  /// 2 + 2·64 rows below the first ground row that a level view's background may sample.
  void maps() {
    const RenderScene& s = scene;
    const View full{s.f, s.cx, s.cy, 0, 0, 0, s.width, s.height};
    int v_ground = s.height;
    for (int v = 0; v < s.height; ++v)
      if (ray_up(s, full, v) < -s.camera_height_m / 2000.0) {
        v_ground = v;
        break;
      }
    const int rows = std::min(s.height, v_ground + 2 + 130);
    map_x.create(rows, s.width, CV_32F);
    map_y.create(rows, s.width, CV_32F);
    const double cp = std::cos(s.pitch_rad), sp = std::sin(s.pitch_rad);
    const double pw = s.panorama.cols, ph = s.panorama.rows;
    for (int v = 0; v < rows; ++v) {
      // the ray R0ᵀ((u − cx)/f, (v − cy)/f, 1) at heading 0: x and z from the row, y from the column
      const double yn = (v - s.cy) / s.f, rx = yn * sp + cp, rz = sp - yn * cp;
      float* mx = map_x.ptr<float>(v);
      float* my = map_y.ptr<float>(v);
      for (int u = 0; u < s.width; ++u) {
        const double ry = -(u - s.cx) / s.f;
        const double az = std::atan2(ry, rx), el = std::atan2(rz, std::hypot(rx, ry));
        mx[u] = static_cast<float>(-az / (2.0 * kPi) * pw);
        my[u] = static_cast<float>(std::clamp((s.pano_el_max - el) / (s.pano_el_max - s.pano_el_min) * (ph - 1),
                                              0.0, ph - 1));
      }
    }
    cv::merge(std::vector<cv::Mat>{map_x, map_y}, map_xy);
    level_map_x.resize(kMapLevels);
    level_map_y.resize(kMapLevels);
    for (int L = 1; L < kMapLevels; ++L) {
      const int k = 1 << L;
      sample_maps(0, 0, k, (s.width + k - 1) / k, (rows + k - 1) / k + 1, level_map_x[L], level_map_y[L]);
    }
  }

  /// map_x and map_y sampled (bilinear) at the centres of a w × rows box of level pixels 2^L = k
  /// full-resolution pixels a side, the box's top-left at full-resolution (x0, y0).
  void sample_maps(int x0, int y0, int k, int w, int rows, cv::Mat& mx, cv::Mat& my) const {
    cv::Mat cu(rows, w, CV_32F), cv_(rows, w, CV_32F);
    for (int j = 0; j < rows; ++j) {
      float* u = cu.ptr<float>(j);
      float* vv = cv_.ptr<float>(j);
      const float y = static_cast<float>(y0 + (j + 0.5) * k - 0.5);
      for (int i = 0; i < w; ++i) {
        u[i] = static_cast<float>(x0 + (i + 0.5) * k - 0.5);
        vv[i] = y;
      }
    }
    cv::Mat xy;
    cv::remap(map_xy, xy, cu, cv_, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    std::vector<cv::Mat> ch;
    cv::split(xy, ch);
    mx = ch[0];
    my = ch[1];
  }

  void background(const RenderView& rv, const View& v, int rows, cv::Mat& img) const;
  void ground_rows(const RenderView& rv, const View& v, int v_ground, cv::Mat& img) const;
  void paint(const RenderView& rv, const View& v, cv::Mat& img) const;
};

PixelRenderer::PixelRenderer(RenderScene scene) : impl_(std::make_unique<Impl>(std::move(scene))) {}
PixelRenderer::~PixelRenderer() = default;
const RenderScene& PixelRenderer::scene() const { return impl_->scene; }

void PixelRenderer::Impl::background(const RenderView& rv, const View& v, int rows, cv::Mat& img) const {
  // The background at infinity: the panorama at the pixel's azimuth relative to the heading.
  const int w = img.cols, k = 1 << v.level;
  cv::Mat mx, my;  // the box's panorama coordinates: copied from a level's maps or sampled (both allocate)
  // A box on its level's grid reads the level's maps (the same samples); any other box samples
  // the full-resolution maps at its level pixels' centres (smooth: bilinear).
  const bool on_grid = v.level < kMapLevels && v.x0 % k == 0 && v.y0 % k == 0;
  const cv::Mat& sx = on_grid ? (v.level == 0 ? map_x : level_map_x[std::size_t(v.level)]) : map_x;
  const cv::Mat& sy = on_grid ? (v.level == 0 ? map_y : level_map_y[std::size_t(v.level)]) : map_y;
  if (on_grid && v.y0 / k + rows <= sx.rows && v.x0 / k + w <= sx.cols) {
    sx(cv::Rect(v.x0 / k, v.y0 / k, w, rows)).copyTo(mx);
    sy(cv::Rect(v.x0 / k, v.y0 / k, w, rows)).copyTo(my);
  } else {
    sample_maps(v.x0, v.y0, k, w, rows, mx, my);
  }
  // The heading shifts the azimuth; the column is wrapped into [0, pw) here, so that remap reads
  // inside the panorama (its BORDER_WRAP path costs a border lookup per pixel).
  // At level L the panorama's level min(L, its levels) is read: texel i of level l is centred on
  // level-0 texel (i + 0.5)·2^l − 0.5.
  const int l = std::min<int>(v.level, int(pano.size()) - 1);
  const cv::Mat& tex = pano[std::size_t(l)];
  const double pw = scene.panorama.cols;
  const float shift = static_cast<float>(std::fmod(std::fmod(-rv.theta / (2.0 * kPi) * pw, pw) + pw, pw));
  const float fpw = static_cast<float>(pw), a = 1.0f / float(1 << l), b = 0.5f * a - 0.5f;
  const float fw = static_cast<float>(tex.cols);
  for (int j = 0; j < rows; ++j) render_detail::pano_row(mx.ptr<float>(j), my.ptr<float>(j), w, shift, fpw, a, b, fw);
  cv::Mat dst = img.rowRange(0, rows);
  cv::remap(tex, dst, mx, my, cv::INTER_LINEAR, cv::BORDER_WRAP);
}

void PixelRenderer::Impl::ground_rows(const RenderView& rv, const View& v, int v_ground, cv::Mat& img) const {
  // The ground plane through H = K [r₁ r₂ −R·C] A (texel → pixel), rows from v_ground, faded into
  // haze with the row's depth.
  const RenderScene& s = scene;
  // The texture is periodic: its origin is moved by whole periods so that the box's middle ground
  // pixel reads the middle tile of the 3 × 3 tiled texture, and nearby pixels read inside it
  // (warpPerspective's BORDER_WRAP path costs a border lookup per pixel outside).
  // At level L the ground's level min(L, its levels) is read, each texel res·2^l a side.
  const int l = std::min<int>(v.level, int(ground3.size()) - 1);
  const int n = s.ground.cols;
  const double period = n * s.ground_res_m, res = s.ground_res_m * (1 << l);
  Eigen::Matrix3d K, P, T;
  K << v.f, 0, v.cx, 0, v.f, v.cy, 0, 0, 1;
  P.col(0) = rv.R.col(0);
  P.col(1) = rv.R.col(1);
  P.col(2) = -rv.R * rv.centre;
  T << 1, 0, 0, 0, 1, -v_ground, 0, 0, 1;
  const Eigen::Matrix3d G = (T * K * P).inverse();  // pixel (rows from v_ground) → ground (x, y) [m]
  const Eigen::Vector3d mid = G * Eigen::Vector3d(0.5 * (img.cols - 1), 0.5 * (img.rows - 1 - v_ground), 1.0);
  const double mx = mid.x() / mid.z(), my = mid.y() / mid.z();
  const double X0 = (std::floor(mx / period) - 1.0) * period, Y0 = (std::floor(my / period) - 1.0) * period;
  Eigen::Matrix3d Ainv;  // ground [m] → texel of the tiled texture
  // ground [m] → texel of level l: level-0 texel j sits at X0 + j·res₀, and level-l texel i is the
  // mean of level-0 texels [i·2^l, (i + 1)·2^l), centred on X0 + (i + 0.5)·res − 0.5·res₀
  const double h0 = 0.5 * s.ground_res_m;
  Ainv << 1.0 / res, 0, (h0 - X0) / res - 0.5, 0, 1.0 / res, (h0 - Y0) / res - 0.5, 0, 0, 1;
  const Eigen::Matrix3d Hinv = Ainv * G;  // pixel (rows from v_ground) → texel
  cv::Matx33d M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M(r, c) = Hinv(r, c);
  cv::Mat g;
  cv::warpPerspective(ground3[std::size_t(l)], g, M, cv::Size(img.cols, img.rows - v_ground),
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_WRAP);
  const float m = ground_mean;
  for (int j = v_ground; j < img.rows; ++j) {
    const double t = s.camera_height_m / std::max(-ray_up(s, v, j), 1e-12);  // the row's camera depth
    const float haze = static_cast<float>(std::exp(-t / s.haze_m));
    render_detail::haze_run(g.ptr<std::uint8_t>(j - v_ground), img.ptr<std::uint8_t>(j), m, haze, img.cols);
  }
}

namespace {

/// A board's mip level just below its size on screen (magnified by 1-2×, so bilinear keeps each
/// edge's ramp symmetric about the true edge), warped into `img` at corners `uv` with its alpha,
/// blurred by the optics' point spread σ = psf (px of this view; none below 0.25 px).  Without the
/// blur an edge magnified ~1× ramps over about a pixel and the refined corners lock to the pixel
/// grid: their disparity error was 0.084 px (RMS) on boards magnified 1.0–1.1× against 0.030 px at
/// 1.6–1.9× in the camera loop's frames.
void warp_board(cv::Mat& img, const std::vector<cv::Mat>& pyr, const Eigen::Matrix<double, 4, 2>& uv, double psf) {
  const bool blur = psf >= 0.25;
  const int pad = blur ? int(std::ceil(3.0 * psf)) : 0;  // the blur's reach
  const Eigen::Vector2d lo = uv.colwise().minCoeff(), hi = uv.colwise().maxCoeff();
  // The board warped over [wx0, wx1) × [wy0, wy1): its box, and for the blur `pad` px more, also
  // beyond the image's edges (a box cut through a board blurs as the whole image would there);
  // drawn into [bx0, bx1) × [by0, by1).
  const int wx0 = std::max(int(std::floor(lo.x())) - 1 - pad, -pad), wy0 = std::max(int(std::floor(lo.y())) - 1 - pad, -pad);
  const int wx1 = std::min(int(std::ceil(hi.x())) + 2 + pad, img.cols + pad);
  const int wy1 = std::min(int(std::ceil(hi.y())) + 2 + pad, img.rows + pad);
  const int bx0 = std::max(wx0, 0), by0 = std::max(wy0, 0), bx1 = std::min(wx1, img.cols), by1 = std::min(wy1, img.rows);
  if (bx1 <= bx0 || by1 <= by0) return;
  double side = 0.0;
  for (int k = 0; k < 4; ++k) side = std::max(side, (uv.row(k) - uv.row((k + 3) % 4)).norm());
  const cv::Mat* tex = &pyr.front();
  for (auto it = pyr.rbegin(); it != pyr.rend(); ++it)
    if (it->rows <= side) {
      tex = &*it;
      break;
    }
  const float s = float(tex->rows);
  const cv::Point2f src[4] = {{-0.5f, -0.5f}, {s - 0.5f, -0.5f}, {s - 0.5f, s - 0.5f}, {-0.5f, s - 0.5f}};
  cv::Point2f dst[4];
  for (int k = 0; k < 4; ++k) dst[k] = cv::Point2f(float(uv(k, 0) - wx0), float(uv(k, 1) - wy0));
  cv::Mat warped;
  cv::warpPerspective(*tex, warped, cv::getPerspectiveTransform(src, dst), cv::Size(wx1 - wx0, wy1 - wy0),
                      cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0, 0));
  const float inv255 = static_cast<float>(1.0 / 255.0);
  if (!blur) {
    for (int y = by0; y < by1; ++y) {
      const cv::Vec2b* wp = warped.ptr<cv::Vec2b>(y - wy0) + (bx0 - wx0);
      std::uint8_t* p = img.ptr<std::uint8_t>(y) + bx0;
      for (int x = 0; x < bx1 - bx0; ++x) {
        const float a = float(wp[x][1]) * inv255, r = float(p[x]);
        p[x] = static_cast<std::uint8_t>(r + (float(wp[x][0]) - r) * a + 0.5f);
      }
    }
    return;
  }
  // Premultiplied (grey·alpha, alpha) blurred together, so the board's edge blends into what is
  // behind it as the optics blur it.
  cv::Mat pm(warped.rows, warped.cols, CV_32FC2);
  for (int y = 0; y < warped.rows; ++y) {
    const cv::Vec2b* wp = warped.ptr<cv::Vec2b>(y);
    cv::Vec2f* q = pm.ptr<cv::Vec2f>(y);
    for (int x = 0; x < warped.cols; ++x) {
      const float a = float(wp[x][1]) * inv255;
      q[x] = cv::Vec2f(float(wp[x][0]) * a, a);
    }
  }
  cv::GaussianBlur(pm, pm, cv::Size(0, 0), psf, psf, cv::BORDER_CONSTANT);
  for (int y = by0; y < by1; ++y) {
    const cv::Vec2f* q = pm.ptr<cv::Vec2f>(y - wy0) + (bx0 - wx0);
    std::uint8_t* p = img.ptr<std::uint8_t>(y) + bx0;
    for (int x = 0; x < bx1 - bx0; ++x) p[x] = cv::saturate_cast<std::uint8_t>(float(p[x]) * (1.0f - q[x][1]) + q[x][0]);
  }
}

}  // namespace

void PixelRenderer::Impl::paint(const RenderView& rv, const View& v, cv::Mat& img) const {
  auto project = [&](const Quad& q) {
    Eigen::Matrix<double, 4, 2> uv;
    for (int k = 0; k < 4; ++k) uv.row(k) << v.f * q(k, 0) / q(k, 2) + v.cx, v.f * q(k, 1) / q(k, 2) + v.cy;
    return uv;
  };
  for (const RenderBoard& b : rv.boards) {
    if (!(b.box[0] < v.x1 && v.x0 < b.box[2] && b.box[1] < v.y1 && v.y0 < b.box[3])) continue;
    if (b.has_pole) {
      const Eigen::Matrix<double, 4, 2> uv = project(b.pole);
      cv::Point pts[4];
      for (int k = 0; k < 4; ++k) pts[k] = cv::Point(int(std::lround(uv(k, 0) * 16)), int(std::lround(uv(k, 1) * 16)));
      cv::fillConvexPoly(img, pts, 4, cv::Scalar(scene.pole_grey), cv::LINE_AA, 4);
    }
    warp_board(img, boards.at(b.id), project(b.corners), scene.psf_sigma_px / (1 << v.level));
  }
}

struct RenderedFrame::Impl {
  std::shared_ptr<const PixelRenderer> renderer;
  std::shared_ptr<const RenderNoise> noise;
  RenderView views[2];
  std::uint64_t seed;
  mutable long draws = 0, pixels = 0;
  Impl(std::shared_ptr<const PixelRenderer> r, std::shared_ptr<const RenderNoise> n, RenderView l, RenderView rt,
       std::uint64_t seed_)
      : renderer(std::move(r)), noise(std::move(n)), views{std::move(l), std::move(rt)}, seed(seed_) {}

  /// N(0, (σ/2^L)²) added to a level-L box at full-resolution (x0, y0), rounded to the nearest grey
  /// level and saturated.  A pixel's noise is a function of the frame, the image, the level and
  /// where the pixel is, not of which boxes were drawn before: the level-L pixel at full-resolution
  /// (X, Y) reads the noise tile at ((X mod S)/2^L, (Y mod S)/2^L) from the offset of its block
  /// (X div S, Y div S), S = side·2^L, which a hash of (frame seed, image, level, block) gives.
  void add_noise(cv::Mat& img, bool right, int level, int x0, int y0) const {
    const int n = noise->side, m = 2 * n, k = 1 << level;
    const long long span = static_cast<long long>(n) * k;
    const float scale = 1.0f / float(k);
    const std::uint64_t image_seed = derive_seed(seed, (right ? 64u : 0u) + std::uint64_t(level));
    for (int j = 0; j < img.rows; ++j) {
      const long long Y = y0 + static_cast<long long>(j) * k, by = Y / span;
      const int ty = int((Y % span) / k);
      std::uint8_t* p = img.ptr<std::uint8_t>(j);
      for (int i = 0; i < img.cols;) {
        const long long X = x0 + static_cast<long long>(i) * k, bx = X / span;
        const int tx = int((X % span) / k), run = std::min(img.cols - i, n - tx);
        const std::uint64_t h = derive_seed(image_seed, (std::uint64_t(bx) << 32) ^ std::uint64_t(by));
        const int r0 = int((h & 0xffffffffu) % std::uint64_t(n)), c0 = int((h >> 32) % std::uint64_t(n));
        const float* t = noise->tile.data() + std::size_t(r0 + ty) * std::size_t(m) + std::size_t(c0 + tx);
        render_detail::add_noise_run(p + i, t, scale, run);
        i += run;
      }
    }
  }
};

RenderedFrame::RenderedFrame(std::shared_ptr<const PixelRenderer> renderer, std::shared_ptr<const RenderNoise> noise,
                             RenderView left, RenderView right, std::uint64_t noise_seed) {
  if (!renderer) detail::bad("RenderedFrame: renderer is null");
  for (const RenderView* v : {&left, &right})
    for (const RenderBoard& b : v->boards)
      if (!renderer->scene().boards.count(b.id))
        detail::bad("RenderedFrame: board " + std::to_string(b.id) + " has no mip pyramid in the scene");
  impl_ = std::make_unique<Impl>(std::move(renderer), std::move(noise), std::move(left), std::move(right), noise_seed);
}

RenderedFrame::~RenderedFrame() = default;
long RenderedFrame::draws() const { return impl_->draws; }
long RenderedFrame::pixels() const { return impl_->pixels; }

void RenderedFrame::draw(bool right, int level, int x0, int y0, int width, int height, std::uint8_t* out,
                         std::ptrdiff_t stride) const {
  const PixelRenderer::Impl& R = *impl_->renderer->impl_;
  const RenderScene& s = R.scene;
  if (level < 0 || level > 16 || width < 1 || height < 1 || x0 < 0 || y0 < 0 ||
      x0 + (std::int64_t(width) << level) > s.width || y0 + (std::int64_t(height) << level) > s.height)
    detail::bad("draw: level " + std::to_string(level) + " box of " + std::to_string(width) + "x" +
                std::to_string(height) + " at (" + std::to_string(x0) + ", " + std::to_string(y0) +
                ") is not inside the " + std::to_string(s.width) + "x" + std::to_string(s.height) + " image");
  const int k = 1 << level;
  const View v{s.f / k, (s.cx - x0 + 0.5) / k - 0.5, (s.cy - y0 + 0.5) / k - 0.5, level, x0, y0, x0 + width * k,
               y0 + height * k};
  const RenderView& rv = impl_->views[right ? 1 : 0];
  cv::Mat img(height, width, CV_8UC1, out, static_cast<std::size_t>(stride));
  int v_ground = height;
  for (int j = 0; j < height; ++j)
    if (ray_up(s, v, j) < -s.camera_height_m / 2000.0) {
      v_ground = j;
      break;
    }
  const int rows = std::min(v_ground + 2, height);
  if (rows > 0) R.background(rv, v, rows, img);
  if (v_ground < height) R.ground_rows(rv, v, v_ground, img);
  R.paint(rv, v, img);
  if (impl_->noise && impl_->noise->sigma > 0) impl_->add_noise(img, right, level, x0, y0);
  ++impl_->draws;
  impl_->pixels += long(width) * height;
}

}  // namespace safenav
