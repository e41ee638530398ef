// Python bindings of the camera loop: LanBLoc's search plan
// (safenav/lanbloc.hpp), camera frames into the Localizer
// (Localizer::observe_frame, safenav/localizer.hpp) and the simulator's camera
// loop (Navigator::run_frames, and run_camera with the simulated camera of
// safenav/render.hpp).  Added to the classes
// that bindings/lanbloc.cpp, guidance.cpp and navigation.cpp made.
#include "common.hpp"
#include "safenav/lanbloc.hpp"
#include "safenav/localizer.hpp"
#include "safenav/navigation.hpp"
#include "safenav/render.hpp"
#include "safenav/seed.hpp"

#include <memory>
#include <optional>

#include <pybind11/numpy.h>

using namespace safenav;

namespace {
using U8Array = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

ImageView grey_view(const U8Array& a, const char* what) {
  if (a.ndim() != 2)
    throw std::invalid_argument(std::string(what) + " image must be (H, W) 8-bit grey, got " +
                                std::to_string(a.ndim()) + " dimensions");
  return ImageView{a.data(), static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), 1,
                   static_cast<std::ptrdiff_t>(a.strides(0))};
}

py::list box_list(const std::vector<Box>& bs) {
  py::list out;
  for (const Box& b : bs) out.append(py::make_tuple(b.x_min, b.y_min, b.x_max, b.y_max));
  return out;
}

/// A Python object with draw(right, level, x0, y0, width, height) -> (height, width) uint8 array as
/// StereoPixels (safenav.vision.pixels.FramePixels); the object is borrowed (the caller keeps it alive).
class PyPixels final : public StereoPixels {
 public:
  explicit PyPixels(py::handle obj) : obj_(obj) {}
  void draw(bool right, int level, int x0, int y0, int width, int height, std::uint8_t* out,
            std::ptrdiff_t stride) const override {
    py::gil_scoped_acquire acquire;
    U8Array a = U8Array::ensure(obj_.attr("draw")(right, level, x0, y0, width, height));
    if (!a || a.ndim() != 2 || a.shape(0) != height || a.shape(1) != width)
      throw py::value_error("pixels.draw(right=" + std::to_string(right) + ", level=" + std::to_string(level) +
                            ", x0=" + std::to_string(x0) + ", y0=" + std::to_string(y0) + ", width=" +
                            std::to_string(width) + ", height=" + std::to_string(height) +
                            ") must return a (height, width) uint8 array");
    for (int r = 0; r < height; ++r) std::copy_n(a.data(r, 0), width, out + r * stride);
  }

 private:
  py::handle obj_;
};

/// Frame pixels from Python: a core StereoPixels (e.g. RenderedFrame), a (left, right) pair of grey
/// arrays, or an object with draw().  `keep`
/// holds what the pixels borrow until the caller drops it (with the GIL held).
std::shared_ptr<const StereoPixels> pixels_of(const py::object& obj, py::object& keep, const char* what) {
  if (py::isinstance<StereoPixels>(obj)) return obj.cast<std::shared_ptr<StereoPixels>>();  // drawn in C++
  if (py::isinstance<py::tuple>(obj)) {
    auto t = obj.cast<py::tuple>();
    if (t.size() != 2)
      throw py::value_error(std::string(what) + " must be (left, right) or an object with draw(), got a tuple of " +
                            std::to_string(t.size()));
    U8Array l = U8Array::ensure(t[0]), r = U8Array::ensure(t[1]);
    if (!l || !r) throw py::value_error(std::string(what) + ": left and right must be 8-bit grey (H, W) arrays");
    const ImageView lv = grey_view(l, "left"), rv = grey_view(r, "right");
    keep = py::make_tuple(l, r);
    return std::make_shared<StereoImages>(lv, rv);
  }
  if (!py::hasattr(obj, "draw"))
    throw py::value_error(std::string(what) + " must be (left, right) grey arrays or an object with "
                          "draw(right, level, x0, y0, width, height), got " + py::repr(obj).cast<std::string>());
  keep = obj;
  return std::make_shared<PyPixels>(obj);
}

/// A front end owned by its Python object: shared without ownership (the caller keeps it alive).
std::shared_ptr<const LanBLocFrontEnd> borrowed(const LanBLocFrontEnd& f) {
  return std::shared_ptr<const LanBLocFrontEnd>(&f, [](const LanBLocFrontEnd*) {});
}

void bind_plan(py::module_& m) {
  py::class_<SearchPlan>(m, "SearchPlan",
                         "Where a frame is searched: mode and reason, the prediction the windows came from, the "
                         "windows, and each image's regions (the windows merged; empty for the whole frame).")
      .def_readonly("mode", &SearchPlan::mode)
      .def_readonly("reason", &SearchPlan::reason)
      .def_property_readonly("prediction",
                             [](const SearchPlan& p) -> py::object {
                               if (!p.prediction) return py::none();
                               return py::make_tuple(p.prediction->pose, p.prediction->covariance);
                             },
                             "(pose (x, y, theta), 3x3 covariance), or None (whole frame without a prediction)")
      .def_readonly("windows", &SearchPlan::windows)
      .def_property_readonly("left_regions", [](const SearchPlan& p) { return box_list(p.left_regions); },
                             "(x_min, y_min, x_max, y_max) [px] of the left image's regions")
      .def_property_readonly("right_regions", [](const SearchPlan& p) { return box_list(p.right_regions); },
                             "the right image's regions");
  py::enum_<FrameUpdate>(m, "FrameUpdate", "How a camera frame's result enters the filter.")
      .value("FIX", FrameUpdate::Fix)
      .value("LANDMARKS", FrameUpdate::Landmarks)
      .value("FIX_OR_LANDMARKS", FrameUpdate::FixOrLandmarks);
  py::class_<FrameResult>(m, "FrameResult", "What became of one camera frame (Localizer.observe_frame).")
      .def_readonly("plan", &FrameResult::plan)
      .def_readonly("fix", &FrameResult::fix)
      .def_readonly("update", &FrameResult::update)
      .def_readonly("landmarks", &FrameResult::landmarks);

  auto fe = py::reinterpret_borrow<py::class_<LanBLocFrontEnd>>(m.attr("LanBLocFrontEnd"));
  fe.def(
        "plan",
        [](const LanBLocFrontEnd& f, const std::optional<Eigen::Vector3d>& pose,
           const std::optional<Eigen::Matrix3d>& covariance) {
          if (pose.has_value() != covariance.has_value())
            throw std::invalid_argument("predicted_pose and predicted_covariance must be given together (or neither)");
          return f.plan(pose ? std::optional<PosePrediction>(PosePrediction{*pose, *covariance}) : std::nullopt);
        },
        py::arg("predicted_pose") = py::none(), py::arg("predicted_covariance") = py::none(),
        "The SearchPlan that localize(left, right, predicted_pose, predicted_covariance) searches.")
      .def(
          "localize_plan",
          [](const LanBLocFrontEnd& f, const U8Array& left, const U8Array& right, const SearchPlan& plan) {
            const ImageView l = grey_view(left, "left"), r = grey_view(right, "right");
            py::gil_scoped_release nogil;
            return f.localize(l, r, plan);
          },
          py::arg("left"), py::arg("right"), py::arg("plan"), "Observations and fix, searched where `plan` says.")
      .def(
          "localize_pixels",
          [](const LanBLocFrontEnd& f, const py::object& pixels, const SearchPlan& plan) {
            py::object keep;
            const std::shared_ptr<const StereoPixels> px = pixels_of(pixels, keep, "pixels");
            py::gil_scoped_release nogil;
            return f.localize(*px, plan);
          },
          py::arg("pixels"), py::arg("plan"),
          "Observations and fix, searched where `plan` says, on pixels drawn on demand: an object with "
          "draw(right, level, x0, y0, width, height) returning that box at that pyramid level (or a (left, right) "
          "pair); only the boxes detection and corner refinement read are drawn.");
}

void bind_localizer_frames(py::module_& m) {
  auto loc = py::reinterpret_borrow<py::class_<Localizer>>(m.attr("Localizer"));
  loc.def(
         "set_front_end",
         [](Localizer& l, const LanBLocFrontEnd* f) { l.set_front_end(f ? borrowed(*f) : nullptr); },
         py::arg("front_end"), py::keep_alive<1, 2>(),
         "The LanBLocFrontEnd that observe_frame runs (None: frames off); its ids are the map's.")
      .def("frame_plan", &Localizer::frame_plan, py::arg("t"),
           "Where the frame at t is searched: windows from the filter's prediction to t, or the whole frame "
           "(before the start, for a frame older than the filter, or when too uncertain).")
      .def(
          "observe_frame",
          [](Localizer& l, double t, const U8Array& left, const U8Array& right, FrameUpdate how) {
            const ImageView lv = grey_view(left, "left"), rv = grey_view(right, "right");
            py::gil_scoped_release nogil;
            return l.observe_frame(t, lv, rv, how);
          },
          py::arg("t"), py::arg("left"), py::arg("right"), py::arg_v("update", FrameUpdate::Fix, "FrameUpdate.FIX"),
          "One rectified grey pair at t: the front end searches where frame_plan(t) says, and the fix "
          "(FrameUpdate.FIX) or each landmark's range and bearing (LANDMARKS; FIX_OR_LANDMARKS: the fix when "
          "there is one, else the landmarks) updates the filter, gated.")
      .def(
          "observe_frame",
          [](Localizer& l, double t, const py::object& pixels, FrameUpdate how) {
            py::object keep;
            const std::shared_ptr<const StereoPixels> px = pixels_of(pixels, keep, "pixels");
            py::gil_scoped_release nogil;
            return l.observe_frame(t, *px, how);
          },
          py::arg("t"), py::arg("pixels"), py::arg_v("update", FrameUpdate::Fix, "FrameUpdate.FIX"),
          "The same on pixels drawn on demand (LanBLocFrontEnd.localize_pixels).");
}

void bind_run_frames(py::module_& m) {
  auto nav = py::reinterpret_borrow<py::class_<Navigator>>(m.attr("Navigator"));
  nav.def(
      "run_frames",
      [](const Navigator& n, std::uint64_t seed, const LanBLocFrontEnd& front_end, py::object frames) {
        py::object keep;  // what the last frame's pixels borrow, alive until the next call (released with the GIL)
        FrameCallback cb = [&frames, &keep](const State& x, int step,
                                            const SearchPlan& plan) -> std::shared_ptr<const StereoPixels> {
          py::gil_scoped_acquire acquire;
          py::object out = frames(x, step, plan);
          if (out.is_none()) return nullptr;
          return pixels_of(out, keep, "frames callback's result");
        };
        TrialResult res;
        {
          py::gil_scoped_release release;
          res = n.run_frames(seed, borrowed(front_end), cb);
        }
        return res;
      },
      py::arg("seed"), py::arg("front_end"), py::arg("frames"),
      "One trial with the camera in the loop: each fix step frames(truth, step, plan) gives the pair (at "
      "least plan's regions) as (left, right) arrays or pixels drawn on demand (an object with draw(), as "
      "LanBLocFrontEnd.localize_pixels takes; None: no frame), and the vehicle's localizer searches it where "
      "its own prediction says (Localizer.observe_frame).");
  nav.def(
      "run_camera",
      [](const Navigator& n, std::uint64_t seed, const LanBLocFrontEnd& front_end,
         std::shared_ptr<const SimulatedCamera> camera, std::shared_ptr<const RenderNoise> noise,
         std::uint64_t noise_seed, bool early_out) {
        if (!camera) throw std::invalid_argument("run_camera: camera is None");
        long frames = 0, early = 0, whole = 0, windows = 0, draws = 0, pixels = 0;
        std::shared_ptr<RenderedFrame> last;
        auto count = [&] {
          if (last) draws += last->draws(), pixels += last->pixels();
          last.reset();
        };
        FrameCallback cb = [&](const State& x, int step,
                               const SearchPlan& plan) -> std::shared_ptr<const StereoPixels> {
          ++frames;
          const Eigen::Vector3d pose(x[kX], x[kY], x[kTheta]);
          count();
          if (early_out && camera->centres_in_view(pose) < 1) {
            ++early;
            return nullptr;
          }
          ++(plan.mode == SearchMode::WholeFrame ? whole : windows);
          last = camera->frame(pose, noise, derive_seed(noise_seed, std::uint64_t(step)));
          return last;
        };
        TrialResult res;
        {
          py::gil_scoped_release nogil;
          res = n.run_frames(seed, borrowed(front_end), cb);
          count();
        }
        py::dict stats;
        stats["frames"] = frames, stats["early_out"] = early, stats["whole_frame"] = whole, stats["windows"] = windows;
        stats["draws"] = draws, stats["pixels"] = pixels;
        return py::make_tuple(res, stats);
      },
      py::arg("seed"), py::arg("front_end"), py::arg("camera"), py::arg("noise"), py::arg("noise_seed"),
      py::arg("early_out") = true,
      "run_frames with the simulated camera in C++: each fix step the frame at the true pose is drawn on demand "
      "(noise offsets from derive_seed(noise_seed, step)); with early_out a frame whose left image holds no board "
      "centre is a dropout.  Returns (TrialResult, counts: frames, early_out, whole_frame, windows, draws, pixels).");
}
}  // namespace

void pybind_lanbloc_loop(py::module_& m) {
  bind_plan(m);
  bind_localizer_frames(m);
  bind_run_frames(m);
}
