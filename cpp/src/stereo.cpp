#include "safenav/stereo.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "declare.hpp"

namespace safenav {

template <>
const ParamSet<BoxRangeOptions>& param_set<BoxRangeOptions>();  // defined below

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument(msg); }

template <class M>
void check_finite(const M& m, const char* what) {
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j)
      if (!std::isfinite(m(i, j))) {
        std::ostringstream os;
        os << "calibration " << what << "[" << i;
        if (m.cols() > 1) os << ", " << j;
        os << "] = " << m(i, j) << " is not finite";
        fail(os.str());
      }
}

void check_intrinsics(const Eigen::Matrix3d& K, const char* what) {
  check_finite(K, what);
  std::ostringstream os;
  if (!(K(0, 0) > 0.0 && K(1, 1) > 0.0))
    os << "calibration " << what << " focal lengths (" << K(0, 0) << ", " << K(1, 1) << ") must be > 0";
  else if (K(1, 0) != 0.0 || K(2, 0) != 0.0 || K(2, 1) != 0.0 || K(2, 2) != 1.0)
    os << "calibration " << what << " must be upper triangular with K[2, 2] = 1, got\n" << K;
  if (!os.str().empty()) fail(os.str());
}

void check_distortion(const Eigen::VectorXd& D, const char* what) {
  const auto n = D.size();
  if (!(n == 0 || n == 4 || n == 5 || n == 8 || n == 12 || n == 14)) {
    std::ostringstream os;
    os << "calibration " << what << " has " << n << " coefficients; OpenCV takes 0, 4, 5, 8, 12 or 14";
    fail(os.str());
  }
  check_finite(D, what);
}

cv::Mat to_cv(const ImageView& v) {
  const int type = v.channels == 1 ? CV_8UC1 : (v.channels == 3 ? CV_8UC3 : CV_8UC4);
  const std::size_t step = v.row_stride > 0 ? static_cast<std::size_t>(v.row_stride) : static_cast<std::size_t>(cv::Mat::AUTO_STEP);
  return cv::Mat(v.rows, v.cols, type, const_cast<std::uint8_t*>(v.data), step);
}

void check_view(const ImageView& v, const char* what) {
  std::ostringstream os;
  if (v.data == nullptr || v.rows <= 0 || v.cols <= 0)
    os << what << " image is empty (" << v.rows << "x" << v.cols << ")";
  else if (!(v.channels == 1 || v.channels == 3 || v.channels == 4))
    os << what << " image has " << v.channels << " channels; 1, 3 or 4 are supported";
  else if (v.row_stride != 0 && v.row_stride < static_cast<std::ptrdiff_t>(v.cols) * v.channels)
    os << what << " image row stride " << v.row_stride << " is shorter than a row";
  if (!os.str().empty()) fail(os.str());
}

void check_pair(const ImageView& l, const ImageView& r, int width, int height) {
  check_view(l, "left");
  check_view(r, "right");
  std::ostringstream os;
  if (l.rows != r.rows || l.cols != r.cols || l.channels != r.channels)
    os << "left and right images differ: " << l.cols << "x" << l.rows << "x" << l.channels << " vs " << r.cols << "x"
       << r.rows << "x" << r.channels << " (width x height x channels)";
  else if (width > 0 && (l.cols != width || l.rows != height))
    os << "image size " << l.cols << "x" << l.rows << " does not match the calibration's " << width << "x" << height;
  if (!os.str().empty()) fail(os.str());
}

Image from_cv(const cv::Mat& m) {
  Image out;
  out.rows = m.rows;
  out.cols = m.cols;
  out.channels = m.channels();
  const std::size_t row_bytes = static_cast<std::size_t>(m.cols) * m.elemSize();
  out.data.resize(row_bytes * m.rows);
  for (int r = 0; r < m.rows; ++r) std::copy_n(m.ptr<std::uint8_t>(r), row_bytes, out.data.data() + r * row_bytes);
  return out;
}

}  // namespace

// --------------------------------------------------------------------------
// validation
// --------------------------------------------------------------------------

void StereoCalibration::validate() const {
  check_intrinsics(K1, "K1");
  check_intrinsics(K2, "K2");
  check_distortion(D1, "D1");
  check_distortion(D2, "D2");
  check_finite(R, "R");
  check_finite(T, "T");
  std::ostringstream os;
  const double ortho = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (ortho > 1e-6 || R.determinant() <= 0.0)
    os << "calibration R is not a rotation (|RᵀR − I| = " << ortho << ", det = " << R.determinant() << ")";
  else if (!(T.norm() > 0.0))
    os << "calibration T = (" << T.transpose() << ") has zero baseline";
  else if (std::abs(T.x()) <= std::abs(T.y()))
    os << "calibration T = (" << T.transpose() << "): vertical stereo rigs are not supported (|T[1]| >= |T[0]|)";
  else if (T.x() >= 0.0)
    os << "calibration T[0] = " << T.x()
       << " >= 0: camera 2 is left of camera 1 (X2 = R X1 + T); swap the cameras so that T[0] < 0";
  else if (width <= 0 || height <= 0)
    os << "calibration image_size = (" << width << ", " << height << ") must be positive";
  if (!os.str().empty()) fail(os.str());
}

void RectifiedCamera::validate() const {
  std::ostringstream os;
  if (!(std::isfinite(f) && f > 0.0))
    os << "rectified camera f = " << f << " must be finite and > 0";
  else if (!std::isfinite(cx) || !std::isfinite(cy))
    os << "rectified camera principal point (" << cx << ", " << cy << ") is not finite";
  else if (!(std::isfinite(baseline) && baseline > 0.0))
    os << "rectified camera baseline = " << baseline << " must be finite and > 0";
  else if (!std::isfinite(doffs))
    os << "rectified camera doffs = " << doffs << " is not finite";
  else if (width <= 0 || height <= 0)
    os << "rectified camera image size (" << width << ", " << height << ") must be positive";
  if (!os.str().empty()) fail(os.str());
}

void SgbmParams::validate() const {
  std::ostringstream os;
  if (num_disparities <= 0 || num_disparities % 16 != 0)
    os << "num_disparities = " << num_disparities << " must be a positive multiple of 16";
  else if (block_size < 1 || block_size % 2 == 0)
    os << "block_size = " << block_size << " must be odd and >= 1";
  else if (P1 < 0 || P2 < 0 || (P1 > 0 && P2 > 0 && P2 <= P1))
    os << "P1 = " << P1 << ", P2 = " << P2 << ": need 0 <= P1 < P2 (or 0 for OpenCV's defaults)";
  else if (pre_filter_cap < 0)
    os << "pre_filter_cap = " << pre_filter_cap << " must be >= 0";
  else if (uniqueness_ratio < 0)
    os << "uniqueness_ratio = " << uniqueness_ratio << " must be >= 0";
  else if (speckle_window_size < 0 || speckle_range < 0)
    os << "speckle_window_size = " << speckle_window_size << ", speckle_range = " << speckle_range
       << " must be >= 0";
  else if (static_cast<int>(mode) < 0 || static_cast<int>(mode) > 3)
    os << "mode = " << static_cast<int>(mode) << " is not an SGBM mode";
  if (!os.str().empty()) fail(os.str());
}

SgbmParams disparity_search(const RectifiedCamera& cam, double near_m, double far_m, const SgbmParams& base,
                            int margin_px) {
  cam.validate();
  std::ostringstream os;
  if (!(std::isfinite(near_m) && near_m > 0.0))
    os << "near_m = " << near_m << " must be finite and > 0";
  else if (!(far_m > near_m))
    os << "far_m = " << far_m << " must be > near_m = " << near_m << " (inf for no far limit)";
  else if (margin_px < 0)
    os << "margin_px = " << margin_px << " must be an integer >= 0";
  else if (base.block_size < 1 || base.block_size % 2 == 0)
    os << "block_size = " << base.block_size << " must be odd";
  if (!os.str().empty()) fail(os.str());
  const double fb = cam.f * cam.baseline;
  const double d_far = std::isinf(far_m) ? -cam.doffs : fb / far_m - cam.doffs;
  double d_near = fb / near_m - cam.doffs;
  const double r = std::nearbyint(d_near);  // within round-off of an integer: that integer
  if (std::abs(d_near - r) <= 1e-9 * std::max(1.0, std::abs(d_near))) d_near = r;
  // In doubles: a near depth of 1e-300 m must not overflow an int.
  const double lo = std::floor(d_far) + 0.0, hi = std::ceil(d_near) + margin_px;  // + 0.0: no "-0"
  const double num = std::ceil((hi - lo + 1.0) / 16.0) * 16.0;
  const double columns = cam.width + std::min(lo, 0.0) - std::max(lo + num, 0.0);
  if (!(columns >= base.block_size)) {
    os << "near_m = " << near_m << " needs disparities " << lo << ".." << hi << " px (num_disparities = " << num
       << "), which leaves " << std::max(columns, 0.0) << " of the image's " << cam.width
       << " columns to match (block_size = " << base.block_size << "); raise near_m (f·B = " << fb << ")";
    fail(os.str());
  }
  SgbmParams out = base;
  out.min_disparity = static_cast<int>(lo);
  out.num_disparities = static_cast<int>(num);
  return out;
}

void BoxRangeOptions::validate() const { param_set<BoxRangeOptions>().check(*this); }

// --------------------------------------------------------------------------
// StereoMatcher
// --------------------------------------------------------------------------

struct StereoMatcher::Impl {
  RectifiedCamera cam;
  SgbmParams params;
  bool rectify = false;
  StereoCalibration calib;
  cv::Mat R1, R2, P1, P2, Q;
  cv::Mat map1l, map2l, map1r, map2r;  // CV_16SC2 + CV_16UC1 (fixed point, fast remap)
  mutable cv::Ptr<cv::StereoSGBM> sgbm;
  mutable int sgbm_channels = -1;

  void make_ideal() {
    R1 = cv::Mat::eye(3, 3, CV_64F);
    R2 = cv::Mat::eye(3, 3, CV_64F);
    P1 = (cv::Mat_<double>(3, 4) << cam.f, 0, cam.cx, 0, 0, cam.f, cam.cy, 0, 0, 0, 1, 0);
    P2 = (cv::Mat_<double>(3, 4) << cam.f, 0, cam.cx + cam.doffs, -cam.f * cam.baseline, 0, cam.f, cam.cy, 0, 0, 0, 1,
          0);
    Q = (cv::Mat_<double>(4, 4) << 1, 0, 0, -cam.cx, 0, 1, 0, -cam.cy, 0, 0, 0, cam.f, 0, 0, 1.0 / cam.baseline,
         cam.doffs / cam.baseline);
  }

  cv::StereoSGBM& matcher(int channels) const {
    if (!sgbm || sgbm_channels != channels) {
      const int area = params.block_size * params.block_size;
      const int p1 = params.P1 > 0 ? params.P1 : 8 * channels * area;
      const int p2 = params.P2 > 0 ? params.P2 : 32 * channels * area;
      sgbm = cv::StereoSGBM::create(params.min_disparity, params.num_disparities, params.block_size, p1, p2,
                                    params.disp12_max_diff, params.pre_filter_cap, params.uniqueness_ratio,
                                    params.speckle_window_size, params.speckle_range, static_cast<int>(params.mode));
      sgbm_channels = channels;
    }
    return *sgbm;
  }
};

StereoMatcher::StereoMatcher(const StereoCalibration& calibration, const SgbmParams& params, double alpha)
    : impl_(std::make_unique<Impl>()) {
  calibration.validate();
  params.validate();
  if (!(alpha == -1.0 || (alpha >= 0.0 && alpha <= 1.0))) {
    std::ostringstream os;
    os << "alpha = " << alpha << " must be in [0, 1] (or -1 for OpenCV's default scaling)";
    fail(os.str());
  }
  Impl& s = *impl_;
  s.params = params;
  s.calib = calibration;
  s.rectify = true;
  cv::Mat K1, K2, D1, D2, R, T;
  cv::eigen2cv(calibration.K1, K1);
  cv::eigen2cv(calibration.K2, K2);
  cv::eigen2cv(calibration.R, R);
  cv::eigen2cv(calibration.T, T);
  D1 = calibration.D1.size() ? cv::Mat(1, static_cast<int>(calibration.D1.size()), CV_64F) : cv::Mat();
  D2 = calibration.D2.size() ? cv::Mat(1, static_cast<int>(calibration.D2.size()), CV_64F) : cv::Mat();
  for (int i = 0; i < D1.cols; ++i) D1.at<double>(0, i) = calibration.D1[i];
  for (int i = 0; i < D2.cols; ++i) D2.at<double>(0, i) = calibration.D2[i];
  const cv::Size size(calibration.width, calibration.height);
  cv::stereoRectify(K1, D1, K2, D2, size, R, T, s.R1, s.R2, s.P1, s.P2, s.Q, cv::CALIB_ZERO_DISPARITY, alpha, size);
  const double f = s.P1.at<double>(0, 0);
  if (std::abs(s.P2.at<double>(1, 3)) > std::abs(s.P2.at<double>(0, 3)))
    fail("calibration gives a vertical rectified rig; only horizontal rigs are supported");
  s.cam.f = f;
  s.cam.cx = s.P1.at<double>(0, 2);
  s.cam.cy = s.P1.at<double>(1, 2);
  s.cam.baseline = -s.P2.at<double>(0, 3) / s.P2.at<double>(0, 0);
  s.cam.doffs = s.P2.at<double>(0, 2) - s.P1.at<double>(0, 2);
  s.cam.width = calibration.width;
  s.cam.height = calibration.height;
  s.cam.validate();
  cv::initUndistortRectifyMap(K1, D1, s.R1, s.P1, size, CV_16SC2, s.map1l, s.map2l);
  cv::initUndistortRectifyMap(K2, D2, s.R2, s.P2, size, CV_16SC2, s.map1r, s.map2r);
}

StereoMatcher::StereoMatcher(const RectifiedCamera& camera, const SgbmParams& params)
    : impl_(std::make_unique<Impl>()) {
  camera.validate();
  params.validate();
  impl_->cam = camera;
  impl_->params = params;
  impl_->make_ideal();
}

StereoMatcher::~StereoMatcher() = default;
StereoMatcher::StereoMatcher(StereoMatcher&&) noexcept = default;
StereoMatcher& StereoMatcher::operator=(StereoMatcher&&) noexcept = default;

const RectifiedCamera& StereoMatcher::camera() const { return impl_->cam; }
const SgbmParams& StereoMatcher::params() const { return impl_->params; }
bool StereoMatcher::needs_rectification() const { return impl_->rectify; }

namespace {
template <int R, int C>
Eigen::Matrix<double, R, C> to_eigen(const cv::Mat& m) {
  Eigen::Matrix<double, R, C> e;
  cv::cv2eigen(m, e);
  return e;
}
}  // namespace

Eigen::Matrix3d StereoMatcher::R1() const { return to_eigen<3, 3>(impl_->R1); }
Eigen::Matrix3d StereoMatcher::R2() const { return to_eigen<3, 3>(impl_->R2); }
Eigen::Matrix<double, 3, 4> StereoMatcher::P1() const { return to_eigen<3, 4>(impl_->P1); }
Eigen::Matrix<double, 3, 4> StereoMatcher::P2() const { return to_eigen<3, 4>(impl_->P2); }
Eigen::Matrix4d StereoMatcher::Q() const { return to_eigen<4, 4>(impl_->Q); }

void StereoMatcher::rectify(const ImageView& left, const ImageView& right, Image& left_rect, Image& right_rect) const {
  const Impl& s = *impl_;
  check_pair(left, right, s.cam.width, s.cam.height);
  const cv::Mat l = to_cv(left), r = to_cv(right);
  if (!s.rectify) {
    left_rect = from_cv(l);
    right_rect = from_cv(r);
    return;
  }
  left_rect.rows = right_rect.rows = left.rows;
  left_rect.cols = right_rect.cols = left.cols;
  left_rect.channels = right_rect.channels = left.channels;
  const std::size_t bytes = static_cast<std::size_t>(left.rows) * left.cols * left.channels;
  left_rect.data.resize(bytes);
  right_rect.data.resize(bytes);
  cv::Mat lo(left.rows, left.cols, l.type(), left_rect.data.data());
  cv::Mat ro(right.rows, right.cols, r.type(), right_rect.data.data());
  cv::remap(l, lo, s.map1l, s.map2l, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::remap(r, ro, s.map1r, s.map2r, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
}

namespace {
Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> undistort(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& pts, const Eigen::Matrix3d& K,
    const Eigen::VectorXd& D, const cv::Mat& Rr, const cv::Mat& Pr) {
  if (!pts.allFinite()) fail("points contain non-finite coordinates");
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> out(pts.rows(), 2);
  if (pts.rows() == 0) return out;
  cv::Mat src(static_cast<int>(pts.rows()), 1, CV_64FC2, const_cast<double*>(pts.data()));
  cv::Mat dst(static_cast<int>(pts.rows()), 1, CV_64FC2, out.data());
  cv::Mat Kc, Dc;
  cv::eigen2cv(K, Kc);
  Dc = D.size() ? cv::Mat(1, static_cast<int>(D.size()), CV_64F, const_cast<double*>(D.data())).clone() : cv::Mat();
  cv::undistortPoints(src, dst, Kc, Dc, Rr, Pr);
  return out;
}
}  // namespace

Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> StereoMatcher::rectify_points_left(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& pts) const {
  if (!impl_->rectify) return pts;
  return undistort(pts, impl_->calib.K1, impl_->calib.D1, impl_->R1, impl_->P1);
}

Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> StereoMatcher::rectify_points_right(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>>& pts) const {
  if (!impl_->rectify) return pts;
  return undistort(pts, impl_->calib.K2, impl_->calib.D2, impl_->R2, impl_->P2);
}

DisparityMap StereoMatcher::disparity(const ImageView& left_rect, const ImageView& right_rect) const {
  const Impl& s = *impl_;
  check_pair(left_rect, right_rect, s.cam.width, s.cam.height);
  const cv::Mat l = to_cv(left_rect), r = to_cv(right_rect);
  cv::Mat raw;
  s.matcher(left_rect.channels).compute(l, r, raw);  // CV_16S, disparity·16
  DisparityMap d(raw.rows, raw.cols);
  const int invalid_below = s.params.min_disparity * 16;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int y = 0; y < raw.rows; ++y) {
    const std::int16_t* src = raw.ptr<std::int16_t>(y);
    float* dst = d.data() + static_cast<std::ptrdiff_t>(y) * raw.cols;
    for (int x = 0; x < raw.cols; ++x) dst[x] = src[x] < invalid_below ? nan : src[x] * (1.0f / 16.0f);
  }
  return d;
}

DisparityMap StereoMatcher::depth(const Eigen::Ref<const DisparityMap>& disparity) const {
  const double fb = impl_->cam.f * impl_->cam.baseline;
  const double doffs = impl_->cam.doffs;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  return disparity.unaryExpr([=](float d) {
    const double w = static_cast<double>(d) + doffs;
    return (std::isfinite(d) && w > 0.0) ? static_cast<float>(fb / w) : nan;
  });
}

BoxRange StereoMatcher::box_range(const Eigen::Ref<const DisparityMap>& disparity, const Box& box,
                                  const BoxRangeOptions& options) const {
  options.validate();
  std::ostringstream os;
  if (!(std::isfinite(box.x_min) && std::isfinite(box.y_min) && std::isfinite(box.x_max) && std::isfinite(box.y_max))) {
    os << "box (" << box.x_min << ", " << box.y_min << ", " << box.x_max << ", " << box.y_max << ") is not finite";
    fail(os.str());
  }
  if (!(box.x_max > box.x_min && box.y_max > box.y_min)) {
    os << "box (" << box.x_min << ", " << box.y_min << ", " << box.x_max << ", " << box.y_max
       << ") is empty: need x_min < x_max and y_min < y_max";
    fail(os.str());
  }
  const RectifiedCamera& c = impl_->cam;
  if (disparity.rows() != c.height || disparity.cols() != c.width) {
    os << "disparity is " << disparity.cols() << "x" << disparity.rows() << " but the camera is " << c.width << "x"
       << c.height;
    fail(os.str());
  }
  BoxRange out;
  // Clamped in doubles first: a coordinate beyond int's range must not wrap.
  const auto pixel = [](double v, int size) { return static_cast<int>(std::clamp(std::ceil(v), 0.0, double(size))); };
  const int x0 = pixel(box.x_min, c.width), y0 = pixel(box.y_min, c.height);
  const int x1 = pixel(box.x_max, c.width), y1 = pixel(box.y_max, c.height);
  if (x1 <= x0 || y1 <= y0) {
    out.reason = "box lies outside the image";
    return out;
  }
  out.n_pixels = (x1 - x0) * (y1 - y0);
  std::vector<double> z;
  std::vector<double> d;
  z.reserve(out.n_pixels);
  d.reserve(out.n_pixels);
  const double fb = c.f * c.baseline;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      const double v = disparity(y, x);
      if (std::isfinite(v) && v + c.doffs > 0.0) {
        d.push_back(v);
        z.push_back(fb / (v + c.doffs));
      }
    }
  out.n_valid = static_cast<int>(z.size());
  const int need = std::max(options.min_valid_pixels,
                            static_cast<int>(std::ceil(options.min_valid_fraction * out.n_pixels)));
  if (out.n_valid < need) {
    os << "too few valid pixels: " << out.n_valid << " of " << out.n_pixels << " (need " << need << ")";
    out.reason = os.str();
    return out;
  }
  auto median = [](std::vector<double>& v) {
    const std::size_t h = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + h, v.end());
    const double hi = v[h];
    if (v.size() % 2) return hi;
    const double lo = *std::max_element(v.begin(), v.begin() + h);
    return 0.5 * (lo + hi);
  };
  out.range = median(z);
  out.disparity = median(d);
  out.sigma = out.range * out.range * options.sigma_d / fb;
  // The centre of the part of the box inside the image, whose pixels gave
  // the range (the same as the box's centre for a box inside the image).
  const double u = 0.5 * (std::max(box.x_min, 0.0) + std::min(box.x_max, static_cast<double>(c.width)));
  const double v = 0.5 * (std::max(box.y_min, 0.0) + std::min(box.y_max, static_cast<double>(c.height)));
  out.point = Eigen::Vector3d((u - c.cx) * out.range / c.f, (v - c.cy) * out.range / c.f, out.range);
  const double d_eff = fb / out.range;  // d + doffs at the median depth
  if (d_eff < options.min_disparity) {
    os << "beyond resolvable range: d + doffs = " << d_eff << " px < min_disparity " << options.min_disparity
       << " px (Z = " << out.range << ")";
    out.reason = os.str();
  } else if (out.range > options.max_range) {
    os << "beyond resolvable range: Z = " << out.range << " > max_range " << options.max_range;
    out.reason = os.str();
  } else {
    out.ok = true;
  }
  return out;
}


// ---------------------------------------------------------------------------
// Parameter declarations (safenav/params.hpp)

template <>
const ParamSet<BoxRangeOptions>& param_set<BoxRangeOptions>() {
  using B = BoxRangeOptions;
  constexpr double kNone = std::numeric_limits<double>::infinity();
  static const ParamSet<B> s =
      Declare<B>{}
          .real("sigma_d", SN_REF(B, sigma_d), "px", above(0, 100), "disparity noise sigma_d; sigma_Z = Z^2 sigma_d / (f B)")
          .integer("min_valid_pixels", SN_REF(B, min_valid_pixels), closed(1, 1e8), "fewer valid pixels in the box: no range")
          .real("min_valid_fraction", SN_REF(B, min_valid_fraction), "", closed(0, 1), "fewer valid pixels than this share of the box: no range")
          .real("min_disparity", SN_REF(B, min_disparity), "px", above(0, 1e5), "d + doffs below this: beyond the resolvable range")
          .real("max_range", SN_REF(B, max_range), "m", above(0, kNone), "a median depth Z above this: no range; inf = none")
          .set;
  return s;
}

template class ParamSet<BoxRangeOptions>;

}  // namespace safenav
