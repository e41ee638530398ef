// safenav/seed.hpp — the one seed rule of the core.
//
// Every random source of a trial (true-vehicle motion, sensors, the particle
// filter, each RAw-RRT* detour, the planner's sampler, tree and simplifier)
// gets its own generator seeded with derive_seed(trial_seed, stream), so that
// adding a source never shifts the numbers of another.  Python binds it as
// safenav.derive_seed; the trial seeds themselves follow the rule in
// safenav/runner.py (docs/paper_map.md lists both).
#pragma once

#include <cstdint>

namespace safenav {

/// splitmix64's output function (Steele, Lea & Flood 2014): a bijection of
/// 64-bit words with good avalanche.
constexpr std::uint64_t splitmix64_mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// splitmix64's golden-ratio increment.
constexpr std::uint64_t kSplitmix64Gamma = 0x9e3779b97f4a7c15ULL;

/// An independent, reproducible sub-seed of `seed` for random source
/// `stream`: the (stream + 1)-th output of a splitmix64 sequence started at
/// `seed`.
constexpr std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t stream) {
  return splitmix64_mix(seed + kSplitmix64Gamma * (stream + 1));
}

}  // namespace safenav
