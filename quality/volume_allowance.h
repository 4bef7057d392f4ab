#pragma once
// How far operations that move the surface (curved slides, feature-line slides, boundary flips
// between faces that are not coplanar) may change each label's volume: an operation that would
// take a label's net change past its limit is refused (flat slides and flips keep volumes
// exactly and spend nothing).
#include <cmath>
#include <unordered_map>

namespace incise {

struct VolumeAllowance {
  std::unordered_map<int, double> limit;  // per label, absolute volume
  std::unordered_map<int, double> moved;  // per label, net change so far
  // Whether `label` may change by `delta` more.
  bool allows(int label, double delta) const {
    const auto lim = limit.find(label);
    if (lim == limit.end()) return false;
    const auto m = moved.find(label);
    return std::abs((m == moved.end() ? 0.0 : m->second) + delta) <= lim->second;
  }
};

}  // namespace incise
