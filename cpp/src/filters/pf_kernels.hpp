// Private: the particle filter's per-particle kernels (used by pf_impl.hpp only).
//
// Layout: structure of arrays, one contiguous column per component (x, y, v,
// θ, and cos θ, sin θ kept in step with θ), log-weights and weights in their
// own arrays.  Each per-particle pass below is a branch-free loop over those
// arrays (an always_inline "kernel") that detail::dispatch runs from a copy
// compiled for AVX2 where the CPU has it, and from the baseline x86-64 copy
// elsewhere.  Sums over particles accumulate in four lanes written out in the
// source (D4), so the result, to the last bit, does not depend on which copy
// ran.  No step allocates.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>

#include "../rng.hpp"
#include "safenav/motion.hpp"

namespace safenav::detail {

/// Taylor coefficients as constants (the core's -frounding-math, from CGAL,
/// stops the compiler folding 1.0/k! itself): 1/k! for exp, and
/// (−1)^k/(2k+1)!, (−1)^k/(2k)! for sin and cos in powers of x².
struct Coefficients {
  double v[14];
  constexpr Coefficients(int first, int step, bool alternate) : v() {
    for (int k = 0; k < 14; ++k) {
      double f = 1.0;
      for (int j = 2; j <= first + step * k; ++j) f *= j;  // exact up to 18! (< 2⁵³); 13! is the most used
      v[k] = (alternate && k % 2 ? -1.0 : 1.0) / f;
    }
  }
  constexpr double operator[](int k) const { return v[k]; }
};
constexpr Coefficients kInvFactorial(0, 1, false), kSin(1, 2, true), kCos(0, 2, true);

/// Four doubles (particles i..i+3) as one 32-byte vector (Bytes = 32, AVX2)
/// or two 16-byte ones (Bytes = 16, SSE2): the same lanes and the same IEEE
/// operations either way.  Sums over particles accumulate in a D4 (lane j
/// takes particles j, j+4, ...) and end in sum(), a fixed order, so reductions
/// give identical bits on both paths.  (Arguments by reference: a 32-byte
/// vector by value has a different ABI without AVX, which GCC remarks on.)
template <int Bytes>
struct D4;
template <>
struct D4<32> {
  typedef double V __attribute__((vector_size(32)));
  V v;
  static D4 load(const double* p) { D4 r; std::memcpy(&r.v, p, 32); return r; }
  static D4 splat(double a) { return {V{a, a, a, a}}; }
  void store(double* p) const { std::memcpy(p, &v, 32); }
  friend D4 operator+(const D4& a, const D4& b) { return {a.v + b.v}; }
  friend D4 operator-(const D4& a, const D4& b) { return {a.v - b.v}; }
  friend D4 operator*(const D4& a, const D4& b) { return {a.v * b.v}; }
  D4& operator+=(const D4& b) { v += b.v; return *this; }
  /// a > b ? a + c : a  (and a <= b ? a + c : a), lane-wise
  static D4 add_if_gt(const D4& a, const D4& b, const D4& c) { return {a.v > b.v ? a.v + c.v : a.v}; }
  static D4 add_if_le(const D4& a, const D4& b, const D4& c) { return {a.v <= b.v ? a.v + c.v : a.v}; }
  double sum() const { return (v[0] + v[1]) + (v[2] + v[3]); }
};
template <>
struct D4<16> {
  typedef double V __attribute__((vector_size(16)));
  V lo, hi;
  static D4 load(const double* p) { D4 r; std::memcpy(&r.lo, p, 16); std::memcpy(&r.hi, p + 2, 16); return r; }
  static D4 splat(double a) { return {V{a, a}, V{a, a}}; }
  void store(double* p) const { std::memcpy(p, &lo, 16); std::memcpy(p + 2, &hi, 16); }
  friend D4 operator+(D4 a, D4 b) { return {a.lo + b.lo, a.hi + b.hi}; }
  friend D4 operator-(D4 a, D4 b) { return {a.lo - b.lo, a.hi - b.hi}; }
  friend D4 operator*(D4 a, D4 b) { return {a.lo * b.lo, a.hi * b.hi}; }
  D4& operator+=(D4 b) { lo += b.lo; hi += b.hi; return *this; }
  static D4 add_if_gt(D4 a, D4 b, D4 c) {
    return {a.lo > b.lo ? a.lo + c.lo : a.lo, a.hi > b.hi ? a.hi + c.hi : a.hi};
  }
  static D4 add_if_le(D4 a, D4 b, D4 c) {
    return {a.lo <= b.lo ? a.lo + c.lo : a.lo, a.hi <= b.hi ? a.hi + c.hi : a.hi};
  }
  double sum() const { return (lo[0] + lo[1]) + (hi[0] + hi[1]); }
};

/// Run body(i, in, n) over the particles in blocks of four: in[c] holds
/// column c of particles i..i+3, n how many of them are real.  The last,
/// partial block is zero-padded, so a weight column is 0 beyond N and the
/// padding adds exactly nothing to any weighted sum (the body stores only n
/// lanes).
template <int Bytes, int K, class Body>
SAFENAV_ALWAYS_INLINE void blocks_of_four(int N, const double* const (&cols)[K], Body&& body) {
  using D = D4<Bytes>;
  int i = 0;
  for (; i + 4 <= N; i += 4) {
    D in[K];
    for (int c = 0; c < K; ++c) in[c] = D::load(cols[c] + i);
    body(i, in, 4);
  }
  if (i < N) {
    double pad[K][4] = {};
    for (int c = 0; c < K; ++c)
      for (int j = 0; i + j < N; ++j) pad[c][j] = cols[c][i + j];
    D in[K];
    for (int c = 0; c < K; ++c) in[c] = D::load(pad[c]);
    body(i, in, N - i);
  }
}

/// Store the first n lanes of a D4 at p.
template <int Bytes>
SAFENAV_ALWAYS_INLINE void store_lanes(const D4<Bytes>& a, double* p, int n) {
  if (n == 4) {
    a.store(p);
  } else {
    double tmp[4];
    a.store(tmp);
    for (int j = 0; j < n; ++j) p[j] = tmp[j];
  }
}

/// a wrapped to (−π, π] for a in (−3π, 3π] (an angle in (−π, π] moved by
/// less than 2π): one comparison each way, as wrap_angle there, branch-free
/// so that the loops calling it vectorise.
SAFENAV_ALWAYS_INLINE double wrap_once(double a) {
  constexpr double two_pi = 2.0 * kPi;
  a = a > kPi ? a - two_pi : a;
  return a <= -kPi ? a + two_pi : a;
}

/// (cos(θ + δ), sin(θ + δ)) from (c, s) = (cos θ, sin θ) for a small turn δ
/// (|δ| ≤ kSmallTurn): sin δ = δ Σ_k s_k u^k, cos δ = Σ_k c_k u^k (u = δ²) in
/// Estrin's form (a short dependency chain, which is what bounds the loops
/// that call this), the rotation, and one Newton step back onto the unit
/// circle.
SAFENAV_ALWAYS_INLINE void turn_small(double d, double c, double s, double& c_out, double& s_out) {
  const double u = d * d, u2 = u * u, u4 = u2 * u2;
  const double sd = d * (((1 + kSin[1] * u) + (kSin[2] + kSin[3] * u) * u2) + (kSin[4] + kSin[5] * u) * u4);
  const double cd =
      ((1 + kCos[1] * u) + (kCos[2] + kCos[3] * u) * u2) + ((kCos[4] + kCos[5] * u) + kCos[6] * u2) * u4;
  const double c1 = c * cd - s * sd;
  const double s1 = s * cd + c * sd;
  const double r = 1.5 - 0.5 * (c1 * c1 + s1 * s1);  // keep (c, s) on the unit circle
  c_out = c1 * r;
  s_out = s1 * r;
}

/// One noisy BMM step (eqs. 3, 4, 6, 7/9, as Bmm::transition) for every
/// particle.  θ moves by δ_i; (cos θ, sin θ) is rotated by δ_i with sin δ and
/// cos δ from their Taylor series (truncation error < 1e-17 for |δ| ≤
/// kSmallTurn, rounding within 1.5 eps; larger turns are redone exactly by
/// the caller, which is told how many there were).  Element-wise, so left to the auto-vectoriser;
/// it needs -fno-trapping-math to if-convert the clamps.  (Kernels take their
/// arrays as __restrict parameters: GCC honours restrict there, through
/// inlining, and not on local copies.)
struct StepParams {
  double vdes, heading_step, up_step, down_step, vmin, vmax, k, sv, st, sp;
};
constexpr double kSmallTurn = 0.25;
SAFENAV_ALWAYS_INLINE long particles_step(int N, double* __restrict x, double* __restrict y, double* __restrict v,
                                          double* __restrict th, double* __restrict cs, double* __restrict sn,
                                          const double* __restrict ex, const double* __restrict ey,
                                          const double* __restrict ev, const double* __restrict et,
                                          const StepParams* a) {
  const double vdes = a->vdes, heading_step = a->heading_step, up_step = a->up_step, down_step = a->down_step,
               vmin = a->vmin, vmax = a->vmax, k = a->k, sv = a->sv, st = a->st, sp = a->sp;
  long n_big = 0;  // turns with |δ| > kSmallTurn (64-bit, like the doubles, so that the loop vectorises)
  for (int i = 0; i < N; ++i) {
    // eq. 3 (Bmm::next_speed) + ε_v, clamped to [v_min, v_max] (v_min = 0, or
    // −v_max with BmmParams::unicycle, whose steps of 2·v_max never bind)
    const double vi = v[i];
    double up = vi + up_step;
    up = up < vdes ? up : vdes;
    up = up < vmax ? up : vmax;
    double down = vi - down_step;
    down = down > vdes ? down : vdes;
    down = down > vmin ? down : vmin;
    down = down < vmax ? down : vmax;
    double v1 = (vdes > vi ? up : down) + sv * ev[i];
    v1 = v1 > vmin ? v1 : vmin;
    v1 = v1 < vmax ? v1 : vmax;
    v[i] = v1;
    // eq. 4 + ε_θ: θ moves by δ; rotate (cos θ, sin θ) by δ.
    const double d = heading_step + st * et[i];
    n_big += (d > kSmallTurn) | (d < -kSmallTurn);
    double c2, s2;
    turn_small(d, cs[i], sn[i], c2, s2);
    cs[i] = c2;
    sn[i] = s2;
    th[i] = wrap_once(th[i] + d);  // exact for |δ| < π
    // eq. 7/9 + (ε_x, ε_y): position moves with the updated v and θ
    x[i] += k * v1 * c2 + sp * ex[i];
    y[i] += k * v1 * s2 + sp * ey[i];
  }
  return n_big;
}

/// Position update: logw_i −= ½ d_iᵀ R⁻¹ d_i with d_i = z − (x_i, y_i), and
/// the prior-weighted moments of d for the NIS: (Σw d0, Σw d1, Σw d0²,
/// Σw d0 d1, Σw d1²).
struct PositionParams {
  double z0, z1, r00, r01, r11;  // r = ½ R⁻¹ (r01 doubled: the cross term appears twice)
};
struct Sums5 {
  double s[5];
};
template <int Bytes>
SAFENAV_ALWAYS_INLINE Sums5 position_loglik(int N, const double* __restrict x, const double* __restrict y,
                                            const double* __restrict w, double* __restrict logw,
                                            const PositionParams* a) {
  using D = D4<Bytes>;
  const D z0 = D::splat(a->z0), z1 = D::splat(a->z1), r00 = D::splat(a->r00), r01 = D::splat(a->r01),
          r11 = D::splat(a->r11);
  D s0 = D::splat(0), s1 = s0, s00 = s0, s01 = s0, s11 = s0;
  const double* const cols[4] = {x, y, w, logw};
  blocks_of_four<Bytes>(N, cols, [&](int i, const D* in, int n) __attribute__((always_inline)) {
    const D d0 = z0 - in[0], d1 = z1 - in[1];
    const D w0 = in[2] * d0, w1 = in[2] * d1;
    s0 += w0;
    s1 += w1;
    s00 += w0 * d0;
    s01 += w0 * d1;
    s11 += w1 * d1;
    store_lanes(in[3] - (r00 * d0 * d0 + r01 * d0 * d1 + r11 * d1 * d1), logw + i, n);
  });
  return {{s0.sum(), s1.sum(), s00.sum(), s01.sum(), s11.sum()}};
}

/// exp(x) for x in [−700, 0], within 2 ulp (exp(0) = 1 exactly), in plain
/// arithmetic that vectorises: x = n·ln2 + r with |r| ≤ ½ln2, exp(r) by its
/// Taylor series to r¹³ (remainder < 5e-18), 2ⁿ put into the exponent bits.
SAFENAV_ALWAYS_INLINE double exp_nonpositive(double x) {
  constexpr double kInvLn2 = 1.4426950408889634, kLn2Hi = 0x1.62e42fee00000p-1, kLn2Lo = 0x1.a39ef35793c76p-33;
  constexpr double kShift = 0x1.8p52;  // adding it rounds to an integer held in the low mantissa bits
  const double kd = x * kInvLn2 + kShift;
  const double n = kd - kShift;
  const double r = (x - n * kLn2Hi) - n * kLn2Lo;  // n·kLn2Hi is exact
  // Estrin's scheme: a short dependency chain (Horner's 13 steps made this
  // loop latency-bound)
  const auto& c = kInvFactorial;
  const double r2 = r * r, r4 = r2 * r2, r8 = r4 * r4;
  const double q0 = c[0] + c[1] * r, q1 = c[2] + c[3] * r, q2 = c[4] + c[5] * r, q3 = c[6] + c[7] * r,
               q4 = c[8] + c[9] * r, q5 = c[10] + c[11] * r, q6 = c[12] + c[13] * r;
  const double p = ((q0 + q1 * r2) + (q2 + q3 * r2) * r4) + ((q4 + q5 * r2) + q6 * r4) * r8;
  std::uint64_t bits;
  std::memcpy(&bits, &kd, sizeof bits);
  bits = (bits << 52) + (std::uint64_t{1023} << 52);  // 2ⁿ: n sits in the low bits of kd, n ≥ −1022
  double scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

/// Normalisation, first pass (element-wise): floor the log-weights at
/// mx + floor and set w_i = exp(logw_i − mx).
SAFENAV_ALWAYS_INLINE void exp_weights(int N, double* __restrict logw, double* __restrict w, double mx, double floor) {
  const double lo = mx + floor;
  for (int i = 0; i < N; ++i) {
    double l = logw[i];
    l = l > lo ? l : lo;
    logw[i] = l;
    w[i] = exp_nonpositive(l - mx);
  }
}

/// Σ w_i.
template <int Bytes>
SAFENAV_ALWAYS_INLINE double sum_weights(int N, const double* __restrict w) {
  using D = D4<Bytes>;
  D s = D::splat(0);
  const double* const cols[1] = {w};
  blocks_of_four<Bytes>(N, cols, [&](int, const D* in, int) __attribute__((always_inline)) { s += in[0]; });
  return s.sum();
}

/// Normalisation, second pass: w_i ·= 1/Σw, logw_i −= log Σ (the
/// log-sum-exp); returns Σ w_i² (for the ESS).
template <int Bytes>
SAFENAV_ALWAYS_INLINE double scale_weights(int N, double* __restrict logw, double* __restrict w, double inv,
                                           double lse) {
  using D = D4<Bytes>;
  const D dinv = D::splat(inv), dlse = D::splat(lse);
  D s = D::splat(0);
  const double* const cols[2] = {w, logw};
  blocks_of_four<Bytes>(N, cols, [&](int i, const D* in, int n) __attribute__((always_inline)) {
    const D wi = in[0] * dinv;  // zero in padding lanes
    s += wi * wi;
    store_lanes(wi, w + i, n);
    store_lanes(in[1] - dlse, logw + i, n);
  });
  return s.sum();
}

/// Weighted sums for the mean: Σw x, Σw y, Σw v, Σw cos θ, Σw sin θ.
template <int Bytes>
SAFENAV_ALWAYS_INLINE Sums5 mean_sums(int N, const double* __restrict x, const double* __restrict y,
                                      const double* __restrict v, const double* __restrict cs,
                                      const double* __restrict sn, const double* __restrict w) {
  using D = D4<Bytes>;
  D s0 = D::splat(0), s1 = s0, s2 = s0, s3 = s0, s4 = s0;
  const double* const cols[6] = {x, y, v, cs, sn, w};
  blocks_of_four<Bytes>(N, cols, [&](int, const D* in, int) __attribute__((always_inline)) {
    const D wi = in[5];
    s0 += wi * in[0];
    s1 += wi * in[1];
    s2 += wi * in[2];
    s3 += wi * in[3];
    s4 += wi * in[4];
  });
  return {{s0.sum(), s1.sum(), s2.sum(), s3.sum(), s4.sum()}};
}

/// d wrapped to (−π, π] for d in (−2π, 2π) (a difference of two angles in
/// (−π, π]), lane-wise: one comparison each way, as wrap_angle there.
template <int Bytes>
SAFENAV_ALWAYS_INLINE D4<Bytes> wrap_difference(D4<Bytes> d) {
  using D = D4<Bytes>;
  d = D::add_if_gt(d, D::splat(kPi), D::splat(-2.0 * kPi));
  return D::add_if_le(d, D::splat(-kPi), D::splat(2.0 * kPi));
}

/// The deviations (x − m, y − m, v − m, θ − m wrapped) of four particles.
template <int Bytes>
SAFENAV_ALWAYS_INLINE void deviations4(const D4<Bytes>* in, const double* m, D4<Bytes> (&d)[4]) {
  using D = D4<Bytes>;
  for (int k = 0; k < 3; ++k) d[k] = in[k] - D::splat(m[k]);
  d[3] = wrap_difference<Bytes>(in[3] - D::splat(m[3]));
}

/// Weighted second moments Σ w_i d_i d_iᵀ about m, θ deviations wrapped (θ_i
/// and m[3] are both in (−π, π]: one wrap suffices); the upper triangle, row
/// by row.
struct Sums10 {
  double s[10];
};
template <int Bytes>
SAFENAV_ALWAYS_INLINE Sums10 covariance_sums(int N, const double* __restrict x, const double* __restrict y,
                                             const double* __restrict v, const double* __restrict th,
                                             const double* __restrict w, const State* m) {
  using D = D4<Bytes>;
  D a0 = D::splat(0), a1 = a0, a2 = a0, a3 = a0, a4 = a0, a5 = a0, a6 = a0, a7 = a0, a8 = a0, a9 = a0;
  const double* const cols[5] = {x, y, v, th, w};
  blocks_of_four<Bytes>(N, cols, [&](int, const D* in, int) __attribute__((always_inline)) {
    D d[4];
    deviations4<Bytes>(in, m->data(), d);
    const D &d0 = d[0], &d1 = d[1], &d2 = d[2], &d3 = d[3];
    const D wi = in[4];
    const D w0 = wi * d0, w1 = wi * d1, w2 = wi * d2, w3 = wi * d3;
    a0 += w0 * d0;
    a1 += w0 * d1;
    a2 += w0 * d2;
    a3 += w0 * d3;
    a4 += w1 * d1;
    a5 += w1 * d2;
    a6 += w1 * d3;
    a7 += w2 * d2;
    a8 += w2 * d3;
    a9 += w3 * d3;
  });
  return {{a0.sum(), a1.sum(), a2.sum(), a3.sum(), a4.sum(), a5.sum(), a6.sum(), a7.sum(), a8.sum(), a9.sum()}};
}

/// Resampling copy: pointer j takes particle src_j = max(start_0..start_j)
/// (see ParticleFilter::Impl::resample); all six columns of a particle are
/// copied together, which keeps the loop at the stores' pace.
inline void copy_selected(int N, const int* __restrict start, const double* __restrict f0,
                          const double* __restrict f1, const double* __restrict f2, const double* __restrict f3,
                          const double* __restrict f4, const double* __restrict f5, double* __restrict t0,
                          double* __restrict t1, double* __restrict t2, double* __restrict t3, double* __restrict t4,
                          double* __restrict t5) {
  int src = 0;
  for (int j = 0; j < N; ++j) {
    src = std::max(src, start[j]);
    t0[j] = f0[src];
    t1[j] = f1[src];
    t2[j] = f2[src];
    t3[j] = f3[src];
    t4[j] = f4[src];
    t5[j] = f5[src];
  }
}

/// The moments of an update by h(x) = (v, θ) (the IMU's speed and heading)
/// in one pass: with y_i = (z_v − v_i, z_θ − θ_i wrapped) (z_θ in (−π, π]) and
/// d_i the deviations about m, the sums Σw y0, Σw y1, Σw y0², Σw y0 y1,
/// Σw y1², Σw d_k (k = 0..3), Σw d_k y0, Σw d_k y1; and the log-likelihood
/// −½ y_iᵀR⁻¹y_i of every particle into `gain`.
struct ImuParams {
  double zv, zt, r00, r01, r11;  // r = ½ R⁻¹ (r01 doubled)
  double m[4];
};
struct Sums17 {
  double s[17];
};
template <int Bytes>
SAFENAV_ALWAYS_INLINE Sums17 imu_moments(int N, const double* __restrict x, const double* __restrict y,
                                         const double* __restrict v, const double* __restrict th,
                                         const double* __restrict w, double* __restrict gain, const ImuParams* a) {
  using D = D4<Bytes>;
  const D zv = D::splat(a->zv), zt = D::splat(a->zt), r00 = D::splat(a->r00), r01 = D::splat(a->r01),
          r11 = D::splat(a->r11);
  D acc[17];
  for (D& t : acc) t = D::splat(0);
  const double* const cols[5] = {x, y, v, th, w};
  blocks_of_four<Bytes>(N, cols, [&](int i, const D* in, int n) __attribute__((always_inline)) {
    D d[4];
    deviations4<Bytes>(in, a->m, d);
    const D y0 = zv - in[2], y1 = wrap_difference<Bytes>(zt - in[3]);
    const D w0 = in[4] * y0, w1 = in[4] * y1;
    acc[0] += w0;
    acc[1] += w1;
    acc[2] += w0 * y0;
    acc[3] += w0 * y1;
    acc[4] += w1 * y1;
    for (int k = 0; k < 4; ++k) {
      const D wd = in[4] * d[k];
      acc[5 + k] += wd;
      acc[9 + k] += wd * y0;
      acc[13 + k] += wd * y1;
    }
    store_lanes(D::splat(0) - (r00 * y0 * y0 + r01 * y0 * y1 + r11 * y1 * y1), gain + i, n);
  });
  Sums17 r;
  for (int k = 0; k < 17; ++k) r.s[k] = acc[k].sum();
  return r;
}

/// The weighted moments of Kc columns of standard normal draws e (one row
/// per particle) and of the particles' deviations d about m, for matching
/// the draws (see ParticleFilter::Impl::match): Σw d_k, Σw e_j, Σw d_k e_j
/// and Σw e_j e_l (j ≤ l, row by row).
template <int Kc>
struct DrawSums {
  double d[4], e[Kc], de[4][Kc], ee[Kc * (Kc + 1) / 2];
};
template <int Kc>
struct DrawColumns {
  const double* p[5 + Kc];  // x, y, v, θ, w, e_0 .. e_{Kc−1}
  double m[4];
};
template <int Bytes, int Kc>
SAFENAV_ALWAYS_INLINE DrawSums<Kc> draw_moments(int N, const DrawColumns<Kc>* a) {
  using D = D4<Bytes>;
  D sd[4], se[Kc], sde[4][Kc], see[Kc * (Kc + 1) / 2];
  for (D& t : sd) t = D::splat(0);
  for (D& t : se) t = D::splat(0);
  for (auto& row : sde)
    for (D& t : row) t = D::splat(0);
  for (D& t : see) t = D::splat(0);
  const double* const(&cols)[5 + Kc] = a->p;
  blocks_of_four<Bytes>(N, cols, [&](int, const D* in, int) __attribute__((always_inline)) {
    D d[4];
    deviations4<Bytes>(in, a->m, d);
    const D* e = in + 5;
    D we[Kc];
    for (int j = 0; j < Kc; ++j) {
      we[j] = in[4] * e[j];
      se[j] += we[j];
    }
    for (int k = 0; k < 4; ++k) {
      sd[k] += in[4] * d[k];
      for (int j = 0; j < Kc; ++j) sde[k][j] += we[j] * d[k];
    }
    for (int j = 0, q = 0; j < Kc; ++j)
      for (int l = j; l < Kc; ++l, ++q) see[q] += we[j] * e[l];
  });
  DrawSums<Kc> r;
  for (int k = 0; k < 4; ++k) r.d[k] = sd[k].sum();
  for (int j = 0; j < Kc; ++j) r.e[j] = se[j].sum();
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < Kc; ++j) r.de[k][j] = sde[k][j].sum();
  for (int q = 0; q < Kc * (Kc + 1) / 2; ++q) r.ee[q] = see[q].sum();
  return r;
}

/// Matched process noise in place: e_i ← T e_i + Q d_i + c for the four
/// noise columns (d_i the deviations about m; see ParticleFilter::Impl::match).
struct NoiseMap {
  double T[4][4], Q[4][4], c[4], m[4];
};
template <int Bytes>
SAFENAV_ALWAYS_INLINE void map_noise(int N, const double* __restrict x, const double* __restrict y,
                                     const double* __restrict v, const double* __restrict th, double* __restrict e0,
                                     double* __restrict e1, double* __restrict e2, double* __restrict e3,
                                     const NoiseMap* a) {
  using D = D4<Bytes>;
  const double* const cols[8] = {x, y, v, th, e0, e1, e2, e3};
  double* const out[4] = {e0, e1, e2, e3};
  blocks_of_four<Bytes>(N, cols, [&](int i, const D* in, int n) __attribute__((always_inline)) {
    D d[4];
    deviations4<Bytes>(in, a->m, d);
    for (int k = 0; k < 4; ++k) {
      D r = D::splat(a->c[k]);
      for (int j = 0; j < 4; ++j) r += D::splat(a->T[k][j]) * in[4 + j];
      for (int j = 0; j < 4; ++j) r += D::splat(a->Q[k][j]) * d[j];
      store_lanes(r, out[k] + i, n);
    }
  });
}

/// The ensemble update of an IMU measurement (ParticleFilter::Impl::
/// ensemble_update), applied: with y_i the residual (as imu_moments), e_i
/// the two draws and d_i the deviations about m,
///   Δx_i = K y_i + A e_i + Q d_i + c,
/// v clamped to [v_min, v_max], θ wrapped, (cos θ, sin θ) turned by Δθ_i
/// (turn_small), Δθ_i kept in `dth`; returns how many |Δθ_i| exceed
/// kSmallTurn (the caller redoes those exactly).
struct ImuApply {
  double zv, zt, m[4], K[4][2], A[4][2], Q[4][4], c[4], vmin, vmax;
};
SAFENAV_ALWAYS_INLINE long imu_apply(int N, double* __restrict x, double* __restrict y, double* __restrict v,
                                     double* __restrict th, double* __restrict cs, double* __restrict sn,
                                     const double* __restrict e0, const double* __restrict e1,
                                     double* __restrict dth, const ImuApply* a) {
  const ImuApply p = *a;
  long n_big = 0;
  for (int i = 0; i < N; ++i) {
    const double t0 = th[i];
    const double d[4] = {x[i] - p.m[0], y[i] - p.m[1], v[i] - p.m[2], wrap_once(t0 - p.m[3])};
    const double y0 = p.zv - v[i], y1 = wrap_once(p.zt - t0);
    double dx[4];
    for (int k = 0; k < 4; ++k)
      dx[k] = (((p.K[k][0] * y0 + p.K[k][1] * y1) + (p.A[k][0] * e0[i] + p.A[k][1] * e1[i])) +
               ((p.Q[k][0] * d[0] + p.Q[k][1] * d[1]) + (p.Q[k][2] * d[2] + p.Q[k][3] * d[3]))) +
              p.c[k];
    x[i] += dx[0];
    y[i] += dx[1];
    double v1 = v[i] + dx[2];
    v1 = v1 > p.vmin ? v1 : p.vmin;
    v1 = v1 < p.vmax ? v1 : p.vmax;
    v[i] = v1;
    const double dt = dx[3];
    dth[i] = dt;
    n_big += (dt > kSmallTurn) | (dt < -kSmallTurn);
    double c2, s2;
    turn_small(dt, cs[i], sn[i], c2, s2);
    cs[i] = c2;
    sn[i] = s2;
    th[i] = wrap_once(t0 + dt);  // exact for |Δθ| < π; larger turns are redone by the caller
  }
  return n_big;
}

}  // namespace safenav::detail
