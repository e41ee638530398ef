// Camera frames into the Localizer (safenav/localizer.hpp): LanBLoc's front
// end (safenav/lanbloc.hpp) searches where the filter's own prediction says
// the landmarks are, and what it finds enters the filter through the normal,
// gated measurement path [SafeNav §IV-A, eqs. 12–14].
#include <cmath>
#include <limits>
#include <string>

#include "errors.hpp"
#include "safenav/localizer.hpp"

namespace safenav {

void Localizer::set_front_end(std::shared_ptr<const LanBLocFrontEnd> front_end) {
  front_end_ = std::move(front_end);
}

SearchPlan Localizer::frame_plan(double t) const {
  if (!front_end_) detail::bad("frame_plan: no front end (set_front_end first)");
  if (!std::isfinite(t)) detail::bad("frame time t = " + detail::num(t) + ": must be finite");
  if (!initialized()) {
    SearchPlan p = front_end_->plan(std::nullopt);
    p.reason = "localizer not started: no prediction";
    return p;
  }
  State x;
  StateCov P;
  if (!predict_to(t, x, P)) {
    if (t < time() - 1e-9) {
      SearchPlan p = front_end_->plan(std::nullopt);
      p.reason = "frame at t = " + detail::num(t) + " is older than the filter (t = " + detail::num(time()) +
                 "): no prediction";
      return p;
    }
    x = this->x();  // t = time(): the estimate is the prediction
    P = this->P();
  }
  // The pose (x, y, θ) and its covariance: the state's rows kX, kY, kTheta.
  const int idx[3] = {kX, kY, kTheta};
  PosePrediction pred;
  for (int i = 0; i < 3; ++i) {
    pred.pose[i] = x[idx[i]];
    for (int j = 0; j < 3; ++j) pred.covariance(i, j) = P(idx[i], idx[j]);
  }
  pred.covariance = 0.5 * (pred.covariance + pred.covariance.transpose()).eval();
  return front_end_->plan(pred);
}

FrameResult Localizer::observe_frame(double t, const ImageView& left, const ImageView& right, FrameUpdate how) {
  if (!front_end_) detail::bad("observe_frame: no front end (set_front_end first)");
  const RectifiedCamera& cam = front_end_->rig().camera;
  for (const auto& [v, name] : {std::pair{&left, "left"}, std::pair{&right, "right"}})
    if (v->cols != cam.width || v->rows != cam.height)
      detail::bad(std::string(name) + " image is " + std::to_string(v->cols) + "x" + std::to_string(v->rows) +
                  " px but the rig is " + std::to_string(cam.width) + "x" + std::to_string(cam.height) + " px");
  return observe_frame(t, StereoImages(left, right), how);
}

FrameResult Localizer::observe_frame(double t, const StereoPixels& pixels, FrameUpdate how,
                                     const SightingEdit& edit) {
  return observe_frame(t, pixels, frame_plan(t), how, edit);
}

FrameResult Localizer::observe_frame(double t, const StereoPixels& pixels, const SearchPlan& plan, FrameUpdate how,
                                     const SightingEdit& edit) {
  if (!front_end_) detail::bad("observe_frame: no front end (set_front_end first)");
  FrameResult out;
  out.plan = plan;
  out.fix = front_end_->localize(pixels, out.plan, edit);
  const std::size_t n = out.fix.observations.size();
  out.update.status = InputStatus::Ignored;
  out.landmarks.assign(n, out.update);
  if (how == FrameUpdate::Fix || (how == FrameUpdate::FixOrLandmarks && out.fix.ok())) {
    if (!out.fix.ok()) return out;
    out.update = fix(t, out.fix.position, out.fix.covariance);
    for (std::size_t i = 0; i < n; ++i)
      if (out.fix.observations[i].ok) out.landmarks[i] = out.update;
    return out;
  }
  for (const LandmarkSighting& o : out.fix.observations)
    if (o.ok && landmark_index(o.landmark_id) < 0)
      detail::bad("front end landmark " + std::to_string(o.landmark_id) +
                  " is not in the localizer's map: FrameUpdate::Landmarks needs the map's ids");
  bool first = true;
  for (std::size_t i = 0; i < n; ++i) {
    const LandmarkSighting& o = out.fix.observations[i];
    if (!o.ok) continue;
    LandmarkObservation obs;
    obs.id = o.landmark_id;
    obs.range = o.range;
    obs.bearing = o.bearing;
    obs.range_std = o.sigma;
    obs.bearing_std = o.bearing_sigma;
    out.landmarks[i] = observe(t, obs);
    if (first || out.landmarks[i].applied()) out.update = out.landmarks[i];
    first = false;
  }
  return out;
}

}  // namespace safenav
