// safenav/yolo.hpp — a YOLO detector for natural landmarks in the core
// ([SafeNav §IV-A]: "landmarks recognised in camera images … a YOLO model").
//
// A user-supplied YOLOv8/YOLO11 detection model exported to ONNX (`yolo
// export format=onnx`), run through OpenCV's dnn module: the image
// letterboxed to the model's square input (Ultralytics' letterbox: the aspect
// kept, grey 114 padding), scaled to [0, 1] in RGB order, the output
// (1, 4 + nc, N) decoded (each column cx, cy, w, h and nc class scores; its
// class the best-scoring one; scores not above conf_threshold dropped) and
// class-wise non-maximum suppression at iou_threshold.  The steps and their
// rounding are safenav.vision.detect's (letterbox, decode_yolo,
// YoloOnnxDetector); the boxes then go to LanBLocFrontEnd::localize_boxes
// for the paper's SGBM ranging.
//
// OpenCV stays inside cpp/src: only std types and the core's ImageView/Box
// cross this header.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "safenav/stereo.hpp"

namespace safenav {

struct YoloSettings {
  int input_size = 640;          ///< the square input the model was exported with [px], >= 32
  double conf_threshold = 0.25;  ///< a box's best class score must be above this, in [0, 1]
  double iou_threshold = 0.45;   ///< class-wise NMS overlap threshold, in [0, 1]
  int max_detections = 300;      ///< the best-scoring this many are kept, >= 1

  void validate() const;  ///< std::invalid_argument naming the field at fault
};

/// One detection: the model's class index, its score, and its box in the
/// image's pixels (x_min, y_min, x_max, y_max; clipped to the image).
struct YoloDetection {
  int class_id = 0;
  double score = 0.0;
  Box box;
};

/// The decode step alone (decode_yolo in Python): `output` is the model's
/// (1, 4 + nc, N) output as rows × columns, row-major (rows = 4 + nc);
/// boxes in the model's input pixels, best score first (ties in column
/// order).  Non-finite columns are dropped.  std::invalid_argument when rows
/// < 5 or the size is not rows × columns.
std::vector<YoloDetection> decode_yolo(const std::vector<float>& output, int rows, int columns,
                                       const YoloSettings& settings = YoloSettings());

/// A YOLO ONNX model.  detect() runs the network under a lock: one detector
/// may serve several threads, one frame at a time.
class YoloDetector {
 public:
  /// Loads the model and runs it once on a blank input to check its output.
  /// std::invalid_argument naming the path when the file is missing, cannot
  /// be read as ONNX, does not run on a (1, 3, input_size, input_size) input,
  /// or does not give (1, 4 + nc, N) with nc >= 1.
  explicit YoloDetector(const std::string& model_path, const YoloSettings& settings = YoloSettings());
  ~YoloDetector();
  YoloDetector(YoloDetector&&) noexcept;
  YoloDetector& operator=(YoloDetector&&) noexcept;

  int num_classes() const;
  const YoloSettings& settings() const;
  const std::string& model_path() const;

  /// Detections in an 8-bit grey or BGR image (1 or 3 channels), best score
  /// first.  std::invalid_argument on an empty image or other channels.
  std::vector<YoloDetection> detect(const ImageView& image) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace safenav
