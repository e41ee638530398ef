// LocalizerSettings (safenav/localizer.hpp): its parameter declarations and
// validation, beside the localizer (localizer.cpp holds the filter itself).
#include "safenav/localizer.hpp"

#include "declare.hpp"
#include "errors.hpp"

namespace safenav {

template <>
const ParamSet<LocalizerSettings>& param_set<LocalizerSettings>();  // defined below

void LocalizerSettings::validate() const {
  bmm.validate();
  if (filter.type == FilterType::InformationFilter)
    detail::bad("localizer.filter.type = InformationFilter: the localizer runs the EKF or the particle filter");
  filter.validate("localizer.filter.");
  augment.validate();
  param_set<LocalizerSettings>().check(*this, "localizer.");
}

template <>
const ParamSet<LocalizerSettings>& param_set<LocalizerSettings>() {
  using L = LocalizerSettings;
  // The nested structs' parameters are declared beside them (FilterOptions in
  // filters/checks.cpp, BmmParams in motion.cpp, AugmentedStates in
  // filters/augmented_params.cpp) and included here: gate_probability,
  // filter_n_particles, …, bmm_dt, …, augment_scale_prior, ….
  static const ParamSet<L> s =
      Declare<L>{}
          .nested("filter_", param_set<FilterOptions>(), SN_REF(L, filter), {{"gate_probability", "gate_probability"}})
          .real("init_window", SN_REF(L, init_window), "s", above(0, 1e4), "starting from the data: the odometry track and ranges of the last init_window seconds are fitted together")
          .real("init_min_path", SN_REF(L, init_min_path), "m", closed(0, 1e4), "starting from the data: odometry path within the window before a fit is tried (heading is unobservable at rest)")
          .integer("init_min_beacons", SN_REF(L, init_min_beacons), closed(2, 1000), "starting from the data: distinct landmarks ranged within the window before a fit is tried")
          .real("init_max_rms", SN_REF(L, init_max_rms), "m or sigma", above(0, 1e4), "starting from the data: accept the fit only if its inlier residual RMS is below this (metres for a range-only fit, sigma units when bearings or headings are fitted)")
          .real("init_max_pos_std", SN_REF(L, init_max_pos_std), "m", above(0, 1e4), "starting from the data: accept the fit only if its position sigma is below this")
          .real("init_max_heading_std", SN_REF(L, init_max_heading_std), "rad", above(0, 3.2), "starting from the data with bearings or headings: accept the fit only if its heading sigma is below this")
          .real("init_min_inlier_share", SN_REF(L, init_min_inlier_share), "", closed(0, 1), "starting from the data: accept the fit only if it keeps this share of its residuals within 3 sigma (a mirror image drops many)")
          .real("init_cov_inflation", SN_REF(L, init_cov_inflation), "", closed(1, 1e4), "starting from the data: the fit's pose covariance is multiplied by this")
          .real("init_baseline", SN_REF(L, init_baseline), "m", above(0, 1e4), "starting from position fixes: motion before the heading is taken from two positions")
          .real("init_speed_std", SN_REF(L, init_speed_std), "m/s", above(0, 100), "sigma of the initial speed when starting from the data")
          .integer("reset_after_rejections", SN_REF(L, reset_after_rejections), closed(0, 1e6), "consecutive fixes rejected by the gate before the next resets the position; 0 = never")
          .integer("reset_after_consistent", SN_REF(L, reset_after_consistent), closed(0, 8), "a rejected fix that agrees (chi-square at the gate's probability, after the predicted motion) with each of the reset_after_consistent - 1 rejected fixes before it resets the position; 0 = never")
          .real("reset_discredit_tail", SN_REF(L, reset_discredit_tail), "", closed(0, 1), "a rejected fix that contradicts the newest fix through the gate (chi-square after the predicted motion, beyond the quantile with this tail) counts toward no agreement reset; 0 = off")
          .real("max_delay", SN_REF(L, max_delay), "s", closed(0, 60), "a measurement at most this much older than the filter's time is applied at its own time (the inputs since are applied again); 0 = late measurements are dropped")
          .nested("bmm_", param_set<BmmParams>(), SN_REF(L, bmm))
          .nested("augment_", param_set<AugmentedStates>(), SN_REF(L, augment))
          .set;
  return s;
}

template class ParamSet<LocalizerSettings>;

}  // namespace safenav
