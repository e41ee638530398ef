// Batch filtering: one filter over a whole control and measurement stream.
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "safenav/filters.hpp"

namespace safenav {

void MeasurementStream::validate(int n_steps) const {
  auto bad_rows = [&](const char* name, Eigen::Index rows) {
    if (rows != 0 && rows != n_steps) {
      std::ostringstream os;
      os << "measurement stream '" << name << "' has " << rows << " rows, expected " << n_steps
         << " (one per control step) or 0";
      throw std::invalid_argument(os.str());
    }
  };
  bad_rows("position", position.rows());
  bad_rows("speed_heading", speed_heading.rows());
  bad_rows("ranges", ranges.rows());
  bad_rows("bearings", bearings.rows());
  auto check_rows = [](const char* name, const RowMatrixX2& m) {
    for (Eigen::Index k = 0; k < m.rows(); ++k) {
      const bool nan0 = std::isnan(m(k, 0)), nan1 = std::isnan(m(k, 1));
      if (nan0 && nan1) continue;  // a gap
      if (nan0 || nan1 || !std::isfinite(m(k, 0)) || !std::isfinite(m(k, 1))) {
        std::ostringstream os;
        os << "measurement stream '" << name << "' row " << k << " = (" << m(k, 0) << ", " << m(k, 1)
           << ") is invalid: use a full NaN row for a gap, finite values otherwise";
        throw std::invalid_argument(os.str());
      }
    }
  };
  check_rows("position", position);
  check_rows("speed_heading", speed_heading);
  auto check_lm = [&](const char* name, const RowMatrixXd& m) {
    if (m.rows() == 0) return;
    if (m.cols() != landmarks.rows()) {
      std::ostringstream os;
      os << "measurement stream '" << name << "' has " << m.cols() << " columns but there are "
         << landmarks.rows() << " landmarks";
      throw std::invalid_argument(os.str());
    }
    for (Eigen::Index k = 0; k < m.rows(); ++k)
      for (Eigen::Index j = 0; j < m.cols(); ++j)
        if (std::isinf(m(k, j))) {
          std::ostringstream os;
          os << "measurement stream '" << name << "' row " << k << " landmark " << j << " = " << m(k, j)
             << " is not finite (use NaN for 'not observed')";
          throw std::invalid_argument(os.str());
        }
  };
  check_lm("ranges", ranges);
  check_lm("bearings", bearings);
}

namespace {

template <class Filter>
State estimate(const Filter& f);
template <>
State estimate(const Ekf& f) { return f.x(); }
template <>
State estimate(const InformationFilter& f) { return f.x(); }
template <>
State estimate(const ParticleFilter& f) { return f.mean(); }

template <class Filter>
StateCov estimate_cov(const Filter& f, const State&);
template <>
StateCov estimate_cov(const Ekf& f, const State&) { return f.P(); }
template <>
StateCov estimate_cov(const InformationFilter& f, const State&) { return f.P(); }
template <>
StateCov estimate_cov(const ParticleFilter& f, const State& mean) { return f.covariance(mean); }

/// Landmark model restricted to the landmarks seen in row k (NaN = unseen).
struct LandmarkStream {
  const RowMatrixXd* data = nullptr;
  std::unique_ptr<MeasurementModel> full;
  std::vector<int> seen;
  Eigen::VectorXd z;

  bool step(Eigen::Index k, std::unique_ptr<MeasurementModel>& subset_out, const MeasurementModel*& model) {
    if (!data || data->rows() == 0) return false;
    seen.clear();
    for (Eigen::Index j = 0; j < data->cols(); ++j)
      if (!std::isnan((*data)(k, j))) seen.push_back(static_cast<int>(j));
    if (seen.empty()) return false;
    z.resize(static_cast<Eigen::Index>(seen.size()));
    for (size_t j = 0; j < seen.size(); ++j) z[static_cast<Eigen::Index>(j)] = (*data)(k, seen[j]);
    if (static_cast<Eigen::Index>(seen.size()) == data->cols()) {
      model = full.get();
    } else {
      subset_out = std::make_unique<MeasurementModel>(full->subset(seen));
      model = subset_out.get();
    }
    return true;
  }
};

template <class Filter>
FilterRun run_impl(Filter& f, const Eigen::Ref<const RowMatrixX2>& controls, const MeasurementStream& st,
                   const std::function<int()>& resampled) {
  const Eigen::Index N = controls.rows();
  FilterRun out;
  out.states.resize(N + 1, 4);
  out.covariances.resize(N + 1, 16);
  out.nis = Eigen::VectorXd::Constant(N, std::numeric_limits<double>::quiet_NaN());
  out.nis_dof = Eigen::VectorXi::Zero(N);

  std::unique_ptr<MeasurementModel> pos, imu;
  if (st.position.rows()) pos = std::make_unique<MeasurementModel>(MeasurementModel::position(st.position_cov));
  if (st.speed_heading.rows())
    imu = std::make_unique<MeasurementModel>(MeasurementModel::speed_heading(st.speed_heading_cov));
  LandmarkStream rng_s, brg_s;
  if (st.ranges.rows()) {
    rng_s.data = &st.ranges;
    rng_s.full = std::make_unique<MeasurementModel>(MeasurementModel::range(st.landmarks, st.range_std));
  }
  if (st.bearings.rows()) {
    brg_s.data = &st.bearings;
    brg_s.full = std::make_unique<MeasurementModel>(MeasurementModel::bearing(st.landmarks, st.bearing_std));
  }

  auto record = [&](Eigen::Index row) {
    const State m = estimate(f);
    const StateCov P = estimate_cov(f, m);
    out.states.row(row) = m.transpose();
    out.covariances.row(row) = Eigen::Map<const Eigen::Matrix<double, 1, 16>>(P.data());  // symmetric
  };
  record(0);
  for (Eigen::Index k = 0; k < N; ++k) {
    const Control u = controls.row(k).transpose();
    if (!u.allFinite()) {
      std::ostringstream os;
      os << "controls row " << k << " = (" << u[0] << ", " << u[1] << ") is not finite";
      throw std::invalid_argument(os.str());
    }
    f.predict(u);
    double nis = 0.0;
    int dof = 0, n_meas = 0;
    auto apply = [&](const MeasurementModel& model, const Eigen::Ref<const Eigen::VectorXd>& z) {
      const UpdateResult r = f.update(model, z);
      ++n_meas;
      if (r.accepted) {
        ++out.n_updates;
        nis += r.nis;
        dof += r.dim;
      } else {
        ++out.n_rejected;
      }
    };
    if (pos && !std::isnan(st.position(k, 0))) apply(*pos, st.position.row(k).transpose());
    if (imu && !std::isnan(st.speed_heading(k, 0))) apply(*imu, st.speed_heading.row(k).transpose());
    std::unique_ptr<MeasurementModel> sub;
    const MeasurementModel* lm_model = nullptr;
    if (rng_s.step(k, sub, lm_model)) apply(*lm_model, rng_s.z);
    if (brg_s.step(k, sub, lm_model)) apply(*lm_model, brg_s.z);
    if (n_meas == 0) ++out.n_gaps;
    if (dof > 0) {
      out.nis[k] = nis;
      out.nis_dof[k] = dof;
    }
    record(k + 1);
  }
  out.n_resampled = resampled();
  return out;
}

}  // namespace

FilterRun run_filter(const BmmParams& params, const FilterOptions& options, const State& x0, const StateCov& P0,
                     const Eigen::Ref<const RowMatrixX2>& controls, const MeasurementStream& stream) {
  stream.validate(static_cast<int>(controls.rows()));
  switch (options.type) {
    case FilterType::Ekf: {
      Ekf f(params, x0, P0);
      f.set_gate(options.gate_probability);
      return run_impl(f, controls, stream, [] { return 0; });
    }
    case FilterType::ParticleFilter: {
      ParticleFilter f(params, x0, P0, options.n_particles, options.seed, options.resample_threshold,
                       options.bandwidth_scale);
      return run_impl(f, controls, stream, [&f] { return f.resample_count(); });
    }
    case FilterType::InformationFilter: {
      InformationFilter f(params, x0, P0);
      return run_impl(f, controls, stream, [] { return 0; });
    }
  }
  throw std::invalid_argument("unknown filter type");
}

}  // namespace safenav
