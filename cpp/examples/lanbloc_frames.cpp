// LanBLoc's stereo front end on one rectified stereo pair, from a program that
// links safenav::core alone (safenav/lanbloc.hpp).
//
//   lanbloc_frames CONFIG LEFT.pgm RIGHT.pgm
//
// The images are binary 8-bit PGM (P5), read here by hand so that the example
// needs no image library.  CONFIG is a text file, one item per line, '#'
// starts a comment:
//
//   camera f cx cy baseline doffs width height   # the rectified rig [px, m]
//   rig camera_height_m pitch_rad                # optional (1.5 0)
//   dictionary DICT_4X4_100                      # optional
//   marker_size_m 1.5                            # optional
//   landmark ID X Y Z                            # one per mapped landmark [m]
//   prediction X Y THETA SIGMA_XY SIGMA_THETA    # optional: search where the estimate predicts
//   ranging sgbm                                 # optional: the paper's SGBM box median (default corners)
//   box ID X0 Y0 X1 Y1                           # optional: boxes of a detector of your own (a YOLO
//                                                # model): SGBM-ranged, no marker detection
//   yolo MODEL.onnx INPUT_SIZE                   # optional: natural landmarks found by a YOLO model
//   class CLASS_ID LANDMARK_ID                   #   (safenav/yolo.hpp), its classes mapped to landmarks,
//                                                #   SGBM-ranged
//
// Prints one line per detected landmark and one line with the fix:
//   observation id=3 ok=1 range=9.871 sigma=0.0123 bearing=0.2012 reason=""
//   fix status=ok x=40.01 y=59.98 cxx=... cxy=... cyy=... gdop=1.9 ranges=5 search=whole_frame
// Exit status: 0 with a fix, 1 without one, 2 on bad input.
#include <cstdio>
#include <fstream>
#include <map>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "safenav/lanbloc.hpp"
#include "safenav/yolo.hpp"

namespace {

struct Pgm {
  int width = 0, height = 0;
  std::vector<std::uint8_t> pixels;
};

/// Binary 8-bit PGM (P5): magic, width, height, maxval (<= 255), comments between them.
Pgm read_pgm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path);
  auto token = [&]() {
    std::string t;
    while (in >> t) {
      if (t[0] != '#') return t;
      std::getline(in, t);  // a comment runs to the end of its line
    }
    throw std::runtime_error(path + ": truncated PGM header");
  };
  if (token() != "P5") throw std::runtime_error(path + ": not a binary PGM (P5)");
  Pgm img;
  int maxval = 0;
  try {
    img.width = std::stoi(token());
    img.height = std::stoi(token());
    maxval = std::stoi(token());
  } catch (const std::logic_error&) {
    throw std::runtime_error(path + ": bad PGM header");
  }
  if (img.width <= 0 || img.height <= 0 || maxval <= 0 || maxval > 255)
    throw std::runtime_error(path + ": PGM must be 8-bit with a positive size");
  in.get();  // the single whitespace after maxval
  img.pixels.resize(static_cast<std::size_t>(img.width) * img.height);
  in.read(reinterpret_cast<char*>(img.pixels.data()), static_cast<std::streamsize>(img.pixels.size()));
  if (in.gcount() != static_cast<std::streamsize>(img.pixels.size()))
    throw std::runtime_error(path + ": fewer pixels than its header says");
  return img;
}

struct Config {
  safenav::LanBLocRig rig;
  safenav::LanBLocSettings settings;
  std::vector<safenav::LanBLocLandmark> landmarks;
  std::optional<safenav::PosePrediction> prediction;
  std::vector<safenav::LandmarkBox> boxes;  // given: ranged by SGBM (localize_boxes)
  std::string yolo_model;                   // given: its detections ranged by SGBM
  safenav::YoloSettings yolo;
  std::map<int, int> landmark_of_class;
};

Config read_config(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  Config c;
  bool camera = false;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    line = line.substr(0, line.find('#'));
    std::istringstream ls(line);
    std::string key;
    if (!(ls >> key)) continue;
    bool ok = true;
    if (key == "camera") {
      auto& k = c.rig.camera;
      ok = static_cast<bool>(ls >> k.f >> k.cx >> k.cy >> k.baseline >> k.doffs >> k.width >> k.height);
      camera = true;
    } else if (key == "rig") {
      ok = static_cast<bool>(ls >> c.rig.camera_height_m >> c.rig.pitch_rad);
    } else if (key == "dictionary") {
      ok = static_cast<bool>(ls >> c.settings.dictionary);
    } else if (key == "marker_size_m") {
      ok = static_cast<bool>(ls >> c.settings.marker_size_m);
    } else if (key == "landmark") {
      safenav::LanBLocLandmark lm;
      ok = static_cast<bool>(ls >> lm.id >> lm.position.x() >> lm.position.y() >> lm.position.z());
      c.landmarks.push_back(lm);
    } else if (key == "ranging") {
      std::string r;
      ok = static_cast<bool>(ls >> r) && (r == "sgbm" || r == "corners");
      c.settings.ranging = r == "sgbm" ? safenav::LanBLocRanging::Sgbm : safenav::LanBLocRanging::Corners;
    } else if (key == "box") {
      safenav::LandmarkBox b;
      ok = static_cast<bool>(ls >> b.landmark_id >> b.box.x_min >> b.box.y_min >> b.box.x_max >> b.box.y_max);
      c.boxes.push_back(b);
    } else if (key == "yolo") {
      ok = static_cast<bool>(ls >> c.yolo_model >> c.yolo.input_size);
      c.settings.dictionary = "";  // no markers: a landmark id is any integer
    } else if (key == "class") {
      int cls = 0, id = 0;
      ok = static_cast<bool>(ls >> cls >> id);
      c.landmark_of_class[cls] = id;
    } else if (key == "prediction") {
      safenav::PosePrediction p;
      double sxy = 0, sth = 0;
      ok = static_cast<bool>(ls >> p.pose.x() >> p.pose.y() >> p.pose.z() >> sxy >> sth);
      p.covariance.diagonal() << sxy * sxy, sxy * sxy, sth * sth;
      c.prediction = p;
    } else {
      throw std::runtime_error(path + " line " + std::to_string(n) + ": unknown item '" + key + "'");
    }
    if (!ok) throw std::runtime_error(path + " line " + std::to_string(n) + ": too few or bad numbers for '" + key + "'");
  }
  if (!camera) throw std::runtime_error(path + ": no 'camera' line");
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: lanbloc_frames CONFIG LEFT.pgm RIGHT.pgm\n";
    return 2;
  }
  safenav::LanBLocFix fix;
  try {
    const Config cfg = read_config(argv[1]);
    const Pgm left = read_pgm(argv[2]), right = read_pgm(argv[3]);
    const safenav::LanBLocFrontEnd front_end(cfg.rig, cfg.landmarks, cfg.settings);
    const safenav::ImageView l{left.pixels.data(), left.height, left.width, 1, left.width};
    const safenav::ImageView r{right.pixels.data(), right.height, right.width, 1, right.width};
    std::vector<safenav::LandmarkBox> boxes = cfg.boxes;
    if (!cfg.yolo_model.empty()) {
      const safenav::YoloDetector yolo(cfg.yolo_model, cfg.yolo);
      for (const safenav::YoloDetection& d : yolo.detect(l)) {
        std::printf("detection class=%d score=%.4f box=%.3f,%.3f,%.3f,%.3f\n", d.class_id, d.score, d.box.x_min,
                    d.box.y_min, d.box.x_max, d.box.y_max);
        const auto it = cfg.landmark_of_class.find(d.class_id);
        if (it != cfg.landmark_of_class.end()) boxes.push_back({it->second, d.box});  // other classes: not landmarks
      }
    }
    fix = boxes.empty() && cfg.yolo_model.empty() ? front_end.localize(l, r, cfg.prediction)
                                                  : front_end.localize_boxes(l, r, boxes);
  } catch (const std::exception& e) {  // std::invalid_argument from the core names the bad value
    std::cerr << "error: " << e.what() << "\n";
    return 2;
  }
  std::printf("search=%s search_reason=\"%s\" windows=%zu\n", safenav::to_string(fix.search),
              fix.search_reason.c_str(), fix.windows.size());
  for (const auto& o : fix.observations)
    std::printf("observation id=%d ok=%d range=%.6f sigma=%.6f bearing=%.6f bearing_sigma=%.6f u=%.3f v=%.3f "
                "reason=\"%s\"\n",
                o.landmark_id, o.ok ? 1 : 0, o.range, o.sigma, o.bearing, o.bearing_sigma, o.centre.x(),
                o.centre.y(), o.reason.c_str());
  std::printf("fix status=%s x=%.6f y=%.6f cxx=%.6g cxy=%.6g cyy=%.6g gdop=%.4f ranges=%d search=%s reason=\"%s\"\n",
              safenav::to_string(fix.status), fix.position.x(), fix.position.y(), fix.covariance(0, 0),
              fix.covariance(0, 1), fix.covariance(1, 1), fix.gdop, fix.n_ranges(), safenav::to_string(fix.search),
              fix.reason.c_str());
  return fix.ok() ? 0 : 1;
}
