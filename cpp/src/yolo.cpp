// A YOLO ONNX detector in the core (safenav/yolo.hpp): letterbox, OpenCV dnn,
// decode and class-wise NMS, step for step as safenav.vision.detect does them.
#include "safenav/yolo.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <mutex>
#include <numeric>

#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "errors.hpp"

namespace safenav {

void YoloSettings::validate() const {
  if (input_size < 32) detail::bad("input_size = " + std::to_string(input_size) + ": must be an integer >= 32");
  if (!(conf_threshold >= 0.0 && conf_threshold <= 1.0))
    detail::bad("conf_threshold = " + detail::num(conf_threshold) + ": must be in [0, 1]");
  if (!(iou_threshold >= 0.0 && iou_threshold <= 1.0))
    detail::bad("iou_threshold = " + detail::num(iou_threshold) + ": must be in [0, 1]");
  if (max_detections < 1) detail::bad("max_detections = " + std::to_string(max_detections) + ": must be >= 1");
}

std::vector<YoloDetection> decode_yolo(const std::vector<float>& out, int rows, int cols, const YoloSettings& s) {
  s.validate();
  if (rows < 5 || cols < 0 || out.size() != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols))
    detail::bad("YOLO output of " + std::to_string(out.size()) + " values as " + std::to_string(rows) + " x " +
                std::to_string(cols) + ": expected (1, 4 + nc, N) with nc >= 1");
  const auto at = [&](int r, int c) { return out[static_cast<std::size_t>(r) * cols + c]; };
  // Each column's best class (the first on ties, as numpy's argmax), kept when its score is finite and
  // above the threshold and its box is finite; the box as (x, y, w, h) in single precision, as numpy does.
  std::vector<cv::Rect2d> boxes;
  std::vector<float> scores;
  std::vector<int> classes;
  for (int c = 0; c < cols; ++c) {
    int best = 4;
    for (int r = 5; r < rows; ++r)
      if (at(r, c) > at(best, c)) best = r;
    const float score = at(best, c), cx = at(0, c), cy = at(1, c), w = at(2, c), h = at(3, c);
    if (!(std::isfinite(score) && score > s.conf_threshold && std::isfinite(cx) && std::isfinite(cy) &&
          std::isfinite(w) && std::isfinite(h)))
      continue;
    const float x0 = cx - w / 2.0f, y0 = cy - h / 2.0f;
    boxes.emplace_back(x0, y0, w, h);
    scores.push_back(score);
    classes.push_back(best - 4);
  }
  if (boxes.empty()) return {};
  // cv::dnn::NMSBoxesBatched (OpenCV >= 4.7): each class's boxes moved apart by class·(max coordinate + 1),
  // then one NMS.
  double max_coord = 0.0;
  for (const cv::Rect2d& b : boxes)
    max_coord = std::max({max_coord, b.x, b.y, b.x + b.width, b.y + b.height});
  std::vector<cv::Rect2d> moved;
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const double off = classes[i] * (max_coord + 1.0);
    moved.emplace_back(boxes[i].x + off, boxes[i].y + off, boxes[i].width, boxes[i].height);
  }
  std::vector<int> keep;
  cv::dnn::NMSBoxes(moved, scores, static_cast<float>(s.conf_threshold), static_cast<float>(s.iou_threshold), keep);
  std::stable_sort(keep.begin(), keep.end(), [&](int a, int b) { return scores[a] > scores[b]; });
  if (static_cast<int>(keep.size()) > s.max_detections) keep.resize(s.max_detections);
  std::vector<YoloDetection> dets;
  for (int i : keep) {
    const float x0 = static_cast<float>(boxes[i].x), y0 = static_cast<float>(boxes[i].y);
    const float x1 = x0 + static_cast<float>(boxes[i].width), y1 = y0 + static_cast<float>(boxes[i].height);
    dets.push_back({classes[i], scores[i], Box{x0, y0, x1, y1}});
  }
  return dets;
}

struct YoloDetector::Impl {
  std::string path;
  YoloSettings settings;
  mutable cv::dnn::Net net;
  mutable std::mutex lock;
  int num_classes = 0;

  /// The network's output on a letterboxed BGR square: (rows, columns, values).
  std::vector<float> forward(const cv::Mat& bgr_square, int& rows, int& cols) const {
    const cv::Mat blob = cv::dnn::blobFromImage(bgr_square, 1.0 / 255.0, cv::Size(), cv::Scalar(), true, false);
    cv::Mat out;
    {
      std::lock_guard<std::mutex> g(lock);
      net.setInput(blob);
      out = net.forward().clone();
    }
    if (out.dims != 3 || out.size[0] != 1 || out.size[1] < 5) {
      std::string shape = "(";
      for (int d = 0; d < out.dims; ++d) shape += (d ? ", " : "") + std::to_string(out.size[d]);
      detail::bad("ONNX model '" + path + "' has output shape " + shape +
                  "); a YOLOv8/11 detection model gives (1, 4 + nc, N)");
    }
    rows = out.size[1];
    cols = out.size[2];
    const float* p = out.ptr<float>();
    return std::vector<float>(p, p + static_cast<std::size_t>(rows) * cols);
  }
};

YoloDetector::YoloDetector(const std::string& model_path, const YoloSettings& settings)
    : impl_(std::make_unique<Impl>()) {
  settings.validate();
  Impl& I = *impl_;
  I.path = model_path;
  I.settings = settings;
  if (!std::ifstream(model_path).good()) detail::bad("YOLO model file not found: '" + model_path + "'");
  try {
    I.net = cv::dnn::readNetFromONNX(model_path);
  } catch (const cv::Exception& e) {
    detail::bad("cannot read ONNX model '" + model_path + "': " + e.err);
  }
  if (I.net.empty()) detail::bad("cannot read ONNX model '" + model_path + "': OpenCV returned an empty network");
  int rows = 0, cols = 0;
  try {
    (void)I.forward(cv::Mat(settings.input_size, settings.input_size, CV_8UC3, cv::Scalar::all(114)), rows, cols);
  } catch (const cv::Exception& e) {
    detail::bad("ONNX model '" + model_path + "' does not run on a (1, 3, " + std::to_string(settings.input_size) +
                ", " + std::to_string(settings.input_size) + ") input: " + e.err);
  }
  I.num_classes = rows - 4;
}

YoloDetector::~YoloDetector() = default;
YoloDetector::YoloDetector(YoloDetector&&) noexcept = default;
YoloDetector& YoloDetector::operator=(YoloDetector&&) noexcept = default;
int YoloDetector::num_classes() const { return impl_->num_classes; }
const YoloSettings& YoloDetector::settings() const { return impl_->settings; }
const std::string& YoloDetector::model_path() const { return impl_->path; }

std::vector<YoloDetection> YoloDetector::detect(const ImageView& image) const {
  if (image.data == nullptr || image.rows <= 0 || image.cols <= 0)
    detail::bad("image is empty (" + std::to_string(image.cols) + "x" + std::to_string(image.rows) + ")");
  if (image.channels != 1 && image.channels != 3)
    detail::bad("image has " + std::to_string(image.channels) + " channels, expected 1 (grey) or 3 (BGR)");
  const std::size_t stride = image.row_stride ? image.row_stride : static_cast<std::size_t>(image.cols) * image.channels;
  cv::Mat img(image.rows, image.cols, image.channels == 1 ? CV_8UC1 : CV_8UC3, const_cast<std::uint8_t*>(image.data),
              stride);
  if (image.channels == 1) cv::cvtColor(img, img, cv::COLOR_GRAY2BGR);
  // letterbox (safenav.vision.detect.letterbox): Python's round() rounds halves to even, as nearbyint does
  const int S = impl_->settings.input_size, w = image.cols, h = image.rows;
  const double scale = std::min(double(S) / w, double(S) / h);
  const int nw = static_cast<int>(std::nearbyint(w * scale)), nh = static_cast<int>(std::nearbyint(h * scale));
  const int left = static_cast<int>(std::nearbyint((S - nw) / 2.0 - 0.1));
  const int top = static_cast<int>(std::nearbyint((S - nh) / 2.0 - 0.1));
  cv::Mat resized = img;
  if (nw != w || nh != h) cv::resize(img, resized, cv::Size(nw, nh), 0, 0, scale < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  cv::Mat padded;
  cv::copyMakeBorder(resized, padded, top, S - nh - top, left, S - nw - left, cv::BORDER_CONSTANT,
                     cv::Scalar::all(114));
  int rows = 0, cols = 0;
  const std::vector<float> out = impl_->forward(padded, rows, cols);
  std::vector<YoloDetection> dets = decode_yolo(out, rows, cols, impl_->settings);
  const double sx = double(nw) / w, sy = double(nh) / h;
  for (YoloDetection& d : dets)
    d.box = Box{std::clamp((d.box.x_min - left) / sx, 0.0, double(w)), std::clamp((d.box.y_min - top) / sy, 0.0, double(h)),
                std::clamp((d.box.x_max - left) / sx, 0.0, double(w)), std::clamp((d.box.y_max - top) / sy, 0.0, double(h))};
  return dets;
}

}  // namespace safenav
