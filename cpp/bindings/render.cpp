// Python bindings of the simulator's stereo pixels (safenav/render.hpp):
// safenav.vision.render draws every image through them.
#include "common.hpp"
#include "safenav/render.hpp"

#include <memory>
#include <optional>

#include <pybind11/numpy.h>

using namespace safenav;

namespace {
using U8Array = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;
using Quad = Eigen::Matrix<double, 4, 3, Eigen::RowMajor>;

Image image_of(const U8Array& a, int channels, const std::string& what) {
  const bool ok = channels == 1 ? a.ndim() == 2 : (a.ndim() == 3 && a.shape(2) == channels);
  if (!ok)
    throw std::invalid_argument(what + " must be an (H, W" + (channels == 1 ? std::string() : ", " +
                                std::to_string(channels)) + ") uint8 array");
  Image im;
  im.rows = static_cast<int>(a.shape(0));
  im.cols = static_cast<int>(a.shape(1));
  im.channels = channels;
  im.data.assign(a.data(), a.data() + a.size());
  return im;
}

RenderView view_of(const py::tuple& t, const char* what) {
  if (t.size() != 4)
    throw std::invalid_argument(std::string(what) + " must be (theta, R, centre, boards)");
  RenderView v;
  v.theta = t[0].cast<double>();
  v.R = t[1].cast<Eigen::Matrix3d>();
  v.centre = t[2].cast<Eigen::Vector3d>();
  for (const py::handle& h : t[3].cast<py::list>()) {
    const auto b = h.cast<py::tuple>();
    if (b.size() != 4) throw std::invalid_argument(std::string(what) + ": a board must be (id, corners, pole, box)");
    RenderBoard rb;
    rb.id = b[0].cast<int>();
    rb.corners = b[1].cast<Quad>();
    rb.has_pole = !b[2].is_none();
    if (rb.has_pole) rb.pole = b[2].cast<Quad>();
    rb.box = b[3].cast<std::array<int, 4>>();
    v.boards.push_back(std::move(rb));
  }
  return v;
}

/// StereoPixels, PixelRenderer (the scene) and RenderNoise.
void bind_scene(py::module_& m) {
  py::class_<StereoPixels, std::shared_ptr<StereoPixels>>(
      m, "StereoPixels", "A rectified grey stereo pair whose pixels the front end reads on demand (C++ side).");
  py::class_<PixelRenderer, std::shared_ptr<PixelRenderer>>(
      m, "PixelRenderer",
      "The simulator's renderer of one scene (safenav/render.hpp): the rig, the ground tile, the panorama and each "
      "landmark's board pyramid (smallest first, (s, s, 2) grey and alpha); frames draw through it.")
      .def(py::init([](double f, double cx, double cy, int width, int height, double camera_height_m, double pitch_rad,
                       const U8Array& ground, double ground_res_m, const U8Array& panorama, double pano_el_min,
                       double pano_el_max, double haze_m, double pole_grey, const py::dict& boards) {
             RenderScene s;
             s.f = f, s.cx = cx, s.cy = cy, s.width = width, s.height = height;
             s.camera_height_m = camera_height_m, s.pitch_rad = pitch_rad;
             s.ground = image_of(ground, 1, "ground");
             s.ground_res_m = ground_res_m;
             s.panorama = image_of(panorama, 1, "panorama");
             s.pano_el_min = pano_el_min, s.pano_el_max = pano_el_max, s.haze_m = haze_m, s.pole_grey = pole_grey;
             for (const auto& [k, v] : boards) {
               const int id = k.cast<int>();
               for (const py::handle& level : v.cast<py::list>())
                 s.boards[id].push_back(image_of(U8Array::ensure(level), 2, "board " + std::to_string(id) + " level"));
             }
             py::gil_scoped_release nogil;
             return std::make_shared<PixelRenderer>(std::move(s));
           }),
           py::arg("f"), py::arg("cx"), py::arg("cy"), py::arg("width"), py::arg("height"), py::arg("camera_height_m"),
           py::arg("pitch_rad"), py::arg("ground"), py::arg("ground_res_m"), py::arg("panorama"),
           py::arg("pano_el_min"), py::arg("pano_el_max"), py::arg("haze_m"), py::arg("pole_grey"), py::arg("boards"));

  py::class_<RenderNoise, std::shared_ptr<RenderNoise>>(
      m, "RenderNoise", "Pixel noise of a trial: a tile of N(0, sigma^2) draws from seed, windows of it per box.")
      .def(py::init<double, std::uint64_t, int>(), py::arg("sigma"), py::arg("seed"), py::arg("side") = 1024)
      .def_readonly("sigma", &RenderNoise::sigma)
      .def_readonly("side", &RenderNoise::side);
}

/// RenderedFrame and SimulatedCamera: what the camera sees and draws.
void bind_camera(py::module_& m) {
  py::class_<RenderedFrame, StereoPixels, std::shared_ptr<RenderedFrame>>(
      m, "RenderedFrame",
      "One frame's pair drawn box by box at any pyramid level (StereoPixels); views are (theta, R, centre, boards), "
      "a board (id, corners (4, 3) in camera coordinates, pole (4, 3) or None, full-resolution box (x0, y0, x1, y1)), "
      "far first.")
      .def(py::init([](std::shared_ptr<const PixelRenderer> r, std::shared_ptr<const RenderNoise> noise,
                       const py::tuple& left, const py::tuple& right, std::uint64_t noise_seed) {
             return std::make_shared<RenderedFrame>(std::move(r), std::move(noise), view_of(left, "left"),
                                                    view_of(right, "right"), noise_seed);
           }),
           py::arg("renderer"), py::arg("noise"), py::arg("left"), py::arg("right"), py::arg("noise_seed"))
      .def(
          "draw",
          [](const RenderedFrame& f, bool right, int level, int x0, int y0, int width, int height) {
            if (width < 1 || height < 1)
              throw std::invalid_argument("draw: width = " + std::to_string(width) + ", height = " +
                                          std::to_string(height) + ": must be >= 1");
            py::array_t<std::uint8_t> out({height, width});
            std::uint8_t* data = out.mutable_data();
            {
              py::gil_scoped_release nogil;
              f.draw(right, level, x0, y0, width, height, data, width);
            }
            return out;
          },
          py::arg("right"), py::arg("level"), py::arg("x0"), py::arg("y0"), py::arg("width"), py::arg("height"),
          "The (height, width) box of pyramid level `level` whose top-left full-resolution pixel is (x0, y0).")
      .def_property_readonly("draws", &RenderedFrame::draws)
      .def_property_readonly("pixels", &RenderedFrame::pixels);
  py::class_<SimulatedCamera, std::shared_ptr<SimulatedCamera>>(
      m, "SimulatedCamera",
      "The simulator's stereo camera (safenav/render.hpp): which boards each camera sees at a pose (range, field of "
      "view, facing, occlusion by the obstacles), drawn by its PixelRenderer on demand.")
      .def(py::init([](std::shared_ptr<const PixelRenderer> r,
                       const std::vector<std::tuple<int, Eigen::Vector3d, std::optional<double>>>& boards,
                       double baseline_m, double max_range_m, double near_m, double board_half_m, double pole_width_m,
                       std::optional<ObstacleChecker> occlusion) {
             std::vector<CameraBoard> bs;
             for (const auto& [id, c, yaw] : boards)
               bs.push_back({id, c, yaw ? *yaw : std::numeric_limits<double>::quiet_NaN()});
             SimulatedCameraSettings s{baseline_m, max_range_m, near_m, board_half_m, pole_width_m};
             return std::make_shared<SimulatedCamera>(std::move(r), std::move(bs), s, std::move(occlusion));
           }),
           py::arg("renderer"), py::arg("boards"), py::arg("baseline_m"), py::arg("max_range_m"), py::arg("near_m"),
           py::arg("board_half_m"), py::arg("pole_width_m"), py::arg("occlusion") = py::none(),
           "boards: (id, centre (x, y, height), yaw or None to face the camera); occlusion: the world's "
           "ObstacleChecker, or None")
      .def_property_readonly("renderer", &SimulatedCamera::renderer)
      .def("centres_in_view", &SimulatedCamera::centres_in_view, py::arg("pose"), release_gil())
      .def(
          "views",
          [](const SimulatedCamera& c, const Eigen::Vector3d& pose) {
            py::list out;
            for (const RenderView& v : c.views(pose)) {
              py::list boards;
              for (const RenderBoard& b : v.boards)
                boards.append(py::make_tuple(b.id, b.corners, b.has_pole ? py::cast(b.pole) : py::none(), b.box));
              out.append(py::make_tuple(v.theta, v.R, v.centre, boards));
            }
            return out;
          },
          py::arg("pose"),
          "[left, right] views at pose: (theta, R, centre, boards far first: (id, corners (4, 3) in camera "
          "coordinates, pole (4, 3) or None, full-resolution box))")
      .def("frame", &SimulatedCamera::frame, py::arg("pose"), py::arg("noise"), py::arg("noise_seed"), release_gil());
}

}  // namespace

void pybind_render(py::module_& m) {
  bind_scene(m);
  bind_camera(m);
}
