#pragma once

// Float-to-grid conversions for the hot loops. std::lround and std::floor are library calls on
// the baseline x86-64 target (no SSE4.1 rounding instructions without -march), and they showed
// as a tenth of the raycast's time.

namespace objscan::fusion {

/// x limited to +-1e9, NaN to -1e9, so that the conversion to int is always defined (a point just
/// in front of the camera projects arbitrarily far out; callers bound-check the result).
inline float saturate(float x) { return x > -1e9f ? (x < 1e9f ? x : 1e9f) : -1e9f; }

/// The largest integer <= x.
inline int floorToInt(float x) {
  x = saturate(x);
  const int i = static_cast<int>(x);  // truncates toward zero
  return i - (static_cast<float>(i) > x ? 1 : 0);
}

/// The nearest integer (halves round up).
inline int roundToInt(float x) { return floorToInt(x + 0.5f); }

}  // namespace objscan::fusion
