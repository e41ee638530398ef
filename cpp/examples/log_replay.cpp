// log_replay — run a timestamped log through the online Localizer.
//
// Reads a log CSV in the format of docs/replay.md (one table; each row one
// input, its `kind` saying which cells it uses), feeds its inputs to a
// safenav::Localizer in time order — exactly as a vehicle's loop would, and
// as `safenav replay LOG` (python/safenav/replay.py) does — and writes the
// estimate after each motion input as CSV:
//
//   t,x,y,speed,heading,var_x,var_y,cov_xy,var_speed,var_heading
//
// The localizer starts from the data (ranges to ≥ 3 landmarks, then the
// motion of the first metres), or with --prior-from-truth from the first
// truth pose (σ = 0.1 m, 0.1 m, 0.5 m/s, 0.02 rad, as the Python CLI).  When
// the log has truth rows the program prints the position RMSE, ADE and FDE,
// causal: each truth pose is scored against the latest estimate at or before
// its time (python/safenav/replay.py's `score`), by the core's TrajectoryScore.
//
//   log_replay LOG.csv [-o TRAJECTORY.csv] [--prior-from-truth]
//
// The trajectory goes to -o's file, or to stdout; the summary (key=value)
// goes to stdout, or to stderr when the trajectory is on stdout.  Plain C++:
// the parser checks the header, the kinds, the numbers and the landmark ids
// (safenav.logs.read_log checks everything the format says).  Exit 0 on
// success, 2 on a usage or log error.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <safenav/localizer.hpp>
#include <safenav/metrics.hpp>

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const char* const kColumns[] = {"t",     "kind",    "landmark",  "x",         "y",           "heading", "speed",
                                "distance", "heading_change", "range", "bearing", "range_std", "bearing_std",
                                "std_x", "std_y"};
enum Col { T, KIND, LANDMARK, X, Y, HEADING, SPEED, DISTANCE, HEADING_CHANGE, RANGE, BEARING, RANGE_STD,
           BEARING_STD, STD_X, STD_Y, NCOLS };

/// One input row of the log (every numeric cell; NaN where empty).
struct Row {
  std::string kind;
  double v[NCOLS];
  int line;
};

struct Log {
  std::map<int, Eigen::Vector2d> landmarks;  // by id (sorted, as the Python replay)
  std::vector<Row> events;                   // stably sorted by t
  std::vector<Row> truth;                    // stably sorted by t
};

[[noreturn]] void fail(const std::string& where, const std::string& what) {
  throw std::runtime_error(where + ": " + what);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

Log read_log(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, "cannot open");
  std::string line;
  if (!std::getline(in, line)) fail(path, "empty file");
  if (!line.empty() && line.back() == '\r') line.pop_back();
  int index[NCOLS];
  std::fill(index, index + NCOLS, -1);
  const std::vector<std::string> header = split(line);
  for (std::size_t i = 0; i < header.size(); ++i) {
    const auto it = std::find(std::begin(kColumns), std::end(kColumns), header[i]);
    if (it == std::end(kColumns)) fail(path, "unknown column '" + header[i] + "'");
    index[it - std::begin(kColumns)] = static_cast<int>(i);
  }
  if (index[KIND] < 0) fail(path, "no 'kind' column");

  Log log;
  for (int lineno = 2; std::getline(in, line); ++lineno) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const std::vector<std::string> cells = split(line);
    const std::string where = path + ": line " + std::to_string(lineno);
    if (cells.size() != header.size())
      fail(where, std::to_string(cells.size()) + " cells, the header has " + std::to_string(header.size()));
    Row row;
    row.line = lineno;
    row.kind = cells[static_cast<std::size_t>(index[KIND])];
    for (int c = 0; c < NCOLS; ++c) {
      row.v[c] = kNaN;
      if (c == KIND || index[c] < 0) continue;
      const std::string& s = cells[static_cast<std::size_t>(index[c])];
      if (s.empty()) continue;
      char* end = nullptr;
      row.v[c] = std::strtod(s.c_str(), &end);
      if (end == s.c_str() || *end != '\0' || !std::isfinite(row.v[c]))
        fail(where, std::string("column '") + kColumns[c] + "' = '" + s + "': not a finite number");
    }
    if (row.kind == "landmark") {
      const double id = row.v[LANDMARK];
      if (!(id >= 0 && id <= 2147483647.0 && id == std::floor(id))) fail(where, "bad landmark id");
      if (!log.landmarks.emplace(static_cast<int>(id), Eigen::Vector2d(row.v[X], row.v[Y])).second)
        fail(where, "landmark " + std::to_string(static_cast<int>(id)) + " defined twice");
    } else if (row.kind == "truth") {
      log.truth.push_back(row);
    } else if (row.kind == "odometry" || row.kind == "motion" || row.kind == "range" || row.kind == "bearing" ||
               row.kind == "range_bearing" || row.kind == "fix") {
      if (std::isnan(row.v[T])) fail(where, "no time 't'");
      log.events.push_back(row);
    } else {
      fail(where, "unknown kind '" + row.kind + "'");
    }
  }
  if (log.events.empty()) fail(path, "no input rows");
  for (const Row& r : log.events)
    if ((r.kind == "range" || r.kind == "bearing" || r.kind == "range_bearing") &&
        !log.landmarks.count(static_cast<int>(r.v[LANDMARK])))
      fail(path + ": line " + std::to_string(r.line), "unknown landmark id " + std::to_string(r.v[LANDMARK]));
  const auto by_time = [](const Row& a, const Row& b) { return a.v[T] < b.v[T]; };
  std::stable_sort(log.events.begin(), log.events.end(), by_time);
  std::stable_sort(log.truth.begin(), log.truth.end(), by_time);
  return log;
}

struct Estimate {
  double t, x, y, speed, heading, var_x, var_y, cov_xy, var_speed, var_heading;
};

int usage(const char* msg) {
  std::fprintf(stderr, "%s\nusage: log_replay LOG.csv [-o TRAJECTORY.csv] [--prior-from-truth]\n", msg);
  return 2;
}

/// One input row to the localizer, by its kind.
void feed(safenav::Localizer& loc, const Row& r) {
  const double t = r.v[T];
  if (r.kind == "odometry") {
    loc.odometry(t, r.v[DISTANCE], r.v[HEADING_CHANGE]);
  } else if (r.kind == "motion") {
    loc.motion(t, safenav::Control(r.v[SPEED], r.v[HEADING_CHANGE]));
  } else if (r.kind == "fix") {
    Eigen::Matrix2d R = Eigen::Matrix2d::Zero();
    R.diagonal() << r.v[STD_X] * r.v[STD_X], r.v[STD_Y] * r.v[STD_Y];
    loc.fix(t, Eigen::Vector2d(r.v[X], r.v[Y]), R);
  } else {  // range, bearing, range_bearing
    safenav::LandmarkObservation obs;
    obs.id = static_cast<int>(r.v[LANDMARK]);
    obs.range = r.v[RANGE];
    obs.bearing = r.v[BEARING];
    obs.range_std = std::isnan(r.v[RANGE_STD]) ? 1.0 : r.v[RANGE_STD];
    obs.bearing_std = std::isnan(r.v[BEARING_STD]) ? 0.05 : r.v[BEARING_STD];
    loc.observe(t, obs);
  }
}

/// Feeds the inputs in time order; records the start, then the estimate after
/// each motion input.  Returns the start time (NaN: never started).
double run(safenav::Localizer& loc, const Log& log, std::vector<Estimate>& traj) {
  traj.reserve(log.events.size() + 1);
  auto record = [&] {
    const safenav::State& x = loc.x();
    const safenav::StateCov& P = loc.P();
    traj.push_back({loc.time(), x[0], x[1], x[2], x[3], P(0, 0), P(1, 1), P(0, 1), P(2, 2), P(3, 3)});
  };
  double t_start = kNaN;
  if (loc.initialized()) {
    t_start = loc.time();
    record();
  }
  for (const Row& r : log.events) {
    feed(loc, r);
    const bool motion = r.kind == "odometry" || r.kind == "motion";
    if (std::isnan(t_start) && loc.initialized()) {  // started from the data: its first estimate
      t_start = loc.time();
      record();
    } else if (motion && loc.initialized()) {
      record();
    }
  }
  return t_start;
}

bool write_trajectory(const std::vector<Estimate>& traj, FILE* out) {
  std::fprintf(out, "t,x,y,speed,heading,var_x,var_y,cov_xy,var_speed,var_heading\n");
  for (const Estimate& e : traj)
    std::fprintf(out, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", e.t, e.x, e.y, e.speed,
                 e.heading, e.var_x, e.var_y, e.cov_xy, e.var_speed, e.var_heading);
  return !std::ferror(out);
}

/// Causal scores: the latest estimate at or before each truth time, fed to the
/// core's one trajectory-score accumulator (as safenav.replay.score).
void print_scores(const Log& log, const std::vector<Estimate>& traj, FILE* info) {
  if (log.truth.empty() || traj.empty()) return;
  safenav::TrajectoryScore score(static_cast<Eigen::Index>(log.truth.size()));
  int before = 0;
  for (const Row& g : log.truth) {
    const auto it = std::upper_bound(traj.begin(), traj.end(), g.v[T] + 1e-9,
                                     [](double t, const Estimate& e) { return t < e.t; });
    if (it == traj.begin()) {
      ++before;
      continue;
    }
    const Estimate& e = *(it - 1);
    score.add(Eigen::Vector2d(e.x, e.y), (Eigen::Matrix2d() << e.var_x, e.cov_xy, e.cov_xy, e.var_y).finished(),
              Eigen::Vector2d(g.v[X], g.v[Y]));
  }
  if (score.size() > 0)
    std::fprintf(info, "truth_rmse=%.17g truth_ade=%.17g truth_fde=%.17g nees=%.17g n_scored=%d n_before_start=%d\n",
                 score.truth_rmse(), score.truth_ade(), score.truth_fde(), score.position_nees(),
                 static_cast<int>(score.size()), before);
}

safenav::Localizer make_localizer(const Log& log) {
  std::vector<int> ids;
  safenav::Landmarks landmarks(static_cast<Eigen::Index>(log.landmarks.size()), 2);
  for (const auto& [id, p] : log.landmarks) {
    landmarks.row(static_cast<Eigen::Index>(ids.size())) = p.transpose();
    ids.push_back(id);
  }
  // As `safenav replay`'s default preset: the online defaults, with the log's
  // motion rows read as the speed the vehicle reported (signed, at once).
  safenav::LocalizerSettings settings;
  settings.bmm.unicycle = true;
  return safenav::Localizer(settings, landmarks, ids);
}

}  // namespace

int main(int argc, char** argv) {
  std::string log_path, out_path;
  bool prior_from_truth = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--prior-from-truth") prior_from_truth = true;
    else if (a == "-o" || a == "--output") {
      if (++i == argc) return usage("-o needs a path");
      out_path = argv[i];
    } else if (!a.empty() && a[0] == '-') return usage(("unknown option " + a).c_str());
    else if (log_path.empty()) log_path = a;
    else return usage("one log only");
  }
  if (log_path.empty()) return usage("no log given");

  Log log;
  try {
    log = read_log(log_path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "log_replay: %s\n", e.what());
    return 2;
  }
  safenav::Localizer loc = make_localizer(log);
  if (prior_from_truth) {
    if (log.truth.empty()) return usage("--prior-from-truth: the log has no truth rows");
    const Row& r = log.truth.front();
    if (std::isnan(r.v[HEADING])) return usage("--prior-from-truth: the first truth row has no heading");
    safenav::StateCov P0 = safenav::StateCov::Zero();
    P0.diagonal() << 0.1 * 0.1, 0.1 * 0.1, 0.5 * 0.5, 0.02 * 0.02;
    loc.initialize(r.v[T], safenav::State(r.v[X], r.v[Y], 0.0, r.v[HEADING]), P0);
  }
  std::vector<Estimate> traj;
  const double t_start = run(loc, log, traj);

  FILE* out = stdout;
  if (!out_path.empty() && !(out = std::fopen(out_path.c_str(), "w"))) {
    std::fprintf(stderr, "log_replay: cannot write %s\n", out_path.c_str());
    return 2;
  }
  const bool written = write_trajectory(traj, out);
  if (out != stdout && std::fclose(out) != 0) return usage("cannot finish writing the trajectory");
  if (!written) return usage("cannot write the trajectory");

  FILE* info = out_path.empty() ? stderr : stdout;
  const safenav::LocalizerCounts& c = loc.counts();
  std::fprintf(info, "started_from=%s t_start=%.17g rows=%zu motion=%d applied=%d rejected=%d late=%d buffered=%d\n",
               prior_from_truth ? "prior" : "data", t_start, traj.size(), c.motion, c.applied, c.rejected, c.late,
               c.buffered);
  print_scores(log, traj, info);
  if (std::isnan(t_start)) {  // nothing was estimated: say why, and fail (as `safenav replay`)
    std::fprintf(stderr, "log_replay: never started: %s\n", loc.reason().c_str());
    return 3;
  }
  return 0;
}
