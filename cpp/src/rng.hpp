// Internal: small, fast, reproducible random number generators.
//
// Rng: xoshiro256++ (Blackman & Vigna, public domain) seeded through
// splitmix64, and standard normals by the ziggurat method (Marsaglia & Tsang
// 2000, 128 layers, with the tail and wedge handled exactly).  Unlike
// std::normal_distribution the sequence is fixed by this file, so results are
// identical across standard libraries and platforms for a given seed.
//
// BatchRng: the particle filter's generator.  Eight xoshiro256++ streams run
// side by side (one vector register lane each) and feed a 1024-layer ziggurat
// that makes normals in batches; on x86-64 an AVX2 copy of the hot loops is
// chosen at run time.  Every path does the same IEEE operations in the same
// order, so a seed gives the same numbers on every machine and path.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "safenav/seed.hpp"

#if (defined(__GNUC__) || defined(__clang__)) && defined(__x86_64__) && !defined(__AVX2__) && \
    !defined(SAFENAV_NO_DISPATCH)
// The build targets baseline x86-64 (no -march): hot loops get a second copy
// compiled for AVX2 and chosen at run time.  AVX2 only, not FMA, so that both
// copies round identically (no contraction of a*b+c).
#define SAFENAV_AVX2_DISPATCH 1
#define SAFENAV_TARGET_AVX2 __attribute__((target("avx2")))
#endif
#if defined(SAFENAV_AVX2_DISPATCH) || (defined(__AVX2__) && defined(__x86_64__))
#define SAFENAV_HAVE_AVX2_CODE 1
#include <immintrin.h>
#ifndef SAFENAV_TARGET_AVX2
#define SAFENAV_TARGET_AVX2
#endif
#endif
#define SAFENAV_ALWAYS_INLINE inline __attribute__((always_inline))

namespace safenav::detail {

/// True when the AVX2 copies of the hot loops run: the CPU has AVX2 and the
/// environment variable SAFENAV_NO_AVX2 is not set (it forces the baseline
/// copies, e.g. to check that both give the same numbers).  Read once.
inline bool use_avx2() {
#if defined(SAFENAV_AVX2_DISPATCH)
  static const bool yes = __builtin_cpu_supports("avx2") && std::getenv("SAFENAV_NO_AVX2") == nullptr;
  return yes;
#elif defined(SAFENAV_HAVE_AVX2_CODE)
  return true;  // built for AVX2 (-march): there is no baseline copy
#else
  return false;
#endif
}

#if defined(SAFENAV_HAVE_AVX2_CODE)
template <auto Kernel, class... A>
SAFENAV_TARGET_AVX2 inline auto call_avx2(A... a) {
  return Kernel(a...);  // Kernel is always_inline: this copy is compiled for AVX2
}
#endif

/// Run an always_inline kernel: AvxKernel compiled for AVX2 where the CPU has
/// it, BaseKernel otherwise.  Kernels must give the same result either way:
/// element-wise IEEE arithmetic, and reductions over a fixed number of lanes
/// written out in the source (never a reduction whose order follows the
/// vector length).
template <auto AvxKernel, auto BaseKernel = AvxKernel, class... A>
inline auto dispatch(A... a) {
#if defined(SAFENAV_HAVE_AVX2_CODE)
  if (use_avx2()) return call_avx2<AvxKernel>(a...);
#endif
  return BaseKernel(a...);
}

inline std::uint64_t rotl64(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
inline std::uint64_t splitmix64(std::uint64_t& x) { return splitmix64_mix(x += kSplitmix64Gamma); }

/// Ziggurat tables with K layers (Marsaglia & Tsang 2000).  A 32-bit draw hz
/// picks layer iz = hz & (K−1); x = hz·wn[iz] is accepted at once when
/// |hz| < kn[iz].  That test equals |x| < tn[iz] with tn = kn·wn: rounding is
/// monotone, and |hz| ≠ kn differ by at least 2⁻³¹ in relative terms, far more
/// than a rounding, so the batched paths may use either form.
///
/// r (start of the tail) and v (area of each layer) make the top layer close
/// exactly; 128 layers uses Marsaglia & Tsang's published pair, 1024 layers a
/// pair solved the same way (bisection on r to 40 digits).
template <int K>
struct Ziggurat {
  static_assert(K == 128 || K == 1024, "ziggurat constants are given for 128 and 1024 layers");
  static constexpr int kMask = K - 1;
  static constexpr double kR = K == 128 ? 3.442619855899 : 4.0388498461095045;
  static constexpr double kV = K == 128 ? 9.91256303526217e-3 : 1.2263246463530881e-3;
  std::uint32_t kn[K];
  double wn[K], fn[K], tn[K];
  Ziggurat() {
    const double m1 = 2147483648.0, vn = kV;
    double dn = kR, tn_ = dn;
    const double q = vn / std::exp(-0.5 * dn * dn);
    kn[0] = static_cast<std::uint32_t>((dn / q) * m1);
    kn[1] = 0;
    wn[0] = q / m1;
    wn[K - 1] = dn / m1;
    fn[0] = 1.0;
    fn[K - 1] = std::exp(-0.5 * dn * dn);
    for (int i = K - 2; i >= 1; --i) {
      dn = std::sqrt(-2.0 * std::log(vn / dn + std::exp(-0.5 * dn * dn)));
      kn[i + 1] = static_cast<std::uint32_t>((dn / tn_) * m1);
      tn_ = dn;
      fn[i] = std::exp(-0.5 * dn * dn);
      wn[i] = dn / m1;
    }
    for (int i = 0; i < K; ++i) tn[i] = static_cast<double>(kn[i]) * wn[i];
  }
  static const Ziggurat& get() {
    static const Ziggurat t;
    return t;
  }
  static std::uint32_t magnitude(std::int32_t hz) {
    return hz < 0 ? 0u - static_cast<std::uint32_t>(hz) : static_cast<std::uint32_t>(hz);
  }
  /// The ziggurat for draw hz, including the wedges and the tail, with fresh
  /// draws from g on rejection.
  template <class G>
  double slow(G& g, std::int32_t hz) const {
    for (;;) {
      const int iz = hz & kMask;
      const double x = hz * wn[iz];
      if (magnitude(hz) < kn[iz]) return x;
      if (iz == 0) {  // tail beyond r
        double xt, yt;
        do {
          xt = -std::log(g.uniform_open()) / kR;
          yt = -std::log(g.uniform_open());
        } while (yt + yt < xt * xt);
        return hz > 0 ? kR + xt : -kR - xt;
      }
      if (fn[iz] + g.uniform() * (fn[iz - 1] - fn[iz]) < std::exp(-0.5 * x * x)) return x;  // wedge
      hz = static_cast<std::int32_t>(g.next_u64() >> 32);
    }
  }
};

class Rng {
 public:
  explicit Rng(std::uint64_t seed) {
    std::uint64_t z = seed;
    for (auto& s : s_) s = splitmix64(z);
  }
  std::uint64_t next_u64() {
    const std::uint64_t result = rotl64(s_[0] + s_[3], 23) + s_[0];
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl64(s_[3], 45);
    return result;
  }
  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }
  /// Uniform in (0, 1), never 0 (safe for log).
  double uniform_open() { return (static_cast<double>(next_u64() >> 11) + 0.5) * 0x1.0p-53; }
  /// Standard normal N(0, 1) (ziggurat).
  double normal() { return normal_from(static_cast<std::int32_t>(next_u64() >> 32), Zig::get()); }

  /// Fill out[0..n) with standard normals; two per 64-bit draw.
  void fill_normal(double* out, long n) {
    const Zig& T = Zig::get();
    long i = 0;
    for (; i + 1 < n; i += 2) {
      const std::uint64_t r = next_u64();
      out[i] = normal_from(static_cast<std::int32_t>(r >> 32), T);
      out[i + 1] = normal_from(static_cast<std::int32_t>(r & 0xffffffffULL), T);
    }
    if (i < n) out[i] = normal();
  }

 private:
  using Zig = Ziggurat<128>;
  /// Ziggurat for one 32-bit draw hz: the fast path (~97% of draws) is inline.
  double normal_from(std::int32_t hz, const Zig& T) {
    const int iz = hz & 127;
    if (__builtin_expect(Zig::magnitude(hz) < T.kn[iz], 1)) return hz * T.wn[iz];
    return normal_slow(hz, T);
  }
  __attribute__((noinline)) double normal_slow(std::int32_t hz, const Zig& T) { return T.slow(*this, hz); }
  std::uint64_t s_[4];
};

// ---------------------------------------------------------------------------
// BatchRng and its kernels
// ---------------------------------------------------------------------------

/// xoshiro256++ state of eight streams, one array per state word.  Lane j is
/// lane 0 advanced by j·2¹²⁸ (the generator's jump polynomial), so the streams
/// never overlap.  Two independent AVX2 registers (four SSE2 ones) per state
/// word keep the generator from waiting on the latency of one update.
struct XoshiroLanes {
  static constexpr int kLanes = 8;
  alignas(32) std::uint64_t s[4][kLanes];
};

/// A vector of Bytes/8 uint64 lanes (GCC/Clang vector extension).
template <int Bytes>
struct U64Vec {
  typedef std::uint64_t type __attribute__((vector_size(Bytes)));
};

/// One xoshiro256++ step of every lane of (s0, s1, s2, s3); the outputs go to o.
template <int Bytes, class Vec = typename U64Vec<Bytes>::type>
SAFENAV_ALWAYS_INLINE void xoshiro_step(Vec& s0, Vec& s1, Vec& s2, Vec& s3, std::uint64_t* o) {
  const Vec x = s0 + s3;
  const Vec r = ((x << 23) | (x >> 41)) + s0;
  std::memcpy(o, &r, sizeof r);
  const Vec t = s1 << 17;
  s2 ^= s0;
  s3 ^= s1;
  s1 ^= s2;
  s0 ^= s3;
  s2 ^= t;
  s3 = (s3 << 45) | (s3 >> 19);
}

/// Advance every stream `blocks` times; out[8b + j] is lane j's b-th draw.
/// Bytes = 32 groups the lanes in two AVX2 vectors per state word, 16 in four
/// SSE2 ones (named variables, so that they stay in registers): the numbers
/// are the same either way.
template <int Bytes>
SAFENAV_ALWAYS_INLINE void xoshiro_lanes_fill(XoshiroLanes* __restrict g, std::uint64_t* __restrict out, long blocks) {
  static_assert(XoshiroLanes::kLanes == 8 && (Bytes == 16 || Bytes == 32), "8 lanes in vectors of 2 or 4");
  using Vec = typename U64Vec<Bytes>::type;
  constexpr int W = Bytes / 8;
  Vec a0, a1, a2, a3, b0, b1, b2, b3, c0, c1, c2, c3, d0, d1, d2, d3;
  auto load = [&](Vec& v, int word, int k) { std::memcpy(&v, g->s[word] + W * k, Bytes); };
  auto store = [&](const Vec& v, int word, int k) { std::memcpy(g->s[word] + W * k, &v, Bytes); };
  load(a0, 0, 0), load(a1, 1, 0), load(a2, 2, 0), load(a3, 3, 0);
  load(b0, 0, 1), load(b1, 1, 1), load(b2, 2, 1), load(b3, 3, 1);
  if constexpr (W == 2) {
    load(c0, 0, 2), load(c1, 1, 2), load(c2, 2, 2), load(c3, 3, 2);
    load(d0, 0, 3), load(d1, 1, 3), load(d2, 2, 3), load(d3, 3, 3);
  }
  for (long k = 0; k < blocks; ++k) {
    std::uint64_t* o = out + XoshiroLanes::kLanes * k;
    xoshiro_step<Bytes>(a0, a1, a2, a3, o);
    xoshiro_step<Bytes>(b0, b1, b2, b3, o + W);
    if constexpr (W == 2) {
      xoshiro_step<Bytes>(c0, c1, c2, c3, o + 2 * W);
      xoshiro_step<Bytes>(d0, d1, d2, d3, o + 3 * W);
    }
  }
  store(a0, 0, 0), store(a1, 1, 0), store(a2, 2, 0), store(a3, 3, 0);
  store(b0, 0, 1), store(b1, 1, 1), store(b2, 2, 1), store(b3, 3, 1);
  if constexpr (W == 2) {
    store(c0, 0, 2), store(c1, 1, 2), store(c2, 2, 2), store(c3, 3, 2);
    store(d0, 0, 3), store(d1, 1, 3), store(d2, 2, 3), store(d3, 3, 3);
  }
}

using BatchZiggurat = Ziggurat<1024>;

/// Fast path of the ziggurat over the 2·npairs 32-bit halves of r: half h of
/// r[i] (h = 0 low, 1 high) becomes out[2i + h] = hz·wn[iz].  Returns how many
/// failed |x| < tn[iz]; their indices, increasing, are in rej[0..count).
SAFENAV_ALWAYS_INLINE long ziggurat_fast(const std::uint64_t* __restrict r, long npairs, double* __restrict out,
                                         int* __restrict rej, const BatchZiggurat* __restrict T) {
  long nrej = 0;
  for (long i = 0; i < 2 * npairs; ++i) {
    const std::int32_t hz = static_cast<std::int32_t>(static_cast<std::uint32_t>(r[i >> 1] >> (32 * (i & 1))));
    const int iz = hz & BatchZiggurat::kMask;
    const double x = hz * T->wn[iz];
    out[i] = x;
    rej[nrej] = static_cast<int>(i);
    nrej += !(std::fabs(x) < T->tn[iz]);
  }
  return nrej;
}

#if defined(SAFENAV_HAVE_AVX2_CODE)
/// ziggurat_fast eight halves at a time with AVX2 gathers (x86 is little-endian:
/// memory order is low half first); the same numbers.
SAFENAV_TARGET_AVX2 inline long ziggurat_fast_avx2(const std::uint64_t* __restrict r, long npairs,
                                                   double* __restrict out, int* __restrict rej,
                                                   const BatchZiggurat* __restrict T) {
  const __m256i mask = _mm256_set1_epi32(BatchZiggurat::kMask), sign = _mm256_set1_epi32(INT32_MIN);
  // masked gathers with a defined source (the unmasked intrinsics trip GCC's -Wuninitialized)
  const __m256i zero = _mm256_setzero_si256(), ones = _mm256_set1_epi32(-1);
  const __m256d zerod = _mm256_setzero_pd(), onesd = _mm256_castsi256_pd(ones);
  const int* kn = reinterpret_cast<const int*>(T->kn);
  long nrej = 0, i = 0;
  const long nh = 2 * npairs;
  for (; i + 8 <= nh; i += 8) {
    const __m256i hz = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(r + i / 2));
    const __m256i iz = _mm256_and_si256(hz, mask);
    // |hz| < kn[iz] as unsigned numbers: bias both by 2³¹ and compare signed
    const __m256i mag = _mm256_xor_si256(_mm256_abs_epi32(hz), sign);
    const __m256i lim = _mm256_xor_si256(_mm256_mask_i32gather_epi32(zero, kn, iz, ones, 4), sign);
    const unsigned ok = static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(lim, mag))));
    const __m128i iz0 = _mm256_castsi256_si128(iz), iz1 = _mm256_extracti128_si256(iz, 1);
    const __m256d w0 = _mm256_mask_i32gather_pd(zerod, T->wn, iz0, onesd, 8);
    const __m256d w1 = _mm256_mask_i32gather_pd(zerod, T->wn, iz1, onesd, 8);
    _mm256_storeu_pd(out + i, _mm256_mul_pd(_mm256_cvtepi32_pd(_mm256_castsi256_si128(hz)), w0));
    _mm256_storeu_pd(out + i + 4, _mm256_mul_pd(_mm256_cvtepi32_pd(_mm256_extracti128_si256(hz, 1)), w1));
    for (unsigned bad = ~ok & 0xffu; bad; bad &= bad - 1) rej[nrej++] = static_cast<int>(i) + __builtin_ctz(bad);
  }
  const long k = ziggurat_fast(r + i / 2, (nh - i) / 2, out + i, rej + nrej, T);  // the last < 8 halves
  for (long m = 0; m < k; ++m) rej[nrej + m] += static_cast<int>(i);
  return nrej + k;
}
#endif

/// The particle filter's generator: eight xoshiro256++ streams
/// (XoshiroLanes) and a 1024-layer ziggurat (0.4% of draws take the slow
/// path, against 2.7% with 128 layers) run over whole batches.  Scalar
/// draws (uniform(), the ziggurat's wedges and tail) come from a buffered
/// block of eight.
class BatchRng {
 public:
  explicit BatchRng(std::uint64_t seed) {
    std::uint64_t z = seed, st[4];
    for (auto& s : st) s = splitmix64(z);
    for (int j = 0; j < XoshiroLanes::kLanes; ++j) {
      for (int k = 0; k < 4; ++k) g_.s[k][j] = st[k];
      jump(st);
    }
  }
  std::uint64_t next_u64() {
    if (pos_ == XoshiroLanes::kLanes) {
      xoshiro_lanes_fill<16>(&g_, buf_, 1);
      pos_ = 0;
    }
    return buf_[pos_++];
  }
  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }
  /// Uniform in (0, 1), never 0 (safe for log).
  double uniform_open() { return (static_cast<double>(next_u64() >> 11) + 0.5) * 0x1.0p-53; }

  /// Fill out[0..n) with standard normals.  Works through the batch in
  /// chunks of kChunk pairs, so that the raw draws stay in L1.
  void fill_normal(double* out, long n) {
    constexpr long kChunk = 256;  // pairs (two normals per 64-bit draw)
    const BatchZiggurat& T = BatchZiggurat::get();
    const long npairs = n / 2;
    for (long p0 = 0; p0 < npairs; p0 += kChunk) {
      const long np = npairs - p0 < kChunk ? npairs - p0 : kChunk;
      const long blocks = (np + XoshiroLanes::kLanes - 1) / XoshiroLanes::kLanes;
      dispatch<xoshiro_lanes_fill<32>, xoshiro_lanes_fill<16>>(&g_, raw_, blocks);
      double* o = out + 2 * p0;
#if defined(SAFENAV_HAVE_AVX2_CODE)
      const long nrej = use_avx2() ? ziggurat_fast_avx2(raw_, np, o, rej_, &T) : ziggurat_fast(raw_, np, o, rej_, &T);
#else
      const long nrej = ziggurat_fast(raw_, np, o, rej_, &T);
#endif
      for (long k = 0; k < nrej; ++k) {  // ~0.4% of draws: the wedges and the tail
        const int i = rej_[k];
        o[i] = T.slow(*this, static_cast<std::int32_t>(static_cast<std::uint32_t>(raw_[i >> 1] >> (32 * (i & 1)))));
      }
    }
    if (n & 1) out[n - 1] = T.slow(*this, static_cast<std::int32_t>(next_u64() >> 32));
  }

 private:
  static void jump(std::uint64_t s[4]) {
    static constexpr std::uint64_t J[] = {0x180ec6d33cfd0abaULL, 0xd5a61266f0c9392cULL, 0xa9582618e03fc9aaULL,
                                          0x39abdc4529b1661cULL};
    std::uint64_t t[4] = {0, 0, 0, 0};
    for (std::uint64_t j : J)
      for (int b = 0; b < 64; ++b) {
        if (j & (1ULL << b))
          for (int k = 0; k < 4; ++k) t[k] ^= s[k];
        const std::uint64_t x = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= x;
        s[3] = rotl64(s[3], 45);
      }
    for (int k = 0; k < 4; ++k) s[k] = t[k];
  }
  XoshiroLanes g_;
  std::uint64_t buf_[XoshiroLanes::kLanes];
  int pos_ = XoshiroLanes::kLanes;
  alignas(32) std::uint64_t raw_[256];
  int rej_[512];
};

}  // namespace safenav::detail
