// Internal: a small, fast, reproducible random number generator.
// xoshiro256++ (Blackman & Vigna, public domain) seeded through splitmix64, and
// standard normals by the ziggurat method (Marsaglia & Tsang 2000, 128 layers,
// with the tail and wedge handled exactly).  Unlike std::normal_distribution
// the sequence is fixed by this file, so results are identical across
// standard libraries and platforms for a given seed.
#pragma once

#include <cmath>
#include <cstdint>

namespace safenav::detail {

class Rng {
 public:
  explicit Rng(std::uint64_t seed) {
    std::uint64_t z = seed;
    for (auto& s : s_) s = splitmix64(z);
  }
  std::uint64_t next_u64() {
    const std::uint64_t result = rotl(s_[0] + s_[3], 23) + s_[0];
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }
  /// Uniform in (0, 1), never 0 (safe for log).
  double uniform_open() { return (static_cast<double>(next_u64() >> 11) + 0.5) * 0x1.0p-53; }
  /// Standard normal N(0, 1) (ziggurat).
  double normal() { return normal_from(static_cast<std::int32_t>(next_u64() >> 32), tables()); }

  /// Fill out[0..n) with standard normals; two per 64-bit draw.
  void fill_normal(double* out, long n) {
    const Tables& T = tables();
    long i = 0;
    for (; i + 1 < n; i += 2) {
      const std::uint64_t r = next_u64();
      out[i] = normal_from(static_cast<std::int32_t>(r >> 32), T);
      out[i + 1] = normal_from(static_cast<std::int32_t>(r & 0xffffffffULL), T);
    }
    if (i < n) out[i] = normal();
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  static std::uint64_t splitmix64(std::uint64_t& x) {
    std::uint64_t z = (x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  static constexpr double kR = 3.442619855899;  // start of the tail
  struct Tables;
  /// Ziggurat for one 32-bit draw hz: the fast path (~99% of draws) is inline.
  double normal_from(std::int32_t hz, const Tables& T) {
    const int iz = hz & 127;
    const std::uint32_t mag = hz < 0 ? 0u - static_cast<std::uint32_t>(hz) : static_cast<std::uint32_t>(hz);
    if (__builtin_expect(mag < T.kn[iz], 1)) return hz * T.wn[iz];
    return normal_slow(hz, T);
  }
  /// Wedge and tail of the ziggurat, with fresh draws on rejection.
  __attribute__((noinline)) double normal_slow(std::int32_t hz, const Tables& T) {
    for (;;) {
      const int iz = hz & 127;
      const double x = hz * T.wn[iz];
      const std::uint32_t mag = hz < 0 ? 0u - static_cast<std::uint32_t>(hz) : static_cast<std::uint32_t>(hz);
      if (mag < T.kn[iz]) return x;
      if (iz == 0) {  // tail beyond r
        double xt, yt;
        do {
          xt = -std::log(uniform_open()) / kR;
          yt = -std::log(uniform_open());
        } while (yt + yt < xt * xt);
        return hz > 0 ? kR + xt : -kR - xt;
      }
      if (T.fn[iz] + uniform() * (T.fn[iz - 1] - T.fn[iz]) < std::exp(-0.5 * x * x)) return x;  // wedge
      hz = static_cast<std::int32_t>(next_u64() >> 32);
    }
  }
  struct Tables {
    std::uint32_t kn[128];
    double wn[128], fn[128];
    Tables() {
      const double m1 = 2147483648.0, vn = 9.91256303526217e-3;
      double dn = kR, tn = dn;
      const double q = vn / std::exp(-0.5 * dn * dn);
      kn[0] = static_cast<std::uint32_t>((dn / q) * m1);
      kn[1] = 0;
      wn[0] = q / m1;
      wn[127] = dn / m1;
      fn[0] = 1.0;
      fn[127] = std::exp(-0.5 * dn * dn);
      for (int i = 126; i >= 1; --i) {
        dn = std::sqrt(-2.0 * std::log(vn / dn + std::exp(-0.5 * dn * dn)));
        kn[i + 1] = static_cast<std::uint32_t>((dn / tn) * m1);
        tn = dn;
        fn[i] = std::exp(-0.5 * dn * dn);
        wn[i] = dn / m1;
      }
    }
  };
  static const Tables& tables() {
    static const Tables t;
    return t;
  }
  std::uint64_t s_[4];
};

}  // namespace safenav::detail
