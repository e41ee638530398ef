// AugmentedStates (safenav/augmented.hpp): its parameter declarations and
// validation.  A sibling of augmented.cpp, which is near the 600-line limit.
#include "safenav/augmented.hpp"

#include "../declare.hpp"

namespace safenav {

template <>
const ParamSet<AugmentedStates>& param_set<AugmentedStates>();  // defined below

void AugmentedStates::validate() const { param_set<AugmentedStates>().check(*this, "augment."); }

template <>
const ParamSet<AugmentedStates>& param_set<AugmentedStates>() {
  using A = AugmentedStates;
  // The on/off switches (range_scale, heading_rate_bias, range_bias) are bools, set directly.
  static const ParamSet<A> s =
      Declare<A>{}
          .real("scale_prior", SN_REF(A, scale_prior), "", closed(-0.5, 0.5), "k0, prior mean of the range scale k: r = (1+k)|p - a| + b (ours; Plaza reads ~7 % long)")
          .real("scale_std", SN_REF(A, scale_std), "", above(0, 1), "sigma of k0")
          .real("scale_walk", SN_REF(A, scale_walk), "1/sqrt(s)", closed(0, 1), "random walk of k per sqrt(second)")
          .real("heading_rate_bias_prior", SN_REF(A, heading_rate_bias_prior), "rad/s", closed(-1, 1), "beta0, prior mean of the heading-rate (gyro) bias: theta' = theta + clip(dtheta) - beta*dt (ours)")
          .real("heading_rate_bias_std", SN_REF(A, heading_rate_bias_std), "rad/s", above(0, 1), "sigma of beta0")
          .real("heading_rate_bias_walk", SN_REF(A, heading_rate_bias_walk), "rad/s/sqrt(s)", closed(0, 1), "random walk of beta per sqrt(second)")
          .real("range_bias_std", SN_REF(A, range_bias_std), "m", above(0, 100), "sigma of each landmark's range bias b_j (prior mean 0; ours)")
          .real("range_bias_walk", SN_REF(A, range_bias_walk), "m/sqrt(s)", closed(0, 10), "random walk of each b_j per sqrt(second)")
          .set;
  return s;
}

template class ParamSet<AugmentedStates>;

}  // namespace safenav
