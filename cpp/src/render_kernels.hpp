// Private: the renderer's per-pixel loops (used by render.cpp only).  Each
// has an SSE2 body, 4 or 16 pixels a step, that performs the scalar loop's
// IEEE single-precision operations in the same order and rounds as the scalar
// conversions do, so both give the same bytes and floats; the scalar loop
// finishes the row (and is the whole loop off x86-64).
#pragma once

#include <cmath>
#include <cstdint>

#include <opencv2/core.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace safenav::render_detail {

#if defined(__SSE2__)
/// 16 bytes as four vectors of 4 int32.
inline void widen(__m128i px, __m128i w[4]) {
  const __m128i zero = _mm_setzero_si128();
  const __m128i lo = _mm_unpacklo_epi8(px, zero), hi = _mm_unpackhi_epi8(px, zero);
  w[0] = _mm_unpacklo_epi16(lo, zero);
  w[1] = _mm_unpackhi_epi16(lo, zero);
  w[2] = _mm_unpacklo_epi16(hi, zero);
  w[3] = _mm_unpackhi_epi16(hi, zero);
}

/// Four vectors of 4 int32 as 16 bytes, each saturated to [0, 255] (as
/// cv::saturate_cast<uchar> of an int: via int16, which keeps the sign).
inline __m128i narrow(const __m128i r[4]) {
  return _mm_packus_epi16(_mm_packs_epi32(r[0], r[1]), _mm_packs_epi32(r[2], r[3]));
}

/// floor(y) exactly, as std::floor: truncation is exact below 2²³, where a
/// float can have a fraction; from 2²³ on (and ±∞) y is its own floor; the
/// sign of y is kept (floor(−0) = −0).
inline __m128 floor_ps(__m128 y) {
  const __m128 sign = _mm_set1_ps(-0.0f);
  __m128 t = _mm_cvtepi32_ps(_mm_cvttps_epi32(y));
  t = _mm_sub_ps(t, _mm_and_ps(_mm_cmpgt_ps(t, y), _mm_set1_ps(1.0f)));
  t = _mm_or_ps(t, _mm_and_ps(y, sign));
  const __m128 big = _mm_cmpge_ps(_mm_andnot_ps(sign, y), _mm_set1_ps(8388608.0f));
  return _mm_or_ps(_mm_and_ps(big, y), _mm_andnot_ps(big, t));
}

/// mask ? a : b.
inline __m128 select(__m128 mask, __m128 a, __m128 b) { return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b)); }
#endif

/// p[q] = saturate_cast<uchar>(p[q] + t[q]·scale), q < n (pixel noise).
inline void add_noise_run(std::uint8_t* p, const float* t, float scale, int n) {
  int q = 0;
#if defined(__SSE2__)
  const __m128 s = _mm_set1_ps(scale);
  for (; q + 16 <= n; q += 16) {
    __m128i w[4];
    widen(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p + q)), w);
    for (int k = 0; k < 4; ++k)  // cvtps2dq rounds to nearest even, as cvRound's cvtss2si
      w[k] = _mm_cvtps_epi32(_mm_add_ps(_mm_cvtepi32_ps(w[k]), _mm_mul_ps(_mm_loadu_ps(t + q + 4 * k), s)));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(p + q), narrow(w));
  }
#endif
  for (; q < n; ++q) p[q] = cv::saturate_cast<std::uint8_t>(p[q] + t[q] * scale);
}

/// dst[i] = uchar((src[i] − m)·haze + m), i < n (the ground faded into haze;
/// the value lies in [0, 255], so the cast truncates).
inline void haze_run(const std::uint8_t* src, std::uint8_t* dst, float m, float haze, int n) {
  int i = 0;
#if defined(__SSE2__)
  const __m128 vm = _mm_set1_ps(m), vh = _mm_set1_ps(haze);
  for (; i + 16 <= n; i += 16) {
    __m128i w[4];
    widen(_mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i)), w);
    for (int k = 0; k < 4; ++k)
      w[k] = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(_mm_sub_ps(_mm_cvtepi32_ps(w[k]), vm), vh), vm));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + i), narrow(w));
  }
#endif
  for (; i < n; ++i) dst[i] = static_cast<std::uint8_t>((float(src[i]) - m) * haze + m);
}

/// The panorama coordinates of one background row at a heading: column p[i]
/// shifted by `shift`, wrapped into [0, pw), moved to the texture level
/// (x·a + b) and wrapped into [0, fw); row q[i] moved to the level.
inline void pano_row(float* p, float* q, int n, float shift, float pw, float a, float b, float fw) {
  int i = 0;
#if defined(__SSE2__)
  const __m128 vs = _mm_set1_ps(shift), vpw = _mm_set1_ps(pw), va = _mm_set1_ps(a), vb = _mm_set1_ps(b),
               vfw = _mm_set1_ps(fw), zero = _mm_setzero_ps();
  for (; i + 4 <= n; i += 4) {
    __m128 x = _mm_add_ps(_mm_loadu_ps(p + i), vs);
    x = _mm_sub_ps(x, _mm_mul_ps(vpw, floor_ps(_mm_div_ps(x, vpw))));
    x = _mm_add_ps(_mm_mul_ps(x, va), vb);
    const __m128 wrapped = select(_mm_cmplt_ps(x, vfw), x, _mm_sub_ps(x, vfw));
    _mm_storeu_ps(p + i, select(_mm_cmplt_ps(x, zero), _mm_add_ps(x, vfw), wrapped));
    _mm_storeu_ps(q + i, _mm_add_ps(_mm_mul_ps(_mm_loadu_ps(q + i), va), vb));
  }
#endif
  for (; i < n; ++i) {
    float x = p[i] + shift;
    x -= pw * std::floor(x / pw);
    x = x * a + b;
    p[i] = x < 0.0f ? x + fw : (x < fw ? x : x - fw);
    q[i] = q[i] * a + b;
  }
}

}  // namespace safenav::render_detail
