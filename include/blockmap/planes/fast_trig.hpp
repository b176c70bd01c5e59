// Polynomial trigonometry in float for the per-sample passes of the detector, where libm's
// double functions cost more than the arithmetic around them: the orientation cell of every
// sample's normal (acos, atan2) and the closed-form eigenvalues of every sample's
// neighbourhood (acos, cos, sin). Each is accurate far below what its caller resolves.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

namespace blockmap::planes {

// acos on [0, 1] within 2e-8 rad (Abramowitz and Stegun 4.4.46).
[[nodiscard]] inline float acos_unit(float x) noexcept {
  const float p =
      1.5707963050f +
      x * (-0.2145988016f +
           x * (0.0889789874f +
                x * (-0.0501743046f +
                     x * (0.0308918810f +
                          x * (-0.0170881256f + x * (0.0066700901f + x * -0.0012624911f))))));
  return std::sqrt(std::max(1.0f - x, 0.0f)) * p;
}

// acos on [-1, 1], by acos(-x) = pi - acos(x).
[[nodiscard]] inline float acos_signed(float x) noexcept {
  const float a = acos_unit(std::abs(x));
  return x < 0.0f ? std::numbers::pi_v<float> - a : a;
}

// cos and sin on [0, pi/3] within 5e-7 (their Taylor series to the 8th and 9th powers).
[[nodiscard]] inline float cos_small(float t) noexcept {
  const float t2 = t * t;
  return 1.0f +
         t2 * (-1.0f / 2.0f + t2 * (1.0f / 24.0f + t2 * (-1.0f / 720.0f + t2 * (1.0f / 40320.0f))));
}
[[nodiscard]] inline float sin_small(float t) noexcept {
  const float t2 = t * t;
  return t * (1.0f + t2 * (-1.0f / 6.0f + t2 * (1.0f / 120.0f +
                                                t2 * (-1.0f / 5040.0f + t2 * (1.0f / 362880.0f)))));
}

// atan2 within 1e-5 rad (a minimax polynomial for atan on [0, 1]).
[[nodiscard]] inline float fast_atan2(float y, float x) noexcept {
  constexpr float kPiF = std::numbers::pi_v<float>;
  const float ax = std::abs(x);
  const float ay = std::abs(y);
  const float big = std::max(ax, ay);
  if (big == 0.0f) {
    return 0.0f;
  }
  const float a = std::min(ax, ay) / big;
  const float a2 = a * a;
  float r =
      a *
      (0.99997726f +
       a2 * (-0.33262347f +
             a2 * (0.19354346f + a2 * (-0.11643287f + a2 * (0.05265332f + a2 * -0.01172120f)))));
  r = ay > ax ? kPiF / 2.0f - r : r;
  r = x < 0.0f ? kPiF - r : r;
  return y < 0.0f ? -r : r;
}

}  // namespace blockmap::planes
