// The online Localizer: late measurements applied at their own time
// (safenav/localizer.hpp, "Time").
//
// Once started, the localizer logs every input of the last max_delay seconds
// and, before each motion input, a checkpoint: a copy of the filter (its
// estimate, particles and generator state), the clock and the counts.  A
// measurement older than the filter's time by at most max_delay goes back to
// the newest checkpoint at or before its time, and the logged inputs from
// there are applied again in their order with the late one among them at its
// time: the result is the one the same inputs would have given in time order,
// bit for bit (a particle filter draws the same numbers, as its generator is
// restored too).  This is the history re-filtering of robot_localization's
// smoothed lag, at the cost of re-running at most max_delay of inputs per
// late measurement; nothing is re-run when no input is late.
#include "localizer_impl.hpp"

namespace safenav {

InputResult Localizer::Impl::take(const LoggedInput& in) {
  if (settings.max_delay <= 0.0) return apply(in);
  if (in.measurement() && in.t < t_f - kSameTime) return take_late(in);
  return take_now(in);
}

InputResult Localizer::Impl::take_now(const LoggedInput& in) {
  if (in.measurement()) {
    const InputResult r = apply(in);
    inputs.push_back(in);
    return r;
  }
  Checkpoint c = capture();
  c.input = first_input + inputs.size();
  InputResult r;
  try {
    r = apply(in);
  } catch (...) {
    recycle(c);
    throw;
  }
  inputs.push_back(in);
  checkpoints.push_back(std::move(c));
  prune();
  return r;
}

InputResult Localizer::Impl::take_late(const LoggedInput& in) {
  // The newest checkpoint at or before the measurement's time.
  std::size_t k = checkpoints.size();
  while (k > 0 && checkpoints[k - 1].clock.t_f > in.t) --k;
  if (in.t < t_f - settings.max_delay - kSameTime) return status(InputStatus::Late);
  if (k == 0) return take_before_start(in);  // older than every checkpoint: from before the start
  --k;
  // Keep everything until the replay succeeds: on an error the localizer is left as it was.
  Checkpoint now = capture();
  const std::vector<LoggedInput> saved_inputs = inputs;
  std::vector<Checkpoint> dropped(std::make_move_iterator(checkpoints.begin() + static_cast<std::ptrdiff_t>(k)),
                                  std::make_move_iterator(checkpoints.end()));
  checkpoints.resize(k);
  const std::size_t from = static_cast<std::size_t>(dropped.front().input - first_input);
  redo.assign(inputs.begin() + static_cast<std::ptrdiff_t>(from), inputs.end());
  inputs.resize(from);
  restore(dropped.front());
  InputResult result;
  replaying = true;  // no pruning: checkpoints [0, k) stay as they are, the new ones follow
  try {
    bool placed = false;
    for (const LoggedInput& e : redo) {
      if (!placed && e.t > in.t) {
        result = take_now(in);
        placed = true;
      }
      take_now(e);
    }
    if (!placed) result = take_now(in);
  } catch (...) {
    replaying = false;
    for (std::size_t i = k; i < checkpoints.size(); ++i) recycle(checkpoints[i]);
    checkpoints.resize(k);
    for (Checkpoint& c : dropped) checkpoints.push_back(std::move(c));
    inputs = saved_inputs;
    restore(now);
    recycle(now);
    throw;
  }
  replaying = false;
  for (Checkpoint& c : dropped) recycle(c);
  recycle(now);
  prune();
  return result;
}

Localizer::Impl::Checkpoint Localizer::Impl::capture() {
  Checkpoint c;
  c.clock = clock();
  c.counts = counts;
  c.fix_rejections = fix_rejections;
  if (smoother) c.smoother_mark = smoother->mark();
  if (spare_filters.empty()) {
    c.filter = filter->clone();
  } else {
    c.filter = std::move(spare_filters.back());
    spare_filters.pop_back();
    c.filter->assign(*filter);
  }
  return c;
}

void Localizer::Impl::restore(const Checkpoint& c) {
  filter->assign(*c.filter);
  set_clock(c.clock);
  counts = c.counts;
  fix_rejections = c.fix_rejections;
  if (smoother) smoother->rewind(c.smoother_mark);  // the inputs after it are recorded again
}

void Localizer::Impl::recycle(Checkpoint& c) {
  if (c.filter) spare_filters.push_back(std::move(c.filter));
}

/// Drops the checkpoints (and the inputs before them) that no measurement
/// within max_delay can need: all but the newest at or before t_f − max_delay.
void Localizer::Impl::prune() {
  if (replaying) return;
  const double horizon = t_f - settings.max_delay;
  std::size_t keep = 0;  // the first checkpoint kept
  while (keep + 1 < checkpoints.size() && checkpoints[keep + 1].clock.t_f <= horizon) ++keep;
  if (keep == 0) return;
  for (std::size_t i = 0; i < keep; ++i) recycle(checkpoints[i]);
  checkpoints.erase(checkpoints.begin(), checkpoints.begin() + static_cast<std::ptrdiff_t>(keep));
  const std::size_t drop = static_cast<std::size_t>(checkpoints.front().input - first_input);
  inputs.erase(inputs.begin(), inputs.begin() + static_cast<std::ptrdiff_t>(drop));
  first_input += drop;
}

void Localizer::Impl::clear_history() {
  for (Checkpoint& c : checkpoints) recycle(c);
  checkpoints.clear();
  first_input += inputs.size();
  inputs.clear();
  start_window = StartWindow();
  spare_filters.clear();  // a new filter may be another implementation or size
}

// -- a measurement older than the start from the data -------------------------
//
// The start from the data fits the observations buffered before it
// (localizer_start.cpp).  A range or bearing taken before that start but
// delivered after it, at most max_delay older than the filter, would have been
// in that fit had it arrived in time order.  So the localizer keeps the
// start's window (its buffered observations, headings and motion integral)
// and a checkpoint at the start while the history reaches back to it; such an
// observation re-runs the start: the fit again with it in the window, then the
// inputs since, applied again.  When the refitted start is refused, the old
// start stands and the observation counts as rejected.

void Localizer::Impl::keep_start(StartWindow w) {
  start_window = StartWindow();
  if (settings.max_delay <= 0.0) return;
  Checkpoint c = capture();
  c.input = first_input + inputs.size();
  c.start = true;
  w.input = c.input;
  w.kept = true;
  start_window = std::move(w);
  checkpoints.push_back(std::move(c));
}

Localizer::Impl::StartWindow Localizer::Impl::start_window_now(double t) const {
  StartWindow w;
  w.t = t;
  w.ranges = ranges;
  w.headings = headings;
  w.track = track;
  w.why = why;
  return w;
}

InputResult Localizer::Impl::take_before_start(const LoggedInput& in) {
  // The start's checkpoint must still be the oldest: every input since it is logged.
  if (in.kind != LoggedInput::Kind::Observation || !start_window.kept || checkpoints.empty() ||
      !checkpoints.front().start || in.t > start_window.t)
    return status(InputStatus::Late);
  StartWindow w = std::move(start_window);
  start_window = StartWindow();
  Checkpoint c0 = std::move(checkpoints.front());
  for (std::size_t i = 1; i < checkpoints.size(); ++i) recycle(checkpoints[i]);
  checkpoints.clear();
  const std::size_t from = static_cast<std::size_t>(c0.input - first_input);
  redo.assign(inputs.begin() + static_cast<std::ptrdiff_t>(from), inputs.end());
  inputs.resize(from);
  // Back to the start's motion input, not started, with the observation in the window.
  spare_filters.push_back(std::move(filter));
  const std::string started = why;
  set_clock(c0.clock);
  counts = c0.counts;
  fix_rejections = c0.fix_rejections;
  if (smoother) smoother->rewind(c0.smoother_mark);  // the inputs after the start are recorded again
  const LandmarkObservation& o = in.obs;
  const bool has_r = !std::isnan(o.range), has_b = !std::isnan(o.bearing);
  ranges = w.ranges;
  ranges.push_back(BufferedObs{in.t, row_of.at(o.id), has_r ? o.range : kNaN, o.range_std,
                               has_b ? o.bearing : kNaN, o.bearing_std});
  headings = w.headings;
  track = w.track;
  why = w.why;
  fresh = true;
  InputResult result = status(InputStatus::Buffered);
  try_fit(w.t);  // the start again; accept_fit keeps its window and checkpoint
  if (!initialized()) {
    // The fit with it is refused: the old start stands, and the observation is rejected.
    ranges.clear();
    headings.clear();
    track.clear();
    filter = std::move(c0.filter);
    set_clock(c0.clock);
    counts = c0.counts;
    ++counts.rejected;
    result = InputResult{};
    result.status = InputStatus::Rejected;
    if (smoother) smoother->cut();
    why = started;
    keep_start(std::move(w));
  }
  recycle(c0);
  replaying = true;
  try {
    for (const LoggedInput& e : redo) take_now(e);
  } catch (...) {
    replaying = false;
    throw;
  }
  replaying = false;
  prune();
  return result;
}

}  // namespace safenav
